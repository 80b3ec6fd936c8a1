"""``meanfield compare``: agents beside the Fokker–Planck equation under the same robots, for several N."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from meanfield.cli.arguments import add_scenario_arguments, scenario_from_args
from meanfield.errors import ParameterError
from meanfield.scenarios.overrides import int_list

__all__ = ["register"]


def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield compare`` to the ``meanfield`` parser; return its handler."""
    c = subparsers.add_parser(
        "compare",
        help="agents (SDE) against the Fokker–Planck PDE under the same robot trajectories, for several N",
    )
    add_scenario_arguments(c)
    c.add_argument(
        "--n-agents", default="100,1000,10000,100000", help="comma-separated crowd sizes (default 100,...,100000)"
    )
    c.add_argument("--t-final", type=float, default=None, help="horizon (default: the scenario's t_final)")
    c.add_argument("--cells", type=int, default=64, help="PDE and density grid, cells per side (default 64)")
    c.add_argument(
        "--repulsion",
        default="0.5,0.1",
        help="STRENGTH,LENGTH of the repulsive Gaussian W for the second case, or 'none' (default 0.5,0.1)",
    )
    c.add_argument("--record-interval", type=float, default=1.0, help="time between measurements (default 1)")
    c.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    c.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    return _cmd_compare


def _cmd_compare(args: argparse.Namespace) -> int:
    from meanfield.workflows.mean_field_limit import run_comparison

    sc = scenario_from_args(args)
    sizes = int_list("--n-agents", args.n_agents)
    if args.cells < 4:
        raise ParameterError("--cells", args.cells, "an integer >= 4")
    if args.t_final is not None and not args.t_final > 0:
        raise ParameterError("--t-final", args.t_final, "a time > 0")
    repulsion = None
    if args.repulsion.strip().lower() != "none":
        try:
            repulsion = tuple(float(v) for v in args.repulsion.split(","))
        except ValueError:
            repulsion = ()
        if len(repulsion) != 2:
            raise ParameterError("--repulsion", args.repulsion, "STRENGTH,LENGTH (two numbers > 0) or 'none'")
    report = run_comparison(
        sc,
        sizes,
        repulsion=repulsion,
        t_final=args.t_final,
        cells=(args.cells, args.cells),
        record_interval=args.record_interval,
        seed=args.seed,
        progress=not args.quiet,
    )
    from meanfield.plotting import figures as plotting

    report.save(args.out, artifacts=[] if args.no_figures else [plotting.save_comparison_figures])
    if not args.quiet:
        for case in report.cases:
            s = case.summary
            print(f"{s['label']}: status {s['status']}")
            for name in ("error_to_expected", "error_to_pde", "error_to_expected_paper_sign"):
                if f"{name}_mean" in s:
                    means = ", ".join(f"N={n}: {v:.4g}" for n, v in s[f"{name}_mean"].items())
                    print(f"  {name}: {means}; slope over 1e2..1e4: {s[f'{name}_slope_1e2_1e4']}")
        print(f"outputs in {args.out}")
    bad = [c.summary for c in report.cases if c.summary["status"] != "completed"]
    if bad:
        print(f"meanfield: compare {bad[0]['status']}: {bad[0]['message']}", file=sys.stderr)
        return 1
    return 0
