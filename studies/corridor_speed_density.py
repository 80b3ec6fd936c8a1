"""Speed against density in a corridor: the crowd models beside Weidmann's relation (docs page *Congestion*).

Run from the repository's root::

    python studies/corridor_speed_density.py            # the point masses' models (10 seeds), jupedsim (3 seeds)
    python studies/corridor_speed_density.py --models linear --radii 0.4 0.8 [--seeds 10] [--densities 1 3 5]
    python studies/corridor_speed_density.py --report   # only the tables, JSON and figures

What an experimenter measures, not the diagram itself: a point mass that walks by the count walks at
``g(ρ_j) v₀`` by construction (``ρ_j`` its own count of neighbours within 0.5 m), so plotting that is
circular; one that walks by the headway (``-headway`` in the models' names, :data:`POINT_MASS_MODELS`) walks at
the diagram's speed at its spacing to the person ahead, and one that walks by the forward cell (the default door
model, ``-forward-cell``) at the diagram's speed at the density of its Voronoi cell ahead.
Here the crowd walks one way along a corridor and we measure, in a *measurement area* across the
corridor, the density (persons in the area over its area, PedPy's *classic* method, and PedPy's
*Voronoi* method) and the mean speed of the people in it, over time windows, at several initial
crowd sizes (:data:`DENSITIES`), for every model and seed.

**The corridor.** :data:`WIDTH` = 3 m wide and :data:`LENGTH` = 80 m long, its east end the exit;
the crowd fills the first :data:`FILL` = 60 m at the initial density ``ρ₀`` (``ρ₀ · 3 m · 60 m``
people) and walks east, the informed crowd (``crowd.guidance = "geodesic"``) at the free speed
1.34 m/s, slowed by ``crowd.congestion``. The measurement area is :data:`AREA`, 2 m of the
corridor's length across its whole width, in the middle of the filled part. The toolkit has no
periodic boundaries; a uniformly filled corridor is its substitute. In the kinematic-wave
(LWR) picture the crowd's middle keeps its density and walks at the speed of that density until
a wave from one of its two ends arrives: the rear (a shock walking at the crowd's speed) and the
front, which empties into the free 20 m before the exit (a rarefaction walking back into the
crowd). No such wave is faster than the free speed (``|q'(ρ)| ≤ v₀`` for both diagrams), so the
measurement runs from :data:`T_START` (the crowds settle from their initial positions) to
:data:`T_END`, when a signal from either end, at 1.34 m/s and 1.5 m earlier for the Brownian
spread (:data:`MARGIN`), could first reach the area. A room feeding a corridor would not do: an
open corridor downstream of a room carries at most its capacity density (1.75 persons/m² for
Weidmann's diagram, 2.7 for the linear one), the free-flow branch only; the congested branch
needs a narrowing downstream, and in front of a narrowing the point masses pack to 15–24
persons/m² (``studies/bottleneck_flow.py``), so the density there would be set by the model's
failure, not by the crowd.

**The initial crowd.** Point masses start uniformly over the filled part (their own law, as
``crowd.initial = "uniform"`` draws it; registered crowd ``corridor-point-mass``). JuPedSim's
bodies (0.2 m radius) must not overlap: they start uniformly too, then pushed apart until no
two overlap, a random packing (``corridor-jupedsim``, :func:`initial_bodies`; the toolkit's
random sequential adsorption jams below 4 persons/m² here, and a lattice sets the bodies'
headways, which JuPedSim's speeds follow).

**The measurement** (PedPy, 10 frames/s): per frame, the classic density (persons strictly
inside the area over its 6 m²) and the mean speed of those in it; the Voronoi density and
speed (every 5th frame, the cells of the people within 6 m of the area, clipped by the walls).
A person's speed is its displacement along the corridor over ±0.5 s (PedPy's
``movement_direction = (1, 0)``, ``frame_step = 5``): the point masses' Brownian steps then
average out, where the norm of the displacement (PedPy's default) adds a bias of
``~√(πσ/Δt)`` (0.4 m/s at σ = 0.05 m²/s over 1 s; recorded as ``speed_norm``). The frames
between :data:`T_START` and :data:`T_END` are split into :data:`WINDOWS` time windows; each window is
a point ``(ρ, v)``: its frames' mean density and the mean over its frames (those with someone in
the area) of the mean speed.

Each run is a line of ``studies/results/corridor.jsonl`` (appended as it finishes, so that an
interrupted study resumes); ``--report`` bins the windows by their measured density
(:data:`BIN_EDGES`), takes per seed the mean speed of its windows in a bin, and writes
``studies/results/corridor.json`` (median and worst seed per bin, the RMS distance from
Weidmann's curve over the bins, and the diagrams on a uniform random crowd, :func:`uniform_crowd_speed`:
the count's noise and the walls without any walking), prints the docs tables and draws
``docs/figures/congestion_corridor.png`` (classic) and ``docs/figures/congestion_corridor_voronoi.png``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.crowds.local_density import DENSITY_RADIUS

WIDTH = 3.0
"""m: the corridor's width."""
FILL = 60.0
"""m: the crowd fills the corridor from x = 0 to here."""
LENGTH = 80.0
"""m: the corridor's length; its east end (x = LENGTH) is the exit."""
AREA = (29.0, 31.0)
"""m: the measurement area spans these x, across the corridor's width (2 m × 3 m = 6 m²)."""
DENSITIES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0)
"""Initial densities ρ₀ of the filled part, persons/m² (``ρ₀ · WIDTH · FILL`` people)."""
FREE_SPEED = 1.34
"""m/s: the free walking speed (Weidmann) and the fastest wave of either diagram."""
MARGIN = 1.5
"""m: what the Brownian spread (σ = 0.05 m²/s, √(2σt) ≈ 1.4 m at 20 s) adds to a wave."""
T_START = 3.0
"""s: the start of the measurement (the crowd settles from its initial positions)."""
T_END = (min(AREA[0], FILL - AREA[1]) - MARGIN) / FREE_SPEED
"""s: the first time a wave from either end of the crowd, at the free speed, could reach the area (20.5 s)."""
WINDOWS = 7
"""Time windows between T_START and T_END (2.5 s each)."""
FPS = 10.0
"""frames/s recorded (every second step of dt = 0.05 s)."""
FRAME_STEP = 5
"""PedPy's frame_step: a speed is the displacement over ±FRAME_STEP frames (±0.5 s)."""
VORONOI_EVERY = 5
"""Voronoi on every 5th frame (2 frames/s: PedPy's cells cost tens of ms per frame)."""
VORONOI_BAND = 6.0
"""m: the Voronoi cells are those of the people within this distance (along x) of the area."""
RESULTS = Path("studies/results/corridor.jsonl")
REPORT = Path("studies/results/corridor.json")
FIGURES = Path("docs/figures")
BIN_EDGES = tuple(np.round(np.arange(0.25, 6.26, 0.5), 2))
"""persons/m²: the density bins of the report (0.5 wide, centred on 0.5, 1.0, ..., 6.0)."""

