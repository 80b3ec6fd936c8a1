"""The agents' door models against the density, in the bottleneck, at three noises (docs page *Congestion*).

Run from the repository's root::

    python studies/door_models.py [--sigmas 0.01 0.05 0.1] [--widths 0.8 1.0 2.0 2.5] [--seeds 3]
    python studies/door_models.py --report        # only the table, from studies/results/door_models.jsonl
    python studies/door_models.py --dt 0.025 --models godunov-twin --widths 2.0   # the step halved

The built-in ``bottleneck`` (a 10 m × 8 m room, a corridor 2 m long and ``b`` wide), with the 200 people
starting in the room (``crowd.initial = "groups"``, the room's rectangle: none in the corridor), the
informed crowd on the fastest route (``crowd.guidance = "fastest-route"``, docs page *Congestion*,
"Routes") and the linear diagram, for

* the point masses with each door model (``crowd.door_model`` = ``"count"``, ``"godunov-twin"``,
  ``"headway"`` or ``"forward-cell"``, the last two with their exits at their capacity), one run per seed: the
  flow ``J`` between the exits of 10 % and 90 % of the crowd (:func:`bottleneck_flow.steady_flow`) and the
  packing, the largest over the recorded seconds of the 95th percentile, among those still in the room, of the
  others within 0.5 m over ``π 0.25`` m² (persons/m², the disk cut by the walls as the agents' own), and the same of
  their Voronoi densities (:func:`voronoi_densities`, which read the jam density itself in a hexagonal
  jam, where the disk reads 7.6);
* the density (``crowd.kind = "fokker-planck"``), one run (it is deterministic): ``J`` from its exits'
  cumulative outflow (:func:`bottleneck_flow.pde_flow`).

Each run is a line of ``studies/results/door_models.jsonl``, appended as it finishes (an interrupted
study resumes); the table is the median and the worst seed of ``J/b`` and the worst seed's packings.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bottleneck_flow import pde_flow, scenario, steady_flow  # noqa: E402

RESULTS = Path("studies/results/door_models.jsonl")
MODELS = ("count", "godunov-twin", "headway", "forward-cell", "density")
ROOM = "POLYGON ((0 0, 10 0, 10 8, 0 8, 0 0))"
PACKING_RADIUS = 0.5
"""m: the packing's disk."""


DT = 0.05
"""s: the bottleneck scenario's step (``--dt`` takes another; a row without ``dt`` was run at it)."""


def build(b: float, model: str, sigma: float, seed: int, dt: float = DT) -> Any:
    """The bottleneck of width ``b`` with the crowd ``model`` at noise ``sigma``, stepped by ``dt`` (recorded
    every second)."""
    sc = scenario(b, "pde-fastest" if model == "density" else "linear", seed)
    values: dict[str, Any] = {
        "crowd.sigma": sigma,
        "crowd.guidance": "fastest-route",
        "crowd.initial": "groups",
        "crowd.groups": [{"region": ROOM, "n": sc.crowd.n}],
    }
    if model != "density":
        values["crowd.door_model"] = model
    if dt != sc.dt:
        if not (dt > 0 and abs(1.0 / dt - round(1.0 / dt)) < 1e-9):
            raise SystemExit(f"--dt: a step that divides a second (0.05, 0.025, 0.01, ...), not {dt}")
        values["dt"], values["record_every"] = dt, round(1.0 / dt)
    return sc.with_values(values)


class Packing:
    """Observer: every recorded second, the 95th percentile of the local density of those still in the room, by
    the disk's count (``worst``) and by Voronoi cells (``worst_voronoi``, :func:`voronoi_densities`)."""

    def __init__(self, every: int) -> None:
        self.every, self.k, self.worst, self.worst_voronoi = every, 0, 0.0, 0.0

    def start(self, loop: Any) -> None:
        from meanfield.crowds.local_density import LocalDensity

        self.density = LocalDensity(len(loop.crowd.engine.positions), PACKING_RADIUS, loop.scenario.domain)
        self.plan = loop.scenario.domain.polygon

    def step(self, loop: Any, record: Any) -> None:
        self.k += 1
        if self.k % self.every:
            return
        engine = loop.crowd.engine
        room = engine.active & (engine.positions[:, 0] < 10.0)
        if room.sum() < 10:
            return
        rho = self.density(engine.positions, engine.active)[room]
        self.worst = max(self.worst, float(np.percentile(rho, 95)))
        voronoi = voronoi_densities(engine.positions[engine.active], self.plan)[room[engine.active]]
        self.worst_voronoi = max(self.worst_voronoi, float(np.percentile(voronoi, 95)))


VORONOI_CUTOFF = 1.0
"""m: a Voronoi cell is cut by a disk of this radius about its person (PedPy's cut-off: the cells at the crowd's
edge would otherwise reach the walls)."""


