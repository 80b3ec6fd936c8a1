"""JuPedSim alone in the bottleneck room: which model and parameters pass it? (issue 42, item 7)

The built-in ``bottleneck`` room (10 m × 8 m, a corridor 2 m long and ``b`` wide), 200 bodies at 1.34 m/s placed in
the room by JuPedSim's ``distribute_by_number`` (0.45 m apart, 0.25 m from the walls), each on JuPedSim's own journey
to an exit stage at the corridor's end (the last 0.6 m of it).  A *setting* is a model and its parameters,
``MODEL[:NAME=VALUE,...]``: ``radius`` is the bodies' radius (0.2 m unless given), ``dt`` JuPedSim's step (0.01 s
unless given), every other name a field of the model's class (``CollisionFreeSpeedModel(strength_neighbor_repulsion=
...)``) or of its agent parameters (``time_gap``, ...), whichever has it; the rest stay at JuPedSim's defaults.
:data:`PRESETS` are the settings of the study, by name.  Each run prints how many are out after ``--horizon`` seconds
and the specific flow ``J/b`` between the 20th and the 180th to leave, and is a line of ``--results`` (JSON);
``--report`` prints the table (per setting and width: the seeds' out counts, how many seeds got everyone out, ``J/b``
median and range over those).  ``--toolkit`` runs the same setting through the toolkit instead: the built-in
``bottleneck`` with ``crowd.kind = "jupedsim"``, the setting as ``crowd.options.jupedsim.*`` (``dt`` as its
``time_step``), the bodies steered by the crowd's guidance (the scenario's informed route, or ``--guidance``).
``--explain T`` shows, for the collision-free speed model, why the bodies at the mouth stand after ``T`` seconds.
Run from the repository's root (needs JuPedSim)::

    python studies/jupedsim_bottleneck_alone.py --models cfsm cfsm3 avm --widths 0.8 2.0 --seeds 0 1 2
    python studies/jupedsim_bottleneck_alone.py --settings "cfsm:radius=0.15,strength_neighbor_repulsion=5"
    python studies/jupedsim_bottleneck_alone.py --presets validation --widths 0.8 1.0 2.0 \\
        --seeds 0 1 2 3 4 5 6 7 8 9 --results studies/results/jupedsim_bottleneck_alone.jsonl      # ~2 min
    python studies/jupedsim_bottleneck_alone.py --toolkit --presets validation --seeds 0 1 2 3 4 5 6 7 8 9 \\
        --results studies/results/jupedsim_bottleneck_alone.jsonl                                   # ~3 min
    python studies/jupedsim_bottleneck_alone.py --explain 150 --seeds 1                         # why it clogs
    python studies/jupedsim_bottleneck_alone.py --report --results studies/results/jupedsim_bottleneck_alone.jsonl

**Why the defaults clog** (collision-free speed model, CFSM; JuPedSim 1.4.2's ``CollisionFreeSpeedModel.cpp``): a
body walks at ``min(v0, s/T)`` where ``s`` is the gap to the nearest neighbour ahead (``e·d ≥ 0``) in a lane ``2r``
wide about its direction (``r1 + r2``: 0.4 m at r = 0.2 m), and its direction is its desired one plus the neighbours'
repulsion (8 exp((2r − d)/0.1)) plus the walls' (5 exp((r − d)/0.02), summed over every wall segment, so that a
corner counts once for each of its two segments).  In a queue the gaps close to 0 (``s/T`` halts a body only at
contact).  The neighbours press a body at the corridor's mouth into a corner, nearer than its radius, where the
corner's repulsion turns it back towards the crowd, whose first body, touching it, is then in its lane: its speed is
0; and that body has the cornered one in its own lane, touching: its speed is 0 too.  Nothing moves again (the model
has no noise).  ``--explain 150 --seeds 1`` (0.8 m, JuPedSim's defaults, 24 of 200 out, the last at 49.5 s): body 49
at (9.823, 4.327), 0.192 m from the corner (10, 4.4), walls' push (−14.06, −5.81) (7.03 from each of the corner's two
segments), neighbours' push (10.65, 2.85), desired direction (0.99, −0.17): direction (−0.61, −0.79) (JuPedSim
reports (−0.59, −0.81)), body 94 touching in its lane; body 94 at (9.557, 4.028), direction (0.91, −0.41), bodies 104
and 49 touching in its lane: both have not moved in the last second.  At ``rimea-9``'s doors (the toolkit, two exits,
seed 0, 320 s, 337 still in) it is an arch of three: the bodies at (4.136, 0.157) and (4.852, 0.136), each 0.20 m from
a door post and turned by it towards the body at (4.499, 0.325) behind the middle of the door, which touches both.

What frees the bodies (the table below): bodies of 0.15 m, the size of JuPedSim's own validation, which fit two abreast
into 0.8 m with room to spare (``r`` alone clears 9 seeds of 10; the neighbour repulsion alone, 5, and a longer range
of the walls' repulsion, 0.05 m, clear none and one of 5), and the validation's step of 0.05 s, which with 0.15 m
bodies clears every seed, alone and through the toolkit (with 0.2 m bodies it clears none).  With steps of 0.01 s the
remaining arches are of three bodies at the mouth (seed 6: 0.167 m from the corner, the body's lane swept back over a
touching neighbour by the corner's push), which no repulsion we tried removed (neighbour repulsion 3: 2 of 10 seeds
clogged; walls' range 0.05 m: 2 of 10).  The other models: CFSM V3 clogs at 0.8 m with either radius (0.15 m: 3 of 5
seeds), the anticipation velocity model too (0.15 m: 5 of 5), and passes 1.25–1.43 persons/(m·s) where it gets
through; JuPedSim's social force model at its defaults, bodies of 0.2 m, pushes a body through a wall (JuPedSim
stops: "outside of accessible area"); the warp driver model lets its bodies overlap (J/b ≈ 9).

JuPedSim's own validation of the bottleneck (jpscore's ``systemtest/Validation/test_13/master_ini.xml``, the test
that compares with Liddle et al.'s flows): the collision-free speed model ("Tordeux2015") with ``force_ped a=5
D=0.1``, ``force_wall a=5 D=0.02``, ``bmax = bmin = amin = 0.15`` ("this is l, assuming peds are circles with
constant radius": in that code ``l = 2 bmax``, a body of radius 0.15 m), ``T = 1`` s, ``v0 = 1.34`` m/s, a step of
0.05 s, 200 agents: the preset ``validation``, the toolkit's choice (``bottleneck`` and ``rimea-9`` set it whole; a
scenario without the table gets its body and step, and JuPedSim's neighbour repulsion, 8, which measured the same).

Measured 2026-12-04/05 (``--report``; 10 seeds): ``validation`` clears 0.8, 1.0 and 2.0 m on every seed, J/b 1.54
(1.44–1.58), 1.84 (1.82–1.92), 1.70 (1.66–1.75) persons/(m·s), J = 1.23, 1.84, 3.40 persons/s; with steps of 0.01 s
the same bodies pass more (1.77, 1.95, 1.81) but clog 1 seed of 10 at 0.8 m; JuPedSim's defaults clog 4 of 5 at
0.8 m and 1 of 5 at 1.0 m and pass 1.11–1.33.  Through the toolkit (the informed route, ``validation``): every seed
clears 0.8 m, J/b 1.45 (1.41–1.50); 1.0 m 1.68, 2.0 m 1.67 (5 seeds).
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import time
from pathlib import Path

import numpy as np

MODELS = {
    "cfsm": ("CollisionFreeSpeedModel", "CollisionFreeSpeedModelAgentParameters"),
    "cfsm2": ("CollisionFreeSpeedModelV2", "CollisionFreeSpeedModelV2AgentParameters"),
    "cfsm3": ("CollisionFreeSpeedModelV3", "CollisionFreeSpeedModelV3AgentParameters"),
    "avm": ("AnticipationVelocityModel", "AnticipationVelocityModelAgentParameters"),
    "sfm": ("SocialForceModel", "SocialForceModelAgentParameters"),
    "wdm": ("WarpDriverModel", "WarpDriverModelAgentParameters"),
}

PRESETS = {
    # JuPedSim's defaults, bodies of 0.2 m (the toolkit's default size)
    "cfsm": "cfsm",
    "cfsm3": "cfsm3",
    "avm": "avm",
    # one change at a time, each from JuPedSim's bottleneck validation (test_13) or the cause above
    "cfsm-r15": "cfsm:radius=0.15",
    "cfsm-a5": "cfsm:strength_neighbor_repulsion=5",
    "cfsm-wall": "cfsm:range_geometry_repulsion=0.05",
    # JuPedSim's validation of the bottleneck: a_ped = 5, D_ped = 0.1, a_wall = 5, D_wall = 0.02, r = 0.15, T = 1,
    # and its step, 0.05 s ("validation-dt001": the same on the study's step of 0.01 s)
    "validation": "cfsm:radius=0.15,strength_neighbor_repulsion=5,dt=0.05",
    "validation-dt001": "cfsm:radius=0.15,strength_neighbor_repulsion=5",
    "cfsm-r15-dt005": "cfsm:radius=0.15,dt=0.05",
    "cfsm-dt005": "cfsm:dt=0.05",
    # the same bodies in the other models
    "cfsm3-r15": "cfsm3:radius=0.15",
    "avm-r15": "avm:radius=0.15",
}

RESULTS = Path("studies/results/jupedsim_bottleneck_alone.jsonl")

TOOLKIT_MODELS = {"cfsm": "collision-free-speed", "cfsm2": "collision-free-speed-v2",
                  "cfsm3": "collision-free-speed-v3", "avm": "anticipation-velocity", "sfm": "social-force",
                  "wdm": "warp-driver"}  # fmt: skip
"""The study's model keys as ``crowd.options.jupedsim.model`` names them."""