WEIDMANN = {"free_speed": 1.34, "gamma": 1.913, "rho_max": 5.4}
"""U. Weidmann, *Transporttechnik der Fussgänger*, Schriftenreihe des IVT 90, ETH Zürich (1993)."""


def weidmann(rho: Any) -> np.ndarray:
    """Weidmann's relation ``v = 1.34 (1 − exp(−1.913 (1/ρ − 1/5.4)))``, m/s (0 from 5.4 persons/m² on)."""
    rho = np.asarray(rho, float)
    w = WEIDMANN
    with np.errstate(divide="ignore"):
        v = w["free_speed"] * -np.expm1(-w["gamma"] * (1.0 / rho - 1.0 / w["rho_max"]))
    return np.clip(v, 0.0, w["free_speed"])


def linear(rho: Any) -> np.ndarray:
    """The linear relation ``v = 1.34 max(0, 1 − ρ/5.4)``, m/s."""
    return WEIDMANN["free_speed"] * np.clip(1.0 - np.asarray(rho, float) / WEIDMANN["rho_max"], 0.0, 1.0)


# --- the runs --------------------------------------------------------------------------------------------


def initial_point_masses(n: int, rng: np.random.Generator, width: float = WIDTH) -> np.ndarray:
    """``n`` point masses uniform over the filled part ``[0, FILL] × [0, width]``."""
    return np.column_stack([rng.uniform(0.0, FILL, n), rng.uniform(0.0, width, n)])


def initial_bodies(n: int, radius: float, rng: np.random.Generator, gap: float = 0.01) -> np.ndarray:
    """``n`` bodies of ``radius`` on the filled part, a radius from the walls, without overlap: uniform
    positions, then relaxed (each pair closer than ``2 radius + gap / 2`` pushed apart to ``2 radius + gap``,
    until no pair is) into a random packing.

    Random sequential adsorption (:func:`~meanfield.crowds.jupedsim_engine.place_bodies`) jams at about
    55 % cover, below 4 persons/m² here; a triangular lattice reaches 5 but puts everyone straight behind a
    neighbour at the lattice spacing, and JuPedSim's speed follows the headway: at 1 person/m² its bodies walk
    at 0.61 m/s on a lattice with rows along the corridor, 0.98 on one with rows across it, 0.87–1.06 on
    random packings (three seeds).
    """
    from scipy.spatial import cKDTree

    r = radius * (1.0 + 1e-6)
    target = 2.0 * radius + gap
    p = np.column_stack([rng.uniform(r, FILL - r, n), rng.uniform(r, WIDTH - r, n)])
    for _ in range(20_000):
        pairs = cKDTree(p).query_pairs(2.0 * radius + 0.5 * gap, output_type="ndarray")
        if not len(pairs):
            return p
        i, j = pairs[:, 0], pairs[:, 1]
        delta = p[j] - p[i]
        dist = np.maximum(np.hypot(delta[:, 0], delta[:, 1]), 1e-12)
        push = (0.5 * (target - dist) / dist)[:, None] * delta
        np.add.at(p, i, -push)
        np.add.at(p, j, push)
        p[:, 0] = np.clip(p[:, 0], r, FILL - r)
        p[:, 1] = np.clip(p[:, 1], r, WIDTH - r)
    raise ValueError(f"{n} bodies of radius {radius} m could not be packed in {FILL} m × {WIDTH} m")


