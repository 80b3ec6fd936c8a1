"""``meanfield study controllers``: every installed controller on the same seeds.

The study itself is :mod:`meanfield.workflows.controller_study`; this module is its command.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from meanfield.cli.arguments import output_dir
from meanfield.errors import ParameterError
from meanfield.workflows.controller_study import _Incomplete, study_controllers, table

__all__ = ["register"]


def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield study`` to the ``meanfield`` parser; return its handler."""
    p = subparsers.add_parser(
        "study",
        help="every installed controller on the same seeds: a table and a figure",
        description=(
            "Run every installed controller (or --controllers) on the scenario for the same seeds, each as a "
            "resumable Dask sweep in OUT/<controller>, and write OUT/controllers.md, .csv and .png: median and "
            "worst seed of the fraction in the target (or evacuated), time to 90 % (or 95 % out), errors, "
            "steps at a speed limit, compute per step against the paper's law, stragglers. Exit status: 0 "
            "every run completed; 1 a run did not (outputs written); 2 bad input."
        ),
    )
    p.add_argument("what", choices=["controllers"], help="what to compare (controllers)")
    p.add_argument("scenario", nargs="?", default="paper", help="built-in name (paper) or a TOML file")
    p.add_argument("--out", required=True, type=output_dir, help="output directory (checked before any work)")
    p.add_argument("--seeds", default="10", help="N for seeds 0..N-1, or A-B, or a,b,c (default 10)")
    p.add_argument("--controllers", default=None, help="comma-separated labels (default: every installed one)")
    p.add_argument(
        "--sensing",
        type=float,
        default=None,
        metavar="R",
        help="also run each controller that can with a sensing radius R (and 2R to talk): label NAME@R",
    )
    p.add_argument("--workers", type=int, default=None, help="worker processes of the local cluster (default: cores)")
    p.add_argument("--quiet", action="store_true", help="no progress bars, no table printout")
    return _handle


def _handle(args: argparse.Namespace) -> int:
    import sys

    from meanfield.workflows.sweep_plan import parse_seeds

    names = None if args.controllers is None else [n.strip() for n in args.controllers.split(",") if n.strip()]
    if names is not None:
        twice = sorted({n for n in names if names.count(n) > 1})
        if not names or twice:
            got = f"{twice[0]!r} twice" if twice else repr(args.controllers)
            raise ParameterError("--controllers", got, "comma-separated controller labels, at least one, each once")
    try:
        rows = study_controllers(
            args.scenario,
            parse_seeds(args.seeds),
            args.out,
            controllers=names,
            sensing=args.sensing,
            workers=args.workers,
            progress=not args.quiet,
        )
        status = 0
    except _Incomplete as exc:
        rows, status = exc.rows, 1
        print("meanfield: study: some runs did not complete (see each controller's sweep)", file=sys.stderr)
    if not args.quiet:
        from meanfield.geometry.exits import exit_segments
        from meanfield.scenarios.scenario import load_scenario

        print(table(rows, len(exit_segments(load_scenario(args.scenario).domain)) > 0))
        print(f"outputs in {args.out}")
    return status
