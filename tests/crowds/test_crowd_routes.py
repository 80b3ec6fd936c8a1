"""Routes the crowd shapes (meanfield.crowds.crowd_routes): Hughes' travel time through the crowd, per exit basin.

Exact answers: the disk mean of a uniform crowd is that crowd's density, beside walls too; the face field
interpolated at a point reproduces a uniform field; in an empty room the route is the geodesic one to
round-off; the speed is the diagram floored; the density on the fastest route passes a door at the linear
diagram's capacity ``v₀ ρ_max / 4`` per metre, at every width (docs page *Congestion*, "Routes").
"""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario
from meanfield.crowds.congestion import Linear
from meanfield.crowds.crowd_routes import SPEED_FLOOR, CrowdRoutes, disk_mean_density, face_velocity_at, route_velocity
from meanfield.crowds.guidance import DensityGuidance
from meanfield.geometry.domain import Domain
from meanfield.geometry.exits import distance_to_segments, exit_segments
from meanfield.geometry.geodesic import exit_distance
from meanfield.geometry.grid import Grid
from meanfield.geometry.plan import Plan

SPEED, JAM = 1.34, 5.4
CAPACITY = SPEED * JAM / 4  # the linear diagram's largest flow, persons/(m·s)


def _linear() -> Linear:
    return Linear(free_speed=SPEED, rho_max=JAM)


def _bottleneck_plan(b: float = 1.0, room: float = 10.0, height: float = 8.0, corridor: float = 2.0) -> Plan:
    lo, hi = height / 2 - b / 2, height / 2 + b / 2
    x1 = room + corridor
    plan = Plan.from_wkt(
        f"POLYGON ((0 0, {room} 0, {room} {lo}, {x1} {lo}, {x1} {hi}, {room} {hi}, {room} {height}, 0 {height}, 0 0))"
    )
    return Plan(plan.polygon, [((x1, lo), (x1, hi))])


def _faces_apart(a, b) -> float:
    return max(float(np.abs(a[k] - b[k]).max()) for k in range(2))


# ---------------------------------------------------------------------------------------------- (R2), the faces


def test_the_disk_mean_of_a_uniform_crowd_is_its_density_beside_walls_and_in_cut_cells():
    """Persons ``c |c ∩ Ω|`` in every cell: the disk mean is ``c`` on every active cell, the bottleneck's cut
    corners and the cells against its walls included (the disk's area is counted in Ω)."""
    grid = Grid(Plan.from_wkt("POLYGON ((0 0, 4 0, 4 1.55, 5 1.55, 5 2.45, 4 2.45, 4 4, 0 4, 0 0))"), (50, 40))
    assert (grid.volume_fraction[grid.active] < 1).any()  # cut cells
    for radius in (0.1, 0.35, 0.5):
        rho = disk_mean_density(grid, 2.5 * grid.volume, radius)
        np.testing.assert_allclose(rho[grid.active], 2.5, rtol=1e-12)
        assert (rho[~grid.active] == 0).all()
    one = np.zeros(grid.shape)
    one[10, 10] = 1.0  # one person: 1 over the disk's cells' area (13 cells of 0.01 m² within 0.2 m)
    rho = disk_mean_density(grid, one, 0.2)
    assert rho[10, 10] == pytest.approx(1.0 / (13 * 0.01), rel=1e-12)
    with pytest.raises(ParameterError) as exc:
        disk_mean_density(grid, one, 0.0)
    assert exc.value.name == "crowd.congestion_radius"


def test_the_face_field_at_a_point_reproduces_a_uniform_field_and_each_face():
    grid = Grid(Domain.box(3.0, 2.0), (30, 20))
    nx, ny = grid.shape
    uniform = (np.full((nx - 1, ny), 0.7), np.full((nx, ny - 1), -0.3))
    rng = np.random.default_rng(0)
    inside = rng.uniform([0.15, 0.15], [2.85, 1.85], (200, 2))  # away from the walls' faces, which carry 0
    np.testing.assert_allclose(face_velocity_at(grid, uniform, inside), [[0.7, -0.3]] * 200, rtol=1e-13)
    field = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
    i, j = 7, 4  # the x-face between cells (7, 4) and (8, 4), and the y-face between (7, 4) and (7, 5)
    at_x_face = np.array([[grid.x_faces[i], grid.y[j]]])
    at_y_face = np.array([[grid.x[i], grid.y_faces[j]]])
    assert face_velocity_at(grid, field, at_x_face)[0, 0] == pytest.approx(field[0][i, j], rel=1e-12)
    assert face_velocity_at(grid, field, at_y_face)[0, 1] == pytest.approx(field[1][i, j], rel=1e-12)


