"""``[controller.options.<kind>]``: one table per controller kind, read by the controller's options dataclass when
the scenario is read (docs page *Running*, "[controller.options.<kind>]")."""

from __future__ import annotations

import dataclasses

import pytest

from meanfield import ParameterError, plugins
from meanfield.errors import MeanfieldDeprecationWarning
from meanfield.scenarios.scenario import Scenario, builtin_scenarios


def test_every_built_in_controller_declares_its_options():
    from meanfield.controllers.coverage import CoverageOptions
    from meanfield.controllers.evacuation import EvacuationOptions
    from meanfield.controllers.guide import GuideOptions
    from meanfield.controllers.static_signs import StaticSignsOptions

    declared = {k: plugins.capabilities("controller", k).options for k in
                ("backstepping", "evacuation", "coverage", "guide", "static-signs")}  # fmt: skip
    assert declared == {"backstepping": None, "evacuation": EvacuationOptions, "coverage": CoverageOptions,
                        "guide": GuideOptions, "static-signs": StaticSignsOptions}  # fmt: skip
    for options in declared.values():
        assert options is None or dataclasses.is_dataclass(options)
    # the coverage runs the evacuation law towards the exits, and takes its options
    law = {f.name for f in dataclasses.fields(EvacuationOptions)}
    assert law < {f.name for f in dataclasses.fields(CoverageOptions)}


def test_the_tables_of_several_kinds_are_kept_and_only_the_kind_s_is_used():
    sc = builtin_scenarios()["hall"](seed=0).with_values(
        {"controller.options.guide.revisit_after": 5.0, "controller.options.coverage.metric": "routed"}
    )
    assert sc.controller.options == {"guide": {"revisit_after": 5.0}, "coverage": {"metric": "routed"}}
    again = Scenario.from_toml(sc.to_toml())  # written as tables, read back the same
    assert again.controller.options == sc.controller.options
    from meanfield import ClosedLoop

    loop = ClosedLoop(sc.with_values({"t_final": 0.1}))
    assert loop.controller.revisit_after == 5.0  # the guide's table, not the coverage's
    coverage = ClosedLoop(sc.with_values({"controller.kind": "coverage", "t_final": 0.1})).controller
    assert coverage.metric == "routed" and coverage.revisit_after == 20.0


def test_options_directly_under_the_table_are_the_kind_s_with_a_warning_naming_their_new_place():
    base = builtin_scenarios()["hall"](seed=0)
    with pytest.warns(MeanfieldDeprecationWarning, match=r"0\.3\.0: use controller\.options\.guide\.revisit_after"):
        sc = base.with_values({"controller.options.revisit_after": 5.0})
    assert sc.controller.options == {"guide": {"revisit_after": 5.0}}
    text = '[controller]\nkind = "coverage"\n[controller.options]\nmetric = "routed"\n'
    with pytest.warns(MeanfieldDeprecationWarning, match=r"controller\.options\.coverage\.metric"):
        assert Scenario.from_toml(text).controller.options == {"coverage": {"metric": "routed"}}
    with pytest.raises(ParameterError) as exc:  # both ways at once
        Scenario.from_toml('[controller]\nkind = "guide"\n[controller.options]\nrevisit_after = 5.0\n'
                           '[controller.options.guide]\nrevisit_after = 6.0\n')  # fmt: skip
    assert exc.value.name == "controller.options.revisit_after"


@pytest.mark.parametrize(
    ("key", "value", "name"),
    [
        ("controller.options.guide.revisit_after", 0.0, "controller.options.guide.revisit_after"),
        ("controller.options.guide.specific_flow", "2", "controller.options.guide.specific_flow"),
        ("controller.options.coverage.weight", "mass", "controller.options.coverage.weight"),
        ("controller.options.coverage.potential", "travel", "controller.options.coverage.potential"),
        ("controller.options.evacuation.rebalance_period", -1.0, "controller.options.evacuation.rebalance_period"),
        ("controller.options.static-signs.k_heading", 0.0, "controller.options.static-signs.k_heading"),
        ("controller.options.static-signs.gain", 1.0, "controller.options.static-signs.gain"),
        ("controller.options.backstepping.alpha", 0.1, "controller.options.backstepping"),
    ],
)
def test_a_bad_option_is_refused_as_the_scenario_is_read_naming_it(key, value, name):
    with pytest.raises(ParameterError) as exc:
        builtin_scenarios()["hall"](seed=0).with_values({key: value})
    assert exc.value.name == name