def parse_setting(spec: str) -> tuple[str, dict[str, float]]:
    """``MODEL[:NAME=VALUE,...]`` (or a preset's name) as the model's key and its parameters."""
    spec = PRESETS.get(spec, spec)
    model, _, rest = spec.partition(":")
    if model not in MODELS:
        raise SystemExit(f"unknown model {model!r} in {spec!r}: one of {', '.join(MODELS)}")
    params = {}
    for item in filter(None, rest.split(",")):
        name, eq, value = item.partition("=")
        if not eq:
            raise SystemExit(f"{item!r} in {spec!r}: expected NAME=VALUE")
        params[name.strip()] = float(value)
    return model, params


def split_parameters(model: str, params: dict[str, float]) -> tuple[dict, dict, float, float]:
    """The model's keyword arguments, the agents', the radius (0.2 m unless given) and JuPedSim's step ``dt``
    (0.01 s unless given); unknown names are refused."""
    import jupedsim as jps

    model_class, agent_class = (getattr(jps, name) for name in MODELS[model])
    model_fields = {f.name for f in dataclasses.fields(model_class)} - {"rng_seed"}
    agent_fields = set(inspect.signature(agent_class).parameters) - {"position", "journey_id", "stage_id", "v0"}
    on_model, on_agent, radius, dt = {}, {}, 0.2, 0.01
    for name, value in params.items():
        if name == "radius":
            radius = value
        elif name == "dt":
            dt = value
        elif name in model_fields:
            on_model[name] = value
        elif name in agent_fields and name not in ("desired_speed",):
            on_agent[name] = value
        else:
            known = sorted(model_fields | agent_fields - {"desired_speed"} | {"dt"})
            raise SystemExit(f"{name!r} is no parameter of {model_class.__name__}: one of {', '.join(known)}")
    return on_model, on_agent, radius, dt