def corridor_point_masses(ctx: Any) -> Any:
    """Registry factory (crowd ``corridor-point-mass``): the point masses on the filled part."""
    from meanfield.crowds.agent_crowd import AgentCrowd
    from meanfield.crowds.point_mass import PointMassEngine

    sc = ctx.scenario
    humans = initial_point_masses(sc.crowd.n, ctx.rng)
    return AgentCrowd.from_context(PointMassEngine(humans, sc.domain, ctx.sigma, ctx.rng), ctx)


def corridor_bodies(ctx: Any) -> Any:
    """Registry factory (crowd ``corridor-jupedsim``): JuPedSim's bodies packed at random over the filled part."""
    from meanfield.crowds.agent_crowd import AgentCrowd
    from meanfield.crowds.jupedsim_engine import JuPedSimEngine, JuPedSimOptions

    sc = ctx.scenario
    p = JuPedSimOptions.of(sc)
    humans = initial_bodies(sc.crowd.n, p.radius, ctx.rng)
    engine = JuPedSimEngine(humans, sc.domain, p.radius, p.max_speed, p.time_step, p.model, sc.seed)
    return AgentCrowd.from_context(engine, ctx)


CROWDS = {
    "corridor-point-mass": (corridor_point_masses, "point-mass"),
    "corridor-jupedsim": (corridor_bodies, "jupedsim"),
}
"""The study's crowds: each a built-in kind's, started on the corridor's filled part, with that kind's capabilities
(the run names it in place of the scenario's ``crowd.kind``, which stays the built-in one)."""


def _register() -> None:
    from meanfield import plugins

    for name, (factory, kind) in CROWDS.items():
        if name not in plugins.available("crowd"):
            plugins.register("crowd", name, factory, capabilities=plugins.capabilities("crowd", kind))


POINT_MASS_MODELS = {
    "weidmann": ("weidmann", "count"),
    "linear": ("linear", "count"),
    "weidmann-headway": ("weidmann", "headway"),
    "linear-headway": ("linear", "headway"),
    "weidmann-forward-cell": ("weidmann", "forward-cell"),
    "linear-forward-cell": ("linear", "forward-cell"),
}
"""The point masses' models: ``(crowd.congestion, crowd.door_model)``.  The bare diagrams walk by the count, as
they were measured before the headway became the default door model (docs page *Congestion*, "The agents' door
model"); the count's speed is ``g`` of the count within the radius, so those are run at each ``--radii``.  The
forward cell is the default since 2026-12-06, the headway before it."""
COUNT_MODELS = tuple(m for m, (_, door) in POINT_MASS_MODELS.items() if door == "count")
"""The models whose speed is the count's: their local-density radius is a parameter of the walk."""


def scenario(model: str, rho0: float, seed: int) -> Any:
    """The corridor with ``ρ₀ · WIDTH · FILL`` informed people and the crowd ``model``, from the
    built-in ``bottleneck`` (SI units, dt = 0.05 s, σ = 0.05 m²/s, free speed 1.34 m/s)."""
    from meanfield.scenarios.scenario import builtin_scenarios

    values: dict[str, Any] = {
        "name": "corridor",
        "domain.wkt": f"POLYGON ((0 0, {LENGTH:g} 0, {LENGTH:g} {WIDTH:g}, 0 {WIDTH:g}, 0 0))",
        "domain.exits": [[[LENGTH, 0.0], [LENGTH, WIDTH]]],
        "grid.cells": [int(round(LENGTH / 0.25)), int(round(WIDTH / 0.25))],  # 0.25 m: the routes are straight
        "crowd.n": int(round(rho0 * WIDTH * FILL)),
        "t_final": T_END + 1.0,
        "target.center": [LENGTH, WIDTH / 2],
        "robots.n": 1,  # a parked sign nobody follows
    }
    if model == "jupedsim":
        values["crowd.kind"] = "jupedsim"
        # the bodies this study was measured with (docs page *Congestion*), not the bottleneck's since issue 42:
        # JuPedSim's defaults, bodies of 0.2 m, steps of 0.01 s
        values["crowd.options.jupedsim.radius"] = 0.2
        values["crowd.options.jupedsim.time_step"] = 0.01
        values["crowd.options.jupedsim.strength_neighbor_repulsion"] = "default"
    else:
        values["crowd.congestion"], values["crowd.door_model"] = POINT_MASS_MODELS[model]
    return builtin_scenarios()["bottleneck"](seed=seed).with_values(values)


def simulate(model: str, radius: float, rho0: float, seed: int) -> tuple[np.ndarray, float]:
    """The positions ``(frames, N, 2)`` at :data:`FPS` from t = 0 to ``t_final`` (NaN: left), and the wall time."""
    from meanfield.simulation.loop import ClosedLoop

    _register()
    sc = scenario(model, rho0, seed).with_values({"crowd.congestion_radius": radius})
    start = time.perf_counter()
    loop = ClosedLoop(sc, crowd="corridor-jupedsim" if model == "jupedsim" else "corridor-point-mass")
    every = int(round(1.0 / (FPS * sc.dt)))
    frames = [loop.crowd.positions.copy()]
    for k in range(sc.steps):
        loop.step()
        if (k + 1) % every == 0:
            frames.append(loop.crowd.positions.copy())
    return np.array(frames), time.perf_counter() - start


