"""A congested closed-loop step against the same step without congestion, at N = 200 and N = 10⁶, for the
forward-cell door model (the default), for the headway and for the count.

Run:  python benchmarks/bench_congestion.py [--quick] [--json FILE]

Congestion (docs page *Congestion*) adds one thing to an agents' step: each human's local
density, the others within 0.5 m over the disk's area in Ω (a cell list,
:class:`meanfield.crowds.local_density.LocalDensity`), and its speed: with the default door model, the
forward cell, the diagram's speed at the density of the Voronoi cell ahead of it, and the contact cone (docs page
*Congestion*, "The forward-cell door model").  Our figure: steps per second with ``crowd.congestion =
"linear"``; anchor: the same scenario, seed and crowd with ``"none"``, timed in turns in the same run.  Goal
(issue 30): a congested step costs at most 1.3 uncongested ones (ratio ``>= 1/1.3``), at both sizes.  The headway
(``crowd.door_model = "headway"``, the spacing to the person ahead in each lane) and the count
(``crowd.door_model = "count"``, ``g`` of the local density) are timed beside it against the same anchor.

* **N = 200**: the built-in ``bottleneck`` (10 m × 8 m room, a 1 m door, the informed crowd at
  2.4 persons/m²), its first ``window`` steps after an untimed first one (2 s of 0.05 s steps:
  nobody has reached the door yet, so both crowds are whole), over ``seeds`` seeds.
* **N = 10⁶**: ``paper-unity`` (the paper's law in metres and seconds) on a square room of
  707 m, so that the million humans stand at 2 persons/m², as in a dense crowd; 64 robots, a
  128² grid (the ``stadium``'s), the navigation field sampled on a lattice.  ``steps`` steps
  after an untimed first one, best of ``repeats``.

Each measurement runs the two settings alternately, so that a change of the machine's load
falls on both.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import emit, machine_line  # noqa: E402

GOAL_COST_RATIO = 1.3  # a congested step costs at most this many uncongested ones
LARGE_CROWD = 1_000_000
LARGE_DENSITY = 2.0  # persons/m² of the large crowd's room


SETTINGS = {
    "none": {"crowd.congestion": "none"},
    "forward-cell": {"crowd.congestion": "linear"},
    "headway": {"crowd.congestion": "linear", "crowd.door_model": "headway"},
    "count": {"crowd.congestion": "linear", "crowd.door_model": "count"},
}
"""The timed settings: the anchor (no congestion), the default door model, the forward cell (its Voronoi cell
ahead, docs page *Congestion*, "The forward-cell door model"), the headway ("The headway door model") and the
count."""


def small_scenario(model: str, seed: int) -> Any:
    """The built-in bottleneck (N = 200) with the setting ``model`` of :data:`SETTINGS`."""
    from meanfield.scenarios.scenario import builtin_scenarios

    return builtin_scenarios()["bottleneck"](seed=seed).with_values(SETTINGS[model])


def large_scenario(model: str, seed: int = 0) -> Any:
    """``paper-unity`` with 10⁶ humans at :data:`LARGE_DENSITY` in a square room, 64 robots, 128² cells."""
    from meanfield import Domain
    from meanfield.scenarios.scenario import builtin_scenarios

    sc = builtin_scenarios()["paper-unity"](seed=seed)
    side = math.sqrt(LARGE_CROWD / LARGE_DENSITY)
    sc = sc.replace(domain=Domain.box(side, side), target=replace(sc.target, center=(side / 2, side / 2), std=side / 4))
    values = {**SETTINGS[model], "crowd.n": LARGE_CROWD, "robots.n": 64, "grid.cells": [128, 128]}
    return sc.with_values({**values, "record_humans": 10_000})


def timed(scenario: Any, steps: int) -> float:
    """Seconds for ``steps`` steps of the scenario's loop after an untimed first one (no recording)."""
    from meanfield import ClosedLoop

    loop = ClosedLoop(scenario)
    loop.step()  # compiled loops warm, work arrays allocated
    t0 = time.perf_counter()
    for _ in range(steps):
        loop.step()
    return time.perf_counter() - t0


def measure(size: str, steps: int, seeds: int, repeats: int) -> dict[str, float]:
    """Best-of-``repeats`` steps/s with each of :data:`SETTINGS`, in turns.

    Parameters
    ----------
    size : {"small", "large"}
        N = 200 (the bottleneck) or N = 10⁶ (the large room).
    steps, seeds, repeats : int
        Steps timed per seed, seeds per repeat, repeats.
    """
    build = small_scenario if size == "small" else large_scenario
    best = dict.fromkeys(SETTINGS, 0.0)
    for _ in range(repeats):
        spent = dict.fromkeys(SETTINGS, 0.0)
        for seed in range(seeds):
            for model in SETTINGS:
                spent[model] += timed(build(model, seed), steps)
        for model in best:
            best[model] = max(best[model], steps * seeds / spent[model])
    return best


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``congestion`` records of ``meanfield bench``: congested steps/s against uncongested, N = 200 and 10⁶.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        Six records (the forward cell, the headway and the count, at each size); the goal of each is a ratio of at least
        ``1 / GOAL_COST_RATIO``.
    """
    s = settings("congestion", quick)
    records = []
    for size, n, what, (steps, seeds, repeats) in (
        ("small", 200, "bottleneck (10x8 m room, 1 m door, 200 informed humans)", s["small"]),
        ("large", LARGE_CROWD, "paper-unity on a 707 m room (1e6 humans at 2/m^2, 64 robots, 128^2)", s["large"]),
    ):
        m = measure(size, steps, seeds, repeats)
        size_name = f"N = {n:.0e}" if n > 1000 else f"N = {n}"
        goal = f"a congested step <= {GOAL_COST_RATIO:g} uncongested ones (ratio >= {1 / GOAL_COST_RATIO:.3f})"
        note = f"{steps} steps after an untimed first one, {seeds} seed(s), best of {repeats}, settings in turns"
        for model, name, ours in (
            ("forward-cell", f"congested step, {size_name}",
             "crowd.congestion = 'linear' (the default door model, the forward cell: the Voronoi cell ahead)"),
            ("headway", f"congested step, headway door model, {size_name}",
             "crowd.congestion = 'linear', crowd.door_model = 'headway' (the person ahead, the contact cone)"),
            ("count", f"congested step, count door model, {size_name}",
             "crowd.congestion = 'linear', crowd.door_model = 'count' (g of the local density within 0.5 m)"),
        ):  # fmt: skip
            records.append(
                measured(
                    "congestion",
                    name,
                    what,
                    f"ClosedLoop.step() with {ours}, steps/s",
                    "the same loop with crowd.congestion = 'none', steps/s",
                    m[model],
                    m["none"],
                    "steps/s",
                    anchor_unit="steps/s",
                    faster="higher",
                    goal=goal,
                    passed=m[model] * GOAL_COST_RATIO >= m["none"],
                    note=note,
                    detail={"steps": steps, "seeds": seeds, "repeats": repeats},
                )
            )
    return records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the quick settings of meanfield bench --quick")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    s = settings("congestion", a.quick)
    out: dict[str, Any] = {"benchmark": "congested closed-loop step against the uncongested one"}
    out["machine"] = machine_line()
    for size in ("small", "large"):
        m = measure(size, *s[size])
        ratios = {f"ratio_{k}_over_none": m[k] / m["none"] for k in SETTINGS if k != "none"}
        out[size] = {**m, **ratios, "goal": f">= {1 / GOAL_COST_RATIO:.3f}"}
    emit(out, a.json)


if __name__ == "__main__":
    main()
