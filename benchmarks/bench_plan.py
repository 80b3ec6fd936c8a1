"""A closed-loop step on a floor plan against a step on a box of the same grid and crowd; each shipped plan's step.

Run:  python benchmarks/bench_plan.py [--window 30] [--seeds 10] [--repeats 3] [--json FILE]

Our figure: steps per second of the built-in ``office`` scenario (a 30 m × 14 m floor of
eight rooms and a corridor, 60×28 cells, 120 humans, 8 robots, its default controller, the guide):
walls that reflect along each step, signs hidden behind walls, the walls' shadows in the crowd's
forward cells, a walking tree for each cell a robot enters whose centroid a wall hides, two exits.
Anchor: the same scenario on the 30 m × 14 m box with the same exits (no inner walls, nothing
hidden: its robots drive straight at their centroids), so the ratio is the price of the plan alone
(until 2026-12-07 the box's guide planted walking trees too, by a bug, and the ratio read about 0.68
instead of 0.48: docs page *Buildings*, "Each shipped plan's step").  Goal: a step on the plan costs at most 1.5× a
step on the box (ratio >= 1/1.5).

*Same crowd*: on the open box the evacuation controller gets people out fast (a quarter
of them in 10 s, all of them in 30 s), and a step with fewer humans is cheaper, so long
runs would compare a full office with an emptying box.  Each seed's two loops are
therefore timed over their first ``--window`` steps after an untimed first step (3 s of
0.1 s steps, during which both still hold nearly all of their crowd: the fractions still
inside at the window's end are reported), over ``--seeds`` seeds, the office and the box
in turns; the rates are the steps over the time summed across seeds, best of ``--repeats``.

**Each shipped plan's step** (:func:`plan_steps`, issue "Speed where it slipped", item 4): milliseconds per step of
each built-in scenario drawn on a plan with exits, as shipped (its crowd, robots and controller), on one core (the
crowd's loops on one thread), over ``window`` steps after :data:`WARM_STEPS` untimed ones, seeds in turns with the
anchor: the same plan with the informed crowd and static signs (the crowd's own step: people on their routes,
robots standing), so that the ratio is what the robots and their controller add.  Goal: at most
:data:`GOAL_PLAN_STEP_MS` a step.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import emit, machine_line  # noqa: E402
from meanfield import ClosedLoop, Domain  # noqa: E402
from meanfield.scenarios.scenario import builtin_scenarios  # noqa: E402

GOAL_COST_RATIO = 1.5  # a step on the plan costs at most this many steps on the box
GOAL_PLAN_STEP_MS = 0.5  # a shipped plan's step at its default crowd, one core
WARM_STEPS = 20  # untimed steps before a plan's window: routes planned, sight rows and compiled loops ready
PLANS = ("l-room", "office", "hall", "hall-crowded-west", "bottleneck", "rimea-9", "rimea-10", "rimea-12")
"""The built-in scenarios drawn on a plan with exits."""
ANCHOR = {"crowd.guidance": "geodesic", "controller.kind": "static-signs"}
"""The anchor of a plan's step: the informed crowd on its routes, the robots standing with their signs."""


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


