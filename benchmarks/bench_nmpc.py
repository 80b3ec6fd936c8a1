"""NMPC compute per control step against backstepping's, measured in the same run, on one core.

Run:  python benchmarks/bench_nmpc.py [--t-final 4] [--repeats 3] [--set KEY=VALUE ...]
                                      [--json FILE] [--out FILE]

Each repeat runs the paper scenario (200 humans, 16 robots, 30×30 grid, dt = 0.01, seed =
repeat) with ``controller.kind = "nmpc"`` (default options of :mod:`analysis.nmpc`, or
``--set controller.options.KEY=VALUE``) for ``--t-final`` seconds.  In that run the NMPC
controller times every IPOPT solve (one per control period) and every call of the
backstepping law, which it evaluates at every step for the diagnostics (V₂ etc.): the two
computations see the same states, the same process and the same machine load.

Reported per repeat and as the median over repeats:

* NMPC: median and p90 wall seconds per solve, IPOPT iterations, statuses, and the solve
  time per simulation step (total solve time / steps; one solve every ``period``);
* backstepping: median and p90 wall seconds per ``robot_inputs`` call (every step);
* the ratio median solve / median backstepping call (what to compare across machines),
  and the amortised ratio (solve time per simulation step / backstepping per call);
* the one-off set-up: building and compiling the Opti problem (``Opti.to_function``).

``--json`` writes the figures as JSON, ``--out`` the printed report as text.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import casadi  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import write_files  # noqa: E402
from meanfield import ClosedLoop, paper_scenario  # noqa: E402
from meanfield.cli import parse_set  # noqa: E402


def one_run(seed: int, t_final: float, sets: dict) -> dict:
    sc = paper_scenario(seed=seed).replace(t_final=t_final).with_values({"controller.kind": "nmpc", **sets})
    t0 = time.perf_counter()
    loop = ClosedLoop(sc)
    build = time.perf_counter() - t0
    result = loop.run(progress=False)
    c = loop.controller
    solves = np.array([s["seconds"] for s in c.stats])
    bs = np.array(c.backstepping_seconds)
    steps = result.summary["steps"]
    statuses: dict[str, int] = {}
    for s in c.stats:
        statuses[s["status"]] = statuses.get(s["status"], 0) + 1
    return {
        "seed": seed,
        "steps": steps,
        "build_seconds": build,
        "solves": len(solves),
        "solve_median": float(np.median(solves)),
        "solve_p90": float(np.percentile(solves, 90)),
        "iterations_median": float(np.median([s["iterations"] for s in c.stats])),
        "ipopt_statuses": statuses,
        "backstepping_median": float(np.median(bs)),
        "backstepping_p90": float(np.percentile(bs, 90)),
        "ratio_solve_over_backstepping": float(np.median(solves) / np.median(bs)),
        "solve_seconds_per_simulation_step": float(solves.sum() / steps),
        "ratio_amortised": float(solves.sum() / steps / np.median(bs)),
        "options": {k: v for k, v in vars(c.options).items()},
    }


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``nmpc`` record of ``meanfield bench`` (``docs/cli.md``): NMPC solve against the backstepping law.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        One record: medians over the repeats of :func:`one_run` (seeds 0, 1, ...).
    """
    s = settings("nmpc", quick)
    runs = [one_run(seed, s["t_final"], {}) for seed in range(s["repeats"])]

    def med(key: str) -> float:
        return float(statistics.median(r[key] for r in runs))

    statuses: dict[str, int] = {}
    for r in runs:
        for k, v in r["ipopt_statuses"].items():
            statuses[k] = statuses.get(k, 0) + v
    amortised = med("solve_seconds_per_simulation_step") * 1e3
    return [
        measured(
            "nmpc",
            "nmpc solve vs backstepping",
            f"controller compute per control step, paper scenario, T={s['t_final']:g} per repeat, "
            f"median over {s['repeats']} repeat(s)",
            "NMPC (analysis.nmpc, CasADi + IPOPT): median solve, one per control period",
            "backstepping robot_inputs (the paper's law): median call, every step",
            med("solve_median") * 1e3,
            med("backstepping_median") * 1e3,
            "ms per control step",
            faster="lower",
            note=(
                f"amortised over the simulation steps: {amortised:.3g} ms per step; "
                f"{sum(r['solves'] for r in runs)} solves, IPOPT {statuses}"
            ),
            detail={"runs": runs, "t_final": s["t_final"], "repeats": s["repeats"]},
        )
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-final", type=float, default=4.0, help="simulated seconds per repeat (default 4)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], help="e.g. controller.options.horizon=3")
    ap.add_argument("--json", default=None, help="write the figures as JSON")
    ap.add_argument("--out", default=None, help="write the printed report as text")
    a = ap.parse_args()
    sets = parse_set(a.set)
    runs = [one_run(r, a.t_final, sets) for r in range(a.repeats)]
    med = {
        k: statistics.median(r[k] for r in runs)
        for k in (
            "solve_median",
            "solve_p90",
            "backstepping_median",
            "backstepping_p90",
            "ratio_solve_over_backstepping",
            "solve_seconds_per_simulation_step",
            "ratio_amortised",
            "build_seconds",
            "iterations_median",
        )
    }
    out = {
        "benchmark": "NMPC solve vs backstepping robot_inputs per control step, paper scenario "
        f"(N=200, n=16, 30x30, dt=0.01), T={a.t_final:g} per repeat, same run",
        "settings": sets,
        "options": runs[0]["options"],
        "runs": runs,
        "median_over_repeats": med,
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}, casadi {casadi.__version__}",
    }
    lines = [
        f"# {out['benchmark']}",
        f"# options: {json.dumps(out['options'])}",
        f"# machine: {out['machine']}",
        "",
        "| repeat (seed) | solves | NMPC solve median (p90) | IPOPT iterations (median) | "
        "backstepping per call median (p90) | ratio solve / backstepping | amortised ratio | build |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        lines.append(
            f"| {r['seed']} | {r['solves']} | {r['solve_median'] * 1e3:.0f} ms ({r['solve_p90'] * 1e3:.0f} ms) | "
            f"{r['iterations_median']:.0f} | {r['backstepping_median'] * 1e3:.3f} ms "
            f"({r['backstepping_p90'] * 1e3:.3f} ms) | {r['ratio_solve_over_backstepping']:.0f} | "
            f"{r['ratio_amortised']:.0f} | {r['build_seconds']:.1f} s |"
        )
    lines += [
        "",
        f"median over {len(runs)} repeats: NMPC solve {med['solve_median'] * 1e3:.0f} ms "
        f"(p90 {med['solve_p90'] * 1e3:.0f} ms), backstepping {med['backstepping_median'] * 1e3:.3f} ms per call; "
        f"ratio {med['ratio_solve_over_backstepping']:.0f} per control step, "
        f"{med['ratio_amortised']:.0f} amortised over the simulation steps",
    ]
    report = "\n".join(lines)
    print(report)
    write_files(out, a.json, report, a.out)


if __name__ == "__main__":
    main()
