"""``meanfield verify [scenario] --out DIR [--quick]``: every claim of the paper, checked.

Registered as a ``meanfield.commands`` entry point (see :mod:`meanfield.plugins`).  Writes
``DIR/report.md`` and ``DIR/verdicts.json`` (see :mod:`verification.report`).  Exit status:
0 when every check ran (whatever the verdicts), 1 when a check crashed or the run was
interrupted (the report then says which), 2 on bad input.
"""

from __future__ import annotations

import argparse
from typing import Any

from meanfield.cli.arguments import add_scenario_arguments, scenario_from_args
from meanfield.errors import ParameterError
from verification.result import CHECK_NAMES

__all__ = ["register"]


def register(subparsers: Any):
    """Add ``meanfield verify`` to the ``meanfield`` parser; return its handler."""
    v = subparsers.add_parser(
        "verify",
        help="check every claim of the paper numerically: report.md + verdicts.json",
    )
    add_scenario_arguments(v)
    v.add_argument(
        "--quick",
        action="store_true",
        help="short variant of every check (about 45 s for paper on 2 cores, plus about 5 min for two_scales)",
    )
    v.add_argument("--checks", default=None, help=f"comma-separated subset of: {', '.join(CHECK_NAMES)} (default: all)")
    v.add_argument("--workers", type=int, default=None, help="worker processes for the fan-out checks")
    v.add_argument(
        "--scheduler",
        default=None,
        help="a running Dask scheduler (tcp://HOST:PORT) for the fan-out runs; default: a local cluster, as sweep",
    )
    v.add_argument("--quiet", action="store_true", help="no progress, no verdict lines")
    return _handle


def _handle(args: argparse.Namespace) -> int:
    from verification.report import write_report
    from verification.runner import CHECKS, verify

    checks = None
    if args.checks is not None:
        checks = [c.strip() for c in args.checks.split(",") if c.strip()]
        bad = [c for c in checks if c not in CHECKS]
        if bad or not checks:
            raise ParameterError("--checks", args.checks, f"a comma-separated subset of {', '.join(CHECKS)}")
    if args.workers is not None and args.workers < 1:
        raise ParameterError("--workers", args.workers, "an integer >= 1")
    scenario: Any = scenario_from_args(args)  # a room that is not convex is a plan, on which the checks run
    args.out.mkdir(parents=True, exist_ok=True)

    def show(result) -> None:
        if not args.quiet:
            print(f"{result.key:>12}: {result.verdict:<12} {result.summary[:160]}", flush=True)

    from analysis.parallel import jobs_on

    with jobs_on(args.scheduler, args.workers):  # the fan-out checks share one Dask cluster
        run = verify(
            scenario,
            args.out,
            quick=args.quick,
            checks=checks,
            progress=not args.quiet,
            workers=args.workers,
            on_result=show,
        )
    paths = write_report(run, args.out)
    if not args.quiet:
        print(f"{run.status} in {run.seconds:.0f} s; report: {paths['report']}")
    return 0 if run.all_ran else 1
