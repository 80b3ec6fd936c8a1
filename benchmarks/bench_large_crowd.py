"""A million-person crowd in closed loop on one and two threads, against the frozen plain step in the same run.

Run:  python benchmarks/bench_large_crowd.py [--quick] [--steps 100] [--json FILE]

The built-in ``stadium`` scenario: the paper's closed loop with N = 10⁶ humans, n = 64
robots, a 128² grid (``meanfield run stadium``).

* **Ours**: ``ClosedLoop(stadium).run()`` for ``--steps`` steps, on two of numba's threads
  (``NUMBA_NUM_THREADS=2``; BLAS on one) and again on one, *all included*: KDE
  (binning + convolution), the controller on the grid, ``v_r`` sampled on a lattice and
  interpolated to every human, the Euler–Maruyama step, the robots, recording a frame every
  10 steps (10 000 humans' positions, the density), then building the dataset and the
  summary (W₂ included).  Figures: steps per second and µs per human per step over the
  whole call, the loop's own rate (``summary["steps_per_second"]``: every step and the
  recording, without the one-off dataset and summary), and the peak resident memory of
  the process, which does nothing else (``VmHWM``).  Each thread count runs 3 times (2 with
  ``--quick``), in turns, and the best run of each counts (a run on two threads needs both
  cores free, and this machine is shared).  Every run's final positions must be the same bit
  for bit (issue 32: a seed gives the same results on any number of threads).
* **Anchor** (issue 32): the frozen plain-numpy step of :mod:`benchmarks.plain_stadium`,
  written straight from the paper's equations (binned KDE, Steps I and II, ``v_r`` summed
  exactly at each human, O(N n), Euler–Maruyama, walls), one warm step then a few timed
  ones, in its own process.  It uses no code of the toolkit, so it holds still when the
  toolkit gets faster.
* **Old anchor** (issues 7 and 19, kept in the record's ``detail`` for continuity): the
  toolkit's own loop with ``crowd.field_evaluation = "exact"`` on the numpy path
  (``MEANFIELD_COMPILED=0``), a few ``ClosedLoop.step`` calls, in its own process.  It
  became 4–6× faster as the toolkit did, which is why it was replaced.
* **Ten million**: ``stadium`` with N = 10⁷, a few steps of ``ClosedLoop.run()`` all
  included, for its peak memory.

Goals: issue 32, on two threads ≥ 1.8× the loop's own rate on one thread and ≥ 15× the frozen
plain step per human-step, everything included except the one-off summary (the loop's own rate),
the same positions on both; issue 19, ≤ 2 GB peak at N = 10⁷; issue 7,
≥ 4 steps per second all included and ≤ 1.5 GB peak at N = 10⁶.  Each measurement runs
in a fresh child process so that its peak memory is its own.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # BLAS on one core

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks.reporting import emit, machine_line, peak_resident_mb  # noqa: E402

GOAL_STEPS_PER_SECOND = 4.0
GOAL_PEAK_MB = 1536.0
GOAL_RATIO = 15.0  # frozen plain step's µs per human-step / ours without the one-off summary (issue 32)
GOAL_PEAK_MB_1E7 = 2048.0  # peak at N = 10⁷ (issue 19)
GOAL_SCALING = 1.8  # the loop's own rate on two threads / on one (issue 32)
THREADS = 2  # the threads of "ours" (numba's; the one-thread run beside it)
REPEATS, REPEATS_QUICK = 3, 2  # runs of each thread count, in turns (the best of each is kept)
TEN_MILLION = 10_000_000


def child(mode: str, steps: int) -> dict:
    """One measurement (run in a fresh process by :func:`measure`)."""
    if mode == "anchor":  # the frozen plain step: meanfield only read for the scenario's numbers
        from benchmarks.plain_stadium import PlainStadiumStep, stadium_numbers

        plain = PlainStadiumStep(seed=0, **stadium_numbers())
        plain.step()  # warm (first touch of the arrays)
        t0 = time.perf_counter()
        plain.run(steps)
        wall = time.perf_counter() - t0
        n = len(plain.X)
        return {
            "steps": steps,
            "steps_per_second": steps / wall,
            "us_per_human_step": wall / steps / n * 1e6,
            "humans": n,
            "peak_mb": peak_resident_mb(),
        }
    from meanfield import ClosedLoop
    from meanfield.scenarios.scenario import stadium_scenario

    sc = stadium_scenario(seed=0)
    if mode == "ten_million":
        sc = sc.with_values({"crowd.n": TEN_MILLION})
        mode = "ours"
    n = sc.crowd.n
    if mode == "ours":
        sc = sc.replace(t_final=steps * sc.dt)
        t0 = time.perf_counter()
        loop = ClosedLoop(sc)
        t1 = time.perf_counter()
        result = loop.run(progress=False)
        wall = time.perf_counter() - t1
        s = result.summary
        assert s["status"] == "completed" and s["steps"] == steps, s["status"]
        import hashlib

        import numba
        import numpy as np

        final = np.ascontiguousarray(loop.crowd.positions)
        return {
            "threads": numba.get_num_threads(),
            "positions_sha1": hashlib.sha1(final).hexdigest(),  # (the buffer itself: no copy)
            "steps": steps,
            "build_seconds": t1 - t0,
            "run_seconds": wall,
            "steps_per_second": steps / wall,
            "us_per_human_step": wall / steps / n * 1e6,
            "loop_steps_per_second": s["steps_per_second"],
            "field_evaluation": s["field_evaluation"],
            "field_error_bound_final": s["field_error_bound_final"],
            "frames_recorded": int(result.timeseries.sizes["time"]),  # (result.dataset would import xarray)
            "humans_recorded": int(result.timeseries.sizes["human"]),
            "humans": n,
            "peak_mb": peak_resident_mb(),
        }
    sc = sc.with_values({"crowd.field_evaluation": "exact"})
    loop = ClosedLoop(sc)
    loop.step()  # warm
    t0 = time.perf_counter()
    for _ in range(steps):
        loop.step()
    wall = time.perf_counter() - t0
    return {
        "steps": steps,
        "steps_per_second": steps / wall,
        "us_per_human_step": wall / steps / n * 1e6,
        "peak_mb": peak_resident_mb(),
    }


def measure(mode: str, steps: int, threads: int = 1) -> dict:
    """One child process on ``threads`` of numba's threads; the old anchor's runs with
    ``MEANFIELD_COMPILED=0`` (the numpy path)."""
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    if mode == "old_anchor":
        env["MEANFIELD_COMPILED"] = "0"
    out = subprocess.run(
        [sys.executable, __file__, "--child", mode, "--steps", str(steps)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def run(quick: bool = False, steps: int = 100) -> dict:
    """The measurements; returns the JSON-ready record."""
    ours_steps = 20 if quick else steps
    anchor_steps = 3 if quick else 5
    old_anchor_steps = 2 if quick else 5
    threads = min(THREADS, len(os.sched_getaffinity(0)))
    # the two thread counts in turns, the best run of each: a run on two threads needs both cores
    # free, and on this shared machine another process often takes one for a while
    twos, ones = [], []
    for _ in range(REPEATS_QUICK if quick else REPEATS):
        twos.append(measure("ours", ours_steps, threads))
        ones.append(measure("ours", ours_steps, 1))
    ours = max(twos, key=lambda r: r["loop_steps_per_second"])
    one = max(ones, key=lambda r: r["loop_steps_per_second"])
    anchor = measure("anchor", anchor_steps)
    old = measure("old_anchor", old_anchor_steps)
    ten = measure("ten_million", 3 if quick else 5, threads)
    # ours without the one-off dataset and summary: every step and the recording (issue 32's figure)
    ours_loop_us = 1e6 / (ours["loop_steps_per_second"] * ours["humans"])
    ratio = anchor["us_per_human_step"] / ours_loop_us
    ratio_all = anchor["us_per_human_step"] / ours["us_per_human_step"]
    scaling = ours["loop_steps_per_second"] / one["loop_steps_per_second"]
    same = len({r["positions_sha1"] for r in twos + ones}) == 1  # every run, on either count
    ok = (
        ours["steps_per_second"] >= GOAL_STEPS_PER_SECOND
        and ours["peak_mb"] <= GOAL_PEAK_MB
        and ratio >= GOAL_RATIO
        and scaling >= GOAL_SCALING
        and same
        and threads == THREADS
    )
    ok_ten = ten["peak_mb"] <= GOAL_PEAK_MB_1E7
    return {
        "benchmark": (
            f"closed loop, stadium scenario (N=1e6 humans, n=64 robots, 128x128 grid), {threads} threads and 1"
        ),
        "machine": machine_line(),
        "command": "python benchmarks/bench_large_crowd.py" + (" --quick" if quick else f" --steps {steps}"),
        "results": [
            {
                "name": "closed_loop_1e6_humans",
                "what": "ClosedLoop(stadium).run(): every step, recording, dataset and summary",
                "ours": "v_r sampled on a lattice + binned KDE",
                "ours_steps_per_second": ours["steps_per_second"],
                "ours_us_per_human_step": ours["us_per_human_step"],
                "ours_loop_us_per_human_step": ours_loop_us,
                "anchor": "the frozen plain-numpy stadium step (benchmarks/plain_stadium.py: v_r summed exactly)",
                "anchor_steps_per_second": anchor["steps_per_second"],
                "anchor_us_per_human_step": anchor["us_per_human_step"],
                # issue 32's ratio: ours without the one-off dataset and summary (the loop's own rate)
                "ratio_anchor_over_ours": ratio,
                "ratio_anchor_over_ours_all_included": ratio_all,
                "threads": threads,
                "scaling_over_one_thread": scaling,
                "same_positions_on_one_thread": same,
                "goal": (
                    f"on {THREADS} threads: >= {GOAL_SCALING:g}x one thread and the same positions, "
                    f">= {GOAL_RATIO:g}x the frozen plain step (all included but the one-off summary), "
                    f">= {GOAL_STEPS_PER_SECOND:g} steps/s all included, peak <= {GOAL_PEAK_MB:g} MB"
                ),
                "pass": ok,
                "ours_detail": ours,
                "one_thread_detail": one,
                "loop_steps_per_second_every_run": {
                    str(threads): [r["loop_steps_per_second"] for r in twos],
                    "1": [r["loop_steps_per_second"] for r in ones],
                },
                "anchor_detail": anchor,
                # the anchor until issue 32: the toolkit's numpy path with exact v_r (it moved with the toolkit)
                "old_anchor": "the same loop with v_r summed exactly at each human, numpy path (ClosedLoop.step)",
                "old_anchor_us_per_human_step": old["us_per_human_step"],
                "ratio_old_anchor_over_ours_all_included": old["us_per_human_step"] / ours["us_per_human_step"],
                "old_anchor_detail": old,
            },
            {
                "name": "closed_loop_1e7_humans",
                "what": "ClosedLoop(stadium with N = 1e7).run(), all included",
                "steps_per_second": ten["steps_per_second"],
                "us_per_human_step": ten["us_per_human_step"],
                "peak_mb": ten["peak_mb"],
                "goal": f"peak <= {GOAL_PEAK_MB_1E7:g} MB",
                "pass": ok_ten,
                "detail": ten,
            },
        ],
        "verdict": "PASS" if ok and ok_ten else "FAIL",
    }


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``large_crowd`` record of ``meanfield bench`` (``docs/cli.md``): ours against the plain step at N = 10⁶.

    This script runs in a process of its own (``--quick``, or ``--steps``): its measurements
    run in child processes, and Linux counts the parent's resident memory at the fork in a
    child's peak (``ru_maxrss``), so they need a small parent -- not the suite's process,
    which holds what the earlier benchmarks loaded.  For the same reason this module imports
    :mod:`benchmarks.records` (and with it ``meanfield``) here, not at its top.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        One record, from the JSON that the script writes.
    """
    import tempfile
    from pathlib import Path

    from benchmarks.records import measured, settings

    s = settings("large_crowd", quick)
    script = __file__
    with tempfile.TemporaryDirectory(prefix="meanfield-bench-") as tmp:
        path = Path(tmp) / "large_crowd.json"
        args = ["--quick"] if quick else ["--steps", str(s["ours_steps"])]
        proc = subprocess.run(
            [sys.executable, script, *args, "--json", str(path)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        if proc.returncode != 0:
            raise RuntimeError(f"bench_large_crowd.py exited with {proc.returncode}: {proc.stderr.strip()[-800:]}")
        out = json.loads(path.read_text())
    r = out["results"][0]
    od = r["ours_detail"]
    return [
        measured(
            "large_crowd",
            "large_crowd N=1e6 vs frozen plain step",
            "closed loop, stadium scenario (N=1e6 humans, n=64 robots, 128x128 grid), two threads and one, "
            "each side in its own process",
            f"{r['ours']}: ClosedLoop.run() on {r['threads']} threads, every step and the recording "
            "(the one-off dataset and summary apart)",
            r["anchor"],
            r["ours_loop_us_per_human_step"],
            r["anchor_us_per_human_step"],
            "µs per human-step",
            faster="lower",
            goal=r["goal"],
            passed=r["pass"],
            note=(
                f"{r['scaling_over_one_thread']:.2f}x one thread "
                f"({'the same' if r['same_positions_on_one_thread'] else 'DIFFERENT'} positions); "
                f"{r['ours_steps_per_second']:.2f} steps/s all included over {od['steps']} steps "
                f"({r['ratio_anchor_over_ours_all_included']:.1f}x the plain step; loop alone "
                f"{od['loop_steps_per_second']:.2f} steps/s), peak {od['peak_mb']:.0f} MB; old anchor "
                f"(numpy path, exact v_r) {r['old_anchor_us_per_human_step']:.3f} µs per human-step: "
                f"{r['ratio_old_anchor_over_ours_all_included']:.1f}x all included"
            ),
            detail=r,
        ),
        measured(
            "large_crowd",
            "large_crowd N=1e7 peak memory",
            "closed loop, stadium scenario with N=1e7 humans, in its own process",
            "ClosedLoop.run() all included: peak resident memory",
            "the goal's 2 GB",
            out["results"][1]["peak_mb"],
            GOAL_PEAK_MB_1E7,
            "MB",
            faster="lower",
            goal=out["results"][1]["goal"],
            passed=out["results"][1]["pass"],
            note=f"{out['results'][1]['steps_per_second']:.3f} steps/s all included",
            detail=out["results"][1],
        ),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--json", default=None)
    modes = ("ours", "anchor", "old_anchor", "ten_million")
    ap.add_argument("--child", choices=modes, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(a.child, a.steps)))
        return
    out = run(a.quick, a.steps)
    emit(out, a.json)


if __name__ == "__main__":
    main()