def measure(frames: np.ndarray, model: str = "none", radius: float = DENSITY_RADIUS) -> list[dict[str, Any]]:
    """The windows' densities and speeds in the measurement area (PedPy), from :func:`simulate`'s frames.

    Besides PedPy's measures, each window has what the people in the area *see*: the mean of their own
    local density ``ρ_j`` (others within ``radius`` over the disk's area in the corridor, the congested point
    masses' count, :class:`~meanfield.crowds.local_density.LocalDensity`) and, for a congested ``model``, the mean of
    ``v₀ g(ρ_j)``, the speed its diagram gives them (None for JuPedSim's bodies).
    """
    import pandas as pd
    import pedpy

    from meanfield import Domain
    from meanfield.crowds.congestion import Linear, Weidmann
    from meanfield.crowds.local_density import LocalDensity

    diagram = {"weidmann": Weidmann(), "linear": Linear()}.get(model)  # the count's: v₀ g(ρ_j) is its speed

    first = int(round((T_START - FRAME_STEP / FPS) * FPS))
    last = int(round((T_END + FRAME_STEP / FPS) * FPS))
    x = frames[first : last + 1]
    keep = np.flatnonzero(
        np.any((x[:, :, 0] > AREA[0] - 2 * VORONOI_BAND) & (x[:, :, 0] < AREA[1] + 2 * VORONOI_BAND), axis=0)
    )
    x = x[:, keep]
    if np.isnan(x).any():
        raise RuntimeError("someone near the measurement area left the corridor while measured")
    t_idx, p_idx = np.meshgrid(np.arange(len(x)), keep, indexing="ij")
    data = pd.DataFrame(
        {
            "id": p_idx.ravel(),
            "frame": (t_idx + first).ravel(),
            "x": x[:, :, 0].ravel(),
            "y": np.clip(x[:, :, 1], 1e-6, WIDTH - 1e-6).ravel(),  # a reflected point may lie on a wall
        }
    )
    traj = pedpy.TrajectoryData(data=data, frame_rate=FPS)
    x0, x1 = AREA
    area = pedpy.MeasurementArea([(x0, 0.0), (x1, 0.0), (x1, WIDTH), (x0, WIDTH)])
    walkable = pedpy.WalkableArea([(0.0, 0.0), (LENGTH, 0.0), (LENGTH, WIDTH), (0.0, WIDTH)])
    border = pedpy.SpeedCalculation.BORDER_SINGLE_SIDED
    along = pedpy.compute_individual_speed(
        traj_data=traj, frame_step=FRAME_STEP, movement_direction=np.array([1.0, 0.0]), speed_calculation=border
    )
    norm = pedpy.compute_individual_speed(traj_data=traj, frame_step=FRAME_STEP, speed_calculation=border)
    classic = pedpy.compute_classic_density(traj_data=traj, measurement_area=area).set_index("frame")["density"]
    v_along = pedpy.compute_mean_speed_per_frame(traj_data=traj, individual_speed=along, measurement_area=area)
    v_norm = pedpy.compute_mean_speed_per_frame(traj_data=traj, individual_speed=norm, measurement_area=area)
    v_along, v_norm = v_along.set_index("frame")["speed"], v_norm.set_index("frame")["speed"]
    # Voronoi: every VORONOI_EVERY-th frame, the people within VORONOI_BAND of the area
    t_first, t_last = int(round(T_START * FPS)), int(round(T_END * FPS))
    picked = data[
        (data["frame"] >= t_first)
        & (data["frame"] < t_last)
        & ((data["frame"] - t_first) % VORONOI_EVERY == 0)
        & (data["x"] > x0 - VORONOI_BAND)
        & (data["x"] < x1 + VORONOI_BAND)
    ]
    sub = pedpy.TrajectoryData(data=picked[["id", "frame", "x", "y"]].reset_index(drop=True), frame_rate=FPS)
    cells = pedpy.compute_individual_voronoi_polygons(traj_data=sub, walkable_area=walkable)
    vor_density, inter = pedpy.compute_voronoi_density(individual_voronoi_data=cells, measurement_area=area)
    vor_speed = pedpy.compute_voronoi_speed(
        traj_data=sub, individual_speed=along, individual_voronoi_intersection=inter, measurement_area=area
    )
    vor_density = vor_density.set_index("frame")["density"]
    vor_speed = vor_speed.set_index("frame")["speed"]
    seen, given = {}, {}  # per frame: the mean ρ_j and v₀ g(ρ_j) of the people in the area
    local_density = LocalDensity(x.shape[1], radius, Domain.box(LENGTH, WIDTH))
    for f in range(t_first, t_last):
        pts = x[f - first]
        rho_j = local_density(pts)
        inside = (pts[:, 0] > x0) & (pts[:, 0] < x1)
        if inside.any():
            seen[f] = float(rho_j[inside].mean())
            if diagram is not None:
                given[f] = float((diagram.free_speed * diagram.speed_factor(rho_j[inside])).mean())
    windows = []
    edges = np.linspace(t_first, t_last, WINDOWS + 1).round().astype(int)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        f = np.arange(a, b)
        rho = classic.reindex(f).to_numpy()
        occupied = rho > 0  # (PedPy's mean speed is 0 in a frame with nobody in the area)
        fv = f[(f - t_first) % VORONOI_EVERY == 0]
        windows.append(
            {
                "t0": float(a / FPS),
                "t1": float(b / FPS),
                "frames": len(f),
                "frames_empty": int((~occupied).sum()),
                "density": float(rho.mean()),
                "speed": float(v_along.reindex(f[occupied]).mean()) if occupied.any() else None,
                "speed_norm": float(v_norm.reindex(f[occupied]).mean()) if occupied.any() else None,
                "voronoi_density": float(vor_density.reindex(fv).mean()),
                "voronoi_speed": float(vor_speed.reindex(fv).mean()),
                "seen_density": float(np.mean([seen[k] for k in f if k in seen])) if occupied.any() else None,
                "diagram_speed": float(np.mean([given[k] for k in f if k in given]))
                if given and occupied.any()
                else None,
            }
        )
    return windows


