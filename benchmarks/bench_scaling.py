"""Scaling curves: closed-loop steps per second and peak memory against the crowd and the grid.

Run:  python benchmarks/bench_scaling.py [--quick] [--json FILE] [--figure FILE.png]

Two sweeps of the ``stadium`` scenario (the paper's loop with 64 robots; the KDE bandwidth
kept at 3.84 cells of the grid, as ``stadium``'s 0.03 is on 128²), each point in a fresh
child process on one core so that its peak memory (``VmHWM``) is its own:

* the crowd: N = 10², 10³, …, 10⁷ humans on the 128² grid;
* the grid: 30², 64², 128², 256², 512² cells with N = 10⁴ humans.

Each point times ``ClosedLoop.step`` after one warm-up step (so numba's cache load and the
first sight of each array size are not counted), in three blocks of at least half a
second (and two steps) each, and keeps the best block's time per step (the machine is
shared: the best block is the least disturbed).  The fitted exponent ``p`` of ``time per step ∝ size^p`` is a least
squares fit on log–log axes over the upper half of each sweep, where the size-dependent
work dominates the fixed cost of a step (an O(N) loop gives p ≈ 1).  The figure has both
curves, log–log, with the fits; ``docs/scale.md`` shows it.

Quick mode stops the crowd at 10⁶ and the grid at 256².
"""

from __future__ import annotations

from benchmarks.environment import one_thread_variables

one_thread_variables()  # one core

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks.reporting import emit, machine_line, peak_resident_mb  # noqa: E402

CROWDS = (100, 1_000, 10_000, 100_000, 1_000_000, 10_000_000)
GRIDS = (30, 64, 128, 256, 512)
CROWD_GRID = 128
GRID_CROWD = 10_000
CELLS_PER_BANDWIDTH = 3.84  # stadium: 0.03 on the unit square's 128 cells


def child(n: int, cells: int) -> dict[str, Any]:
    """One point (run in a fresh process by :func:`point`): steps per second and peak memory."""
    from meanfield import ClosedLoop
    from meanfield.scenarios.scenario import stadium_scenario

    sc = stadium_scenario(seed=0).with_values(
        {"crowd.n": n, "grid.cells": [cells, cells], "density.bandwidth": CELLS_PER_BANDWIDTH / cells}
    )
    t0 = time.perf_counter()
    loop = ClosedLoop(sc.replace(t_final=10.0, record_every=1000))  # stepped by hand below
    build = time.perf_counter() - t0
    loop.step()  # warm-up: numba's cache, the work arrays
    blocks, total = [], 0  # three blocks of at least 0.5 s (and 2 steps) each: the best is the least disturbed
    for _ in range(3):
        steps, t0 = 0, time.perf_counter()
        while steps < 2 or time.perf_counter() - t0 < 0.5:
            loop.step()
            steps += 1
        blocks.append((time.perf_counter() - t0) / steps)
        total += steps
    best = min(blocks)
    return {
        "humans": n,
        "cells": cells * cells,
        "steps": total,
        "seconds_per_step": best,
        "steps_per_second": 1.0 / best,
        "block_seconds_per_step": blocks,
        "field_evaluation": loop.crowd.field_evaluation,
        "build_seconds": build,
        "peak_mb": peak_resident_mb(),
    }


def point(n: int, cells: int) -> dict[str, Any]:
    out = subprocess.run(
        [sys.executable, __file__, "--child", str(n), str(cells)], check=True, capture_output=True, text=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def exponent(sizes: list[float], seconds: list[float]) -> float:
    """Least-squares slope of ``log seconds`` against ``log size`` over the upper half of the points."""
    k = len(sizes) // 2
    x, y = np.log(sizes[k:]), np.log(seconds[k:])
    return float(np.polyfit(x, y, 1)[0])


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    crowds = [n for n in CROWDS if not quick or n <= 1_000_000]
    grids = [g for g in GRIDS if not quick or g <= 256]
    out: dict[str, Any] = {"benchmark": "scaling curves, stadium scenario, one core", "machine": machine_line()}
    for name, sweep in (("crowd", [(n, CROWD_GRID) for n in crowds]), ("grid", [(GRID_CROWD, g) for g in grids])):
        points = []
        for n, g in sweep:
            if progress:
                print(f"scaling: N = {n:.0e}, grid {g}^2 ...", file=sys.stderr, flush=True)
            points.append(point(n, g))
        size = [p["humans"] if name == "crowd" else p["cells"] for p in points]
        out[name] = {"points": points, "exponent": exponent(size, [p["seconds_per_step"] for p in points])}
    return out


def figure(out: dict[str, Any], path: str) -> None:
    """Two log–log panels: seconds per step and peak memory against N and against the grid's cells."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for ax, name, key, label in (
        (axes[0], "crowd", "humans", f"humans N (grid {CROWD_GRID}², 64 robots)"),
        (axes[1], "grid", "cells", f"grid cells G (N = {GRID_CROWD:.0e}, 64 robots)"),
    ):
        pts = out[name]["points"]
        x = np.array([p[key] for p in pts], float)
        t = np.array([p["seconds_per_step"] for p in pts])
        mem = np.array([p["peak_mb"] for p in pts])
        ax.loglog(x, t * 1e3, "o-", color="C0", label=f"time per step (fitted exponent {out[name]['exponent']:.2f})")
        ax.set_xlabel(label)
        ax.set_ylabel("milliseconds per closed-loop step", color="C0")
        ax.grid(True, which="both", alpha=0.3)
        twin = ax.twinx()
        twin.loglog(x, mem, "s--", color="C1", label="peak memory")
        twin.set_ylabel("peak resident memory (MB)", color="C1")
        lines = ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
        ax.legend(lines, [h.get_label() for h in lines], loc="upper left", fontsize=8)
    fig.suptitle("Closed-loop step against crowd size and grid size (one core)")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``scaling`` records of ``meanfield bench``: the fitted exponents, one record per sweep.

    The anchor of each is the linear law fitted through the sweep's smallest point (time ∝
    size): the ratio > 1 says the largest point costs less than linear extrapolation.
    """
    from benchmarks.records import measured

    out = run(quick, progress=False)
    records = []
    for name, key in (("crowd", "humans"), ("grid", "cells")):
        pts = out[name]["points"]
        first, last = pts[0], pts[-1]
        linear = first["seconds_per_step"] * last[key] / first[key]
        records.append(
            measured(
                "scaling",
                f"scaling against the {name} (largest point)",
                f"closed-loop step, stadium scenario, {name} sweep up to {last[key]:.0e}",
                "ClosedLoop.step, seconds per step at the largest point",
                "linear extrapolation from the smallest point",
                last["seconds_per_step"],
                linear,
                "s per step",
                faster="lower",
                note=f"fitted exponent {out[name]['exponent']:.2f}; peak {last['peak_mb']:.0f} MB",
                detail=out[name],
            )
        )
    return records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", default=None)
    ap.add_argument("--figure", default=None, help="write the log-log figure here (PNG)")
    ap.add_argument("--child", nargs=2, type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(*a.child)))
        return
    out = run(a.quick)
    if a.figure:
        figure(out, a.figure)
    emit(out, a.json)


if __name__ == "__main__":
    main()
