"""Routes to assigned exits in one look-up (issue 45, "Small crowds fast"): the same numbers as exit by exit.

:meth:`~meanfield.geometry.geodesic.AssignedRoutes.heading` and
:meth:`~meanfield.geometry.geodesic.AssignedRoutes.heading_to_each` read every point's waypoint from one table of the
planned routes' waypoints when each route reaches every cell: each point's heading is, to the bit, its own exit's
:meth:`~meanfield.geometry.geodesic.ExitRoutes.heading` (the nearest open exit's for ``-1``), before and after an exit
closes; :meth:`~meanfield.geometry.geodesic.ExitRoutes.reaches` is ``isfinite(distance)``, and
:meth:`~meanfield.geometry.geodesic.AssignedRoutes.reaches` each point's own exit's, on a whole plan and on one a block
cut in pieces (where the routes go exit by exit, as before).
"""

from __future__ import annotations

import numpy as np

from meanfield import Grid
from meanfield.geometry.blocking import blocked_region
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import AssignedRoutes
from meanfield.scenarios.scenario import builtin_scenarios
from tests.simulation.test_block_events import SPLIT  # the hall cut in two by a wall


def _exit_by_exit(plan: AssignedRoutes, points: np.ndarray, exit_of: np.ndarray) -> np.ndarray:
    """Each point's heading from its own exit's routes alone (the nearest open exit's for ``-1``)."""
    out = plan.nearest.heading(points)
    for k in np.unique(exit_of[exit_of >= 0]):
        rows = np.flatnonzero(exit_of == k)
        out[rows] = plan.to(k).heading(points[rows])
    return out


def test_every_point_heads_along_its_own_exit_s_route_to_the_bit():
    hall = builtin_scenarios()["hall"](seed=0).domain
    grid = Grid(hall, (60, 40))
    plan = AssignedRoutes(grid, exit_segments(hall))
    rng = np.random.default_rng(5)
    points = hall.sample_uniform(400, rng)
    points[:4] = grid.centers[0][10, 10], grid.centers[1][10, 10]  # points on a cell's centre
    for closed in (None, 1):
        if closed is not None:  # exit 1 closes: the nearest open exit is another, those sent to it go there
            exit_of = rng.integers(-1, 4, len(points))
            open_exits = np.arange(4) != closed
            plan.exits_closed(open_exits, exit_of)
        else:
            exit_of = rng.integers(-1, 4, len(points))
            exit_of[:50] = -1
        heading = plan.heading(points, exit_of)
        assert plan._table is not None  # (the one look-up ran)
        np.testing.assert_array_equal(heading, _exit_by_exit(plan, points, exit_of))
        each = plan.heading_to_each(points, exit_of)
        expected = _exit_by_exit(plan, points, exit_of)
        expected[exit_of < 0] = 0.0
        np.testing.assert_array_equal(each, expected)
        assert plan._in_table.all()  # every exit planned: the table kept, read again without sorting the exits out
        np.testing.assert_array_equal(plan.heading(points, exit_of), heading)
    for k in range(4):
        np.testing.assert_array_equal(plan.to(k).reaches(points), np.isfinite(plan.to(k).distance(points)))
    np.testing.assert_array_equal(plan.reaches(points, exit_of), exit_of >= 0)


def test_a_plan_in_pieces_goes_exit_by_exit():
    region = blocked_region(builtin_scenarios()["hall"]().domain, SPLIT)
    grid = Grid(region, (60, 40))
    plan = AssignedRoutes(grid, exit_segments(region))
    people = np.array([[5.0, 10.0], [25.0, 5.0], [25.0, 12.0]])  # west of the wall, east, east
    exit_of = np.array([3, 1, 2])  # the west one to an east door, the east ones to the north and the west door
    assert plan._waypoints(np.array([1, 2, 3])) is None  # a route that does not reach every cell: no table
    heading = plan.heading(people, exit_of)
    np.testing.assert_array_equal(heading[0], plan.nearest.heading(people[:1])[0])  # (as before: its own piece's)
    np.testing.assert_array_equal(heading[1], plan.to(1).heading(people[1:2])[0])
    each = plan.heading_to_each(people, exit_of)
    np.testing.assert_array_equal(each, _exit_by_exit(plan, people, exit_of))
    np.testing.assert_array_equal(each[2], 0.0)  # no route from the east piece to the west door
    for k in range(4):
        reaches = plan.to(k).reaches(people)
        np.testing.assert_array_equal(reaches, np.isfinite(plan.to(k).distance(people)))
    assert not plan.to(2).reaches(people[2:])[0] and plan.to(2).reaches(people[:1])[0]
    np.testing.assert_array_equal(plan.reaches(people, np.array([3, 1, 2])), [False, True, False])
    np.testing.assert_array_equal(plan.reaches(people, np.array([2, -1, 1])), [True, False, True])
