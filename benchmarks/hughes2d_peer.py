"""An independent peer for the density on Hughes' route: hughes2d (finite volumes on triangles, fast marching).

Run:  python benchmarks/hughes2d_peer.py [--ours 10,20,40] [--peer 0.12,0.06,0.03] [--sigma 0.01] [--json FILE]
(or ``meanfield bench --only hughes2d``, :mod:`benchmarks.bench_hughes2d`).

The problem, identical in both codes (issue 42, item 5):

* a room of 5 m × 4 m (:data:`ROOM`), walls everywhere but one door of 1 m in the middle of the east wall
  (:data:`DOOR`, ``x = 5``, ``1.5 <= y <= 2.5``);
* :data:`PERSONS` = 18 people, uniform in the block :data:`BLOCK` = [0.5, 3.5]² (2 persons/m², 0.37 of the jam
  density), nobody elsewhere;
* the linear diagram ``v(ρ) = v₀ (1 − ρ/ρ_max)``, ``v₀`` = 1.34 m/s, ``ρ_max`` = 5.4 persons/m² (the scenario's
  ``crowd.free_speed`` and ``crowd.rho_max``: the door's capacity ``v₀ ρ_max / 4`` = 1.809 persons/(m·s));
* Hughes' route: ``|∇T| = 1/max(v(ρ), 0.05 v₀)``, ``T = 0`` on the door, everyone walking down ``T``;
* measured: the times at which 10, 50 and 90 % of the people are out, and each code's wall time (set-up and the
  run until 90 % are out, on one core).

**Ours** (:func:`run_ours`): the toolkit as a user runs it, ``ClosedLoop`` of a scenario with
``crowd.kind = "fokker-planck"``, ``crowd.guidance = "hughes"``, ``crowd.congestion = "linear"``, the crowd as one
group in :data:`BLOCK` (``crowd.initial = "groups"``, each cell its share of the block), on square cells of
``1/cells_per_metre`` m.  The routes are planned again every control period, ``dt`` = :data:`PERIOD_PER_METRE` × the
cell (the ``bottleneck`` scenario's 0.05 s at 0.1 m): kept at 0.05 s on 0.025 m cells, the door passed
1.765 persons/s instead of its capacity and the 90 % time came 6 % later (the lanes of docs page *Congestion*,
"Routes").  The density has a diffusion σ (``crowd.sigma``, :data:`SIGMA` = 0.01 m²/s by default); hughes2d has
none.  Ours runs at σ = 0 too, but there its door passes less than its capacity on a coarse grid: the exit takes
the exit cell's drift (the mean of its faces), which Hughes' route bends towards the dense corners of the door
(``a_n/v₀`` = 0.83, 0.96, 0.99 in the three cells at each end), a deficit that halves with the cell (1.73, 1.77,
1.79 persons/s on 0.1, 0.05, 0.025 m cells, against 1.809); at σ > 0 the exit's diffusive outflow ``σρ/d`` fills
it up to the capacity.

**The peer** (:func:`run_peer`, hughes2d 1.1.8 by T. Girard, GPL-3.0, ``pip install hughes2d``, imported only
here): ``PedestrianSolver`` with ``model = "hughes"`` and its default options (mid-vector Godunov flux, fast
marching on triangles, constrained, narrow band 2), on the mesh ``triangle`` makes of the room with triangles of
at most ``max_area`` m² and angles of at least 30°, and its documented CFL step
``dt = min|T| / (3 max|e| Lip)``, ``Lip = v₀``.  hughes2d's density is normalised, ``0 <= ρ <= 1``
(``LWR2D.py``: every new density is clipped to [0, 1]), so the translation is

* its density ``ρ_h = ρ/ρ_max`` (persons/m² over the jam density), each triangle its exact share of the block
  (shapely), so that the mesh holds 18 persons to round-off;
* its ``speed_function(ρ_h) = v₀ (1 − ρ_h)`` (metres and seconds), flux ``ρ_h v₀ (1 − ρ_h)``;
* its ``cost_function(ρ_h) = 1/max(v₀ (1 − ρ_h), 0.05 v₀)``: its eikonal is ``|∇u| = c(ρ)``
  (``EikonalSolver.py``), our (R1) with the same floor;
* its exit: the edges on the door (``NonConvexDomain.add_exit``), ``u = 0`` on their vertices and, in the flux, an
  empty outside (``far_density = 0``): the door passes the demand ``f(min(ρ, ρ_c))`` times the cosine of the
  triangle's direction with the door's normal, at most the capacity, as ours (whose door passes
  ``min(a_n⁺ D(ρ) + σρ/d, q_max)`` per metre).

Nothing here changes either code; hughes2d's pure-Python loops (about 0.1 ms per triangle and step) are why the
room is small: the issue's 10 m × 8 m room with a 2 m door, 72 people and the same block scaled is this problem at
twice the scale (times doubled, σ doubled), and takes hughes2d 8 times as long per mesh size.
"""

