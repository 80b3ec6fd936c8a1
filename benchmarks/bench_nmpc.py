"""NMPC in real time: compute per control step of the NMPC controller, against the control period and IPOPT.

Run:  python benchmarks/bench_nmpc.py [--t-final 4] [--repeats 3] [--set KEY=VALUE ...]
                                      [--anchor-set KEY=VALUE ...] [--json FILE] [--out FILE]

Each repeat runs the paper scenario (200 humans, 16 robots, 30×30 grid, dt = 0.01, seed =
repeat) for ``--t-final`` seconds twice, one core, one run after the other: with the NMPC
controller as configured (``controller.kind = "nmpc"``, its default options — the real-time
SQP — or ``--set controller.options.nmpc.KEY=VALUE``), and with the anchor, the same problem solved
by IPOPT to convergence (``controller.options.nmpc.solver = "ipopt"``, or ``--anchor-set``).  The
first seconds are the busiest (the signs turn, the crowd is gathered), so they are the ones timed.

In each run every call of the controller's ``act`` is timed: the plan (a solve once per control
period, or a slice of it), the restriction onto the coarse cells and the backstepping
diagnostics reported beside the plan — the compute of a control step.  Reported per run: the
mean over the steps (amortised: the solves spread over the steps between them), the 99th
percentile and the slowest step (the first step, which also pays one-off start-up costs, is
reported apart); the solves (median, slowest), iterations and statuses; the
backstepping law alone (median per call, the paper's controller, measured in the same run).

**Real-time factor** (docs/controllers.md, "Compute per control step"): the paper's time unit
taken as a second, a control period of 10 ms, so ``factor = mean act time / 10 ms``.  The goal
is ``factor <= 0.5`` (:data:`GOAL_FACTOR`) for the default NMPC (H = 5): PASS or FAIL, with
the slowest step's factor printed beside it (a goal on the mean, not a hard real-time bound).

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
from benchmarks.reporting import time_act_calls, write_files  # noqa: E402
from meanfield import ClosedLoop, paper_scenario  # noqa: E402
from meanfield.scenarios.overrides import parse_set  # noqa: E402

CONTROL_PERIOD = 0.01  # s: dt of the paper scenario, its time unit taken as a second
GOAL_FACTOR = 0.5  # mean compute per control step <= half the control period
ANCHOR = {"controller.options.nmpc.solver": "ipopt"}


def one_run(seed: int, t_final: float, sets: dict) -> dict:
    """One closed loop with NMPC (``sets`` on top of ``controller.kind = "nmpc"``): ``act`` and solve times."""
    sc = paper_scenario(seed=seed).replace(t_final=t_final).with_values({"controller.kind": "nmpc", **sets})
    t0 = time.perf_counter()
    loop = ClosedLoop(sc)
    build = time.perf_counter() - t0
    c = loop.controller
    acts = time_act_calls(c)
    result = loop.run(progress=False)
    steps = result.summary["steps"]
    act = np.array(acts[1:steps])  # the first call (one-off start-up costs) apart, the final frame's excluded
    solves = np.array([s["seconds"] for s in c.stats])
    bs = np.array(c.backstepping_seconds)
    statuses: dict[str, int] = {}
    for s in c.stats:
        statuses[s["status"]] = statuses.get(s["status"], 0) + 1
    return {
        "seed": seed,
        "steps": steps,
        "build_seconds": build,
        "act_mean": float(act.mean()),
        "act_p99": float(np.percentile(act, 99)),
        "act_max": float(act.max()),
        "first_act": float(acts[0]),
        "real_time_factor": float(act.mean() / CONTROL_PERIOD),
        "slowest_step_factor": float(act.max() / CONTROL_PERIOD),
        "solves": len(solves),
        "solve_median": float(np.median(solves)),
        "solve_max": float(solves.max()),
        "iterations_median": float(np.median([s["iterations"] for s in c.stats])),
        "statuses": statuses,
        "backstepping_median": float(np.median(bs)),
        "fraction_in_target": result.summary["fraction_in_target"],
        "max_robot_speed": result.summary["max_robot_speed"],
        "options": {k: v for k, v in vars(c.options).items()},
    }


def measure(t_final: float, repeats: int, sets: dict, anchor: dict) -> dict[str, Any]:
    """``repeats`` pairs of runs (seed = repeat), the NMPC then the anchor, and their medians."""
    runs = {"nmpc": [], "anchor": []}
    for r in range(repeats):
        runs["nmpc"].append(one_run(r, t_final, sets))
        runs["anchor"].append(one_run(r, t_final, {**sets, **anchor}))
    keys = ("act_mean", "act_p99", "act_max", "real_time_factor", "slowest_step_factor", "solve_median", "solve_max")
    med = {
        name: {k: statistics.median(x[k] for x in rs) for k in (*keys, "iterations_median", "backstepping_median")}
        for name, rs in runs.items()
    }
    for name, rs in runs.items():  # the slowest step over all repeats, not a median
        med[name]["act_max"] = max(x["act_max"] for x in rs)
        med[name]["slowest_step_factor"] = max(x["slowest_step_factor"] for x in rs)
    factor = med["nmpc"]["real_time_factor"]
    return {
        "runs": runs,
        "median_over_repeats": med,
        "goal": f"mean compute per control step <= {GOAL_FACTOR:g} x the {CONTROL_PERIOD * 1e3:g} ms control period",
        "pass": bool(factor <= GOAL_FACTOR),
        "verdict": "PASS" if factor <= GOAL_FACTOR else "FAIL",
    }


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``nmpc`` records of ``meanfield bench`` (``docs/cli.md``): real time, and the speed-up over IPOPT.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        Two records: the default NMPC's mean ``act`` against the control period (goal
        ``<= 0.5×``), and against IPOPT on the same problem in the same process.
    """
    s = settings("nmpc", quick)
    m = measure(s["t_final"], s["repeats"], {}, ANCHOR)
    ours, ipopt = m["median_over_repeats"]["nmpc"], m["median_over_repeats"]["anchor"]
    what = f"compute per control step, paper scenario, T={s['t_final']:g}, median over {s['repeats']} repeat(s)"
    slow = f"slowest step {ours['act_max'] * 1e3:.3g} ms ({ours['slowest_step_factor']:.2g} x the period)"
    return [
        measured(
            "nmpc",
            "nmpc real time",
            what,
            "NMPC (default options, H = 5): mean act() per control step",
            f"the control period, {CONTROL_PERIOD * 1e3:g} ms (the paper's time unit as a second)",
            ours["act_mean"] * 1e3,
            CONTROL_PERIOD * 1e3,
            "ms per control step",
            faster="lower",
            goal=f"<= {GOAL_FACTOR:g} x real time (ratio >= {1 / GOAL_FACTOR:g})",
            passed=m["pass"],
            note=f"real-time factor {ours['real_time_factor']:.3g}; {slow}",
            detail={"t_final": s["t_final"], "repeats": s["repeats"], **m},
        ),
        measured(
            "nmpc",
            "nmpc vs ipopt",
            what,
            "NMPC (default options): mean act() per control step",
            "the same problem solved by IPOPT to convergence: mean act(), same process",
            ours["act_mean"] * 1e3,
            ipopt["act_mean"] * 1e3,
            "ms per control step",
            faster="lower",
            note=f"IPOPT slowest step {ipopt['act_max'] * 1e3:.3g} ms; ours {ours['act_max'] * 1e3:.3g} ms",
        ),
    ]