def one_run(model: str, radius: float, rho0: float, seed: int) -> dict[str, Any]:
    """One run's windows."""
    frames, wall = simulate(model, radius, rho0, seed)
    start = time.perf_counter()
    windows = measure(frames, model, radius)
    return {
        "model": model,
        "radius": radius if model in COUNT_MODELS else None,
        "rho0": rho0,
        "seed": seed,
        "n": int(frames.shape[1]),
        "windows": windows,
        "wall_seconds": wall,
        "measure_seconds": time.perf_counter() - start,
    }


def _key(row: dict[str, Any]) -> tuple:
    return row["model"], row["radius"], row["rho0"], row["seed"]


def _rows() -> list[dict[str, Any]]:
    if not RESULTS.exists():
        return []
    return [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]


def run_all(
    seeds: int, body_seeds: int, models: list[str], radii: list[float], densities: list[float], workers: int
) -> None:
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    done = {_key(r) for r in _rows()}
    jobs = []
    for seed in range(max(seeds, body_seeds)):
        for model in models:
            if seed >= (body_seeds if model == "jupedsim" else seeds):
                continue
            for radius in radii if model in COUNT_MODELS else [None]:
                for rho0 in densities:
                    if (model, radius, rho0, seed) not in done:
                        jobs.append((model, radius if radius is not None else DENSITY_RADIUS, rho0, seed))
    print(f"{len(jobs)} runs to do", flush=True)
    with ProcessPoolExecutor(workers) as pool, RESULTS.open("a") as out:
        futures = {pool.submit(one_run, *job): job for job in jobs}
        for i, f in enumerate(as_completed(futures), 1):
            row = f.result()
            out.write(json.dumps(row) + "\n")
            out.flush()
            os.fsync(out.fileno())
            rho = np.mean([w["density"] for w in row["windows"]])
            v = np.nanmean([w["speed"] if w["speed"] is not None else np.nan for w in row["windows"]])
            print(
                f"[{i}/{len(jobs)}] {futures[f]}: ρ {rho:.2f} persons/m², v {v:.2f} m/s "
                f"({row['wall_seconds']:.1f} s + {row['measure_seconds']:.1f} s)",
                flush=True,
            )


# --- the report ------------------------------------------------------------------------------------------

METHODS = {"classic": ("density", "speed"), "voronoi": ("voronoi_density", "voronoi_speed")}


def _label(model: str, radius: float | None) -> str:
    return model if radius is None else f"{model} r={radius:g}"


def _order(label: str) -> tuple[int, str]:
    """Weidmann's diagram, the linear one (the count, then the headway), then JuPedSim's bodies (the tables' and
    the figures' order)."""
    order = {"weidmann": 0, "linear": 1, "weidmann-headway": 2, "linear-headway": 3, "jupedsim": 4}
    return order.get(label.split()[0], 9), label


def _bins(rows: list[dict[str, Any]], method: str) -> dict[int, dict[int, tuple[float, float, int]]]:
    """``{bin: {seed: (mean ρ, mean v, windows)}}`` over the windows of ``rows`` (every ρ₀) in each density bin."""
    dkey, vkey = METHODS[method]
    per: dict[int, dict[int, list[tuple[float, float]]]] = {}
    edges = np.asarray(BIN_EDGES)
    for r in rows:
        for w in r["windows"]:
            if w[vkey] is None or w[dkey] is None or not np.isfinite(w[vkey]):
                continue
            k = int(np.searchsorted(edges, w[dkey], side="right")) - 1
            if 0 <= k < len(edges) - 1:
                per.setdefault(k, {}).setdefault(r["seed"], []).append((w[dkey], w[vkey]))
    return {
        k: {s: (float(np.mean([p[0] for p in ps])), float(np.mean([p[1] for p in ps])), len(ps)) for s, ps in d.items()}
        for k, d in sorted(per.items())
    }