def voronoi_densities(points: np.ndarray, plan: Any) -> np.ndarray:
    """Each person's Voronoi density, 1 / (the area of its Voronoi cell in the plan, cut at :data:`VORONOI_CUTOFF`),
    persons/m² (PedPy's ``compute_individual_voronoi_polygons``; Steffen and Seyfried, Physica A 389 (2010)
    1902–1910).  Unlike a count in a disk of 0.5 m, which reads 7.6 in a hexagonal lattice at the jam density
    (its six nearest neighbours at 0.46 m are all in the disk), it reads the lattice's own 5.4 persons/m²."""
    import pandas as pd
    import pedpy
    import shapely

    frame = pd.DataFrame({"id": np.arange(len(points)), "frame": 0, "x": points[:, 0], "y": points[:, 1]})
    frame["point"] = shapely.points(points)
    cells = pedpy.compute_individual_voronoi_polygons(
        traj_data=pedpy.TrajectoryData(data=frame, frame_rate=1.0),
        walkable_area=pedpy.WalkableArea(plan),
        cut_off=pedpy.Cutoff(radius=VORONOI_CUTOFF, quad_segments=3),
    )
    return cells.sort_values("id")["density"].to_numpy()


def one_run(b: float, model: str, sigma: float, seed: int, dt: float = DT) -> dict[str, Any]:
    from meanfield.simulation.loop import ClosedLoop

    sc = build(b, model, sigma, seed, dt)
    start = time.perf_counter()
    n = sc.crowd.n
    if model == "density":
        loop = ClosedLoop(sc)
        crowd, times, out = loop.crowd, [0.0], [0.0]
        while loop.t < sc.t_final - 1e-9 and out[-1] < n - 0.5:
            loop.step()
            times.append(loop.t)
            out.append(n * float(crowd.out_per_exit.sum()) / crowd.initial_mass)
        flow, packing, packing_voronoi = pde_flow(np.array(times), np.array(out), n), None, None
    else:
        packing_observer = Packing(round(1.0 / sc.dt))
        loop = ClosedLoop(sc, observers=[packing_observer])
        loop.run(progress=False)
        flow = steady_flow(np.asarray(loop.crowd.engine.exit_time, float), n)
        packing, packing_voronoi = packing_observer.worst, packing_observer.worst_voronoi
    return {"model": model, "width": b, "sigma": sigma, "seed": seed, "dt": sc.dt, "flow": flow,
            "specific_flow": None if flow is None else flow / b, "packing": packing,
            "packing_voronoi": packing_voronoi,
            "wall_seconds": time.perf_counter() - start}  # fmt: skip


def rows() -> list[dict[str, Any]]:
    if not RESULTS.exists():
        return []
    found = [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]
    for r in found:
        r.setdefault("dt", DT)
    return found


def report() -> str:
    """The docs' table: ``J/b`` median (worst seed) per width, and the worst packing, per σ and model."""
    table: dict[tuple, list[dict[str, Any]]] = {}
    for r in rows():
        table.setdefault((r["sigma"], r["model"], r["dt"]), []).append(r)
    widths = sorted({r["width"] for r in rows()})
    lines = ["| σ (m²/s) | model | " + " | ".join(f"b = {w:g}" for w in widths) + " | packing (disk) | (Voronoi) |",
             "|---" * (len(widths) + 4) + "|"]  # fmt: skip
    for (sigma, model, dt), rs in sorted(table.items(), key=lambda kv: (kv[0][0], MODELS.index(kv[0][1]), -kv[0][2])):
        name = model if dt == DT else f"{model}, dt = {dt:g} s"
        cells = []
        for w in widths:
            js = [r["specific_flow"] for r in rs if r["width"] == w]
            if not js:
                cells.append("")
            elif any(j is None for j in js):
                cells.append(f"not 90 % out ({sum(j is None for j in js)} of {len(js)})")
            elif len(js) == 1:
                cells.append(f"{js[0]:.2f}")
            else:
                cells.append(f"{np.median(js):.2f} ({min(js):.2f})")
        packs = [
            "—" if not values else f"{max(values):.1f}"
            for values in ([r.get(key) for r in rs if r.get(key) is not None] for key in ("packing", "packing_voronoi"))
        ]
        lines.append(f"| {sigma:g} | {name} | " + " | ".join(cells) + " | " + " | ".join(packs) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sigmas", type=float, nargs="+", default=[0.01, 0.05, 0.1])
    p.add_argument("--widths", type=float, nargs="+", default=[0.8, 1.0, 2.0, 2.5])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    p.add_argument("--dt", type=float, default=DT, help="the step, s (one that divides a second)")
    p.add_argument("--report", action="store_true", help="only print the table from the results")
    args = p.parse_args(argv)
    if not args.report:
        done = {(r["model"], r["width"], r["sigma"], r["seed"], r["dt"]) for r in rows()}
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        for sigma in args.sigmas:
            for model in args.models:
                for b in args.widths:
                    for seed in range(1 if model == "density" else args.seeds):
                        if (model, b, sigma, seed, args.dt) in done:
                            continue
                        row = one_run(b, model, sigma, seed, args.dt)
                        with RESULTS.open("a") as f:
                            f.write(json.dumps(row) + "\n")
                        print(f"σ={sigma:g} dt={args.dt:g} {model} b={b:g} seed={seed}: J/b={row['specific_flow']}",
                              flush=True)  # fmt: skip
    print(report())


if __name__ == "__main__":
    main()
