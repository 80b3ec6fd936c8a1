"""The ``meanfield`` command.

:mod:`~meanfield.cli.app` builds the parser from the registered commands and holds :func:`main`;
each built-in command is one module that registers like a plugin's (:mod:`~meanfield.cli.run`,
:mod:`~meanfield.cli.compare`, :mod:`~meanfield.cli.scenario`, :mod:`~meanfield.cli.sweep`,
:mod:`~meanfield.cli.study`); :mod:`~meanfield.cli.arguments` holds the arguments they share,
for command plugins too.

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "SCENARIO_HELP": "meanfield.cli.arguments",
    "add_scenario_arguments": "meanfield.cli.arguments",
    "builtin_description": "meanfield.cli.arguments",
    "builtin_names": "meanfield.cli.arguments",
    "main": "meanfield.cli.app",
    "output_dir": "meanfield.cli.arguments",
    "output_file": "meanfield.cli.arguments",
    "run_artifacts": "meanfield.cli.run",
    "scenario_from_args": "meanfield.cli.arguments",
}

# Names the old module meanfield.cli held that live elsewhere now, until 0.3.0 (meanfield.errors.REMOVED_IN).
_DEPRECATED = {
    "parse_set": ("meanfield.scenarios.overrides", "parse_set"),
    "int_list": ("meanfield.scenarios.overrides", "int_list"),
    "float_list": ("meanfield.scenarios.overrides", "float_list"),
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY, _DEPRECATED)

__all__ = sorted(_LAZY)
