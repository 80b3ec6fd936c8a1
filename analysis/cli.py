"""``meanfield analyze``: the constants behind the paper's guarantees, for one scenario.

Registered as a ``meanfield.commands`` entry point (see :mod:`meanfield.plugins`).  Writes
``DIR/analysis.json`` (last, atomically: a directory with it is complete) and figures:

- ``poincare_mode.png``: μ₂ of Ω, its eigenfunction, the Payne–Weinberger bound (``null`` in
  the JSON and "not applicable" in the figure when Ω is not convex, e.g. a floor plan with
  a re-entrant corner or a pillar: ``docs/poincare.md``, *Floor plans*);
- ``robot_count.png``: the coverage estimates ``n(ε)`` against closed-loop runs over ``n``;
- ``speed_limits.png``: min-norm (clipped) against the bounded program over ``u_max``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from meanfield.cli.arguments import add_scenario_arguments, scenario_from_args
from meanfield.errors import ParameterError
from meanfield.scenarios.overrides import float_list, int_list

__all__ = ["register", "analyze"]


def register(subparsers: Any):
    """Add ``meanfield analyze`` to the ``meanfield`` parser; return its handler."""
    a = subparsers.add_parser(
        "analyze",
        help="Poincaré constant, decay rate and ISS gain, robot count, cost of speed limits (JSON + figures)",
    )
    add_scenario_arguments(a, seed_help="random seed of the reference run (overrides the scenario's)")
    a.add_argument("--cells", type=int, default=128, help="cells per side of the eigenvalue grid (default 128)")
    a.add_argument("--eps", default="0.5,0.2,0.1,0.05", help="coverage levels ε as fractions of the kernel peak c")
    a.add_argument("--robot-counts", default="1,2,4,6,9,12,16,25", help="robot counts of the empirical study")
    a.add_argument(
        "--limits", default=None, help="speed limits of the limits study (default 0.25, 0.5, 1, 2 × the scenario's)"
    )
    a.add_argument("--seeds", default="0-2", help="seeds of the studies, 'A-B' or 'a,b' (default 0-2)")
    a.add_argument("--workers", type=int, default=None, help="worker processes (default: the cores)")
    a.add_argument(
        "--scheduler",
        default=None,
        help="a running Dask scheduler (tcp://HOST:PORT) for the fan-out runs; default: a local cluster, as sweep",
    )
    a.add_argument("--quick", action="store_true", help="64² eigenvalue, no robot-count or limits study")
    a.add_argument("--quiet", action="store_true", help="no progress bars, no summary printout")
    return _handle


def _handle(args: argparse.Namespace) -> int:
    sc = scenario_from_args(args)
    if args.cells < 4:
        raise ParameterError("--cells", args.cells, "an integer >= 4")
    eps = float_list("--eps", args.eps)
    if not all(0 < e < 1 for e in eps):
        raise ParameterError("--eps", args.eps, "fractions of the kernel peak, each in (0, 1)")
    counts = int_list("--robot-counts", args.robot_counts, ranges=True)
    if min(counts) < 1:
        raise ParameterError("--robot-counts", args.robot_counts, "robot counts, each >= 1")
    seeds = int_list("--seeds", args.seeds, ranges=True)
    if min(seeds) < 0:
        raise ParameterError("--seeds", args.seeds, "seeds >= 0")
    if args.limits is not None:
        limits = float_list("--limits", args.limits)
        if not all(math.isfinite(u) and u > 0 for u in limits):
            raise ParameterError("--limits", args.limits, "speed limits, each > 0")
    elif sc.robots.u_max is not None:
        limits = [f * sc.robots.u_max for f in (0.25, 0.5, 1.0, 2.0)]
    else:
        limits = []
    if args.workers is not None and args.workers < 1:
        raise ParameterError("--workers", args.workers, "an integer >= 1")
    from analysis.parallel import jobs_on

    with jobs_on(args.scheduler, args.workers):  # the fan-out runs share one Dask cluster
        report = analyze(
            sc,
            args.out,
            cells=64 if args.quick else args.cells,
            eps_fractions=eps,
            robot_counts=[] if args.quick else counts,
            limits=[] if args.quick else limits,
            seeds=seeds,
            workers=args.workers,
            progress=not args.quiet,
        )
    if not args.quiet:
        p = report["poincare"]
        g = report["gains_scenario"]
        from analysis.poincare import NOT_CONVEX

        pw = p["payne_weinberger"]
        pw_text = f"{pw:.4g}" if pw is not None else NOT_CONVEX
        print(f"mu2 = {p['mu2']:.6g} (Payne–Weinberger bound {pw_text}, exact {p['exact']})")
        print(f"at the target: alpha_inf = {g['alpha_inf']:.4g}, k_p = {g['k_p']:.4g}, ISS gain = {g['iss_gain']:.4g}")
        b = g["bulk"]
        print(
            f"  bulk (95 % of the mass, not a guarantee): alpha = {b['alpha']:.4g}, k_p = {b['k_p']:.4g}, "
            f"ISS gain = {b['iss_gain']:.4g}"
        )
        cov = ", ".join(f"eps={k}: n={v['n']}" for k, v in report["coverage"].items())
        print(f"coverage estimate: {cov}")
        if "robot_count" in report:
            print(f"empirical minimum robot count: {report['robot_count']['minimum']}")
        if "limits" in report:
            for row in report["limits"]["table"]:
                print(
                    f"{row['strategy']:>9} u_max={row['u_max']:.3g}: fraction {row['fraction_in_target']:.3f}, "
                    f"l2 ratio {row['l2_error_ratio']:.3f}, limits binding {row['limits_binding_fraction']:.2f}"
                )
        print(f"outputs in {args.out}")
    return 0 if report["status"] == "completed" else 1


def analyze(
    scenario,
    out_dir: Path,
    *,
    cells: int = 128,
    eps_fractions: list[float] = (0.5, 0.2, 0.1, 0.05),
    robot_counts: list[int] = (1, 2, 4, 6, 9, 12, 16, 25),
    limits: list[float] = (),
    seeds: list[int] = (0, 1, 2),
    workers: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Compute every analysis of a scenario, write ``analysis.json`` and the figures.

    Steps: μ₂ and its mode (:mod:`analysis.poincare`); the gains at the target and along
    one closed-loop run (:mod:`analysis.rates`); coverage estimates for each ``ε``
    (:mod:`analysis.robot_count`); then, if asked, the empirical robot count over
    ``robot_counts`` and the limits study over ``limits`` (:mod:`analysis.limits`).  A
    KeyboardInterrupt stops the studies; what was computed is written, with
    ``status = "interrupted"``.
    """
    from analysis import figures
    from analysis.limits import limits_study
    from analysis.poincare import exact_neumann_eigenvalue, neumann_eigenvalue, payne_weinberger_bound
    from analysis.rates import gains_for_scenario, gains_from_run
    from analysis.robot_count import coverage_estimate, empirical_robot_count
    from meanfield.geometry.grid import Grid
    from meanfield.io.atomic import atomic_write_json
    from meanfield.simulation.loop import ClosedLoop

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    report: dict[str, Any] = {"scenario": scenario.to_dict(), "status": "completed"}
    try:
        mu2, mode = neumann_eigenvalue(scenario.domain, cells=(cells, cells), return_mode=True)
        exact = exact_neumann_eigenvalue(scenario.domain)
        pw = payne_weinberger_bound(scenario.domain)
        report["poincare"] = {
            "mu2": mu2,
            "c2": math.sqrt(mu2),
            "cells": cells,
            "payne_weinberger": pw,
            "exact": exact,
            "relative_error": None if exact is None else abs(mu2 - exact) / exact,
        }
        grid = Grid(scenario.domain, (cells, cells))
        fig = figures.plot_poincare_mode(scenario.domain, grid, mode, mu2, pw, exact)
        figures.save_figure(fig, out / "poincare_mode.png")
        report["gains_scenario"] = gains_for_scenario(scenario, mu2=mu2).to_dict()
        result = ClosedLoop(scenario).run(progress=progress)
        report["reference_run"] = {k: result.summary[k] for k in ("status", "fraction_in_target", "l2_error_ratio")}
        report["gains_run"] = gains_from_run(result, mu2=mu2).to_dict()
        c, eta = scenario.kernel.c, scenario.kernel.eta
        coverage = {f: coverage_estimate(scenario.domain, c, eta, f * c) for f in eps_fractions}
        report["coverage"] = {str(f): {"eps": f * c, **layout.to_dict()} for f, layout in coverage.items()}
        if robot_counts:
            study = empirical_robot_count(scenario, robot_counts, seeds, workers=workers, progress=progress)
            report["robot_count"] = study.to_dict()
            fig = figures.plot_robot_count(study, {f * c: lay.n for f, lay in coverage.items()}, c)
            figures.save_figure(fig, out / "robot_count.png")
        if limits:
            lim = limits_study(scenario, limits, seeds=seeds, workers=workers, progress=progress)
            report["limits"] = lim.to_dict()
            figures.save_figure(figures.plot_limits(lim), out / "speed_limits.png")
    except KeyboardInterrupt:
        report["status"] = "interrupted"
        print("meanfield: analyze interrupted; writing what was computed", file=sys.stderr)
    report["wall_seconds"] = time.perf_counter() - t0
    atomic_write_json(out / "analysis.json", report)
    return json.loads(json.dumps(report, default=str))
