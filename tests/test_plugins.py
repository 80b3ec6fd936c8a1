"""What a part can do, and how the core asks (meanfield.plugins.capabilities): the core never tests a part's name;
each registered part carries one typed record of what it can do (meanfield.capabilities), a plug-in part the same."""

from __future__ import annotations

import dataclasses
import warnings

import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario, plugins
from meanfield.capabilities import (
    BetaGammaCapabilities,
    ControllerCapabilities,
    CrowdCapabilities,
    GuidanceCapabilities,
    declares,
)
from meanfield.errors import MeanfieldDeprecationWarning
from meanfield.interfaces import StabilityStep
from meanfield.simulation.assembly import sensing_controllers
from meanfield.simulation.preflight import stability_warnings


def test_built_in_parts_declare_what_they_need():
    assert sensing_controllers() == ["backstepping", "coverage", "evacuation"]
    assert plugins.capabilities("controller", "evacuation").requires_exits is True
    assert plugins.capabilities("controller", "backstepping").requires_exits is False
    assert plugins.capabilities("controller", "static-signs").accepts_sensing is False
    assert plugins.capabilities("beta_gamma", "min-norm").accepts_kernel_scaling is True
    assert plugins.capabilities("beta_gamma", "bounded").accepts_kernel_scaling is False
    assert plugins.capabilities("crowd", "jupedsim").options.__name__ == "JuPedSimOptions"
    assert plugins.capabilities("crowd", "point-mass").options is None
    assert plugins.capabilities("crowd", "point-mass").door_models[0] == "forward-cell"
    assert plugins.capabilities("crowd", "fokker-planck").door_models == ("count",)
    assert plugins.capabilities("congestion", "none").slows is False
    assert plugins.capabilities("guidance", "hughes").for_density is not None


def test_a_misspelt_capability_fails_loudly():
    """A field a record does not have is an error when read and when declared, never a silent default."""
    record = plugins.capabilities("controller", "coverage")
    with pytest.raises(AttributeError, match="acepts_sensing"):
        record.acepts_sensing  # noqa: B018 - the read is the test
    with pytest.raises(TypeError, match="acepts_sensing"):
        ControllerCapabilities(acepts_sensing=True)
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.accepts_sensing = False
    with pytest.raises(TypeError, match="door_models"):
        CrowdCapabilities(door_models=())
    with pytest.raises(TypeError, match="options"):
        ControllerCapabilities(options={"k": 1})  # an instance where the options' dataclass belongs
    with pytest.raises(TypeError, match="capability record"):
        declares({"accepts_sensing": True})


def test_a_plugin_without_a_capability_record_is_refused_when_registered_naming_the_record():
    def factory(parts):  # pragma: no cover - never built
        raise AssertionError

    with pytest.raises(ParameterError) as exc:
        plugins.register("controller", "test-recordless", factory)
    assert "test-recordless" in exc.value.name and "ControllerCapabilities" in exc.value.allowed
    assert exc.value.value == "no capability record"
    with pytest.raises(ParameterError) as exc:  # a record of another kind
        plugins.register("controller", "test-recordless", factory, capabilities=BetaGammaCapabilities())
    assert "BetaGammaCapabilities" in exc.value.value
    assert "test-recordless" not in plugins.available("controller")  # nothing was registered
    with pytest.raises(ParameterError):  # a command has no record to give
        plugins.register("command", "test-recordless", factory, capabilities=ControllerCapabilities())


def test_the_old_string_question_still_answers_with_a_dated_warning():
    with pytest.warns(MeanfieldDeprecationWarning, match=r"removed in 0\.3\.0"):
        assert plugins.declared("controller", "evacuation", "requires_exits") is True


@declares(
    ControllerCapabilities(
        accepts_sensing=True,
        stability_step=lambda scenario, grid: StabilityStep(
            dt=1e-9, what="the parked robots' made-up step", why="(a test)"
        ),
    )
)
def _parked(parts):
    from meanfield.controllers.static_signs import StaticSigns

    return StaticSigns.from_parts(parts)


def test_the_core_asks_a_plugin_for_its_stability_step_and_sensing():
    plugins.register("controller", "test-parked", _parked)
    try:
        sc = paper_scenario(seed=0).replace(t_final=0.05).with_values({"controller.kind": "test-parked"})
        grid = ClosedLoop(sc).grid
        said = stability_warnings(sc, grid, {})
        assert said == ["dt = 0.01 exceeds the parked robots' made-up step = 1e-09 (a test)"]
        assert "test-parked" in sensing_controllers()
        ClosedLoop(sc.with_values({"sensing.radius": 0.3}))  # accepted: its record says accepts_sensing
    finally:
        plugins.unregister("controller", "test-parked")


def test_a_record_given_at_registration_is_the_part_s_own():
    """A plain function registered with its record (no attribute set on it) is asked through that record."""

    def guidance(ctx, positions):  # pragma: no cover - never built
        raise AssertionError

    plugins.register("guidance", "test-follow", guidance, capabilities=GuidanceCapabilities())
    try:
        assert plugins.capabilities("guidance", "test-follow") == GuidanceCapabilities()
        assert not hasattr(guidance, "capabilities")
    finally:
        plugins.unregister("guidance", "test-follow")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plugins.capabilities("guidance", "signs")  # the new question warns of nothing


def test_a_controller_that_does_not_declare_sensing_is_refused_with_the_ones_that_do():
    sc = paper_scenario(seed=0).with_values({"controller.kind": "static-signs", "sensing.radius": 0.3})
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)
    assert exc.value.name == "sensing" and "coverage" in str(exc.value) and "static-signs" not in exc.value.allowed


def test_the_paper_law_warns_past_its_step_and_hughes_step_one_does_not():
    sc = paper_scenario(seed=0)
    grid = ClosedLoop(sc.replace(t_final=0.05)).grid
    assert "0.9 h²/(4 α₀)" in stability_warnings(sc, grid, {})[0]
    assert plugins.capabilities("controller", "evacuation").stability_step is None


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
