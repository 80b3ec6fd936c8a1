"""NMPC in real time: outcome and compute per control step of NMPC settings on the paper scenario.

Usage:  python studies/nmpc_real_time.py --seeds 0-2 --t-final 10 --out FILE.json \\
            --setting NAME 'KEY=VALUE;KEY=VALUE' [--setting ...]

Each setting is a set of ``controller.options.nmpc`` of the ``nmpc`` controller (e.g.
``'solver="ipopt"'`` or ``'max_iter=2;blocks=[1,1,3]'``; ``NAME`` labels it).  For every seed
the settings run one after the other in this one process (one core: BLAS threads pinned to
one), so their timings see the same machine load; per run the script records the outcome
(``fraction_in_target``, ``time_to_90``, largest robot speed and turn rate) and the compute:
the wall time of every ``act`` call of the controller (the NMPC plan, the backstepping
diagnostics it reports beside it, the restriction onto the coarse cells), i.e. what a
control step costs, amortised over the steps between solves, and its slowest call (the
first call, which also pays one-off start-up costs, is recorded apart: ``first_act_ms``).

The real-time factor is the one of docs/controllers.md ("Compute per control step"): the
paper's time unit taken as a second, a control period of ``dt = 0.01`` s, so
``factor = mean act time / 10 ms``.  Results are appended to ``--out`` (JSON lines) as each
run ends, so an interrupted study keeps what it did; ``--summary FILE.json`` prints the
medians per setting.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks.reporting import time_act_calls  # noqa: E402
from meanfield import ClosedLoop, paper_scenario  # noqa: E402
from meanfield.scenarios.overrides import parse_set  # noqa: E402

CONTROL_PERIOD = 0.01  # s: the paper scenario's dt, its time unit taken as a second


def parse_seeds(text: str) -> list[int]:
    """``"0-9"`` or ``"0,3,5"``."""
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def one_run(seed: int, t_final: float, options: dict[str, Any]) -> dict[str, Any]:
    """A closed loop on ``paper`` (seed, t_final) with NMPC ``options``; outcome and ``act`` times."""
    sets = {"controller.kind": "nmpc", **{f"controller.options.nmpc.{k}": v for k, v in options.items()}}
    sc = paper_scenario(seed=seed).replace(t_final=t_final).with_values(sets)
    t0 = time.perf_counter()
    loop = ClosedLoop(sc)
    build = time.perf_counter() - t0
    controller = loop.parts.controller
    times = time_act_calls(controller)
    result = loop.run(progress=False)
    s = result.summary
    # the final frame's diagnostics-only call excluded; the first call (one-off start-up costs:
    # first evaluations, lazy imports, page faults) recorded apart from the steady steps
    acts = np.array(times[1 : s["steps"]])
    stats = controller.stats
    return {
        "seed": seed,
        "t_final": t_final,
        "options": options,
        "status": s["status"],
        "fraction_in_target": s["fraction_in_target"],
        "time_to_90": s.get("time_to_90"),
        "max_robot_speed": s["max_robot_speed"],
        "max_robot_turn_rate": s["max_robot_turn_rate"],
        "steps": s["steps"],
        "act_ms_mean": float(acts.mean() * 1e3),
        "act_ms_p99": float(np.percentile(acts, 99) * 1e3),
        "act_ms_max": float(acts.max() * 1e3),
        "first_act_ms": float(times[0] * 1e3),
        "real_time_factor": float(acts.mean() / CONTROL_PERIOD),
        "solves": len(stats),
        "solve_ms_median": float(np.median([x["seconds"] for x in stats]) * 1e3),
        "solve_ms_max": float(np.max([x["seconds"] for x in stats]) * 1e3),
        "iterations_median": float(np.median([x["iterations"] for x in stats])),
        "statuses": {k: sum(1 for x in stats if x["status"] == k) for k in {x["status"] for x in stats}},
        "projected": int(sum(x["projected"] for x in stats)),
        "max_speed_solver": float(max(x["max_speed_solver"] for x in stats)),
        "build_seconds": build,
    }


def summarise(rows: list[dict[str, Any]]) -> str:
    """Per setting: median and worst fraction in target, median time_to_90, act times, real-time factor."""
    lines = [
        "| setting | runs | fraction in target, median (worst) | time_to_90, median (worst) | act ms mean "
        "| act ms p99 | slowest act ms | real-time factor (10 ms step) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    names = list(dict.fromkeys(r["name"] for r in rows))
    for name in names:
        rs = [r for r in rows if r["name"] == name]
        frac = [r["fraction_in_target"] for r in rs]
        t90 = [r["time_to_90"] if r["time_to_90"] is not None else float("inf") for r in rs]
        lines.append(
            f"| {name} | {len(rs)} | {statistics.median(frac):.3f} ({min(frac):.3f}) | "
            f"{statistics.median(t90):.3g} ({max(t90):.3g}) | "
            f"{statistics.median(r['act_ms_mean'] for r in rs):.2f} | "
            f"{statistics.median(r['act_ms_p99'] for r in rs):.1f} | {max(r['act_ms_max'] for r in rs):.0f} | "
            f"{statistics.median(r['real_time_factor'] for r in rs):.2f} |"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-2")
    ap.add_argument("--t-final", type=float, default=10.0)
    ap.add_argument("--setting", nargs=2, action="append", default=[], metavar=("NAME", "OPTIONS"))
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per run")
    ap.add_argument("--summary", type=Path, default=None, help="print the table of a --out file and exit")
    a = ap.parse_args()
    if a.summary is not None:
        rows = [json.loads(line) for line in a.summary.read_text().splitlines() if line.strip()]
        print(summarise(rows))
        return
    settings = [(name, parse_set([kv for kv in text.split(";") if kv]) if text else {}) for name, text in a.setting]
    settings = settings or [("default", {})]
    rows = []
    for seed in parse_seeds(a.seeds):
        for name, options in settings:
            row = {"name": name, **one_run(seed, a.t_final, options)}
            rows.append(row)
            keys = (
                "name",
                "seed",
                "fraction_in_target",
                "time_to_90",
                "act_ms_mean",
                "act_ms_max",
                "iterations_median",
            )
            print(json.dumps({k: row[k] for k in keys}), flush=True)
            if a.out is not None:
                with open(a.out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")
    print(summarise(rows))


if __name__ == "__main__":
    main()
