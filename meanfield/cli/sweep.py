"""``meanfield sweep``: closed-loop runs over a grid of scenario values × seeds on Dask.

The sweep itself is :mod:`meanfield.workflows.sweep`; this module is its command.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from meanfield.cli.arguments import output_dir
from meanfield.errors import ParameterError
from meanfield.workflows.dask_cluster import CONNECT_TIMEOUT
from meanfield.workflows.sweep import run_sweep
from meanfield.workflows.sweep_plan import parse_seeds, parse_values

__all__ = ["register"]


def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield sweep`` to the ``meanfield`` parser; return its handler."""
    p = subparsers.add_parser(
        "sweep",
        help="closed-loop runs over a grid of scenario values x seeds on Dask: sweep.nc + runs/*.json",
        description=(
            "Run the closed loop for the cartesian product of the --set values and the seeds, on a local "
            "Dask cluster or an existing one (--scheduler). Resumable: re-running with the same arguments "
            "reuses the finished runs in OUT/runs. Exit status: 0 every run completed; 1 a run failed, "
            "diverged or the sweep was interrupted (outputs written); 2 bad input."
        ),
    )
    p.add_argument("scenario", nargs="?", default="paper", help="built-in name (paper) or a TOML file")
    p.add_argument("--out", required=True, type=output_dir, help="output directory (checked before any work)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=V1,V2,...",
        help="a swept scenario field and its values, e.g. --set robots.n=4,9,16 (repeatable)",
    )
    p.add_argument("--seeds", default="1", help="N for seeds 0..N-1, or A-B, or a,b,c (default 1)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="an existing Dask scheduler, tcp://host:port")
    p.add_argument("--workers", type=int, default=None, help="worker processes of the local cluster (default: cores)")
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=CONNECT_TIMEOUT,
        help=f"seconds to wait for --scheduler before refusing it (default {CONNECT_TIMEOUT:g})",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    return _handle


def _handle(args: argparse.Namespace) -> int:
    from meanfield.scenarios.scenario import load_scenario

    sets = parse_values(args.set)
    seeds = parse_seeds(args.seeds)
    if not args.connect_timeout > 0:
        raise ParameterError("--connect-timeout", args.connect_timeout, "a number of seconds > 0")
    ds = run_sweep(
        load_scenario(args.scenario),
        sets,
        seeds,
        args.out,
        scheduler=args.scheduler,
        workers=args.workers,
        progress=not args.quiet,
        connect_timeout=args.connect_timeout,
    )
    counts: dict[str, int] = {}
    for st in ds["status"].values.flat:
        counts[st] = counts.get(st, 0) + 1
    if not args.quiet:
        print(
            f"sweep {ds.attrs['status']}: {ds.attrs['runs_total']} runs "
            f"({ds.attrs['runs_reused']} reused, {ds.attrs['runs_executed']} run now); "
            + ", ".join(f"{n} {st}" for st, n in sorted(counts.items()))
        )
        print(f"outputs in {args.out}")
    if ds.attrs["status"] != "completed":
        import sys

        flat = zip(ds["status"].values.flat, ds["message"].values.flat, strict=True)
        bad = [f"{st}: {m}" if m else st for st, m in flat if st != "completed"]
        first = f"; first: {bad[0]}" if bad else ""
        print(f"meanfield: sweep {ds.attrs['status']}: {len(bad)} run(s) not completed{first}", file=sys.stderr)
        return 1
    return 0
