"""The arguments the ``meanfield`` commands share: a scenario, ``--out``, ``--seed``, ``--set``,
and on every command ``--allow-plugins`` and ``--plugin``.

A command plugin (``meanfield.commands`` entry point, :mod:`meanfield.plugins`) adds them with
:func:`add_scenario_arguments` and reads the scenario back with :func:`scenario_from_args`;
:mod:`meanfield.cli.app` adds :func:`add_plugin_arguments` to every command and applies them
around its handler.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from meanfield.errors import ParameterError
from meanfield.scenarios.overrides import parse_set

__all__ = [
    "add_plugin_arguments",
    "add_scenario_arguments",
    "scenario_from_args",
    "builtin_names",
    "builtin_description",
    "output_dir",
    "output_file",
    "SCENARIO_HELP",
]


def output_dir(text: str) -> Path:
    """argparse type of an ``--out`` folder: checked when the command line is read, before any work.

    A path that is a file, lies under a file or is not writable is refused (exit 2) with the reason.
    """
    from meanfield.io.atomic import check_output_dir

    try:
        return check_output_dir(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def output_file(text: str) -> Path:
    """argparse type of an ``--out`` file (a JSON report): not a folder, its folder writable."""
    from meanfield.io.atomic import check_output_file

    try:
        return check_output_file(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


SCENARIO_HELP = "a built-in scenario ({}), a TOML file, or a JuPedSim web-app export (ZIP, folder or JSON)"


def add_plugin_arguments(parser: argparse.ArgumentParser) -> None:
    """``--allow-plugins`` and ``--plugin FILE_OR_MODULE`` (repeatable), unless the command has them.

    A scenario file is shared like data: the modules its ``plugins`` lists are imported (their
    code runs) only with ``--allow-plugins``.  ``--plugin`` imports a module the user names,
    before the command runs, and allows a scenario's ``plugins`` entry naming that same module,
    no other.  Read back as ``args.allow_plugins`` and ``args.plugin_modules``;
    :func:`meanfield.cli.app.main` applies them (:func:`meanfield.plugins.allow_scenario_plugins`).
    """
    have = parser._option_string_actions  # argparse keeps no public view of the options
    if "--allow-plugins" not in have:
        parser.add_argument(
            "--allow-plugins",
            action="store_true",
            help="import the modules the scenario lists in `plugins` (a scenario file runs no code without it)",
        )
    if "--plugin" not in have:
        parser.add_argument(
            "--plugin",
            action="append",
            default=[],
            dest="plugin_modules",
            metavar="FILE_OR_MODULE",
            help="import this module (a .py file or a dotted name), e.g. one that registers a controller, "
            "before the command runs; allows a scenario's `plugins` entry naming it (repeatable)",
        )


def builtin_names() -> list[str]:
    """The built-in scenarios (``meanfield/scenarios/*.toml``), read without importing the toolkit."""
    from importlib import resources

    folder = resources.files("meanfield").joinpath("scenarios")
    return sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_description(name: str) -> str:
    """The first comment line of a built-in scenario's TOML (what it is)."""
    from importlib import resources

    text = resources.files("meanfield").joinpath("scenarios", f"{name}.toml").read_text(encoding="utf-8")
    first = next((line for line in text.splitlines() if line.startswith("#")), "")
    return first.lstrip("# ").strip()


def add_scenario_arguments(parser: argparse.ArgumentParser, seed_help: str = "random seed (overrides the scenario's)"):
    """The arguments every scenario command shares: ``[scenario] --out DIR [--seed S] [--set K=V]...``.

    Read them back with :func:`scenario_from_args`.  Command plugins use both.
    """
    parser.add_argument("scenario", nargs="?", default="paper", help=SCENARIO_HELP.format(", ".join(builtin_names())))
    parser.add_argument("--out", required=True, type=output_dir, help="output directory (checked before any work)")
    parser.add_argument("--seed", type=int, default=None, help=seed_help)
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario field, e.g. --set robots.n=9 (repeatable)",
    )


def scenario_from_args(args: argparse.Namespace):
    """The scenario named by ``args.scenario``, after ``--seed``, ``--set`` and ``--crowd`` (``--backend``, its old
    name, warns: removed in 0.3.0).

    The crowd it names is built when the loop is assembled, before anything runs: there,
    ``jupedsim`` without JuPedSim installed raises a :class:`ParameterError` that names the
    install command (exit status 2).
    """
    from meanfield.scenarios.scenario import load_scenario

    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise ParameterError("--seed", args.seed, "an integer from 0 to 2**63 - 1 (it is stored as a 64-bit integer)")
    sc = load_scenario(args.scenario, seed=args.seed)
    if args.set:
        sc = sc.with_values(parse_set(args.set))
    crowd, backend = getattr(args, "crowd", None), getattr(args, "backend", None)
    if backend is not None:
        if crowd is not None:
            raise ParameterError("--backend", backend, "one of --crowd and --backend (deprecated), not both")
        from meanfield.errors import deprecated

        deprecated("--backend", "use --crowd (it sets crowd.kind)")
        crowd = backend
    if crowd is not None:
        sc = sc.with_values({"crowd.kind": crowd})
    return sc
