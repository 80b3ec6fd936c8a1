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


# ---------------------------------------------------------------------- a scenario file runs no code unless allowed
# (issue "Nothing lost", item 9): a scenario's ``plugins`` are imported only when the user allows it
def _marker_plugin(folder, name="marker_plugin"):
    """A plugin module that leaves a file beside itself when it is imported (its code ran)."""
    module = folder / f"{name}.py"
    module.write_text("from pathlib import Path\nPath(__file__).with_suffix('.imported').write_text('ran')\n")
    return module, module.with_suffix(".imported")


def _scenario_file(folder, module, name="listing.toml"):
    path = folder / name
    path.write_text(f'plugins = ["{module.name}"]\nt_final = 0.05\n')  # relative to the file
    return path


def test_a_scenario_that_lists_plugins_is_refused_by_every_loader_and_nothing_is_imported(tmp_path):
    from meanfield import Scenario, load_scenario

    module, marker = _marker_plugin(tmp_path)
    path = _scenario_file(tmp_path, module)
    text = f'plugins = ["{module}"]\n'
    for load in (
        lambda: load_scenario(path),
        lambda: Scenario.from_toml(text),
        lambda: Scenario.from_dict({"plugins": [str(module)]}),
        lambda: paper_scenario().with_values({"plugins": [str(module)]}),
    ):
        with pytest.raises(ParameterError) as exc:
            load()
        err = exc.value
        assert err.name == "plugins" and err.value == [str(module)]
        assert "--allow-plugins" in err.allowed and "allow_plugins=True" in err.allowed
        assert "shared like data" in err.allowed
        assert not marker.exists()  # refused before anything was imported


def test_allow_plugins_imports_a_scenario_s_modules(tmp_path):
    from meanfield import load_scenario

    module, marker = _marker_plugin(tmp_path)
    sc = load_scenario(_scenario_file(tmp_path, module), allow_plugins=True)
    assert marker.exists() and sc.plugins == (str(module),)
    # the scenario's own modules are imported already: with_values keeps them without asking again
    assert sc.with_values({"robots.n": 4}).plugins == sc.plugins


def test_the_permission_holds_within_its_block_and_leaks_into_no_later_call(tmp_path):
    import threading

    from meanfield import load_scenario

    first, first_marker = _marker_plugin(tmp_path, "first_plugin")
    second, second_marker = _marker_plugin(tmp_path, "second_plugin")
    with plugins.allow_scenario_plugins():  # --allow-plugins
        load_scenario(_scenario_file(tmp_path, first, "first.toml"))
        seen = []
        worker = threading.Thread(target=lambda: seen.append(plugins.current_permission()))
        worker.start()
        worker.join()
    assert first_marker.exists()
    assert seen == [plugins.PluginPermission()]  # another thread starts without it
    with pytest.raises(ParameterError):
        load_scenario(_scenario_file(tmp_path, second, "second.toml"))  # after the block: refused again
    assert not second_marker.exists()


def test_a_named_module_allows_that_module_and_no_other(tmp_path):
    from meanfield import load_scenario

    first, first_marker = _marker_plugin(tmp_path, "named_plugin")
    second, second_marker = _marker_plugin(tmp_path, "other_plugin")
    both = tmp_path / "both.toml"
    both.write_text(f'plugins = ["{first.name}", "{second.name}"]\n')
    with plugins.allow_scenario_plugins([str(first)]):  # --plugin named_plugin.py
        with pytest.raises(ParameterError) as exc:
            load_scenario(both)
        assert exc.value.name == "plugins"
        assert not first_marker.exists() and not second_marker.exists()  # all or nothing
        load_scenario(_scenario_file(tmp_path, first, "one.toml"))
    assert first_marker.exists() and not second_marker.exists()


def test_a_scenario_built_in_python_imports_its_plugins(tmp_path):
    """The documented choice: the dataclass itself is Python code asking for the modules by name."""
    from meanfield import Scenario

    module, marker = _marker_plugin(tmp_path)
    sc = Scenario(plugins=(str(module),), t_final=0.05)
    assert marker.exists() and sc.plugins == (str(module),)


def test_built_in_scenarios_and_entry_points_need_no_permission():
    from meanfield import load_scenario

    assert load_scenario("paper").plugins == ()
    assert "bounded" in plugins.available("beta_gamma")  # the analysis package's entry point


def test_a_permission_for_a_worker_must_be_one(tmp_path):
    with pytest.raises(ParameterError) as exc:
        with plugins.permitted(True):
            pass
    assert exc.value.name == "permission"