def uniform_crowd_speed(
    model: str, rho: float, radius: float = DENSITY_RADIUS, walls: bool = True, samples: int = 40, seed: int = 0
) -> float:
    """``mean v₀ g(ρ_j)`` over a uniform random crowd of density ``rho`` in the corridor (its middle 20 m):
    the speed the diagram gives a crowd of point masses that has not moved, the count's noise and the walls'
    walls' share of the disk included (``ρ_j`` from :func:`~meanfield.crowds.local_density.local_density`,
    the disk cut by the corridor's walls as the agents' is).  Without ``walls``: the people farther than
    ``radius`` from the walls of a crowd 10 m wide, whose disks no wall cuts (the count's noise alone)."""
    from meanfield import Domain
    from meanfield.crowds.congestion import Linear, Weidmann
    from meanfield.crowds.local_density import local_density

    diagram = {"weidmann": Weidmann(), "linear": Linear()}[model]
    width = WIDTH if walls else 10.0
    rng = np.random.default_rng(seed)
    speeds = []
    for _ in range(samples):
        p = initial_point_masses(max(1, int(round(rho * width * FILL))), rng, width)
        mid = (p[:, 0] > FILL / 2 - 10) & (p[:, 0] < FILL / 2 + 10)
        if not walls:
            mid &= (p[:, 1] > radius) & (p[:, 1] < width - radius)
        if mid.any():
            rho_j = local_density(p, None, radius, Domain.box(FILL, width))[mid]
            speeds.append(diagram.free_speed * diagram.speed_factor(rho_j))
    return float(np.mean(np.concatenate(speeds)))


def _median_of_runs(rows: list[dict[str, Any]], key: str) -> float | None:
    """The median over ``rows`` of each run's mean of ``key`` over its windows (None where no window has it)."""
    means = []
    for r in rows:
        vals = [w.get(key) for w in r["windows"]]
        vals = [v for v in vals if v is not None and np.isfinite(v)]
        if vals:
            means.append(np.mean(vals))
    return float(np.median(means)) if means else None


MIN_SEEDS = 2
"""A bin enters the table, the RMS and the figures' medians when at least this many seeds have windows in it."""
RMS_UP_TO = 5.0
"""persons/m²: the RMS is over the bins centred at most here (0.5–5, the range of the initial densities;
the point masses' bins above Weidmann's jam density 5.4, where his curve is 0, are in the table apart)."""


def report() -> dict[str, Any]:
    """Per model, method and density bin: the median over the seeds of their mean speed, the worst seed
    (the farthest from Weidmann's curve at its own density) and the lowest–highest; the RMS over the bins
    of ``median v − Weidmann(median ρ)`` (and against the linear relation); per initial density ρ₀ the
    medians of the measured density and speed."""
    rows = _rows()
    groups: dict[str, list[dict]] = {}
    for r in rows:
        groups.setdefault(_label(r["model"], r["radius"]), []).append(r)
    out: dict[str, Any] = {
        "corridor_m": {"width": WIDTH, "length": LENGTH, "filled": FILL, "measurement_area_x": list(AREA)},
        "measured_s": [T_START, T_END],
        "windows": WINDOWS,
        "bin_edges": list(BIN_EDGES),
        "weidmann_1993": WEIDMANN,
        "speed": "mean over the frames (with someone in the area) of the people's mean speed along the corridor",
        "models": {},
    }
    for label, rs in sorted(groups.items(), key=lambda kv: _order(kv[0])):
        m: dict[str, Any] = {"seeds": sorted({r["seed"] for r in rs}), "runs": len(rs)}
        for method in METHODS:
            bins = _bins(rs, method)
            per = {}
            for k, seeds in bins.items():
                rho = np.array([v[0] for v in seeds.values()])
                v = np.array([v[1] for v in seeds.values()])
                gap = v - weidmann(rho)
                worst = int(np.argmax(np.abs(gap)))
                centre = 0.5 * (BIN_EDGES[k] + BIN_EDGES[k + 1])
                per[f"{centre:g}"] = {
                    "seeds": len(v),
                    "windows": int(sum(s[2] for s in seeds.values())),
                    "density_median": float(np.median(rho)),
                    "speed_median": float(np.median(v)),
                    "speed_min": float(v.min()),
                    "speed_max": float(v.max()),
                    "speed_worst": float(v[worst]),
                    "density_worst": float(rho[worst]),
                    "worst_seed": int(list(seeds)[worst]),
                    "weidmann_at_median": float(weidmann(np.median(rho))),
                    "linear_at_median": float(linear(np.median(rho))),
                }
                if rs[0]["model"] in ("weidmann", "linear") and method == "classic":  # a mean over the people
                    per[f"{centre:g}"]["uniform_crowd_speed_at_median"] = uniform_crowd_speed(
                        rs[0]["model"], float(np.median(rho)), rs[0]["radius"]
                    )
            used = [p for k, p in per.items() if p["seeds"] >= MIN_SEEDS and float(k) <= RMS_UP_TO]
            gaps_w = [p["speed_median"] - p["weidmann_at_median"] for p in used]
            gaps_l = [p["speed_median"] - p["linear_at_median"] for p in used]
            m[method] = {
                "per_bin": per,
                "rms_minus_weidmann": float(np.sqrt(np.mean(np.square(gaps_w)))) if used else None,
                "rms_minus_linear": float(np.sqrt(np.mean(np.square(gaps_l)))) if used else None,
                "bins_compared": [k for k, p in per.items() if p["seeds"] >= MIN_SEEDS and float(k) <= RMS_UP_TO],
                # (classic) the medians minus the diagram on a uniform random crowd, over the same bins
                "rms_minus_uniform_crowd": float(
                    np.sqrt(np.mean([(p["speed_median"] - p["uniform_crowd_speed_at_median"]) ** 2 for p in used]))
                )
                if used and all("uniform_crowd_speed_at_median" in p for p in used)
                else None,
            }
        by_rho0: dict[str, Any] = {}
        for rho0 in sorted({r["rho0"] for r in rs}):
            sel = [r for r in rs if r["rho0"] == rho0]
            drift = [(r["windows"][-1]["density"] - r["windows"][0]["density"]) for r in sel]
            p = {"n": sel[0]["n"], "seeds": len(sel)}
            for key in ("density", "voronoi_density", "speed", "speed_norm", "seen_density", "diagram_speed"):
                p[f"{key}_median"] = _median_of_runs(sel, key)
            p["density_drift_median"] = float(np.median(drift))  # last window minus first, persons/m²
            p["density_drift_max_abs"] = float(np.max(np.abs(drift)))
            p["wall_seconds_median"] = float(np.median([r["wall_seconds"] for r in sel]))
            by_rho0[f"{rho0:g}"] = p
        m["per_initial_density"] = by_rho0
        out["models"][label] = m
    out["uniform_random_crowd"] = {  # the diagrams on crowds that have not moved: the count's noise, the walls
        "densities": [1.0, 2.0, 3.0, 4.0, 5.0],
        "radius_m": DENSITY_RADIUS,
        **{
            f"{model}_{where}": [
                uniform_crowd_speed(model, d, DENSITY_RADIUS, walls, samples=10) for d in (1, 2, 3, 4, 5)
            ]
            for model in ("weidmann", "linear")
            for where, walls in (("corridor", True), ("no_walls", False))
        },
        "weidmann_curve": [float(weidmann(d)) for d in (1, 2, 3, 4, 5)],
        "linear_curve": [float(linear(d)) for d in (1, 2, 3, 4, 5)],
    }
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    REPORT.write_text(json.dumps(out, indent=1) + "\n")
    return out


