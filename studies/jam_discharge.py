"""A jam let go: the flow through the jam's front in a straight corridor, against its exact value ``q_max``.

Run from the repository's root::

    python studies/jam_discharge.py [--widths 1 2 4 6] [--sigmas 0.01 0.05 0.1] [--seeds 10] [--dt 0.05]
    python studies/jam_discharge.py --report     # only the table, from studies/results/jam_discharge.jsonl

**The exact answer.**  A corridor ``w`` wide holds a jam at :data:`RHO_JAM` = 4.5 persons/m² over its first
:data:`JAM_LENGTH` = 20 m and nobody beyond; everyone walks east, to an exit 30 m past the jam's front.  Under
the Lighthill–Whitham–Richards law ``∂ₜρ + ∂ₓ(ρ v₀ g(ρ)) = 0`` this is a Riemann problem whose solution is a
centred rarefaction (the left state above the critical density ``ρ_c``): at the jam's initial front the
density is ``ρ_c`` at every ``t > 0``, so the flow through it is the diagram's capacity ``q_max`` per metre of
width (1.81 persons/(m·s) for the linear diagram, ``v₀ ρ_max / 4``), whatever the width, until the fan's back
reaches the corridor's end (``20 m / |f'(4.5)|`` = 22 s) or its front the exit (22 s).  The width has no part
in it: the law has no length scale across the corridor.  The density (``crowd.kind = "fokker-planck"``,
Godunov's flux) reads it at every width; the point masses' headway model (docs page *Congestion*, "The headway
door model") is meant to be its particle twin, so its flow through the front should read the same.

**Measured:** the number of people past the jam's front (or out) against time, the least-squares slope over
:data:`WINDOW` (5 s to 15 s, after the random start has settled), over the width.  Each run is the built-in
``bottleneck`` scenario's crowd, diagram and step with the corridor in place of its room (the informed crowd on
the shortest route, which is straight east), placed uniform at random in the jam; the density's run is one
(it is deterministic), on 0.2 m cells.  Each run is a line of ``studies/results/jam_discharge.jsonl``, appended
as it finishes (an interrupted study resumes).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = Path("studies/results/jam_discharge.jsonl")
RHO_JAM = 4.5
"""persons/m²: the jam's density (above the linear diagram's ρ_c = 2.7, below its ρ_max = 5.4)."""
JAM_LENGTH = 20.0
"""m: the jam's length; the exit is :data:`RUN_OUT` m beyond its front."""
RUN_OUT = 30.0
WINDOW = (5.0, 15.0)
"""s: the flow's window."""
CELL = 0.2
"""m: the cells (the routes' for the agents, the density's)."""
KINDS = ("point-mass", "fokker-planck")
DOOR_MODELS = ("headway", "forward-cell")
"""The point masses' door models the study runs (``--door-models``)."""


def scenario(width: float, sigma: float, kind: str, seed: int, dt: float, door_model: str = "headway") -> Any:
    """The corridor ``width`` m wide with the jam over its first :data:`JAM_LENGTH` m (module docstring)."""
    from meanfield.scenarios.scenario import builtin_scenarios

    total = JAM_LENGTH + RUN_OUT
    n = round(RHO_JAM * JAM_LENGTH * width)
    jam = f"POLYGON ((0 0, {JAM_LENGTH:g} 0, {JAM_LENGTH:g} {width:g}, 0 {width:g}, 0 0))"
    values: dict[str, Any] = {
        "domain.wkt": f"POLYGON ((0 0, {total:g} 0, {total:g} {width:g}, 0 {width:g}, 0 0))",
        "domain.exits": [[[total, 0.0], [total, width]]],
        "grid.cells": [round(total / CELL), max(round(width / CELL), 5)],
        "crowd.kind": kind,
        "crowd.n": n,
        "crowd.initial": "groups",
        "crowd.groups": [{"region": jam, "n": n}],
        "crowd.guidance": "geodesic",
        "crowd.sigma": sigma,
        "target.center": [total, width / 2],
        "t_final": WINDOW[1],
        "dt": dt,
    }
    if kind == "point-mass":
        values["crowd.door_model"] = door_model
    return builtin_scenarios()["bottleneck"](seed=seed).with_values(values)


def past_front(loop: Any) -> float:
    """People past the jam's front or out of the corridor (the density's: its mass there, in persons)."""
    crowd = loop.crowd
    if getattr(crowd, "positions", None) is not None:
        x = crowd.positions[:, 0]
        return float(np.count_nonzero(~np.isfinite(x) | (x > JAM_LENGTH)))
    g = crowd.grid
    beyond = float(g.integrate(np.where(g.centers[0] > JAM_LENGTH, crowd.rho, 0.0))) / crowd.initial_mass
    return crowd.people * (beyond + 1.0 - crowd.remaining_fraction())


