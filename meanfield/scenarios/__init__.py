"""Scenarios: every parameter of a run, validated, round-tripping to TOML; the built-in TOML files.

:mod:`~meanfield.scenarios.scenario` holds :class:`Scenario` and the loaders, :mod:`~meanfield.scenarios.sections`
one dataclass per TOML table, :mod:`~meanfield.scenarios.overrides` the values read from text
(``--set``); the built-in scenarios are the ``*.toml`` files beside them.

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "ControllerSpec": "meanfield.scenarios.sections",
    "CrowdSpec": "meanfield.scenarios.sections",
    "DensitySpec": "meanfield.scenarios.sections",
    "DisturbanceSpec": "meanfield.scenarios.sections",
    "GridSpec": "meanfield.scenarios.sections",
    "InteractionSpec": "meanfield.scenarios.sections",
    "KernelSpec": "meanfield.scenarios.sections",
    "RobotSpec": "meanfield.scenarios.sections",
    "SECTIONS": "meanfield.scenarios.sections",
    "Scenario": "meanfield.scenarios.scenario",
    "SensingSpec": "meanfield.scenarios.sections",
    "EventSpec": "meanfield.scenarios.sections",
    "TargetSpec": "meanfield.scenarios.sections",
    "ViewSpec": "meanfield.scenarios.sections",
    "builtin_scenarios": "meanfield.scenarios.scenario",
    "field_hint": "meanfield.scenarios.sections",
    "float_list": "meanfield.scenarios.overrides",
    "int_list": "meanfield.scenarios.overrides",
    "load_scenario": "meanfield.scenarios.scenario",
    "paper_scenario": "meanfield.scenarios.scenario",
    "paper_unity_scenario": "meanfield.scenarios.scenario",
    "parse_set": "meanfield.scenarios.overrides",
    "region_keys": "meanfield.scenarios.sections",
    "resolve_key": "meanfield.scenarios.scenario",
    "settable": "meanfield.scenarios.sections",
    "stadium_scenario": "meanfield.scenarios.scenario",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
