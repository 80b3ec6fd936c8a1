"""RiMEA tests 9 and 12 measured: evacuation times, each door's flow, and where the crowd jams.

Run from the repository's root (JuPedSim needs the ``pedestrians`` extra)::

    python studies/rimea.py 9 0 1 2 3 4                    # point masses, seeds 0-4 (about 15 s a run)
    python studies/rimea.py 9 --backend jupedsim 0 1       # JuPedSim's bodies
    python studies/rimea.py 12 0 1 2 3 4                   # test 12, seconds a run

**Test 9** (``rimea-9``: 1000 people, a 30 m × 20 m room, four 1 m doors), then the variant with the two south
doors only (:data:`SOUTH`).  For each seed and variant one line of ``studies/results/rimea9.jsonl``: the time
the last person is out (``t100``, s), the share out, each door's flow over the central 90 % of its passages
(persons/s, :func:`door_flows`), the deepest overlap of two bodies (m, bodies only), the flow bound and the door
model.

**Test 12** (``rimea-12``: 150 people leave a 10 m room through a 5 m × 1 m corridor into a second room and out
by its 1 m exit).  For each seed one line of ``studies/results/rimea12.jsonl``: ``t100``, the exit's flow over
the central 90 % of its passages, the peak 1 s mean density in the box in front of the corridor (after the
first 10 s) and in the box in front of the exit (persons/m², :data:`BEFORE`, :data:`AFTER`; the first is the box
of ``tests/scenarios/test_rimea.py``), the most people in room 2 at once, and JuPedSim's two flows of its system
test 12 (:func:`line_flow`, at the corridor's end and 1 m before the exit) with its verdict, no jam at the exit
when the second is at least the first less 0.05 persons/s.

The crowds are the scenarios' own: the point masses by the linear diagram and their default door model (the
headway), JuPedSim's bodies (``--backend jupedsim``) as JuPedSim's bottleneck validation sets them (docs page
*Congestion*, "JuPedSim's bodies").  Each line is appended as its run finishes and printed.  The figures are in
the docs page *Buildings*, "RiMEA tests".
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

SOUTH = [[[4.0, 0.0], [5.0, 0.0]], [[25.0, 0.0], [26.0, 0.0]]]
"""Test 9's closed variant's exits: the two on the south wall (``rimea-9.toml``)."""
BEFORE = (8.0, 10.0, 3.5, 6.5)
"""Test 12: the box in front of the corridor's entrance (x0, x1, y0, y1; m; 6 m²)."""
AFTER = (23.0, 25.0, 3.5, 6.5)
"""Test 12: the box in front of the exit (m; 6 m²)."""
ROOM_2 = 15.0
"""Test 12: room 2 starts at this x (m), where the corridor ends."""
BEFORE_EXIT = 24.0
"""Test 12: the line 1 m before the exit (x, m) where JuPedSim's system test reads the last flow."""
FLOW_TOLERANCE = 0.05
"""Test 12: JuPedSim's tolerance (persons/s): no jam at the exit if its flow is at least the corridor's less this."""
RESULTS = {9: Path("studies/results/rimea9.jsonl"), 12: Path("studies/results/rimea12.jsonl")}


def door_flows(exit_time: np.ndarray, exit_index: np.ndarray, doors: int) -> list[float]:
    """Each door's flow, persons/s, between its 5th and 95th percentile passages (NaN with 20 or fewer)."""
    flows = []
    for k in range(doors):
        t = np.sort(exit_time[(exit_index == k) & np.isfinite(exit_time)])
        if len(t) <= 20:
            flows.append(float("nan"))
            continue
        a, b = int(0.05 * len(t)), int(0.95 * len(t)) - 1
        flows.append(round((b - a) / (t[b] - t[a]), 3))
    return flows


def line_flow(crossed: np.ndarray) -> float:
    """JuPedSim's flow at a line (its system tests' ``utils.flow``): ``(N − 1) / (t_last − t_first)`` over each
    person's first step past it (persons/s; ``crossed`` the times, ``inf`` for who never passed)."""
    t = crossed[np.isfinite(crossed)]
    return float((len(t) - 1) / (t.max() - t.min())) if len(t) > 1 else float("nan")


