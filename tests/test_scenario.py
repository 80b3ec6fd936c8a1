"""Scenarios: validation naming the field, TOML round trip, with_values."""

from __future__ import annotations

import math

import pytest

from meanfield import Domain, ParameterError, Scenario, load_scenario, paper_scenario
from meanfield.scenario import CrowdSpec, KernelSpec, RobotSpec, TargetSpec

from .conftest import PENTAGON


def _err(call) -> ParameterError:
    with pytest.raises(ParameterError) as info:
        call()
    return info.value


def test_toml_round_trip_paper():
    sc = paper_scenario()
    back = Scenario.from_toml(sc.to_toml())
    assert back.to_dict() == sc.to_dict()
    assert back.to_toml() == sc.to_toml()


@pytest.mark.parametrize("domain", [Domain.disk(0.8, (0.2, -0.1)), Domain.polygon(PENTAGON)])
def test_toml_round_trip_other_shapes(domain):
    sc = Scenario(
        domain=domain,
        robots=RobotSpec(
            n=2,
            layout="explicit",
            positions=[list(domain.center), list(domain.center)],
            headings=[0.1, 2.0],
            u_max=None,
            omega_max=1.5,
        ),
        target=TargetSpec(center=domain.center, std=0.2),
        t_final=1.0,
    )
    back = Scenario.from_toml(sc.to_toml())
    assert back.to_dict() == sc.to_dict()
    assert back.domain == domain
    assert back.robots.u_max is None


def test_save_and_load(tmp_path):
    sc = paper_scenario(seed=5).replace(t_final=2.0)
    sc.save(tmp_path / "s.toml")
    back = load_scenario(tmp_path / "s.toml")
    assert back.to_dict() == sc.to_dict()
    assert load_scenario(tmp_path / "s.toml", seed=9).seed == 9
    assert load_scenario("paper").to_dict() == paper_scenario().to_dict()
    assert _err(lambda: load_scenario(tmp_path / "missing.toml")).name == "scenario"


def test_with_values_sets_and_validates():
    sc = paper_scenario()
    new = sc.with_values({"kernel.eta": 0.02, "robots.n": 9, "t_final": 1.5})
    assert new.kernel.eta == 0.02 and new.robots.n == 9 and new.t_final == 1.5
    assert sc.kernel.eta == paper_scenario().kernel.eta != 0.02  # the original is untouched
    assert _err(lambda: sc.with_values({"crowd.sigma": -1.0})).name == "crowd.sigma"
    assert _err(lambda: sc.with_values({"kernel.size": 1.0})).name == "kernel.size"
    assert _err(lambda: sc.with_values({"nope.c": 1.0})).name == "nope.c"


def test_steps():
    assert paper_scenario().replace(t_final=0.2, dt=0.01).steps == 20


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: CrowdSpec(sigma=-0.1), "crowd.sigma"),
        (lambda: CrowdSpec(sigma=math.nan), "crowd.sigma"),
        (lambda: CrowdSpec(n=0), "crowd.n"),
        (lambda: CrowdSpec(n=2.5), "crowd.n"),
        (lambda: KernelSpec(c=0.0), "kernel.c"),
        (lambda: KernelSpec(c=-1.0), "kernel.c"),
        (lambda: KernelSpec(eta=0.0), "kernel.eta"),
        (lambda: KernelSpec(eta=math.nan), "kernel.eta"),
        (lambda: Scenario(dt=0.0), "dt"),
        (lambda: Scenario(dt=-0.01), "dt"),
        (lambda: Scenario(dt=math.nan), "dt"),
        (lambda: Scenario(t_final=math.inf), "t_final"),
        (lambda: Scenario(seed=-1), "seed"),
        (
            lambda: Scenario(robots=RobotSpec(n=2, layout="explicit", positions=[[0.5, 0.5], [1.5, 0.5]])),
            "robots.positions[1]",
        ),
        (lambda: Scenario(target=TargetSpec(center=(10.0, 10.0), std=0.1)), "target.center"),
        (lambda: Scenario(target=TargetSpec(center=(0.5, math.nan))), "target.center[1]"),
    ],
)
def test_bad_fields_refused(call, name):
    assert _err(call).name == name


BAD_TOML = [
    ("[crowd]\nsigma = -0.5\n", "crowd.sigma"),
    ("[kernel]\nc = 0.0\n", "kernel.c"),
    ("[kernel]\neta = -1.0\n", "kernel.eta"),
    ("dt = 0.0\n", "dt"),
    ("dt = nan\n", "dt"),
    ("[kernel]\nc = nan\n", "kernel.c"),
    ("[crowd]\nn = 0\n", "crowd.n"),
    ('[robots]\nn = 1\nlayout = "explicit"\npositions = [[2.0, 0.5]]\nheadings = [0.0]\n', "robots.positions[0]"),
    ("[target]\ncenter = [50.0, 50.0]\nstd = 0.1\n", "target.center"),
    ("[crowd]\nsigmaa = 0.1\n", "crowd.sigmaa"),
    ("speed = 3\n", "speed"),
    ('[domain]\nkind = "polygon"\nvertices = [[0, 0], [2, 0], [1, 0.3], [1, 2]]\n', "domain.vertices"),
    ("this is not toml", "scenario file"),
]


@pytest.mark.parametrize(("text", "name"), BAD_TOML)
def test_bad_toml_refused_naming_the_field(text, name):
    assert _err(lambda: Scenario.from_toml(text)).name == name


def test_short_keys_resolve_to_dotted_fields():
    from meanfield.scenario import resolve_key

    assert resolve_key("robots") == "robots.n" and resolve_key("crowd") == "crowd.n"
    assert resolve_key("eta") == "kernel.eta" and resolve_key("u_max") == "robots.u_max"
    assert resolve_key("t_final") == "t_final" and resolve_key("kernel.c") == "kernel.c"
    sc = paper_scenario().with_values({"robots": 9, "eta": 0.02})
    assert sc.robots.n == 9 and sc.kernel.eta == 0.02
    with pytest.raises(ParameterError) as info:
        resolve_key("radius")  # [view] and [pedestrians] both have one
    assert "view.radius" in str(info.value) and "pedestrians.radius" in str(info.value)
    with pytest.raises(ParameterError) as info:
        paper_scenario().with_values({"robotz": 3})
    assert info.value.name == "robotz"