def table(rep: dict[str, Any], method: str = "classic") -> str:
    """The docs page's table: per density bin, the median over the seeds of the mean speed (m/s) and, in
    brackets, the worst seed (farthest from Weidmann's curve); Weidmann's and the linear relation's speeds at
    the bin's centre; the RMS of the medians minus Weidmann's curve over the bins with ≥ MIN_SEEDS seeds centred at
    0.5–5 persons/m² (:data:`RMS_UP_TO`); for the
    point masses (classic) also the speed their diagram gives a uniform random crowd at the bin's density."""
    centres = sorted({float(k) for m in rep["models"].values() for k in m[method]["per_bin"]})
    head = "| model | " + " | ".join(f"ρ ≈ {c:g}" for c in centres) + " | RMS − Weidmann | RMS − linear |"
    lines = [head, "|---" * (len(centres) + 3) + "|"]
    lines.append("| Weidmann (1993) | " + " | ".join(f"{float(weidmann(c)):.2f}" for c in centres) + " | | |")
    lines.append("| linear | " + " | ".join(f"{float(linear(c)):.2f}" for c in centres) + " | | |")
    for label, m in rep["models"].items():
        per = m[method]["per_bin"]
        cells = []
        for c in centres:
            p = per.get(f"{c:g}")
            if p is None:
                cells.append("–")
            elif p["seeds"] < MIN_SEEDS:
                cells.append(f"({p['speed_median']:.2f}; 1 seed)")
            else:
                cells.append(f"{p['speed_median']:.2f} ({p['speed_worst']:.2f})")
        rw, rl = m[method]["rms_minus_weidmann"], m[method]["rms_minus_linear"]
        rw_cell = "–" if rw is None else f"{rw:.2f}"
        rl_cell = "–" if rl is None else f"{rl:.2f}"
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {rw_cell} | {rl_cell} |")
        if method == "classic" and any("uniform_crowd_speed_at_median" in p for p in per.values()):
            cells = []
            for c in centres:
                p = per.get(f"{c:g}")
                ok = p is not None and p["seeds"] >= MIN_SEEDS and "uniform_crowd_speed_at_median" in p
                cells.append(f"{p['uniform_crowd_speed_at_median']:.2f}" if ok else "–")
            lines.append(f"| {label}: its diagram on a uniform random crowd | " + " | ".join(cells) + " | | |")
    return "\n".join(lines)