def _row(name: str, r: dict) -> str:
    return (
        f"| {name} | {r['seed']} | {r['solves']} | {r['act_mean'] * 1e3:.2f} ms | {r['act_p99'] * 1e3:.1f} ms | "
        f"{r['act_max'] * 1e3:.0f} ms | {r['real_time_factor']:.2f} | {r['slowest_step_factor']:.1f} | "
        f"{r['solve_median'] * 1e3:.0f} ms | {r['iterations_median']:.0f} | {r['backstepping_median'] * 1e3:.3f} ms | "
        f"{r['fraction_in_target']:.3f} |"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-final", type=float, default=4.0, help="simulated seconds per repeat (default 4)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], help="e.g. controller.options.nmpc.blocks=[1,2,2]")
    ap.add_argument("--anchor-set", action="append", default=[], help='default controller.options.nmpc.solver="ipopt"')
    ap.add_argument("--json", default=None, help="write the figures as JSON")
    ap.add_argument("--out", default=None, help="write the printed report as text")
    a = ap.parse_args()
    sets = parse_set(a.set)
    anchor = parse_set(a.anchor_set) if a.anchor_set else ANCHOR
    m = measure(a.t_final, a.repeats, sets, anchor)
    out = {
        "benchmark": "NMPC compute per control step (act), paper scenario (N=200, n=16, 30x30, dt=0.01), "
        f"T={a.t_final:g} per repeat; the anchor ({anchor}) in the same process",
        "settings": sets,
        "options": m["runs"]["nmpc"][0]["options"],
        "anchor_options": m["runs"]["anchor"][0]["options"],
        **m,
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}, casadi {casadi.__version__}",
    }
    med = m["median_over_repeats"]
    lines = [
        f"# {out['benchmark']}",
        f"# options: {json.dumps(out['options'])}",
        f"# machine: {out['machine']}",
        "",
        "| run | seed | solves | act mean | act p99 | slowest act | real-time factor | slowest step / period "
        "| solve median | iterations (median) | backstepping per call | fraction in target |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r, q in zip(m["runs"]["nmpc"], m["runs"]["anchor"], strict=True):
        lines += [_row("nmpc", r), _row("anchor", q)]
    o, p = med["nmpc"], med["anchor"]
    lines += [
        "",
        f"median over {a.repeats} repeats: NMPC {o['act_mean'] * 1e3:.2f} ms per control step (real-time factor "
        f"{o['real_time_factor']:.2f}, slowest step {o['act_max'] * 1e3:.0f} ms = {o['slowest_step_factor']:.1f} x "
        f"the period); anchor {p['act_mean'] * 1e3:.2f} ms (factor {p['real_time_factor']:.2f}, slowest "
        f"{p['act_max'] * 1e3:.0f} ms); ratio anchor / NMPC {p['act_mean'] / o['act_mean']:.1f}",
        f"goal: {m['goal']}: {m['verdict']} (factor {o['real_time_factor']:.2f})",
    ]
    report = "\n".join(lines)
    print(report)
    write_files(out, a.json, report, a.out)


if __name__ == "__main__":
    main()
