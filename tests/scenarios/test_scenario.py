"""Scenarios: validation naming the field, TOML round trip, with_values."""

from __future__ import annotations

import math

import pytest

from meanfield import Domain, ParameterError, Scenario, load_scenario, paper_scenario
from meanfield.scenarios.scenario import CrowdSpec, KernelSpec, RobotSpec, TargetSpec, builtin_scenarios
from tests.conftest import PENTAGON


def _err(call) -> ParameterError:
    with pytest.raises(ParameterError) as info:
        call()
    return info.value


def test_toml_round_trip_paper():
    sc = paper_scenario()
    back = Scenario.from_toml(sc.to_toml())
    assert back.to_dict() == sc.to_dict()
    assert back.to_toml() == sc.to_toml()


def test_a_bare_scenario_is_the_paper_s_room():
    """Every default is the paper's (issue 44, "Defaults that tell the truth"): no congestion, no memory, the
    paper's speed limits, in its dimensionless units."""
    bare = Scenario()
    assert bare.to_dict() == paper_scenario().replace(name="custom").to_dict()
    assert (bare.units, bare.congestion_model, bare.memory) == ("dimensionless", "none", "none")
    assert (bare.robots.u_max, bare.robots.omega_max) == (0.2, 3.0)


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
    ('[domain]\nkind = "polygon"\nvertices = [[0, 0], [2, 2], [2, 0], [0, 2]]\n', "domain.vertices"),  # a bow tie
    ("this is not toml", "scenario file"),
]


@pytest.mark.parametrize(("text", "name"), BAD_TOML)
def test_bad_toml_refused_naming_the_field(text, name):
    assert _err(lambda: Scenario.from_toml(text)).name == name


def test_short_keys_resolve_to_dotted_fields():
    from meanfield.scenarios.scenario import resolve_key

    assert resolve_key("robots") == "robots.n" and resolve_key("crowd") == "crowd.n"
    assert resolve_key("eta") == "kernel.eta" and resolve_key("u_max") == "robots.u_max"
    assert resolve_key("t_final") == "t_final" and resolve_key("kernel.c") == "kernel.c"
    sc = paper_scenario().with_values({"robots": 9, "eta": 0.02})
    assert sc.robots.n == 9 and sc.kernel.eta == 0.02
    with pytest.raises(ParameterError) as info:
        resolve_key("radius")  # [view] and [sensing] both have one
    assert "view.radius" in str(info.value) and "sensing.radius" in str(info.value)
    with pytest.raises(ParameterError) as info:
        paper_scenario().with_values({"robotz": 3})
    assert info.value.name == "robotz"


# ---------------------------------------------------------------------- built-ins from TOML
def test_builtins_are_toml_package_data():
    from importlib import resources

    from meanfield.scenarios.scenario import builtin_scenarios

    folder = resources.files("meanfield") / "scenarios"
    names = ["bottleneck", "hall", "hall-crowded-west", "l-room", "office", "paper", "paper-unity", "rimea-10",
             "rimea-12", "rimea-9", "stadium"]  # fmt: skip
    assert list(builtin_scenarios()) == names
    for name in builtin_scenarios():
        assert (folder / f"{name}.toml").is_file()
        assert load_scenario(name).name == name


def test_paper_builtin_has_the_values_of_the_paper_study():
    sc = paper_scenario(seed=7)
    assert sc.seed == 7 and sc.name == "paper"
    assert sc.crowd.n == 200 and sc.robots.n == 16 and sc.grid.cells == (30, 30)
    assert sc.dt == 0.01 and sc.t_final == 40.0 and sc.record_every == 10 and sc.steps == 4000
    assert sc.domain == Domain.box(1.0, 1.0)
    assert sc.kernel == KernelSpec(c=0.2, eta=0.05) and sc.crowd.sigma == 0.015
    assert (sc.robots.layout, sc.robots.headings, sc.robots.u_max, sc.robots.omega_max) == ("grid", "random", 0.2, 3.0)
    assert sc.target == TargetSpec(center=(1.0, 1.0), std=0.15)
    assert (sc.density.bandwidth, sc.density.boundary) == (0.08, "reflect")
    c = sc.controller
    assert (c.alpha, c.alpha_schedule, c.rho_floor, c.k_u, c.k_omega) == (0.2, "saturating", 2.0, 10.0, 10.0)
    assert (c.beta_gamma, c.dvd_dt, c.kind) == ("min-norm", "finite-difference", "backstepping")
    assert sc.plugins == () and "plugins" not in sc.to_toml()


