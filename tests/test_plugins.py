"""What a part declares, and how the core asks (meanfield.plugins.declared): the core never tests a
part's name; each built-in part declares what it needs, a plug-in part may declare the same."""

from __future__ import annotations

import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario, plugins
from meanfield.interfaces import StabilityStep
from meanfield.simulation.assembly import sensing_controllers
from meanfield.simulation.preflight import stability_warnings


def test_built_in_parts_declare_what_they_need():
    assert sensing_controllers() == ["backstepping", "coverage", "evacuation"]
    assert plugins.declared("controller", "evacuation", "requires_exits") is True
    assert plugins.declared("controller", "backstepping", "requires_exits", False) is False
    assert plugins.declared("controller", "static-signs", "accepts_sensing", False) is False
    assert plugins.declared("beta_gamma", "min-norm", "accepts_kernel_scaling") is True
    assert plugins.declared("crowd", "jupedsim", "options").__name__ == "JuPedSimOptions"
    assert plugins.declared("crowd", "point-mass", "options") is None


class _Parked:
    """A controller plug-in that declares its own stability step and accepts sensing radii."""

    accepts_sensing = True

    @staticmethod
    def stability_step(scenario, grid):
        return StabilityStep(dt=1e-9, what="the parked robots' made-up step", why="(a test)")


def test_the_core_asks_a_plugin_for_its_stability_step_and_sensing():
    from meanfield.controllers.static_signs import StaticSigns

    def factory(parts):
        return StaticSigns.from_parts(parts)

    factory.accepts_sensing = _Parked.accepts_sensing
    factory.stability_step = _Parked.stability_step
    plugins.register("controller", "test-parked", factory)
    try:
        sc = paper_scenario(seed=0).replace(t_final=0.05).with_values({"controller.kind": "test-parked"})
        grid = ClosedLoop(sc).grid
        warnings = stability_warnings(sc, grid, {})
        assert warnings == ["dt = 0.01 exceeds the parked robots' made-up step = 1e-09 (a test)"]
        assert "test-parked" in sensing_controllers()
        ClosedLoop(sc.with_values({"sensing.radius": 0.3}))  # accepted: it declares accepts_sensing
    finally:
        plugins.unregister("controller", "test-parked")


def test_a_controller_that_does_not_declare_sensing_is_refused_with_the_ones_that_do():
    sc = paper_scenario(seed=0).with_values({"controller.kind": "static-signs", "sensing.radius": 0.3})
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)
    assert exc.value.name == "sensing" and "coverage" in str(exc.value) and "static-signs" not in exc.value.allowed


def test_the_paper_law_warns_past_its_step_and_hughes_step_one_does_not():
    sc = paper_scenario(seed=0)
    grid = ClosedLoop(sc.replace(t_final=0.05)).grid
    assert "0.9 h²/(4 α₀)" in stability_warnings(sc, grid, {})[0]
    assert plugins.declared("controller", "evacuation", "stability_step", "absent") is None
