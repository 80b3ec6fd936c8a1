"""``meanfield scenario``: a scenario printed as TOML, or the list of the built-in ones."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from meanfield.cli.arguments import SCENARIO_HELP, builtin_description, builtin_names

__all__ = ["register"]


def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield scenario`` to the ``meanfield`` parser; return its handler."""
    s = subparsers.add_parser("scenario", help="print a scenario as TOML (a starting point for your own)")
    s.add_argument("scenario", nargs="?", default="paper", help=SCENARIO_HELP.format(", ".join(builtin_names())))
    s.add_argument("--list", action="store_true", help="list the built-in scenarios, one line each")
    return _cmd_scenario


def _cmd_scenario(args: argparse.Namespace) -> int:
    from meanfield.scenarios.scenario import load_scenario

    if args.list:
        names = builtin_names()
        width = max(map(len, names))
        for name in names:
            print(f"{name:<{width}}  {builtin_description(name)}")
        return 0
    sys.stdout.write(load_scenario(args.scenario).to_toml())
    return 0