def one_run(model: str, b: float, seed: int, horizon: float = 300.0, n: int = 200, params: dict | None = None) -> dict:
    """How many of ``n`` bodies leave the bottleneck of width ``b`` within ``horizon`` seconds, and their flow."""
    import jupedsim as jps
    import shapely

    on_model, on_agent, radius, dt = split_parameters(model, params or {})
    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    area = shapely.Polygon([(0, 0), (10, 0), (10, lo), (12, lo), (12, hi), (10, hi), (10, 8), (0, 8)])
    model_class, parameters = (getattr(jps, name) for name in MODELS[model])
    if model == "avm":
        on_model = {"rng_seed": seed, **on_model}  # its class default is drawn once per import
    sim = jps.Simulation(model=model_class(**on_model), geometry=area, dt=dt)
    exit_id = sim.add_exit_stage(shapely.box(11.4, lo, 12.0, hi))  # (a body's centre stays 0.2 m off the end wall)
    journey = sim.add_journey(jps.JourneyDescription([exit_id]))
    room = shapely.box(0.3, 0.3, 9.7, 7.7)
    for p in jps.distribute_by_number(
        polygon=room, number_of_agents=n, distance_to_agents=0.45, distance_to_polygon=0.25, seed=seed
    ):
        sim.add_agent(
            parameters(journey_id=journey, stage_id=exit_id, position=p, radius=radius, desired_speed=1.34, **on_agent)
        )
    start, times = time.perf_counter(), []
    while sim.agent_count() > 0 and sim.elapsed_time() < horizon:
        before = sim.agent_count()
        sim.iterate()
        times += [sim.elapsed_time()] * (before - sim.agent_count())
    t = np.sort(times)
    flow = (180 - 20) / (t[179] - t[19]) if len(t) >= 180 else None
    return {
        "model": model, "params": params or {}, "width": b, "seed": seed, "n": n, "out": n - sim.agent_count(),
        "specific_flow": None if flow is None else flow / b, "time": sim.elapsed_time(), "horizon": horizon,
        "wall_seconds": time.perf_counter() - start, "jupedsim": str(jps.__version__),
    }  # fmt: skip


