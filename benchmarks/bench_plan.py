"""A closed-loop step on a floor plan against a step on a box of the same grid and crowd.

Run:  python benchmarks/bench_plan.py [--steps 300] [--repeats 3] [--json FILE]

Our figure: steps per second of the built-in ``office`` scenario (a 30 m × 14 m floor of
eight rooms and a corridor, 60×28 cells, 120 humans, 8 robots, the coverage controller):
walls that reflect along each step, signs hidden behind walls, two exits.  Anchor: the same
scenario on the 30 m × 14 m box with the same exits (no inner walls, nothing hidden), so
the ratio is the price of the plan alone.  Goal: a step on the plan costs at most 1.5× a
step on the box (ratio >= 1/1.5).  The runs are short enough that few people leave.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import emit, machine_line  # noqa: E402
from meanfield import ClosedLoop, Domain  # noqa: E402
from meanfield.scenario import builtin_scenarios  # noqa: E402

GOAL_COST_RATIO = 1.5  # a step on the plan costs at most this many steps on the box


def scenarios(steps: int, seed: int) -> tuple[Any, Any]:
    """The office and the box of the same size, grid, crowd, robots and exits."""
    office = builtin_scenarios()["office"](seed=seed)
    office = office.replace(t_final=steps * office.dt)
    x0, x1, y0, y1 = office.domain.bounds
    box = Domain.box(x1 - x0, y1 - y0, origin=(x0, y0), exits=office.domain.exits)
    return office, office.replace(domain=box)


def rate(scenario: Any, steps: int) -> float:
    """Steps per second of the scenario's closed loop (stepped directly: no recording)."""
    loop = ClosedLoop(scenario)
    loop.step()  # the first step builds what is built once (sight rows of the robots' cells)
    t0 = time.perf_counter()
    for _ in range(steps):
        loop.step()
    return steps / (time.perf_counter() - t0)


def measure(steps: int, repeats: int) -> tuple[float, float]:
    """Best-of-``repeats`` steps/s on the office and on the box, interleaved (same machine load)."""
    ours = anchor = 0.0
    for r in range(repeats):
        office, box = scenarios(steps + 1, r)
        ours = max(ours, rate(office, steps))
        anchor = max(anchor, rate(box, steps))
    return ours, anchor


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``plan`` record of ``meanfield bench``: office steps/s against the same loop on a box.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        One record; the goal is a ratio of at least ``1 / GOAL_COST_RATIO``.
    """
    s = settings("plan", quick)
    ours, anchor = measure(s["steps"], s["repeats"])
    return [
        measured(
            "plan",
            "closed_loop office vs box",
            "office plan (30x14 m, 60x28 cells, N=120, n=8, coverage controller) against the same loop on a box",
            "ClosedLoop(office).step(): walls, sight lines, exits, steps/s",
            "ClosedLoop(office on a 30x14 m box, same exits).step(), steps/s",
            ours,
            anchor,
            "steps/s",
            anchor_unit="steps/s",
            faster="higher",
            goal=f"a plan step <= {GOAL_COST_RATIO:g} box steps (ratio >= {1 / GOAL_COST_RATIO:.3f})",
            passed=ours * GOAL_COST_RATIO >= anchor,
            note="the ratio is the price of the plan: walls, sight lines",
            detail={"steps": s["steps"], "repeats": s["repeats"]},
        )
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    ours, anchor = measure(a.steps, a.repeats)
    out = {
        "benchmark": "closed-loop step, office plan against a box of the same grid and crowd",
        "ours_steps_per_second": ours,
        "anchor": "the same scenario on a 30x14 m box with the same exits",
        "anchor_steps_per_second": anchor,
        "ratio_ours_over_anchor": ours / anchor,
        "goal": f"ratio >= {1 / GOAL_COST_RATIO:.3f}",
        "machine": machine_line(),
    }
    emit(out, a.json)


if __name__ == "__main__":
    main()
