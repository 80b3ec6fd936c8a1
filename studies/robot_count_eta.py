"""Robot count × kernel range η: the study behind docs/robot_count.md and its figure.

Usage:  python studies/robot_count_eta.py [scenario] [--counts 1,4,9,16,25,36]
            [--etas 0.005,0.01,0.02,0.05,0.1,0.2] [--seeds 10] [--out DIR]
            [--scheduler ADDRESS] [--workers N] [--set KEY=VALUE ...] [--figure FILE]

Runs the scenario (``paper`` by default) for every count × η × seed with
:func:`analysis.robot_count_sweep.run_robot_count_sweep` (Dask: a local cluster, or the
one at ``--scheduler``; resumable: rerun the same command after an interruption and the
finished runs are reused from ``OUT/runs``), then writes ``OUT/robot_count_eta.json`` (the
medians, the smallest successful count per η, the coverage estimates) and the figure
(``OUT/robot_count_eta.png``, or ``--figure``), and prints the tables in Markdown.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from analysis.figures import plot_robot_count_sweep, save_figure
from analysis.robot_count_sweep import run_robot_count_sweep, summarize_robot_count_sweep
from meanfield.errors import ParameterError
from meanfield.io.atomic import atomic_write_json
from meanfield.scenarios.overrides import float_list, int_list, parse_set
from meanfield.scenarios.scenario import load_scenario
from meanfield.workflows.sweep import parse_seeds


def _table(study, values, fmt) -> str:
    head = "| robots n | " + " | ".join(f"η = {e:g}" for e in study.etas) + " |"
    rule = "|---|" + "---|" * len(study.etas)
    rows = [f"| {n} | " + " | ".join(fmt(v) for v in values[i]) + " |" for i, n in enumerate(study.counts)]
    cov = [
        f"| coverage n, ε = {f:g}·c | " + " | ".join(str(n) for n in ns) + " |" for f, ns in study.coverage.items()
    ]
    return "\n".join([head, rule, *rows, *cov])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default="paper")
    ap.add_argument("--counts", default="1,4,9,16,25,36")
    ap.add_argument("--etas", default="0.005,0.01,0.02,0.05,0.1,0.2")
    ap.add_argument("--seeds", default="10")
    ap.add_argument("--out", type=Path, default=Path("studies/out/robot_count_eta"))
    ap.add_argument("--scheduler", default=None)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--figure", type=Path, default=None)
    ap.add_argument("--threshold", type=float, default=0.9)
    a = ap.parse_args(argv)
    try:
        sc = load_scenario(a.scenario)
        if a.set:
            sc = sc.with_values(parse_set(a.set))
        counts = list(int_list("--counts", a.counts, ranges=True))
        etas = list(float_list("--etas", a.etas))
        seeds = parse_seeds(a.seeds)
        t0 = time.perf_counter()
        ds = run_robot_count_sweep(sc, counts, etas, seeds, a.out, scheduler=a.scheduler, workers=a.workers)
        wall = time.perf_counter() - t0
        study = summarize_robot_count_sweep(ds, threshold=a.threshold)
    except ParameterError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    record = study.to_dict() | {
        "scenario": sc.name,
        "sweep_status": ds.attrs["status"],
        "runs_total": int(ds.attrs["runs_total"]),
        "runs_executed": int(ds.attrs["runs_executed"]),
        "runs_reused": int(ds.attrs["runs_reused"]),
        "wall_seconds": wall,
        "command": " ".join(["python", "studies/robot_count_eta.py", *(argv if argv is not None else sys.argv[1:])]),
    }
    atomic_write_json(a.out / "robot_count_eta.json", record)
    fig_path = a.figure or a.out / "robot_count_eta.png"
    save_figure(plot_robot_count_sweep(study), fig_path)
    print(f"{record['runs_total']} runs ({record['runs_executed']} run now, {record['runs_reused']} reused) "
          f"in {wall:.0f} s; sweep status {record['sweep_status']}\n")
    print("Median fraction in the target region at t_final:\n")
    print(_table(study, study.fraction, lambda v: "–" if math.isnan(v) else f"{v:.3f}"))
    print("\nMedian time to 90 % (s):\n")
    t90 = study.time_to_90
    print(_table(study, t90, lambda v: "never" if math.isinf(v) else ("–" if math.isnan(v) else f"{v:.1f}")))
    print("\nSmallest count with median fraction ≥", study.threshold, ":",
          ", ".join(f"η = {e:g}: {n}" for e, n in study.minimum.items()))
    print(f"\nfigure: {fig_path}")
    return 0 if ds.attrs["status"] == "completed" else 1


if __name__ == "__main__":
    raise SystemExit(main())