def toolkit_run(
    model: str, b: float, seed: int, horizon: float = 300.0, params: dict | None = None, guidance: str | None = None
) -> dict:
    """The same through the toolkit: the built-in ``bottleneck`` with a corridor ``b`` wide, ``crowd.kind =
    "jupedsim"`` (its exits, its steering by the crowd's ``guidance``: the scenario's, the informed route, unless
    given) and the setting as ``crowd.options.jupedsim.*``, for ``horizon`` seconds."""
    from meanfield.scenarios.scenario import builtin_scenarios
    from meanfield.simulation.loop import ClosedLoop

    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    values = {
        "domain.wkt": f"POLYGON ((0 0, 10 0, 10 {lo:g}, 12 {lo:g}, 12 {hi:g}, 10 {hi:g}, 10 8, 0 8, 0 0))",
        "domain.exits": [[[12.0, lo], [12.0, hi]]],
        "crowd.kind": "jupedsim",
        "t_final": horizon,
        "crowd.options.jupedsim.model": TOOLKIT_MODELS[model],
        **{f"crowd.options.jupedsim.{'time_step' if k == 'dt' else k}": v for k, v in (params or {}).items()},
    }
    if guidance is not None:
        values["crowd.guidance"] = guidance
    sc = builtin_scenarios()["bottleneck"](seed=seed).with_values(values)
    start = time.perf_counter()
    loop = ClosedLoop(sc)
    loop.run(progress=False)
    t = np.sort(np.asarray(loop.crowd.engine.exit_time, float))
    t = t[np.isfinite(t)]
    n = sc.crowd.n
    flow = (180 - 20) / (t[179] - t[19]) if len(t) >= 180 else None
    return {
        "model": model, "params": params or {}, "width": b, "seed": seed, "n": n, "out": len(t),
        "specific_flow": None if flow is None else flow / b, "time": float(loop.t), "horizon": horizon,
        "wall_seconds": time.perf_counter() - start, "path": "toolkit", "guidance": sc.crowd.guidance,
    }  # fmt: skip


