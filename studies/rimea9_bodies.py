"""RiMEA test 9 with JuPedSim's bodies: the evacuation time with four and with two exits, and each door's flow.

The built-in ``rimea-9`` (1000 people, a 30 m × 20 m room, four 1 m doors) with ``crowd.kind = "jupedsim"`` and
the scenario's own bodies (JuPedSim's bottleneck validation: docs page *Congestion*, "JuPedSim's bodies"), then
the variant with the two south doors only.  For each seed and variant one JSON line: the time the last body is
out (``t100``, s), the share out, each door's flow over the central 90 % of its passages (persons/s) and the
deepest overlap of two bodies (m).  Run from the repository's root (needs JuPedSim; about 2 minutes a run)::

    python studies/rimea9_bodies.py 0 1

Measured 2026-12-05 (docs page *Buildings*, "RiMEA tests"): seed 0, four exits 84.6 s, two 164.1 s; seed 1,
86.6 s and 161.4 s; every door 3.05–3.21 persons/s.
"""

from __future__ import annotations

import json
import sys

import numpy as np

SOUTH = [[[4.0, 0.0], [5.0, 0.0]], [[25.0, 0.0], [26.0, 0.0]]]
"""The closed variant's exits: the two on the south wall (``rimea-9.toml``)."""


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


def main() -> None:
    from meanfield.scenarios.scenario import builtin_scenarios
    from meanfield.simulation.loop import ClosedLoop

    for seed in map(int, sys.argv[1:] or ["0"]):
        for name, values in (("four", {}), ("two", {"domain.exits": SOUTH})):
            sc = builtin_scenarios()["rimea-9"](seed=seed).with_values({"crowd.kind": "jupedsim", **values})
            loop = ClosedLoop(sc)
            s = loop.run(progress=False).summary
            engine = loop.crowd.engine
            row = {
                "seed": seed,
                "exits": name,
                "t100": s.get("evacuation_time_100"),
                "out": s.get("fraction_evacuated"),
                "door_flows": door_flows(np.asarray(engine.exit_time, float), np.asarray(engine.exit_index),
                                         len(sc.domain.exits)),  # fmt: skip
                "overlap": s.get("body_overlap_max"),
            }
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