def plan_steps(window: int, seeds: int, repeats: int, plans: tuple[str, ...] = PLANS) -> dict[str, dict[str, float]]:
    """Each plan's milliseconds per step as shipped and with :data:`ANCHOR`, on one core (best of ``repeats``).

    Parameters
    ----------
    window : int
        Steps timed per seed, after :data:`WARM_STEPS` untimed ones.
    seeds, repeats : int
        Seeds per repeat (the plan and its anchor in turns), repeats.
    plans : tuple of str
        Built-in scenario names (:data:`PLANS`).

    Returns
    -------
    dict
        Per plan: ``ours`` and ``anchor`` (ms/step), the crowd's size ``n`` and the share still inside at the
        windows' ends ``inside``.
    """
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    out = {}
    try:
        for name in plans:
            best = {"ours": math.inf, "anchor": math.inf}
            inside = []
            for _ in range(repeats):
                spent = {"ours": 0.0, "anchor": 0.0}
                for seed in range(seeds):
                    shipped = builtin_scenarios()[name](seed=seed)
                    for key, sc in (("ours", shipped), ("anchor", shipped.with_values(ANCHOR))):
                        sc = sc.replace(t_final=(WARM_STEPS + window + 1) * sc.dt)
                        loop = ClosedLoop(sc)
                        for _ in range(WARM_STEPS):
                            loop.step()
                        t0 = time.perf_counter()
                        for _ in range(window):
                            loop.step()
                        spent[key] += time.perf_counter() - t0
                        if key == "ours":
                            inside.append(loop.crowd.remaining() / loop.crowd.n)
                for key in best:
                    best[key] = min(best[key], 1e3 * spent[key] / (window * seeds))
            out[name] = {**best, "n": builtin_scenarios()[name]().crowd.n, "inside": sum(inside) / len(inside)}
    finally:
        numba.set_num_threads(threads)
    return out


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``plan`` records of ``meanfield bench``: office steps/s against the same loop on a box, and each shipped
    plan's step (:func:`plan_steps`).

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        The office against the box (goal: a ratio of at least ``1 / GOAL_COST_RATIO``), then one record per plan of
        :data:`PLANS` (goal: at most :data:`GOAL_PLAN_STEP_MS` a step).
    """
    s = settings("plan", quick)
    m = measure(s["window"], s["seeds"], s["repeats"])
    ours, anchor = m["office"], m["box"]
    steps = plan_steps(s["window"], s["plan_seeds"], s["repeats"])
    per_plan = [
        measured(
            "plan",
            f"plan step, {name}",
            f"{name} as shipped (N = {r['n']}, its robots and controller), one core",
            "ClosedLoop.step() of the scenario as shipped, ms/step",
            "the same plan, informed crowd (crowd.guidance = 'geodesic'), static signs, ms/step",
            r["ours"],
            r["anchor"],
            "ms/step",
            anchor_unit="ms/step",
            faster="lower",
            goal=f"a step <= {GOAL_PLAN_STEP_MS:g} ms",
            passed=r["ours"] <= GOAL_PLAN_STEP_MS,
            note=(
                f"{s['window']} steps after {WARM_STEPS} untimed ones, {s['plan_seeds']} seed(s), best of "
                f"{s['repeats']}; {r['inside']:.0%} of the crowd still inside at the window's end"
            ),
            detail={"window": s["window"], "seeds": s["plan_seeds"], "repeats": s["repeats"], "n": r["n"]},
        )  # fmt: skip
        for name, r in steps.items()
    ]
    return [
        measured(
            "plan",
            "closed_loop office vs box",
            "office plan (30x14 m, 60x28 cells, N=120, n=8, the guide) against the same loop on a box",
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
        ),
        *per_plan,
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--window", type=int, default=30, help="steps timed per seed (after an untimed first one)")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--plans", nargs="*", default=list(PLANS), help="the plans whose step is timed (none: skip)")
    ap.add_argument("--plan-seeds", type=int, default=3, help="seeds per plan's step")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    m = measure(a.window, a.seeds, a.repeats)
    steps = plan_steps(a.window, a.plan_seeds, a.repeats, tuple(a.plans)) if a.plans else {}
    out = {
        "benchmark": "closed-loop step, office plan against a box of the same grid and crowd",
        "ours_steps_per_second": m["office"],
        "anchor": "the same scenario on a 30x14 m box with the same exits",
        "anchor_steps_per_second": m["box"],
        "ratio_ours_over_anchor": m["office"] / m["box"],
        "fraction_inside_at_window_end": {"office": m["office_inside"], "box": m["box_inside"]},
        "goal": f"ratio >= {1 / GOAL_COST_RATIO:.3f}",
        "plan_steps_ms": steps,
        "plan_step_goal_ms": GOAL_PLAN_STEP_MS,
        "machine": machine_line(),
    }
    emit(out, a.json)


if __name__ == "__main__":
    main()