def explain(b: float, seed: int, at: float, params: dict | None = None) -> None:
    """Why the bodies at the corridor's mouth stand (CFSM): run ``at`` seconds, then, for the body nearest the mouth
    and the nearest one in its lane, recompute the direction the model gives (JuPedSim 1.4.2's
    ``CollisionFreeSpeedModel.cpp``: desired direction + neighbours' + walls' repulsion) and its speed (the gap to
    the nearest body ahead in its lane of width ``2r``, over the time gap), beside what JuPedSim reports."""
    import jupedsim as jps
    import shapely

    on_model, on_agent, r, dt = split_parameters("cfsm", params or {})
    model = jps.CollisionFreeSpeedModel(**on_model)
    time_gap = on_agent.get("time_gap", 1.0)
    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    corners = [(0, 0), (10, 0), (10, lo), (12, lo), (12, hi), (10, hi), (10, 8), (0, 8)]
    sim = jps.Simulation(model=model, geometry=shapely.Polygon(corners), dt=dt)
    exit_id = sim.add_exit_stage(shapely.box(11.4, lo, 12.0, hi))
    journey = sim.add_journey(jps.JourneyDescription([exit_id]))
    for p in jps.distribute_by_number(
        polygon=shapely.box(0.3, 0.3, 9.7, 7.7), number_of_agents=200, distance_to_agents=0.45,
        distance_to_polygon=0.25, seed=seed,
    ):  # fmt: skip
        sim.add_agent(jps.CollisionFreeSpeedModelAgentParameters(
            journey_id=journey, stage_id=exit_id, position=p, radius=r, desired_speed=1.34, **on_agent))  # fmt: skip
    while sim.elapsed_time() < at and sim.agent_count() > 0:
        sim.iterate()
    before = {a.id: np.array(a.position) for a in sim.agents()}
    for _ in range(round(1.0 / dt)):
        sim.iterate()
    agents = {a.id: a for a in sim.agents()}
    walls = [
        (np.array(corners[i], float), np.array(corners[(i + 1) % len(corners)], float)) for i in range(len(corners))
    ]

    def hidden(p: np.ndarray, q: np.ndarray) -> bool:  # a wall between two bodies: they ignore each other
        line = shapely.LineString([p, q])
        return any(line.intersects(shapely.LineString([a, c])) for a, c in walls)

    def why(i: int) -> int | None:
        a = agents[i]
        p = np.array(a.position)
        e0 = np.array(a.target) - p
        e0 /= np.linalg.norm(e0)
        wall, near = np.zeros(2), []
        for w0, w1 in walls:  # every segment counts, so a corner counts for both of its segments
            q = w0 + np.clip(np.dot(p - w0, w1 - w0) / np.dot(w1 - w0, w1 - w0), 0, 1) * (w1 - w0)
            d = np.linalg.norm(q - p)
            push = -model.strength_geometry_repulsion * np.exp((r - d) / model.range_geometry_repulsion) * (q - p) / d
            wall += push
            if np.linalg.norm(push) > 0.01:
                near.append(f"{d:.3f} m from {w0.tolist()}–{w1.tolist()}")
        others = [(k, np.array(o.position) - p) for k, o in agents.items() if k != i]
        others = [(k, v) for k, v in others if np.linalg.norm(v) <= 3.0 and not hidden(p, p + v)]
        a_n, d_n = model.strength_neighbor_repulsion, model.range_neighbor_repulsion
        push = sum((-a_n * np.exp((2 * r - np.linalg.norm(v)) / d_n) * v / np.linalg.norm(v) for _, v in others),
                   np.zeros(2))  # fmt: skip
        e = e0 + push + wall
        e /= np.linalg.norm(e)
        left = np.array([-e[1], e[0]])
        ahead = sorted((np.linalg.norm(v) - 2 * r, k) for k, v in others if e @ v >= 0 and abs(left @ v) <= 2 * r)
        gap = ahead[0][0] if ahead else np.inf
        lane = ", ".join(f"{k} (gap {g:.3f} m)" for g, k in ahead[:2]) or "none"
        speed = min(1.34, max(gap, 0) / time_gap)
        print(f"body {i} at {np.round(p, 3).tolist()}, moved {np.linalg.norm(p - before[i]):.4f} m in the last "
              f"second; desired direction {np.round(e0, 2).tolist()}, walls' push {np.round(wall, 2).tolist()} "
              f"({'; '.join(near) or 'none'}), neighbours' push {np.round(push, 2).tolist()}: direction "
              f"{np.round(e, 3).tolist()} (JuPedSim's {np.round(a.orientation, 3).tolist()}); nearest in its lane "
              f"ahead: {lane}; speed {speed:.3f} m/s")  # fmt: skip
        return ahead[0][1] if ahead else None

    print(f"b = {b:g} m, seed {seed}: {200 - len(agents)} of 200 out at {sim.elapsed_time():.0f} s")
    first = min(agents, key=lambda k: np.hypot(*(np.array(agents[k].position) - (10.0, 4.0))))
    blocker = why(first)
    if blocker is not None:
        why(blocker)


