"""JuPedSim alone in the bottleneck room: does a model clog without the toolkit's steering? (issue 42, item 7)

The built-in ``bottleneck`` room (10 m × 8 m, a corridor 2 m long and ``b`` wide), 200 bodies of radius 0.2 m at
1.34 m/s placed in the room by JuPedSim's ``distribute_by_number`` (0.45 m apart, 0.25 m from the walls), each on
JuPedSim's own journey to an exit stage at the corridor's end (the last 0.6 m of it), JuPedSim's step 0.01 s and every
other parameter at the model's default.  It prints how many are out after ``--horizon`` seconds and the specific flow
``J/b`` between the 20th and the 180th to leave.  Run from the repository's root (needs JuPedSim)::

    python studies/jupedsim_bottleneck_alone.py --models cfsm cfsm3 avm --widths 0.8 2.0 --seeds 0 1 2

Measured 2026-12-04 (b = 0.8 m unless said): CFSM seed 0 all 200 out (J/b 1.11), seeds 1 and 2 only 24 and 44 out
in 300 s; CFSM V3 seed 0 none; the anticipation velocity model seed 0 12; CFSM at 2.0 m seed 0 all out (J/b 1.29).
The toolkit's bodies, steered by the informed route, clog there too (86, 14 and 4 out of 200 for the same three
models, seed 0): the clog is the models' at their defaults in this room, not only the steering's.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

MODELS = {
    "cfsm": ("CollisionFreeSpeedModel", "CollisionFreeSpeedModelAgentParameters"),
    "cfsm3": ("CollisionFreeSpeedModelV3", "CollisionFreeSpeedModelV3AgentParameters"),
    "avm": ("AnticipationVelocityModel", "AnticipationVelocityModelAgentParameters"),
}


def one_run(model: str, b: float, seed: int, horizon: float = 300.0, n: int = 200) -> dict:
    """How many of ``n`` bodies leave the bottleneck of width ``b`` within ``horizon`` seconds, and their flow."""
    import jupedsim as jps
    import shapely

    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    area = shapely.Polygon([(0, 0), (10, 0), (10, lo), (12, lo), (12, hi), (10, hi), (10, 8), (0, 8)])
    model_class, parameters = (getattr(jps, name) for name in MODELS[model])
    sim = jps.Simulation(model=model_class(), geometry=area, dt=0.01)
    exit_id = sim.add_exit_stage(shapely.box(11.4, lo, 12.0, hi))  # (a body's centre stays 0.2 m off the end wall)
    journey = sim.add_journey(jps.JourneyDescription([exit_id]))
    room = shapely.box(0.3, 0.3, 9.7, 7.7)
    for p in jps.distribute_by_number(
        polygon=room, number_of_agents=n, distance_to_agents=0.45, distance_to_polygon=0.25, seed=seed
    ):
        sim.add_agent(parameters(journey_id=journey, stage_id=exit_id, position=p, radius=0.2, desired_speed=1.34))
    start, times = time.perf_counter(), []
    while sim.agent_count() > 0 and sim.elapsed_time() < horizon:
        before = sim.agent_count()
        sim.iterate()
        times += [sim.elapsed_time()] * (before - sim.agent_count())
    t = np.sort(times)
    flow = (180 - 20) / (t[179] - t[19]) if len(t) >= 180 else None
    return {
        "model": model, "width": b, "seed": seed, "out": n - sim.agent_count(),
        "specific_flow": None if flow is None else flow / b, "time": sim.elapsed_time(),
        "wall_seconds": time.perf_counter() - start,
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--widths", nargs="+", type=float, default=[0.8])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--horizon", type=float, default=300.0, help="seconds of simulated time (default 300)")
    args = parser.parse_args()
    for model in args.models:
        for b in args.widths:
            for seed in args.seeds:
                r = one_run(model, b, seed, args.horizon)
                flow = "—" if r["specific_flow"] is None else f"{r['specific_flow']:.2f}"
                print(f"{model:6s} b={b:g} m seed {seed}: {r['out']:3d} of 200 out in {r['time']:.0f} s, J/b {flow} "
                      f"persons/(m·s) ({r['wall_seconds']:.0f} s wall)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