def test_paper_unity_builtin_is_paper_under_the_similarity():
    from meanfield.scenarios.scenario import UNITY_LENGTH as L
    from meanfield.scenarios.scenario import UNITY_TIME as T
    from meanfield.scenarios.scenario import ControllerSpec, DensitySpec, ViewSpec, paper_unity_scenario

    base, sc = paper_scenario(3), paper_unity_scenario(3)
    b = base.controller
    expected = Scenario(
        name="paper-unity",
        seed=3,
        units="SI",
        dt=base.dt * T,
        t_final=base.t_final * T,
        domain=Domain.box(L, L),
        crowd=CrowdSpec(
            n=200,
            sigma=0.5,
            options={"jupedsim": dict(model="collision-free-speed", radius=0.2, max_speed=1.34, time_step=0.05)},
        ),
        robots=RobotSpec(n=16, u_max=base.robots.u_max * L / T, omega_max=base.robots.omega_max / T),
        kernel=KernelSpec(c=base.kernel.c * L / T, eta=base.kernel.eta * L * L),
        target=TargetSpec(center=(L, L), std=base.target.std * L),
        density=DensitySpec(bandwidth=base.density.bandwidth * L),
        controller=ControllerSpec(
            alpha=b.alpha * L * L / T, rho_floor=b.rho_floor / (L * L), k_u=b.k_u / T, k_omega=b.k_omega / T
        ),
        view=ViewSpec(radius=30.0, walk_speed=1.0, turning_rate=0.05),
    )
    assert sc == expected
    assert sc.to_toml() == expected.to_toml()


def test_stadium_builtin_is_paper_with_a_stadium_crowd():
    import dataclasses

    from meanfield.scenarios.scenario import STADIUM_CROWD, DensitySpec, GridSpec, stadium_scenario

    base = paper_scenario(2)
    expected = base.replace(
        name="stadium",
        grid=GridSpec((128, 128)),
        crowd=dataclasses.replace(base.crowd, n=STADIUM_CROWD),
        robots=dataclasses.replace(base.robots, n=64),
        density=DensitySpec(bandwidth=0.03, boundary="reflect"),
        record_humans=10_000,
    )
    assert stadium_scenario(2) == expected and load_scenario("stadium", seed=2) == expected


# ---------------------------------------------------------------------- names from the registry
def test_plugin_module_registers_a_controller_the_scenario_names(tmp_path):
    import json

    from meanfield import plugins

    name = "test-scenario-parked"
    module = tmp_path / "scenario_plugin_parked.py"
    module.write_text(
        "from meanfield import plugins\nfrom meanfield.capabilities import ControllerCapabilities\n"
        f"plugins.register('controller', {name!r}, lambda parts: None, capabilities=ControllerCapabilities())\n"
    )
    text = f'[controller]\nkind = "{name}"\n'
    try:
        assert _err(lambda: Scenario.from_toml(text)).name == "controller.kind"  # not registered yet
        sc = Scenario.from_toml(f"plugins = [{json.dumps(str(module))}]\n" + text, allow_plugins=True)
        assert sc.controller.kind == name and sc.plugins == (str(module),)
        assert name in plugins.available("controller")
        back = Scenario.from_toml(sc.to_toml(), allow_plugins=True)  # written back, imported again (once)
        assert back == sc and back.to_dict()["plugins"] == [str(module)]
    finally:
        plugins.unregister("controller", name)


@pytest.mark.parametrize(
    ("text", "name"),
    [
        ('plugins = "not a list"\n', "plugins"),
        ('plugins = ["meanfield_no_such_plugin_module"]\n', "plugins"),
        ("plugins = [3]\n", "plugins[0]"),
        ('[controller]\nkind = "no-such-controller"\n', "controller.kind"),
        ('[controller]\nbeta_gamma = "no-such-rule"\n', "controller.beta_gamma"),
        ('[controller]\ndvd_dt = "guess"\n', "controller.dvd_dt"),
        ('[crowd]\nkind = "no-such-crowd"\n', "crowd.kind"),
        ('[crowd.options.jupedsim]\nmodel = "no-such-model"\n', "crowd.options.jupedsim.model"),
        ('[crowd.options.jupedsim]\nwings = 2\n', "crowd.options.jupedsim.wings"),
        ('[crowd.options.no-such-crowd]\nradius = 2\n', "crowd.options.no-such-crowd"),
        ('[crowd.options.point-mass]\nradius = 2\n', "crowd.options.point-mass"),
        ('[pedestrians]\nbackend = "no-such-crowd"\n', "crowd.kind"),
        ('[pedestrians]\nmodel = "no-such-model"\n', "crowd.options.jupedsim.model"),
        ('[pedestrians]\nwings = 2\n', "pedestrians.wings"),
        ('[pedestrians]\nbackend = "jupedsim"\n[crowd]\nkind = "jupedsim"\n', "pedestrians.backend"),
        ('[domain]\nkind = "polygon"\n', "domain.vertices"),
        ("[domain]\nwidth = -1.0\n", "domain.width"),
        ("[domain]\nradius = 1.0\n", "domain"),
        ("domain = 3\n", "domain"),
    ],
)
def test_registry_names_and_plugins_refused_naming_the_field(text, name):
    assert _err(lambda: Scenario.from_toml(text)).name == name