# ---------------------------------------------------------------------------------------------- (R1)


@pytest.mark.parametrize("keep_exit", [False, True])
def test_in_an_empty_room_the_route_is_the_geodesic_route(keep_exit):
    """``ρ̄ = 0``: ``f̂ = v₀`` on every cell, and a march of a constant speed is exactly the distance over it, so
    the drift is the geodesic one to round-off, round the bottleneck's corners included (one exit: its basin is
    the whole plan)."""
    plan = _bottleneck_plan()
    grid = Grid(plan, (60, 40))
    segs = exit_segments(plan)
    routes = CrowdRoutes(grid, segs, _linear(), keep_exit)
    empty = np.zeros(grid.shape)
    np.testing.assert_array_equal(routes.speed(empty)[grid.active], SPEED)
    dist = exit_distance(grid, segs)
    phi = routes.travel_time(empty, 0 if keep_exit else None)
    np.testing.assert_allclose(SPEED * phi[grid.active], dist[grid.active], rtol=1e-13)
    routes.plan(empty)
    assert _faces_apart(routes.density_velocity(), route_velocity(grid, dist, SPEED)) < 1e-12


def test_at_a_small_density_the_route_is_the_geodesic_route_to_fast_marching_accuracy():
    """A room 6 m × 4 m with a 1 m door, a crowd of at most 10⁻⁴ persons/m² (``g`` ≥ 1 − 2·10⁻⁵, not constant):
    the travel time times ``v₀`` and the drift are the geodesic ones to within the fast march's own error, that
    is the geodesic route's distance from the exact one (the straight line to the door in a convex room)."""
    room = Domain.box(6.0, 4.0, exits=[((6.0, 1.5), (6.0, 2.5))])
    grid = Grid(room, (60, 40))
    segs = exit_segments(room)
    X, Y = grid.centers
    exact = distance_to_segments(np.column_stack([X.ravel(), Y.ravel()]), segs).min(axis=1).reshape(grid.shape)
    dist = exit_distance(grid, segs)
    geodesic = route_velocity(grid, dist, SPEED)
    march_error = float(np.abs(dist - exact)[grid.active].max())  # measured 0.040 h
    route_error = _faces_apart(geodesic, route_velocity(grid, exact, SPEED))  # measured 0.036 m/s
    rho = 1e-4 * np.exp(-((X - 2.0) ** 2 + (Y - 2.0) ** 2) / 2.0)
    routes = CrowdRoutes(grid, segs, _linear(), keep_exit=False)
    speed = routes.speed(rho)[grid.active]
    assert speed.min() < speed.max()  # the speed is not constant: a march of its own
    phi = SPEED * routes.travel_time(rho)
    assert np.abs(phi - dist)[grid.active].max() <= march_error  # measured 0.018 h
    routes.plan(rho)
    assert _faces_apart(routes.density_velocity(), geodesic) <= route_error  # measured 0.017 m/s


def test_the_speed_is_the_diagram_floored():
    """``f̂ = max(v₀ g(ρ̄), f_min)`` on the cells: 0.05 v₀ at and beyond the jam density, ``v₀ g`` above the floor."""
    room = Domain.box(2.0, 1.0, exits=[((2.0, 0.0), (2.0, 1.0))])
    grid = Grid(room, (4, 2))
    routes = CrowdRoutes(grid, exit_segments(room), _linear(), keep_exit=False)
    persons = np.array([[0.0, 1.08], [2.7, 5.13], [5.4, 6.0], [5.4, 5.3]])  # per m²
    floor = SPEED_FLOOR * SPEED
    expected = [[SPEED, 0.8 * SPEED], [0.5 * SPEED, floor], [floor, floor], [floor, floor]]  # g(5.13) = 0.05
    np.testing.assert_allclose(routes.speed(persons), expected, rtol=1e-12)
    from meanfield.controllers.evacuation import SPEED_FLOOR as CONTROLLER_FLOOR

    assert SPEED_FLOOR == CONTROLLER_FLOOR  # the evacuation controller's Hughes potential takes the same floor