def one_run(width: float, sigma: float, kind: str, seed: int, dt: float, door_model: str = "headway") -> dict[str, Any]:
    """The flow per metre through the jam's front over :data:`WINDOW`, persons/(m·s) (the point masses with the
    door model ``door_model``)."""
    from meanfield.simulation.loop import ClosedLoop

    start = time.perf_counter()
    sc = scenario(width, sigma, kind, seed, dt, door_model)
    loop = ClosedLoop(sc)
    times, past = [], []
    while loop.t < WINDOW[1] - 1e-9:
        loop.step()
        times.append(loop.t)
        past.append(past_front(loop))
    t, p = np.asarray(times), np.asarray(past)
    inside = (t >= WINDOW[0] - 1e-9) & (t <= WINDOW[1] + 1e-9)
    flow = float(np.polyfit(t[inside], p[inside], 1)[0])
    q_max = sc.crowd.free_speed * sc.crowd.rho_max / 4.0
    model = {"door_model": door_model} if kind == "point-mass" else {}
    return {"width": width, "sigma": sigma, "kind": kind, **model, "seed": seed, "dt": dt, "people": sc.crowd.n,
            "flow_per_m": flow / width, "q_max": q_max, "wall_seconds": time.perf_counter() - start}  # fmt: skip


def rows() -> list[dict[str, Any]]:
    """The results so far (a point-mass row without ``door_model`` was run with the headway model)."""
    if not RESULTS.exists():
        return []
    out = [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]
    for r in out:
        if r["kind"] == "point-mass":
            r.setdefault("door_model", "headway")
    return out


def report(dt: float = 0.05) -> str:
    """The docs' table: the agents' median (lowest, highest seed) and the density's flow per metre, per width and
    σ, at the step ``dt``."""
    rs = [r for r in rows() if r["dt"] == dt]
    widths = sorted({r["width"] for r in rs})
    lines = ["| σ (m²/s) | crowd | " + " | ".join(f"w = {w:g} m" for w in widths) + " |",
             "|---" * (len(widths) + 2) + "|"]  # fmt: skip
    for sigma in sorted({r["sigma"] for r in rs}):
        crowds = [(m, f"agents ({m})") for m in DOOR_MODELS if any(r.get("door_model") == m for r in rs)]
        for model, label in [*crowds, (None, "density")]:
            cells = []
            for w in widths:
                got = [r["flow_per_m"] for r in rs
                       if r.get("door_model") == model and r["sigma"] == sigma and r["width"] == w]  # fmt: skip
                if not got:
                    cells.append("—")
                elif len(got) == 1:
                    cells.append(f"{got[0]:.2f}")
                else:
                    cells.append(f"{np.median(got):.2f} ({min(got):.2f}–{max(got):.2f}, {len(got)} seeds)")
            lines.append(f"| {sigma:g} | {label} | " + " | ".join(cells) + " |")
    q_max = {round(r["q_max"], 3) for r in rs}
    lines.append(f"\nThe exact flow, q_max: {', '.join(f'{q:.3f}' for q in sorted(q_max))} persons/(m·s).")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--widths", type=float, nargs="+", default=[1.0, 2.0, 4.0, 6.0], help="m")
    p.add_argument("--sigmas", type=float, nargs="+", default=[0.01, 0.05, 0.1], help="m²/s")
    p.add_argument("--seeds", type=int, default=10, help="the agents' seeds 0 … N−1")
    p.add_argument("--dt", type=float, default=0.05, help="s: the step")
    p.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    p.add_argument("--door-models", nargs="+", default=list(DOOR_MODELS), choices=DOOR_MODELS,
                   help="the point masses' door models")  # fmt: skip
    p.add_argument("--report", action="store_true", help="only print the table from the results")
    args = p.parse_args(argv)
    if not args.report:
        done = {(r["kind"], r.get("door_model"), r["width"], r["sigma"], r["seed"], r["dt"]) for r in rows()}
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        for sigma in args.sigmas:
            for width in args.widths:
                runs = [("point-mass", m) for m in args.door_models if "point-mass" in args.kinds]
                runs += [("fokker-planck", None)] if "fokker-planck" in args.kinds else []
                for kind, model in runs:
                    for seed in range(args.seeds if kind == "point-mass" else 1):
                        if (kind, model, width, sigma, seed, args.dt) in done:
                            continue
                        row = one_run(width, sigma, kind, seed, args.dt, model or "headway")
                        with RESULTS.open("a") as f:
                            f.write(json.dumps(row) + "\n")
                        flow, wall = row["flow_per_m"], row["wall_seconds"]
                        label = f"{model or kind} w={width:g} σ={sigma:g} seed={seed} dt={args.dt:g}"
                        print(f"{label}: {flow:.3f} persons/(m·s) ({wall:.0f} s)", flush=True)
    print(report(args.dt))


if __name__ == "__main__":
    main()
