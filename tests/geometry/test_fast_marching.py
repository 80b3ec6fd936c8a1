"""The eikonal distance to the exits by fast marching, and the routes down it (issue 30, item 5).

Exact answers: a whole wall as the exit, the Euclidean distance to a small door in every
direction (where the 8-neighbour Dijkstra metric the toolkit used before was 8 % long) and to a
slanted exit on cut cells, the straight line to the corner of an L and on, a door one cell wide,
a corridor of two speeds, and the walked route.  Each bound is the measured error, rounded up.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from meanfield import Domain, Grid, ParameterError
from meanfield.geometry import geodesic
from meanfield.geometry.exits import ExitSink, distance_to_segments, exit_segments
from meanfield.geometry.geodesic import ExitEikonal, ExitRoutes, exit_distance
from meanfield.geometry.plan import Plan

DOOR = Domain.box(2.0, 2.0, exits=[((2.0, 0.95), (2.0, 1.05))])  # a 0.1 m door in the middle of the east wall
L_PLAN = Plan(Plan.from_wkt("POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0))").polygon, [((1, 0), (1, 0.4))])


def _euclidean(grid: Grid, segs: np.ndarray) -> np.ndarray:
    X, Y = grid.centers
    return distance_to_segments(np.column_stack([X.ravel(), Y.ravel()]), segs).min(axis=1).reshape(grid.shape)


def _dijkstra_distance(grid: Grid, segs: np.ndarray) -> np.ndarray:
    """The toolkit's former φ: Dijkstra on the cells' 8-neighbour links, an exit cell starting at its centre's
    distance to the exit."""
    act = grid.active
    n = int(act.sum())
    index = -np.ones(grid.shape, dtype=np.int64)
    index[act] = np.arange(n)
    a, b, w = geodesic.cell_links(grid, index)
    X, Y = grid.centers
    src = np.flatnonzero((ExitSink(grid, segs, 1.0).total_rate > 0)[act])
    start = distance_to_segments(np.column_stack([X[act], Y[act]])[src], segs).min(axis=1)
    a, b, w = np.r_[a, np.full(len(src), n)], np.r_[b, src], np.r_[w, start]
    graph = coo_matrix((np.r_[w, w], (np.r_[a, b], np.r_[b, a])), shape=(n + 1, n + 1)).tocsr()
    out = np.full(grid.shape, np.inf)
    out[act] = dijkstra(graph, indices=n)[:n]
    return out


@pytest.mark.parametrize(
    ("exits", "exact"),
    [([((1.0, 0.0), (1.0, 0.5))], lambda X, Y: 1.0 - X), ([((0.0, 0.0), (1.0, 0.0))], lambda X, Y: Y)],
)
def test_a_whole_wall_as_the_exit_gives_the_distance_to_the_wall(exits, exact):
    box = Domain.box(1.0, 0.5, exits=exits)
    grid = Grid(box, (20, 10))
    X, Y = grid.centers
    np.testing.assert_allclose(exit_distance(grid, exit_segments(box)), exact(X, Y), rtol=0, atol=1e-13)


@pytest.mark.parametrize("n", [40, 80])
def test_a_small_door_is_the_euclidean_distance_in_every_direction(n):
    """Measured: within 0.040 h everywhere; beyond 5 cells at most 0.49 % long in every 15° sector, where the
    8-neighbour Dijkstra metric is 6.7 % to 8.2 % long (``1/cos 22.5° − 1``) in every sector."""
    grid = Grid(DOOR, (n, n))
    segs = exit_segments(DOOR)
    X, Y = grid.centers
    exact = _euclidean(grid, segs)
    phi = exit_distance(grid, segs)
    old = _dijkstra_distance(grid, segs)
    assert np.abs(phi - exact).max() <= 0.041 * grid.dx
    assert (phi >= exact * (1 - 2e-4)).all()
    bearing = np.degrees(np.arctan2(Y - 1.0, 2.0 - X))
    far = exact > 5 * grid.dx
    for start in range(-90, 90, 15):
        sector = far & (bearing >= start) & (bearing < start + 15)
        assert sector.sum() > 20
        assert (phi[sector] / exact[sector] - 1).max() <= 0.005, start
        assert (old[sector] / exact[sector] - 1).max() >= 0.067, start  # what fast marching removed
    assert (old / exact - 1).max() == pytest.approx(1 / math.cos(math.pi / 8) - 1, abs=1e-3)


PENTAGON = [(0.0, 0.0), (1.0, -0.1), (1.3, 0.6), (0.6, 1.1), (-0.2, 0.7)]


@pytest.mark.parametrize("edge", [0, 1, 2])
def test_a_slanted_exit_on_cut_cells_is_the_euclidean_distance(edge):
    """A convex pentagon, a whole slanted edge as the exit: the geodesic is the Euclidean distance.  Measured at the
    cells whose centre is in Ω (60 × 60): within −0.04 h and +0.26 h; Dijkstra was 2.7 h to 3.4 h long."""
    region = Domain.polygon(PENTAGON, exits=[(PENTAGON[edge], PENTAGON[edge + 1])])
    grid = Grid(region, (60, 60))
    segs = exit_segments(region)
    X, Y = grid.centers
    inside = grid.active & region.contains(X, Y)
    exact = _euclidean(grid, segs)
    err = (exit_distance(grid, segs) - exact)[inside]
    assert err.min() >= -0.05 * grid.dx and err.max() <= 0.27 * grid.dx
    assert (_dijkstra_distance(grid, segs) - exact)[inside].max() >= 2.7 * grid.dx


@pytest.mark.parametrize("n", [40, 80])
def test_the_distance_goes_round_the_corner_of_an_l_in_a_straight_line(n):
    """Behind the re-entrant corner c = (0.4, 0.4) every point's geodesic is |p − c| + 0.6 (the exit's top end is
    level with c).  Measured: within [−0.24 h, 0.022 h] of it (−0.7 % to +0.1 %); Dijkstra was 4.5 % long."""
    grid = Grid(L_PLAN, (n, n))
    segs = exit_segments(L_PLAN)
    X, Y = grid.centers
    hidden = grid.active & (X < 0.4) & (Y > 0.4)
    exact = np.hypot(0.4 - X, Y - 0.4) + 0.6
    phi = exit_distance(grid, segs)
    err = (phi - exact)[hidden]
    assert err.min() >= -0.25 * grid.dx and err.max() <= 0.025 * grid.dx
    assert np.abs(phi / exact - 1)[hidden].max() <= 0.007
    assert (_dijkstra_distance(grid, segs) / exact - 1)[hidden].max() >= 0.044
    seen = grid.active & (Y < 0.4)  # in sight of the exit: the Euclidean distance
    assert np.abs(phi - _euclidean(grid, segs))[seen].max() <= 0.041 * grid.dx


def test_a_door_one_cell_wide_joins_two_rooms_and_a_wall_without_one_does_not():
    """Two rooms, a wall 0.1 thick at x in [0.5, 0.6], a door one cell (0.05) wide at y in [0.45, 0.5]: round the
    door's near corner, through it, straight to the exit x = 1.  Measured within [−0.22 h, 0.022 h] of that
    (the former Dijkstra distance: up to 1.06 h long)."""
    wkt = "POLYGON ((0 0, 0.5 0, 0.5 0.45, 0.6 0.45, 0.6 0, 1 0, 1 1, 0.6 1, 0.6 0.5, 0.5 0.5, 0.5 1, 0 1, 0 0))"
    plan = Plan(Plan.from_wkt(wkt).polygon, [((1.0, 0.0), (1.0, 1.0))])
    grid = Grid(plan, (20, 20))
    phi = exit_distance(grid, exit_segments(plan))
    X, Y = grid.centers
    west = grid.active & (X < 0.5)
    # round the door's near corner (0.5, 0.5) or (0.5, 0.45), through the door, then straight to x = 1
    via = np.minimum(np.hypot(0.5 - X, Y - 0.5), np.hypot(0.5 - X, 0.45 - Y))
    via = np.where((Y >= 0.45) & (Y <= 0.5), 0.5 - X, via) + 0.5
    assert np.isfinite(phi[west]).all()
    assert np.abs(phi - via)[west].max() <= 0.25 * grid.dx
    closed = Grid(Domain.box(1.0, 1.0), (10, 10))
    closed.aperture_x[4, :] = 0.0  # a thin wall the grid cannot cross: the west half reaches no exit
    with pytest.raises(ParameterError) as exc:
        exit_distance(closed, np.array([[[1.0, 0.2], [1.0, 0.4]]]))
    assert exc.value.name == "grid.cells" and "50 cells do not" in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        ExitEikonal(closed, np.zeros((0, 2, 2)))
    assert exc.value.name == "domain.exits"


def test_a_corridor_of_two_speeds_takes_the_sum_of_its_travel_times():
    """|∇φ| = 1/F with F = 2 on the exit's half and 0.5 on the other: (2 − x)/2, and 0.5 + (1 − x)/0.5 beyond.
    Exact on the fast half; on the slow one within 0.12 h/F_slow (measured 0.113: the speed at the interface
    is the mean of the two cells'); a constant speed c gives φ/c exactly."""
    box = Domain.box(2.0, 0.5, exits=[((2.0, 0.0), (2.0, 0.5))])
    for n in (40, 80):
        grid = Grid(box, (n, n // 4))
        X, _ = grid.centers
        eikonal = ExitEikonal(grid, exit_segments(box))
        T = eikonal.travel_time(np.where(X < 1.0, 0.5, 2.0))
        exact = np.where(X > 1.0, (2.0 - X) / 2.0, 0.5 + (1.0 - X) / 0.5)
        np.testing.assert_allclose(T[X > 1.0], exact[X > 1.0], rtol=0, atol=1e-12)
        assert np.abs(T - exact).max() <= 0.12 * grid.dx / 0.5
        np.testing.assert_array_equal(eikonal.travel_time(np.full(grid.shape, 1.7)), eikonal.distance / 1.7)
    with pytest.raises(ParameterError) as exc:
        eikonal.travel_time(np.zeros(grid.shape))
    assert exc.value.name == "speed"


def _walk(routes: ExitRoutes, start: tuple[float, float], segs: np.ndarray, step: float = 0.02) -> float:
    """The length walked along ``routes.heading`` from ``start`` until within a step of the exit."""
    p, length = np.array(start, float), 0.0
    for _ in range(5000):
        left = distance_to_segments(p[None], segs).min()
        if left <= step:
            return length + left
        p = p + step * routes.heading(p[None])[0]
        length += step
    raise AssertionError(f"no exit reached from {start}")


def test_the_route_walks_down_phi_in_a_straight_line():
    """A 10 m room, 0.25 m cells, a 0.2 m door: measured, the walked route is at most 0.58 % longer than the
    straight line (the 8-neighbour Dijkstra tree: 0.98 %) and ``distance()`` 1.44 % (Dijkstra's tree: 5.7 %)."""
    room = Domain.box(10.0, 10.0, exits=[((10.0, 4.9), (10.0, 5.1))])
    grid = Grid(room, (40, 40))
    segs = exit_segments(room)
    routes = ExitRoutes(grid, segs)
    assert routes.tree == "descent"
    starts = [(0.5, 0.5), (0.5, 9.5), (2.0, 0.3), (0.3, 3.0), (5.0, 0.5)]
    exact = distance_to_segments(np.array(starts), segs).min(axis=1)
    walked = np.array([_walk(routes, s, segs) for s in starts])
    assert (walked / exact - 1).max() <= 0.006 and (walked / exact - 1).min() >= -0.002
    ratio = routes.distance(np.array(starts)) / exact - 1
    assert ratio.max() <= 0.015 and ratio.min() >= 0.0
    np.testing.assert_array_equal(routes.phi, exit_distance(grid, segs))


def test_a_loop_in_the_tree_falls_back_to_dijkstra(monkeypatch):
    """Were a cell's next cell to lead back to it, the routes take Dijkstra's tree (still to the exit)."""

    def looped(phi, *args):
        pred = np.full(len(phi), -1, dtype=np.int64)
        pred[0], pred[1] = 1, 0  # two cells that point at each other, the rest stuck
        return pred

    monkeypatch.setattr(geodesic, "_descent_tree", looped)
    grid = Grid(L_PLAN, (20, 20))
    routes = ExitRoutes(grid, exit_segments(L_PLAN))
    assert routes.tree == "dijkstra"
    assert geodesic._reaches_exits(np.array([1, 0, 3])) is False
    assert geodesic._reaches_exits(np.array([3, 0, 1])) is True
    X, Y = grid.centers
    p = np.column_stack([X[grid.active], Y[grid.active]])
    assert np.isfinite(routes.distance(p)).all()
    np.testing.assert_allclose(np.hypot(*routes.heading(p).T), 1.0)