def test_a_route_stays_in_its_exit_s_basin_and_hughes_crosses_to_the_emptier_door():
    """A room 12 m × 4 m with a door in the middle of each end wall, jammed (5 persons/m²) on 4 m in front of
    the east door.  From a point 1 m east of the middle (the east door's basin) ``fastest-route`` still leads
    east, to the exit it keeps; Hughes' route, the travel time to any exit, leads west, round the queue."""
    length, width = 12.0, 4.0
    room = Domain.box(length, width, exits=[((0.0, 1.5), (0.0, 2.5)), ((length, 1.5), (length, 2.5))])
    grid = Grid(room, (60, 20))
    segs = exit_segments(room)
    X, _ = grid.centers
    jam = np.where(X > length - 4.0, 5.0, 0.0)
    point = np.array([[length / 2 + 1.0, width / 2]])
    keep = CrowdRoutes(grid, segs, _linear(), keep_exit=True)
    np.testing.assert_array_equal(keep.basin[grid.active], np.where(X[grid.active] < length / 2, 0, 1))
    keep.plan(jam)
    assert keep.headings(point, np.array([1]))[0, 0] > 0.99  # east, to its own exit
    assert keep.headings(point, np.array([0]))[0, 0] < -0.99  # the west door's people walk west
    hughes = CrowdRoutes(grid, segs, _linear(), keep_exit=False)
    hughes.plan(jam)
    assert hughes.headings(point)[0, 0] < -0.99  # west, round the queue
    with pytest.raises(ParameterError) as exc:
        keep.travel_time(jam)
    assert exc.value.name == "exit"
    with pytest.raises(ParameterError) as exc:
        hughes.travel_time(jam, 0)
    assert exc.value.name == "exit"


# ---------------------------------------------------------------------------------------------- the crowds


def _small_bottleneck(guidance: str, b: float, kind: str = "fokker-planck", n: int = 60, **extra):
    """A room 4 m × 4 m with a corridor 1 m long and ``b`` wide, ``n`` people uniform in the room, σ = 0.01 m²/s."""
    plan = _bottleneck_plan(b, room=4.0, height=4.0, corridor=1.0)
    sc = paper_scenario(seed=0).replace(domain=plan, units="SI", dt=0.05, t_final=60.0)
    values = {
        "grid.cells": [50, 40],
        "crowd.kind": kind,
        "crowd.n": n,
        "crowd.sigma": 0.01,
        "crowd.guidance": guidance,
        "crowd.congestion": "linear",
        "crowd.initial": "groups",
        "crowd.groups": [{"region": "POLYGON ((0 0, 4 0, 4 4, 0 4, 0 0))", "n": n}],
        "robots.n": 1,
        "controller.kind": "static-signs",
        "target.center": [2.0, 2.0],
        "target.std": 1.0,
        **extra,
    }
    return sc.with_values(values)


def _density_flow(sc) -> float | None:
    """``(N₉₀ − N₁₀) / (t₉₀ − t₁₀)`` of the density, persons/s (None: 90 % not out by ``t_final``)."""
    loop = ClosedLoop(sc)
    n = sc.crowd.n
    times, out = [0.0], [0.0]
    while loop.t < sc.t_final - 1e-9 and out[-1] < 0.9 * n:
        loop.step()
        times.append(loop.t)
        out.append(n * float(loop.crowd.out_per_exit.sum()) / loop.crowd.initial_mass)
    times, out = np.array(times), np.array(out)
    if out[-1] < 0.9 * n:
        return None
    t10, t90 = (float(np.interp(q * n, out, times)) for q in (0.1, 0.9))
    return 0.8 * n / (t90 - t10)