from __future__ import annotations

import contextlib
import io
import math
import sys
import time
from typing import Any

import numpy as np

ROOM = (5.0, 4.0)
"""m: the room ``[0, 5] × [0, 4]``."""
DOOR = ((5.0, 1.5), (5.0, 2.5))
"""m: the door, 1 m in the middle of the east wall."""
BLOCK = (0.5, 0.5, 3.5, 3.5)
"""m: ``(x0, y0, x1, y1)``, where everyone starts, uniform."""
PERSONS = 18
"""People in the room at the start (2 persons/m² in :data:`BLOCK`)."""
SIGMA = 0.01
"""m²/s: our diffusion (hughes2d has none)."""
SHARES = (0.1, 0.5, 0.9)
"""The shares of the people out whose times are compared."""
TOLERANCE = 0.03
"""The criterion: each time within 3 % of hughes2d's."""
PERIOD_PER_METRE = 0.5
"""s/m: our control period (the routes planned again) over the cell: 0.05 s at 0.1 m, as the ``bottleneck``."""
T_MAX = 60.0
"""s: a run stops here if 90 % are not out (then it has no 90 % time)."""
SPEED_FLOOR = 0.05
"""``f_min / v₀`` of Hughes' cost; the toolkit's :data:`meanfield.crowds.crowd_routes.SPEED_FLOOR` (checked)."""

__all__ = [
    "ROOM",
    "DOOR",
    "BLOCK",
    "PERSONS",
    "SIGMA",
    "SHARES",
    "TOLERANCE",
    "scenario",
    "run_ours",
    "peer_missing",
    "peer_mesh",
    "peer_initial",
    "peer_functions",
    "peer_dt",
    "run_peer",
    "crossing_times",
    "compare",
]


def _polygon_wkt() -> str:
    w, h = ROOM
    return f"POLYGON ((0 0, {w:g} 0, {w:g} {h:g}, 0 {h:g}, 0 0))"


def _block_wkt() -> str:
    x0, y0, x1, y1 = BLOCK
    return f"POLYGON (({x0:g} {y0:g}, {x1:g} {y0:g}, {x1:g} {y1:g}, {x0:g} {y1:g}, {x0:g} {y0:g}))"


def door_width() -> float:
    """m: the door's width."""
    return math.dist(*DOOR)


def block_area() -> float:
    x0, y0, x1, y1 = BLOCK
    return (x1 - x0) * (y1 - y0)


# --------------------------------------------------------------------------------------------- ours
def scenario(cells_per_metre: int, sigma: float = SIGMA, period: float | None = None) -> Any:
    """The problem as a toolkit scenario: the density on Hughes' route with the linear diagram.

    Built on the ``bottleneck`` scenario (SI units, ``v₀`` = 1.34 m/s, ``ρ_max`` = 5.4 persons/m²) with the room,
    the door, the crowd and the grid replaced; ``period`` (s) defaults to :data:`PERIOD_PER_METRE` × the cell.
    One robot (the least a scenario takes) carries a static sign that the density does not follow.
    """
    from meanfield.scenarios.scenario import builtin_scenarios

    w, h = ROOM
    if period is None:
        period = PERIOD_PER_METRE / cells_per_metre
    values = {
        "domain.wkt": _polygon_wkt(),
        "domain.exits": [[list(DOOR[0]), list(DOOR[1])]],
        "grid.cells": [round(w * cells_per_metre), round(h * cells_per_metre)],
        "crowd.kind": "fokker-planck",
        "crowd.guidance": "hughes",
        "crowd.congestion": "linear",
        "crowd.sigma": float(sigma),
        "crowd.n": PERSONS,
        "crowd.initial": "groups",
        "crowd.groups": [{"n": PERSONS, "region": _block_wkt()}],
        "dt": float(period),
        "t_final": T_MAX,
        "robots.n": 1,
    }
    return builtin_scenarios()["bottleneck"](seed=0).with_values(values)