def test_an_allowed_plugin_that_cannot_be_imported_is_refused_naming_the_field():
    err = _err(lambda: Scenario.from_toml('plugins = ["meanfield_no_such_plugin_module"]\n', allow_plugins=True))
    assert err.name == "plugins" and "importable module" in err.allowed


def test_unknown_region_kind_refused_listing_the_registered_kinds():
    from meanfield import plugins

    err = _err(lambda: Scenario.from_toml('[domain]\nkind = "hexagon"\n'))
    assert err.name == "domain.kind" and err.value == "hexagon"
    for kind in plugins.available("region"):
        assert repr(kind) in err.allowed


def test_region_from_table_passes_the_table_to_the_registered_factory():
    from meanfield import plugins
    from meanfield.capabilities import RegionCapabilities
    from meanfield.geometry.region import region_from_table

    assert region_from_table({}) == Domain.box(1.0, 1.0)
    assert region_from_table({"kind": "disk", "radius": 0.5, "center": [1, 2]}) == Domain.disk(0.5, (1.0, 2.0))
    square = RegionCapabilities()
    plugins.register("region", "test-square", lambda side=1.0: Domain.box(side, side), capabilities=square)
    try:
        assert region_from_table({"kind": "test-square", "side": 2.0}) == Domain.box(2.0, 2.0)
        err = _err(lambda: region_from_table({"kind": "test-square", "width": 1.0}))
        assert err.name == "domain" and "['side']" in err.allowed
        assert _err(lambda: region_from_table({"kind": "test-square", "side": -1.0})).name == "domain.width"
    finally:
        plugins.unregister("region", "test-square")


def test_plugins_settable_with_values():
    from meanfield import plugins

    sc = paper_scenario()
    assert sc.with_values({"plugins": []}) == sc
    refused = _err(lambda: sc.with_values({"plugins": ["meanfield_no_such_plugin_module"]}))  # a new module
    assert refused.name == "plugins" and "--allow-plugins" in refused.allowed
    with plugins.allow_scenario_plugins():
        err = _err(lambda: sc.with_values({"plugins": ["meanfield_no_such_plugin_module"]}))
    assert err.name == "plugins" and "importable module" in err.allowed


# ---------------------------------------------------------------------- --set on empty fields (issue 16, item 5)
def test_set_reaches_a_field_that_is_empty_today():
    from meanfield import paper_scenario

    base = paper_scenario(seed=0)
    assert base.view.radius is None  # omitted from the scenario's table
    assert base.with_values({"view.radius": 0.3}).view.radius == 0.3
    sc = base.with_values(
        {"robots.layout": "explicit", "robots.positions": [[0.2, 0.2], [0.8, 0.8]], "robots.n": 2}
    )
    assert sc.robots.positions is not None and len(sc.robots.positions) == 2


def test_set_switches_the_shape_and_then_takes_its_keys():
    from meanfield import paper_scenario

    sc = paper_scenario(seed=0).with_values({"domain.kind": "disk", "domain.radius": 0.5, "domain.center": [0.5, 0.5]})
    assert sc.domain.kind == "disk" and sc.domain.radius == 0.5 and sc.domain.center == (0.5, 0.5)
    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({"domain.radius": 0.5})  # still a box
    assert exc.value.name == "domain.radius" and "'box' region" in str(exc.value) and "width" in str(exc.value)


@pytest.mark.parametrize(
    ("key", "suggestion"), [("view.radiuss", "view.radius"), ("kernel.etta", "kernel.eta"), ("robot.n", "robots.n")]
)
def test_a_misspelt_key_is_refused_with_the_field_it_resembles(key, suggestion):
    from meanfield import paper_scenario

    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({key: 1})
    assert exc.value.name == key and f"did you mean {suggestion}" in str(exc.value)


def test_with_values_leaves_the_caller_s_tables_alone():
    """A table given as a value (``{"controller.options": {}}``) and a key under it in the same call once wrote the
    key into the caller's table, so that the next scenario built from it carried the option too."""
    empty: dict = {}
    sc = builtin_scenarios()["hall"](seed=0).with_values(
        {"controller.options": empty, "controller.options.guide.revisit_after": 5.0}
    )
    assert sc.controller.options == {"guide": {"revisit_after": 5.0}} and empty == {}


def test_with_values_leaves_the_original_crowd_options_alone():
    """Setting ``crowd.options.<kind>.<field>`` on a copy once wrote into the original's table too (the copy
    shared the inner tables)."""
    base = builtin_scenarios()["bottleneck"](seed=0)
    before = base.crowd.options["jupedsim"]["radius"]
    changed = base.with_values({"crowd.options.jupedsim.radius": 0.25})
    assert changed.crowd.options["jupedsim"]["radius"] == 0.25
    assert base.crowd.options["jupedsim"]["radius"] == before == 0.15
    assert base.to_dict()["crowd"]["options"]["jupedsim"] is not base.crowd.options["jupedsim"]