def table_by_initial_density(rep: dict[str, Any]) -> str:
    """Per model and initial density ρ₀: the medians over the seeds of the measured densities (classic, Voronoi),
    of the mean local density the people in the area see (0.5 m disk cut by the walls, the point masses'
    count), of the speed along the corridor, of the speed the diagram gives them ``v₀ g(ρ_j)``, of PedPy's
    default speed (the norm of the displacement), and the density's drift over the measurement (last window
    minus first)."""
    lines = [
        "| model | ρ₀ | people | ρ classic | ρ Voronoi | ρ_j seen | v along | v₀ g(ρ_j) | ‖v‖ | ρ drift |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def cell(v: float | None) -> str:
        return "–" if v is None else f"{v:.2f}"

    for label, m in rep["models"].items():
        for rho0, p in m["per_initial_density"].items():
            keys = ("density", "voronoi_density", "seen_density", "speed", "diagram_speed", "speed_norm")
            bodies = label == "jupedsim"  # bodies walk by no count: "–"
            cells = " | ".join(cell(None if bodies and k == "seen_density" else p[f"{k}_median"]) for k in keys)
            drift = f"{p['density_drift_median']:+.2f} (max {p['density_drift_max_abs']:.2f})"
            lines.append(f"| {label} | {rho0} | {p['n']} | {cells} | {drift} |")
    return "\n".join(lines)


def figures(rep: dict[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    rows = _rows()
    labels = sorted(rep["models"], key=_order)
    rho = np.linspace(0.05, 6.2, 400)
    uniform: dict[tuple[str, str], list[float]] = {}  # the diagram on a uniform random crowd, per model and radius
    uniform_label = "point masses' diagram on a uniform random crowd, mean v₀ g(ρ_j)"
    for method, name in (("classic", "congestion_corridor.png"), ("voronoi", "congestion_corridor_voronoi.png")):
        dkey, vkey = METHODS[method]
        fig, axes = plt.subplots(1, len(labels), figsize=(4.2 * len(labels), 5.0), sharey=True, squeeze=False)
        for ax, label in zip(axes[0], labels, strict=True):
            pts = np.array(
                [
                    (w[dkey], w[vkey])
                    for r in rows
                    if _label(r["model"], r["radius"]) == label
                    for w in r["windows"]
                    if w[vkey] is not None and np.isfinite(w[vkey])
                ]
            )
            if len(pts):
                window = f"one time window ({(T_END - T_START) / WINDOWS:.1f} s)"
                ax.plot(pts[:, 0], pts[:, 1], ".", color="tab:blue", ms=2.5, alpha=0.35, label=window)
            per = rep["models"][label][method]["per_bin"]
            shown = [p for p in per.values() if p["seeds"] >= MIN_SEEDS]
            if shown:
                d = [p["density_median"] for p in shown]
                ax.errorbar(
                    d,
                    [p["speed_median"] for p in shown],
                    yerr=[
                        [p["speed_median"] - p["speed_min"] for p in shown],
                        [p["speed_max"] - p["speed_median"] for p in shown],
                    ],
                    fmt="o",
                    color="tab:red",
                    ms=5,
                    capsize=2,
                    label="median over seeds per 0.5 bin (bars: lowest–highest seed)",
                )
            ax.plot(rho, weidmann(rho), "k-", lw=1.5, label="Weidmann (1993)")
            ax.plot(rho, linear(rho), "k--", lw=1.0, label="linear, 1.34 (1 − ρ/5.4)")
            model, _, radius = label.partition(" r=")
            if model in ("weidmann", "linear") and method == "classic":  # (a mean over the people, as classic)
                grid = np.arange(0.25, 6.26, 0.25)
                if (model, radius) not in uniform:
                    uniform[model, radius] = [uniform_crowd_speed(model, float(d), float(radius)) for d in grid]
                ax.plot(grid, uniform[model, radius], ":", color="tab:green", lw=2.0, label=uniform_label)
            rms = rep["models"][label][method]["rms_minus_weidmann"]
            title = label if rms is None else f"{label}: RMS − Weidmann {rms:.2f} m/s"
            ax.set_title(title, fontsize=9)
            ax.set_xlabel(f"density ρ ({'Voronoi' if method == 'voronoi' else 'classic'}), persons/m²")
            ax.set_xlim(0, 6.2)
            ax.set_ylim(-0.05, 1.6)
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("mean speed along the corridor v (m/s)")
        handles = {}
        for ax in axes[0]:
            for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
                handles.setdefault(lab, h)
        fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=3, fontsize=8, frameon=False)
        fig.suptitle(
            f"Corridor {WIDTH:g} m wide, measurement area {AREA[1] - AREA[0]:g} m × {WIDTH:g} m, "
            f"{T_START:g}–{T_END:.1f} s ({'Voronoi' if method == 'voronoi' else 'classic'} density and speed)",
            fontsize=10,
        )
        fig.tight_layout(rect=(0, 0.1, 1, 1))
        fig.savefig(FIGURES / name, dpi=120)
        plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds of the point masses")
    parser.add_argument("--body-seeds", type=int, default=3, help="seeds of JuPedSim's bodies")
    parser.add_argument(
        "--models", nargs="+", default=[*POINT_MASS_MODELS, "jupedsim"], choices=[*POINT_MASS_MODELS, "jupedsim"]
    )
    parser.add_argument("--radii", nargs="+", type=float, default=[DENSITY_RADIUS])
    parser.add_argument("--densities", nargs="+", type=float, default=list(DENSITIES))
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--report", action="store_true", help="only the JSON, the tables and the figures")
    args = parser.parse_args()
    if not args.report:
        run_all(args.seeds, args.body_seeds, args.models, args.radii, args.densities, args.workers)
    rep = report()
    print(table(rep, "classic"))
    print()
    print(table(rep, "voronoi"))
    print()
    print(table_by_initial_density(rep))
    figures(rep)


if __name__ == "__main__":
    main()