def crossing_times(times: np.ndarray, out: np.ndarray, shares: tuple[float, ...] = SHARES) -> list[float | None]:
    """When the share out (``out``, nondecreasing at ``times``) first reaches each share, linearly interpolated;
    None for a share never reached."""
    times, out = np.asarray(times, float), np.asarray(out, float)
    result: list[float | None] = []
    for level in shares:
        k = int(np.searchsorted(out, level, side="left"))
        if k >= len(out):
            result.append(None)
        elif k == 0 or out[k] == out[k - 1]:
            result.append(float(times[k]))
        else:
            frac = (level - out[k - 1]) / (out[k] - out[k - 1])
            result.append(float(times[k - 1] + frac * (times[k] - times[k - 1])))
    return result


def _door_flow(t: list[float | None]) -> float | None:
    """persons/s between 50 % and 90 % out."""
    if t[1] is None or t[2] is None or t[2] <= t[1]:
        return None
    return (SHARES[2] - SHARES[1]) * PERSONS / (t[2] - t[1])


def run_ours(cells_per_metre: int, sigma: float = SIGMA, period: float | None = None) -> dict[str, Any]:
    """Our density until 90 % are out (or :data:`T_MAX`): the times, the wall times, the grid.

    ``setup_time``: the scenario and ``ClosedLoop`` (the grid, the exits, the solver, the eikonal's set-up);
    ``wall_time``: every control period until 90 % are out (the routes planned, the solver's steps).
    """
    from meanfield.simulation.loop import ClosedLoop

    t0 = time.perf_counter()
    sc = scenario(cells_per_metre, sigma, period)
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    setup = time.perf_counter() - t0
    times, out = [0.0], [0.0]
    t1 = time.perf_counter()
    while out[-1] < SHARES[-1] and loop.t < T_MAX - 1e-9:
        loop.step()
        times.append(loop.t)
        out.append(float(crowd.out_per_exit.sum()) / crowd.initial_mass)
    wall = time.perf_counter() - t1
    g = crowd.grid
    t = crossing_times(np.array(times), np.array(out))
    persons = PERSONS * float(g.integrate(crowd.rho)) / crowd.initial_mass
    return {
        "code": "meanfield",
        "cells_per_metre": cells_per_metre,
        "cell": 1.0 / cells_per_metre,
        "cells": int(g.active.sum()),
        "grid": list(g.shape),
        "sigma": float(sigma),
        "period": float(sc.dt),
        "periods": len(times) - 1,
        "method": crowd.fp.method,
        "t": t,
        "door_flow": _door_flow(t),
        "capacity": float(crowd.fp.congestion.door * PERSONS * door_width()),
        "mass_error": abs(persons + PERSONS * out[-1] - PERSONS),
        "setup_time": setup,
        "wall_time": wall,
    }


# --------------------------------------------------------------------------------------------- the peer
def peer_missing() -> str | None:
    """Why hughes2d cannot run here, or None."""
    try:
        import hughes2d  # noqa: F401
        import triangle  # noqa: F401
    except Exception as exc:  # ImportError, or a broken install
        return f"{type(exc).__name__}: {exc}"
    return None