def test_the_density_on_the_fastest_route_passes_the_door_at_the_diagram_s_capacity_at_every_width():
    """The Godunov flux passes at most ``v₀ ρ_max / 4`` per metre of door (1.809 persons/(m·s)).  On the fastest
    route the crowd spreads across the door and passes that capacity at 0.8 m and at 1.6 m; on the shortest
    route it piles at the corridor's corners and passes far less (measured: 1.808 and 1.800 against no 90 % out
    in 60 s and 0.73)."""
    for b in (0.8, 1.6):
        fastest = _density_flow(_small_bottleneck("fastest-route", b)) / b
        shortest = _density_flow(_small_bottleneck("geodesic", b))
        assert 0.98 * CAPACITY <= fastest <= CAPACITY * (1 + 1e-9), (b, fastest)
        assert shortest is None or shortest / b < 0.5 * CAPACITY, (b, shortest)


def test_the_agents_take_the_routes_and_keep_their_exit():
    """60 point masses in a room with two doors, the crowd on the east side: on ``fastest-route`` everyone leaves by
    the exit nearest where they started, on ``hughes`` some of the east side's people go round the east queue to
    the west door; the agents' heading is the route's face field at their point, normalised."""
    length, width = 12.0, 4.0
    room = Domain.box(length, width, exits=[((0.0, 1.5), (0.0, 2.5)), ((length, 1.5), (length, 2.5))])
    sc = paper_scenario(seed=0).replace(domain=room, units="SI", dt=0.05, t_final=40.0)
    sc = sc.with_values(
        {
            "grid.cells": [60, 20],
            "crowd.kind": "point-mass",
            "crowd.n": 60,
            "crowd.sigma": 0.01,
            "crowd.congestion": "linear",
            "crowd.initial": "gaussian",
            "crowd.initial_center": [length / 2 + 1.5, width / 2],
            "crowd.initial_std": 1.5,
            "robots.n": 1,
            "controller.kind": "static-signs",
            "target.center": [length / 2, width / 2],
            "target.std": 1.0,
        }
    )
    west = {}
    for guidance in ("fastest-route", "hughes"):
        loop = ClosedLoop(sc.with_values({"crowd.guidance": guidance}))
        crowd = loop.crowd
        g = crowd.guidance
        start = crowd.positions.copy()
        loop.step()
        heading = g.routes.headings(crowd.positions, g.exit_of)
        w = face_velocity_at(loop.grid, g.routes.faces[0] if guidance == "hughes" else g.routes.faces[1],
                             crowd.positions)  # fmt: skip
        if guidance == "hughes":
            expected = w / np.hypot(w[:, 0], w[:, 1])[:, None]
            np.testing.assert_allclose(heading, expected, rtol=1e-12)
        else:
            east = g.exit_of == 1
            expected = w[east] / np.hypot(w[east, 0], w[east, 1])[:, None]
            np.testing.assert_allclose(heading[east], expected, rtol=1e-12)
        loop.run(progress=False)
        engine = crowd.engine
        assert not engine.active.any()  # everyone out by 40 s
        west[guidance] = int((engine.exit_index == 0).sum())
        if guidance == "fastest-route":
            np.testing.assert_array_equal(engine.exit_index, np.where(start[:, 0] < length / 2, 0, 1))
    assert west["hughes"] > west["fastest-route"]


def test_hughes_and_the_fastest_route_need_exits_and_the_density_guidance_refuses_two_drifts():
    for guidance in ("hughes", "fastest-route"):
        for kind in ("fokker-planck", "point-mass"):
            with pytest.raises(ParameterError) as exc:
                ClosedLoop(paper_scenario(seed=0).with_values({"crowd.guidance": guidance}), crowd=kind)
            assert exc.value.name == "crowd.guidance" and exc.value.value == guidance
    ones = (np.zeros((2, 1)), np.zeros((1, 2)))
    with pytest.raises(ParameterError) as exc:
        DensityGuidance(velocity=ones, velocity_of=lambda rho: ones)
    assert exc.value.name == "velocity_of"
    with pytest.raises(ParameterError) as exc:
        DensityGuidance(follows_signs=True, velocity_of=lambda rho: ones)
    assert exc.value.name == "velocity_of"