def _in_box(x: np.ndarray, box: tuple[float, float, float, float]) -> int:
    x0, x1, y0, y1 = box
    with np.errstate(invalid="ignore"):  # NaN: people who left
        return int(np.count_nonzero((x[:, 0] >= x0) & (x[:, 0] <= x1) & (x[:, 1] >= y0) & (x[:, 1] <= y1)))


def rimea_9(seed: int, backend: str) -> list[dict[str, Any]]:
    """Test 9 on one seed: the row of the four-exit run and that of the two-exit run."""
    from meanfield.scenarios.scenario import builtin_scenarios
    from meanfield.simulation.loop import ClosedLoop

    rows = []
    for name, values in (("four", {}), ("two", {"domain.exits": SOUTH})):
        sc = builtin_scenarios()["rimea-9"](seed=seed).with_values({"crowd.kind": backend, **values})
        loop = ClosedLoop(sc)
        s = loop.run(progress=False).summary
        engine = loop.crowd.engine
        rows.append(
            {
                "backend": backend,
                "door_model": sc.door_model,
                "seed": seed,
                "exits": name,
                "t100": s.get("evacuation_time_100"),
                "out": s.get("fraction_evacuated"),
                "door_flows": door_flows(np.asarray(engine.exit_time, float), np.asarray(engine.exit_index),
                                         len(sc.domain.exits)),  # fmt: skip
                "overlap": s.get("body_overlap_max"),
                "lower_bound_flow": s.get("lower_bound_flow"),
            }
        )
    return rows


def rimea_12(seed: int, backend: str) -> list[dict[str, Any]]:
    """Test 12 on one seed: its row (the boxes' densities every step, averaged over 1 s as the test does)."""
    from meanfield.scenarios.scenario import builtin_scenarios
    from meanfield.simulation.loop import ClosedLoop

    sc = builtin_scenarios()["rimea-12"](seed=seed).with_values({"crowd.kind": backend})
    before: list[int] = []
    after: list[int] = []
    room_2: list[int] = []
    crossed = {line: np.full(sc.crowd.n, np.inf) for line in (ROOM_2, BEFORE_EXIT)}

    def count(loop: ClosedLoop) -> None:
        x = loop.crowd.positions
        before.append(_in_box(x, BEFORE))
        after.append(_in_box(x, AFTER))
        with np.errstate(invalid="ignore"):
            room_2.append(int(np.count_nonzero(x[:, 0] >= ROOM_2)))
            for line, first in crossed.items():
                first[(x[:, 0] >= line) & np.isinf(first)] = loop.t

    loop = ClosedLoop(sc)
    s = loop.run(progress=False, callback=count).summary
    window = max(1, int(round(1.0 / sc.dt)))
    kernel = np.ones(window) / window
    rho_before = np.convolve(before, kernel, mode="valid") / 6.0
    rho_after = np.convolve(after, kernel, mode="valid") / 6.0
    engine = loop.crowd.engine
    j_corridor, j_exit = line_flow(crossed[ROOM_2]), line_flow(crossed[BEFORE_EXIT])
    return [
        {
            "backend": backend,
            "door_model": sc.door_model,
            "seed": seed,
            "t100": s.get("evacuation_time_100"),
            "exit_flow": door_flows(np.asarray(engine.exit_time, float), np.asarray(engine.exit_index), 1)[0],
            "peak_before_corridor": round(float(rho_before[int(10.0 / sc.dt) :].max()), 3),
            "peak_before_exit": round(float(rho_after.max()), 3),
            "most_in_room_2": max(room_2),
            "flow_corridor_end": round(j_corridor, 4),
            "flow_before_exit": round(j_exit, 4),
            "no_jam_at_exit": bool(j_exit >= j_corridor - FLOW_TOLERANCE),
        }
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("test", type=int, choices=sorted(RESULTS), help="RiMEA's test number")
    ap.add_argument("seeds", nargs="*", type=int, default=[0])
    ap.add_argument("--backend", default="point-mass", help="crowd.kind (point-mass or jupedsim)")
    args = ap.parse_args()
    measure = rimea_9 if args.test == 9 else rimea_12
    path = RESULTS[args.test]
    path.parent.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:
        for row in measure(seed, args.backend):
            print(json.dumps(row), flush=True)
            with path.open("a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
