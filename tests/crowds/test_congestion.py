"""Fundamental diagrams (meanfield.crowds.congestion) against their published and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ParameterError, paper_scenario, plugins
from meanfield.crowds.congestion import Linear, NoCongestion, Weidmann


def test_weidmann_reproduces_its_published_capacity():
    """Weidmann (1993): free speed 1.34 m/s, jam density 5.4 /m², maximum specific flow about
    1.225 persons/(m·s) at 1.75 persons/m²."""
    q, rho_c = Weidmann().capacity()
    assert q == pytest.approx(1.225, abs=0.002) and rho_c == pytest.approx(1.75, abs=0.01)
    g = Weidmann().speed_factor(np.array([0.0, 5.4, 8.0]))
    assert g.tolist() == [1.0, 0.0, 0.0]


def test_linear_capacity_is_its_closed_form():
    d = Linear(free_speed=1.2, rho_max=6.0)
    assert d.capacity() == (1.2 * 6.0 / 4.0, 3.0)
    rho = np.linspace(0, 8, 33)
    assert np.allclose(d.speed_factor(rho), np.clip(1 - rho / 6.0, 0, 1), rtol=0, atol=0)


@pytest.mark.parametrize("diagram", [Weidmann(), Linear(), NoCongestion()])
def test_every_diagram_starts_at_one_and_never_speeds_up(diagram):
    rho = np.linspace(0.0, 10.0, 1001)
    g = diagram.speed_factor(rho)
    assert g[0] == 1.0 and np.all((g >= 0) & (g <= 1)) and np.all(np.diff(g) <= 0)


def test_the_scenario_names_a_registered_diagram_and_refuses_bad_values():
    assert set(plugins.available("congestion")) >= {"none", "weidmann", "linear"}
    sc = paper_scenario()
    assert sc.crowd.congestion == "auto" and sc.congestion_model == "none" and sc.crowd.rho_max == 5.4
    for key, value in (("crowd.congestion", "traffic-jam"), ("crowd.rho_max", 0.0), ("crowd.rho_max", -1.0)):
        with pytest.raises(ParameterError) as exc:
            sc.with_values({key: value})
        assert exc.value.name == key
    with pytest.raises(ParameterError) as exc:
        plugins.load("congestion", "weidmann")(free_speed=1.34, rho_max=math.inf)
    assert exc.value.name == "crowd.rho_max"


def test_auto_congestion_is_the_crowd_kinds_default_for_the_units():
    """``"auto"``: the paper's dimensionless room walks by none (the paper, unchanged); SI point masses and
    density by the linear diagram; JuPedSim's bodies by their own model, which refuses a diagram."""
    from meanfield.scenarios.scenario import builtin_scenarios

    assert paper_scenario().congestion_model == "none"
    si = builtin_scenarios()["office"]()
    assert si.units == "SI" and si.crowd.congestion == "auto" and si.congestion_model == "linear"
    assert si.with_values({"crowd.kind": "fokker-planck"}).congestion_model == "linear"
    assert si.with_values({"crowd.congestion": "weidmann"}).congestion_model == "weidmann"
    assert si.with_values({"crowd.congestion": "none"}).congestion_model == "none"
    if "jupedsim" in plugins.available("crowd"):
        bodies = si.with_values({"crowd.kind": "jupedsim"})
        assert bodies.congestion_model == "none"
        with pytest.raises(ParameterError) as exc:
            si.with_values({"crowd.kind": "jupedsim", "crowd.congestion": "linear"})
        assert exc.value.name == "crowd.congestion"