def _diagram() -> tuple[float, float]:
    """``(v₀, ρ_max)`` of our scenario, so that both codes take the same numbers."""
    from meanfield.crowds.crowd_routes import SPEED_FLOOR as ours

    if ours != SPEED_FLOOR:  # the cost below must be the toolkit's (R1)
        raise RuntimeError(f"meanfield's SPEED_FLOOR is {ours}, this peer takes {SPEED_FLOOR}")
    c = scenario(10).crowd
    return float(c.free_speed), float(c.rho_max)


def peer_functions(free_speed: float) -> tuple[Any, Any]:
    """hughes2d's ``speed_function`` and ``cost_function`` of the normalised density ``ρ_h = ρ/ρ_max``:
    ``v₀ (1 − ρ_h)`` and ``1/max(v₀ (1 − ρ_h), 0.05 v₀)``."""
    v0 = float(free_speed)
    floor = SPEED_FLOOR * v0

    def speed(r: float) -> float:
        return v0 * (1.0 - r)

    def cost(r: float) -> float:
        return 1.0 / max(v0 * (1.0 - r), floor)

    return speed, cost


def peer_mesh(max_area: float) -> Any:
    """hughes2d's mesh of the room: triangles of at most ``max_area`` m² (angles >= 30°), the door as its exit."""
    from hughes2d import Mesh, NonConvexDomain

    w, h = ROOM
    domain = NonConvexDomain([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    domain.add_exit([list(DOOR[0]), list(DOOR[1])])
    mesh = Mesh()
    mesh.generate_mesh_from_domain(domain, max_area)
    return mesh


def peer_initial(mesh: Any, rho_max: float) -> np.ndarray:
    """The normalised initial density on the triangles: ``(N/|B|)/ρ_max`` times each triangle's share of the
    block ``B`` (exact, by shapely), so that ``ρ_max Σ ρ_h |T|`` is :data:`PERSONS`."""
    import shapely

    corners = np.asarray(mesh.vertices, float)[np.asarray(mesh.triangles)]
    share = shapely.area(shapely.intersection(shapely.polygons(corners), shapely.box(*BLOCK)))
    return (PERSONS / block_area() / rho_max) * share / np.asarray(mesh.cell_areas, float)


def peer_dt(mesh: Any, free_speed: float) -> float:
    """hughes2d's documented CFL step ``min|T| / (3 max|e| Lip)`` with ``Lip = v₀`` (``LWRSolver.check_cfl``)."""
    return float(mesh.min_cell_area) / (3.0 * float(mesh.max_edge_length) * float(free_speed))


def run_peer(max_area: float) -> dict[str, Any]:
    """hughes2d until 90 % are out (or :data:`T_MAX`): the times, the wall times, the mesh.

    ``setup_time``: the mesh (``triangle`` and hughes2d's own tables) and the solver (its first eikonal);
    ``wall_time``: every step until 90 % are out.  What hughes2d prints is kept in ``printed``.
    """
    import hughes2d
    from hughes2d import CellValueMap, PedestrianSolver

    v0, rho_max = _diagram()
    speed, cost = peer_functions(v0)
    printed = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(printed):
        mesh = peer_mesh(max_area)
        dt = peer_dt(mesh, v0)
        rho0 = CellValueMap(mesh)
        rho0.values = peer_initial(mesh, rho_max).tolist()
        options = {  # hughes2d's defaults, written out (its module-level default dict is mutated in place)
            "model": "hughes",
            "save": False,
            "verbose": False,
            "lwrSolver": {"convexFlux": True, "anNum": "dichotomy", "method": "midVector",
                          "ApproximationThreshold": 0.0001},
            "eikoSolver": {"method": "FMT", "constrained": True, "NarrowBandDepth": 2},
        }  # fmt: skip
        solver = PedestrianSolver(mesh, dt, rho0, speed_function=speed, cost_function=cost, options=options)
    setup = time.perf_counter() - t0
    areas = np.asarray(mesh.cell_areas, float)
    mass0 = float(np.dot(solver.lwr_solver.densityt0, areas))
    times, out = [0.0], [0.0]
    steps = 0
    t1 = time.perf_counter()
    with contextlib.redirect_stdout(printed):
        while out[-1] < SHARES[-1] and steps * dt < T_MAX - 1e-9:
            solver.compute_step()
            steps += 1
            times.append(steps * dt)
            out.append(1.0 - float(np.dot(solver.lwr_solver.densityt0, areas)) / mass0)
    wall = time.perf_counter() - t1
    t = crossing_times(np.array(times), np.array(out))
    rho = np.asarray(solver.lwr_solver.densityt0, float)
    return {
        "code": "hughes2d",
        "version": getattr(hughes2d, "__version__", "?"),
        "max_area": float(max_area),
        "triangles": len(mesh.triangles),
        "vertices": len(mesh.vertices),
        "min_area": float(mesh.min_cell_area),
        "max_edge": float(mesh.max_edge_length),
        "dt": dt,
        "steps": steps,
        "persons_at_start": mass0 * rho_max,
        "t": t,
        "door_flow": _door_flow(t),
        "max_density": float(rho.max()) * rho_max,
        "printed": printed.getvalue()[-2000:],
        "setup_time": setup,
        "wall_time": wall,
    }


# --------------------------------------------------------------------------------------------- the comparison
def relative(ours: list[float | None], peer: list[float | None]) -> list[float | None]:
    """``(ours − peer)/peer`` per share (None where either is missing)."""
    return [None if a is None or b is None else (a - b) / b for a, b in zip(ours, peer, strict=True)]


def agrees(ours: dict[str, Any], peer: dict[str, Any]) -> bool:
    """Every time within :data:`TOLERANCE` of hughes2d's (a missing time fails)."""
    return all(r is not None and abs(r) <= TOLERANCE for r in relative(ours["t"], peer["t"]))


def compare(
    ours_levels: list[int],
    peer_levels: list[float],
    sigma: float = SIGMA,
    sigmas: list[float] | None = None,
    sigma_level: int | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Both refinement series, the verdict on the finest of each, and our times at other σ.

    Parameters
    ----------
    ours_levels : list of int
        Our cells per metre, coarse to fine.
    peer_levels : list of float
        hughes2d's largest triangle area (m²), coarse to fine.
    sigma : float
        Our σ of the series (m²/s).
    sigmas : list of float, optional
        Other σ to run ours at, on ``sigma_level`` cells per metre (the second of ``ours_levels`` by default).
    """

    def say(text: str) -> None:
        if progress:
            print(text, file=sys.stderr, flush=True)

    why = peer_missing()
    ours: list[dict[str, Any]] = []
    for n in ours_levels:
        if not ours:  # warm-up: this process loads our compiled loops (numba's cache), untimed
            _warm_up(n, sigma)
        ours.append(run_ours(n, sigma))
        say(f"ours {n} cells/m: t = {_fmt(ours[-1]['t'])}, {ours[-1]['setup_time'] + ours[-1]['wall_time']:.1f} s")
    peer: list[dict[str, Any]] = []
    if why is None:
        for a in peer_levels:
            peer.append(run_peer(a))
            say(f"hughes2d {a:g} m²: t = {_fmt(peer[-1]['t'])}, {peer[-1]['setup_time'] + peer[-1]['wall_time']:.1f} s")
    others = []
    if sigmas:
        level = sigma_level if sigma_level is not None else ours_levels[min(1, len(ours_levels) - 1)]
        for s in sigmas:
            others.append(run_ours(level, s))
            say(f"ours {level} cells/m, sigma {s:g}: t = {_fmt(others[-1]['t'])}")
    doc: dict[str, Any] = {"ours": ours, "peer": peer, "sigma": sigma, "sigmas": others, "peer_missing": why}
    if peer:
        doc["relative_finest"] = relative(ours[-1]["t"], peer[-1]["t"])
        doc["agrees"] = agrees(ours[-1], peer[-1])
    return doc


def _warm_up(cells_per_metre: int, sigma: float) -> None:
    from meanfield.simulation.loop import ClosedLoop

    loop = ClosedLoop(scenario(cells_per_metre, sigma))
    for _ in range(3):
        loop.step()


def _fmt(t: list[float | None]) -> str:
    return " / ".join("-" if x is None else f"{x:.3f}" for x in t)


def _pct(r: float | None) -> str:
    return "-" if r is None else f"{100 * r:+.1f} %"


def table(doc: dict[str, Any]) -> str:
    """The Markdown tables of :func:`compare`: both series, and ours at other σ."""
    lines = [
        "| code | resolution | cells | t10 (s) | t50 (s) | t90 (s) | door flow 50–90 % (persons/s) "
        "| set-up (s) | run (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for o in doc["ours"]:
        lines.append(
            f"| meanfield, σ = {o['sigma']:g} | {o['cell']:g} m cells, period {o['period']:g} s | {o['cells']} | "
            + " | ".join("-" if x is None else f"{x:.3f}" for x in o["t"])
            + f" | {_num(o['door_flow'])} | {o['setup_time']:.2f} | {o['wall_time']:.1f} |"
        )
    for p in doc["peer"]:
        lines.append(
            f"| hughes2d | triangles ≤ {p['max_area']:g} m², dt {p['dt']:.4f} s | {p['triangles']} | "
            + " | ".join("-" if x is None else f"{x:.3f}" for x in p["t"])
            + f" | {_num(p['door_flow'])} | {p['setup_time']:.2f} | {p['wall_time']:.1f} |"
        )
    if doc.get("peer"):
        rel = doc["relative_finest"]
        verdict = "PASS" if doc["agrees"] else "FAIL"
        lines.append("")
        lines.append(
            f"finest of each, (ours − hughes2d)/hughes2d: t10 {_pct(rel[0])}, t50 {_pct(rel[1])}, t90 {_pct(rel[2])}: "
            f"{verdict} (each within {100 * TOLERANCE:g} %)"
        )
    else:
        lines.append(f"\nhughes2d not available ({doc['peer_missing']}): install it with `pip install hughes2d`")
    if doc.get("sigmas"):
        finest = doc["peer"][-1]["t"] if doc.get("peer") else None
        lines += [
            "",
            "| ours at | σ (m²/s) | t10 (s) | t50 (s) | t90 (s) | door flow (persons/s) | vs hughes2d's finest |",
        ]
        lines.append("|---|---|---|---|---|---|---|")
        level = doc["sigmas"][0]["cells_per_metre"]
        same_grid = [x for x in doc["ours"] if x["cells_per_metre"] == level]
        for o in sorted([*doc["sigmas"], *same_grid], key=lambda x: x["sigma"]):
            lines.append(
                f"| {o['cell']:g} m cells | {o['sigma']:g} | "
                + " | ".join("-" if x is None else f"{x:.3f}" for x in o["t"])
                + f" | {_num(o['door_flow'])} | "
                + ("-" if finest is None else ", ".join(_pct(r) for r in relative(o["t"], finest)))
                + " |"
            )
    return "\n".join(lines)


def _num(x: float | None) -> str:
    return "-" if x is None else f"{x:.3f}"


def main(argv: list[str] | None = None) -> int:
    import argparse
    import json

    from benchmarks.environment import one_thread_variables

    one_thread_variables()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ours", default="10,20,40", help="our cells per metre, coarse to fine")
    ap.add_argument("--peer", default="0.12,0.06,0.03", help="hughes2d's largest triangle (m²), coarse to fine")
    ap.add_argument("--sigma", type=float, default=SIGMA, help="our diffusion (m²/s)")
    ap.add_argument("--sigmas", default="0.005,0.02", help="other σ for ours, on the second grid ('' for none)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    ours = [int(s) for s in a.ours.split(",") if s]
    peer = [float(s) for s in a.peer.split(",") if s]
    sigmas = [float(s) for s in a.sigmas.split(",") if s]
    doc = compare(ours, peer, a.sigma, sigmas, progress=True)
    print(table(doc))
    if a.json:
        from pathlib import Path

        from meanfield.io.atomic import atomic_write_json

        atomic_write_json(Path(a.json), json.loads(json.dumps(doc, default=float)))
    return 0 if not doc["peer"] or doc["agrees"] else 1


if __name__ == "__main__":
    sys.exit(main())