def label(model: str, params: dict) -> str:
    """A setting's name in the table: the model and its parameters that differ from JuPedSim's defaults."""
    return model + "".join(f" {k}={v:g}" for k, v in sorted(params.items()))


def report(path: Path) -> None:
    """The table of ``path``'s runs: per setting and width, the out counts, how many seeds cleared, J/b."""
    rows: dict[tuple[str, float], list[dict]] = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        path = "" if r.get("path", "alone") == "alone" else f"toolkit ({r['guidance']}): "
        rows.setdefault((path + label(r["model"], r["params"]), r["width"]), []).append(r)
    print("| setting | b (m) | seeds | out of 200 in 300 s | all out | J/b median (min–max) |")
    print("|---|---|---|---|---|---|")
    for (name, b), runs in sorted(rows.items()):
        runs = sorted({r["seed"]: r for r in runs}.values(), key=lambda r: r["seed"])  # the last run of each seed
        flows = [r["specific_flow"] for r in runs if r["specific_flow"] is not None and r["out"] == r["n"]]
        cleared = sum(r["out"] == r["n"] for r in runs)
        flow = f"{np.median(flows):.2f} ({min(flows):.2f}–{max(flows):.2f})" if flows else "–"
        k = [r["seed"] for r in runs]
        seeds = f"{k[0]}–{k[-1]}" if k == list(range(k[0], k[-1] + 1)) and len(k) > 1 else ", ".join(map(str, k))
        outs = ", ".join(str(r["out"]) for r in runs)
        print(f"| {name} | {b:g} | {seeds} | {outs} | {cleared} of {len(runs)} | {flow} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=[], choices=list(MODELS), help="models at their defaults")
    parser.add_argument("--presets", nargs="+", default=[], choices=list(PRESETS), help="the study's settings")
    parser.add_argument("--settings", nargs="+", default=[], help="MODEL[:NAME=VALUE,...] (radius or a parameter)")
    parser.add_argument("--widths", nargs="+", type=float, default=[0.8])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--horizon", type=float, default=300.0, help="seconds of simulated time (default 300)")
    parser.add_argument(
        "--results", type=Path, default=None, help=f"append each run to this JSON lines file ({RESULTS})"
    )
    parser.add_argument("--report", action="store_true", help="print the table of --results and stop")
    parser.add_argument(
        "--toolkit", action="store_true", help="run the toolkit's bottleneck with crowd.kind = jupedsim"
    )
    parser.add_argument("--guidance", default=None, help="with --toolkit: crowd.guidance (default the scenario's)")
    parser.add_argument("--explain", type=float, default=None, metavar="T",
                        help="CFSM: after T s, why the body at the mouth and the one it blocks stand "
                        "(the first width and seed)")  # fmt: skip
    args = parser.parse_args()
    if args.report:
        report(args.results or RESULTS)
        return
    settings = [parse_setting(s) for s in [*args.models, *args.presets, *args.settings]] or [parse_setting("cfsm")]
    if args.explain is not None:
        explain(args.widths[0], args.seeds[0], args.explain, settings[0][1])
        return
    for model, params in settings:
        split_parameters(model, params)  # refuse a wrong name before the first run
    for model, params in settings:
        for b in args.widths:
            for seed in args.seeds:
                if args.toolkit:
                    r = toolkit_run(model, b, seed, args.horizon, params, args.guidance)
                else:
                    r = one_run(model, b, seed, args.horizon, params=params)
                flow = "—" if r["specific_flow"] is None else f"{r['specific_flow']:.2f}"
                print(f"{'toolkit: ' if args.toolkit else ''}{label(model, params)}, b={b:g} m seed {seed}: "
                      f"{r['out']:3d} of 200 out in {r['time']:.0f} s, "
                      f"J/b {flow} persons/(m·s) ({r['wall_seconds']:.0f} s wall)", flush=True)  # fmt: skip
                if args.results is not None:
                    with args.results.open("a") as f:
                        f.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main()
