"""The ``meanfield`` command: its parser, built from the registered commands, and :func:`main`.

Every sub-command is a part registered by name (kind ``"command"``, :mod:`meanfield.plugins`):
the toolkit's own (``run``, ``compare``, ``scenario``, ``sweep``, ``study``: one module each in
this package) and those of packages built on :mod:`meanfield`, through the ``meanfield.commands``
entry points (``meanfield analyze`` comes from :mod:`analysis`).  A command module's
``register(subparsers)`` adds its parser and returns its handler, ``handler(args) -> int``.

Every command takes ``--allow-plugins`` (a scenario's ``plugins`` may be imported) and
``--plugin FILE_OR_MODULE`` (import this module first; :func:`~meanfield.cli.arguments.add_plugin_arguments`):
without them, a scenario file that lists ``plugins`` is refused before any of its modules is
imported (exit 2).

Exit status: 0 success; 1 the run diverged or was interrupted (outputs of the last good
state are still written); 2 invalid input (bad parameter, unknown scenario or key).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from meanfield import plugins
from meanfield.errors import ParameterError

__all__ = ["main"]


def _build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="meanfield",
        description="Mean-field control of crowds by robots (Zheng et al.): simulate, analyse, verify.",
    )
    from importlib.metadata import PackageNotFoundError, version

    from meanfield.cli.arguments import add_plugin_arguments

    try:
        installed = version("meanfield-crowd")
    except PackageNotFoundError:  # pragma: no cover - run from a source tree without installing
        installed = "unknown (not installed)"
    p.add_argument("--version", action="version", version=f"meanfield {installed}")
    sub = p.add_subparsers(dest="command", required=True)
    for name, load in plugins.loaders("command").items():  # run, compare, ...; `meanfield analyze` from analysis
        try:
            handler = load()(sub)
        except (ImportError, AttributeError) as exc:  # a broken plugin must not break the other commands
            handler = _unavailable(name, exc)
            stub = sub.add_parser(name, help=f"(unavailable: {exc})", add_help=False)
            stub.add_argument("rest", nargs=argparse.REMAINDER)
        else:
            add_plugin_arguments(sub.choices[name])
        sub.choices[name].set_defaults(plugin_handler=handler)
    return p


def _unavailable(name: str, exc: Exception):
    def handler(args: argparse.Namespace) -> int:
        print(f"meanfield: error: the '{name}' command could not be loaded: {exc}", file=sys.stderr)
        return 2

    return handler


def _terminated(signum: int, frame: object) -> None:
    """SIGTERM (batch schedulers, containers, ``kill``) as Ctrl-C: the run keeps its last good state."""
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``meanfield`` command; returns the exit status.

    SIGTERM is handled as SIGINT while a command runs: a run stops with ``"status":
    "interrupted"`` and writes its last good state, as after Ctrl-C.
    """
    import warnings

    from meanfield.errors import MeanfieldDeprecationWarning, ScenarioWarning

    def show(message, category, filename, lineno, file=None, line=None):  # warnings.showwarning's signature
        from meanfield._compiled.core import CompiledFallbackWarning

        if issubclass(category, (MeanfieldDeprecationWarning, ScenarioWarning, CompiledFallbackWarning)):  # one line
            print(f"meanfield: warning: {message}", file=sys.stderr)
        else:
            default_show(message, category, filename, lineno, file, line)

    default_show = warnings.showwarning
    warnings.showwarning = show
    try:
        return _main(argv)
    finally:
        warnings.showwarning = default_show


def _main(argv: Sequence[str] | None) -> int:
    import signal
    import threading

    args = _build_parser().parse_args(argv)
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        named = getattr(args, "plugin_modules", None) or []
        with plugins.allow_scenario_plugins(None if getattr(args, "allow_plugins", False) else named):
            plugins.import_plugin_modules(named, field="--plugin")
            return args.plugin_handler(args)
    except ParameterError as exc:
        print(f"meanfield: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM where a command has no handler of its own (start-up)
        print(f"meanfield: {args.command} interrupted", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