def test_a_plugin_s_options_are_checked_by_its_record_when_the_scenario_is_read():
    """A controller plug-in declares its options' dataclass in its record: a key it does not take is refused when
    the scenario is read, naming it; one whose record declares none is refused any option."""
    from meanfield import paper_scenario
    from meanfield.capabilities import ControllerCapabilities
    from meanfield.controllers.static_signs import StaticSigns

    @dataclasses.dataclass(frozen=True)
    class WingOptions:
        k_position: float = 1.0

    def factory(parts):  # pragma: no cover - never built
        return StaticSigns.from_parts(dataclasses.replace(parts, options={}))

    plugins.register("controller", "winged", factory, capabilities=ControllerCapabilities(options=WingOptions))
    plugins.register("controller", "wingless", factory, capabilities=ControllerCapabilities())
    try:
        sc = paper_scenario(seed=0).with_values(
            {"controller.kind": "winged", "controller.options.winged.k_position": 2.0}
        )
        assert sc.controller.options == {"winged": {"k_position": 2.0}}
        with pytest.raises(ParameterError) as exc:
            paper_scenario(seed=0).with_values({"controller.kind": "winged", "controller.options.winged.wings": 2})
        assert exc.value.name == "controller.options.winged.wings" and "k_position" in exc.value.allowed
        with pytest.raises(ParameterError) as exc:
            paper_scenario(seed=0).with_values({"controller.kind": "wingless", "controller.options.wingless.k": 2})
        assert exc.value.name == "controller.options.wingless"
    finally:
        plugins.unregister("controller", "winged")
        plugins.unregister("controller", "wingless")


def test_the_evacuation_law_deprecates_its_walking_speed():
    with pytest.warns(MeanfieldDeprecationWarning, match=r"controller\.options\.coverage\.v_free.*crowd\.free_speed"):
        builtin_scenarios()["hall"](seed=0).with_values({"controller.options.coverage.v_free": 1.2})


@pytest.mark.parametrize(
    ("option", "old", "new"),
    [("metric", "straight", "routed"), ("weight", "density", "tracking-error"), ("weight", "excess", "tracking-error"),
     ("v_d", "safe-zone", "auto"), ("v_d", "exits", "auto")],  # fmt: skip
)
def test_coverage_values_no_study_found_winning_are_read_with_a_warning_naming_the_replacement(option, old, new):
    with pytest.warns(MeanfieldDeprecationWarning, match=rf"coverage\.{option} = '{old}'.*use '{new}'"):
        sc = builtin_scenarios()["hall"](seed=0).with_values({f"controller.options.coverage.{option}": old})
    assert sc.controller.options["coverage"][option] == old  # still read, until 0.3.0


def test_coverage_routes_its_robots_by_default_and_builds_no_walking_distances_in_a_convex_room():
    from meanfield import ClosedLoop, paper_scenario

    paper = ClosedLoop(paper_scenario(seed=0).with_values({"controller.kind": "coverage", "t_final": 0.1})).controller
    assert paper.metric == "routed" and paper.walking is None  # nothing hides a centroid: the straight law
    hall = ClosedLoop(builtin_scenarios()["hall"](seed=0).with_values({"controller.kind": "coverage"})).controller
    assert hall.metric == "routed" and hall.walking is not None


def test_the_deprecated_options_are_removed_by_the_release_their_warnings_name():
    """The warnings say "removed in 0.3.0": this fails once the package reaches that version with them still read."""
    import meanfield
    from meanfield.controllers.coverage import DEPRECATED
    from meanfield.scenarios.sections import FLAT_CONTROLLER_OPTIONS_REMOVED_IN

    assert FLAT_CONTROLLER_OPTIONS_REMOVED_IN == "0.3.0" and DEPRECATED
    def version(v: str) -> tuple[int, ...]:
        return tuple(int(part) for part in v.split(".")[:3])

    assert version(meanfield.__version__) < version(FLAT_CONTROLLER_OPTIONS_REMOVED_IN), (
        "remove the flat [controller.options] keys, coverage's DEPRECATED values and the evacuation law's v_free"
    )
