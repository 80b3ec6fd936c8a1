"""A closed-loop step on a floor plan against a step on a box of the same grid and crowd.

Run:  python benchmarks/bench_plan.py [--window 30] [--seeds 10] [--repeats 3] [--json FILE]

Our figure: steps per second of the built-in ``office`` scenario (a 30 m × 14 m floor of
eight rooms and a corridor, 60×28 cells, 120 humans, 8 robots, the coverage controller):
walls that reflect along each step, signs hidden behind walls, two exits.  Anchor: the same
scenario on the 30 m × 14 m box with the same exits (no inner walls, nothing hidden), so
the ratio is the price of the plan alone.  Goal: a step on the plan costs at most 1.5× a
step on the box (ratio >= 1/1.5).

*Same crowd*: on the open box the evacuation controller gets people out fast (a quarter
of them in 10 s, all of them in 30 s), and a step with fewer humans is cheaper, so long
runs would compare a full office with an emptying box.  Each seed's two loops are
therefore timed over their first ``--window`` steps after an untimed first step (3 s of
0.1 s steps, during which both still hold nearly all of their crowd: the fractions still
inside at the window's end are reported), over ``--seeds`` seeds, the office and the box
in turns; the rates are the steps over the time summed across seeds, best of ``--repeats``.
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
from meanfield.scenarios.scenario import builtin_scenarios  # noqa: E402

GOAL_COST_RATIO = 1.5  # a step on the plan costs at most this many steps on the box


def scenarios(steps: int, seed: int) -> tuple[Any, Any]:
    """The office and the box of the same size, grid, crowd, robots and exits."""
    office = builtin_scenarios()["office"](seed=seed)
    office = office.replace(t_final=steps * office.dt)
    x0, x1, y0, y1 = office.domain.bounds
    box = Domain.box(x1 - x0, y1 - y0, origin=(x0, y0), exits=office.domain.exits)
    return office, office.replace(domain=box)


def timed_window(scenario: Any, window: int) -> tuple[float, float]:
    """Seconds for ``window`` steps of the scenario's loop after an untimed first step, and the
    fraction of the crowd still inside at the end (stepped directly: no recording)."""
    loop = ClosedLoop(scenario)
    loop.step()  # the first step builds what is built once (sight rows of the robots' cells)
    t0 = time.perf_counter()
    for _ in range(window):
        loop.step()
    return time.perf_counter() - t0, loop.crowd.remaining() / loop.crowd.n


def measure(window: int, seeds: int, repeats: int) -> dict[str, float]:
    """Best-of-``repeats`` steps/s on the office and on the box over ``seeds`` windows each, in turns.

    Returns the two rates and the mean fractions of the crowds still inside at the windows' ends.
    """
    best = {"office": 0.0, "box": 0.0}
    inside = {"office": [], "box": []}
    for _ in range(repeats):
        spent = {"office": 0.0, "box": 0.0}
        for seed in range(seeds):
            office, box = scenarios(window + 1, seed)
            for name, sc in (("office", office), ("box", box)):
                seconds, left = timed_window(sc, window)
                spent[name] += seconds
                inside[name].append(left)
        for name in best:
            best[name] = max(best[name], window * seeds / spent[name])
    return {
        "office": best["office"],
        "box": best["box"],
        "office_inside": float(sum(inside["office"]) / len(inside["office"])),
        "box_inside": float(sum(inside["box"]) / len(inside["box"])),
    }


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
    m = measure(s["window"], s["seeds"], s["repeats"])
    ours, anchor = m["office"], m["box"]
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
            note=(
                f"the ratio is the price of the plan: walls, sight lines; timed over each seed's first "
                f"{s['window']} steps, when {m['office_inside']:.0%} (office) and {m['box_inside']:.0%} (box) "
                "of the crowds are still inside"
            ),
            detail={**s, "office_inside": m["office_inside"], "box_inside": m["box_inside"]},
        )
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--window", type=int, default=30, help="steps timed per seed (after an untimed first one)")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    m = measure(a.window, a.seeds, a.repeats)
    out = {
        "benchmark": "closed-loop step, office plan against a box of the same grid and crowd",
        "ours_steps_per_second": m["office"],
        "anchor": "the same scenario on a 30x14 m box with the same exits",
        "anchor_steps_per_second": m["box"],
        "ratio_ours_over_anchor": m["office"] / m["box"],
        "fraction_inside_at_window_end": {"office": m["office_inside"], "box": m["box_inside"]},
        "goal": f"ratio >= {1 / GOAL_COST_RATIO:.3f}",
        "machine": machine_line(),
    }
    emit(out, a.json)


if __name__ == "__main__":
    main()
