"""People who remember the way (``view.memory = "route"``, :mod:`meanfield.crowds.memory`).

* who a sign reached walks the route to the exit the sign showed at the free speed from then on, others
  are untouched; a later sign that reaches the person decides again;
* nobody forgets: once the robots are out of sight they still walk the route;
* the default is the paper's humans, number for number; the routes are planned again when an exit closes;
* bad values and crowds that do not model individuals are refused, naming ``view.memory``.
"""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ClosedLoop, Grid, ParameterError
from meanfield.crowds.memory import RouteMemory
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import ExitRoutes
from meanfield.scenarios.scenario import builtin_scenarios


def _hall(**values):
    before_the_guide = {"controller.kind": "coverage", "view.memory": "none"}  # the hall as these tests measured it
    return builtin_scenarios()["hall"](seed=0).with_values({**before_the_guide, **values})


def test_who_a_sign_reached_walks_the_route_the_sign_showed_and_the_others_keep_their_velocity():
    sc = _hall()
    grid = Grid(sc.domain, sc.grid.cells)
    segs = exit_segments(sc.domain)  # 0 south (15, 0), 1 north (15, 20), 2 west (0, 10), 3 east (30, 10)
    memory = RouteMemory(4, grid, segs, 1.34, shown=True)
    positions = np.array([[5.0, 5.0], [25.0, 15.0], [10.0, 17.0], [20.0, 3.0]])
    felt = np.array([[0.0, -0.5], [0.3, 0.0], [0.0, 0.4], [-0.2, 0.0]])  # south, east, north, west
    velocity = felt.copy()
    memory.walk(velocity, positions, np.array([True, False, True, False]))
    # no route within 45° of the sign: the one most nearly along it (person 0's nearest exit is the west door)
    assert memory.exit[[0, 2]].tolist() == [0, 1]
    for j, k in ((0, 0), (2, 1)):
        one = ExitRoutes(grid, segs[k : k + 1])
        np.testing.assert_allclose(velocity[j], 1.34 * one.heading(positions[j : j + 1])[0], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(velocity[[1, 3]], felt[[1, 3]])
    velocity = felt.copy()
    memory.walk(velocity, positions, np.array([False, False, False, True]))  # nobody forgets
    # pointed west at (20, 3): the west door (19° off) and the south one (31° off) lie within 45°; the nearer, south
    assert memory.knows.tolist() == [True, False, True, True] and memory.exit[3] == 0
    np.testing.assert_array_equal(velocity[1], felt[1])
    assert memory.summary() == {"knew_the_way_fraction": 0.75}
    velocity = felt.copy()
    velocity[0] = [0.1, 0.5]  # a later sign at (5, 5) points north-north-east: the north door is 22° off it, the
    memory.walk(velocity, positions, np.array([True, False, False, False]))  # west 56°; the latest sign decides
    assert memory.exit[0] == 1
    np.testing.assert_allclose(velocity[0], 1.34 * ExitRoutes(grid, segs[1:2]).heading(positions[:1])[0], atol=1e-15)
    memory.exits_closed(np.array([True, False, True, True]))  # the north door closes: 0 and 2 take the nearest
    assert memory.exit[[0, 2, 3]].tolist() == [-1, -1, 0]
    velocity = felt.copy()
    memory.walk(velocity, positions, np.zeros(4, dtype=bool))
    nearest_open = ExitRoutes(grid, segs[[0, 2, 3]])
    np.testing.assert_allclose(velocity[2], 1.34 * nearest_open.heading(positions[2:3])[0], rtol=0, atol=1e-15)


def test_with_route_who_a_sign_reached_walks_to_the_nearest_exit_whatever_the_sign_showed():
    sc = _hall()
    grid = Grid(sc.domain, sc.grid.cells)
    segs = exit_segments(sc.domain)
    memory = RouteMemory(2, grid, segs, 1.34)
    positions = np.array([[5.0, 5.0], [10.0, 17.0]])
    felt = np.array([[0.0, -0.5], [0.0, 0.4]])
    velocity = felt.copy()
    memory.walk(velocity, positions, np.array([True, True]))
    np.testing.assert_allclose(velocity, 1.34 * ExitRoutes(grid, segs).heading(positions), rtol=0, atol=1e-15)
    assert memory.exit.tolist() == [-1, -1] and memory.plan.planned == {}  # no exit alone was planned


def test_a_person_who_knew_the_way_walks_on_when_no_robot_is_in_view():
    """Static signs on the hall: people the signs reached go on to the exits out of every robot's view,
    and more people get out than without memory, when nobody walks the route once out of a sign's reach."""
    values = {"controller.kind": "static-signs", "t_final": 60.0}
    loop = ClosedLoop(_hall(**values, **{"view.memory": "route"}))
    s = loop.run(progress=False).summary
    knows = loop.crowd.memory.knows
    assert 0 < s["knew_the_way_fraction"] == pytest.approx(knows.mean())
    gone = loop.crowd.engine.exit_time >= 0
    assert gone[knows].mean() > 0.99  # who knew the way got out within the minute
    without = ClosedLoop(_hall(**values)).run(progress=False).summary
    assert s["fraction_evacuated"] > without["fraction_evacuated"] + 0.2
    assert "knew_the_way_fraction" not in without


def test_the_default_is_the_paper_s_humans_number_for_number():
    a = ClosedLoop(_hall(t_final=3.0)).run(progress=False)
    b = ClosedLoop(_hall(t_final=3.0, **{"view.memory": "none"})).run(progress=False)
    np.testing.assert_array_equal(a.dataset["fraction_evacuated"].values, b.dataset["fraction_evacuated"].values)
    assert a.summary["l2_error_final"] == b.summary["l2_error_final"]


def test_the_routes_are_planned_again_when_an_exit_closes_in_a_run():
    loop = ClosedLoop(_hall(t_final=1.0, events=[{"time": 0.5, "close_exit": 0}], **{"view.memory": "route"}))
    loop.run(progress=False)
    m = loop.crowd.memory
    assert m.plan.open.tolist() == [False, True, True, True] and len(m.plan.nearest.segs) == 3
    assert not (m.exit == 0).any()


@pytest.mark.parametrize(
    ("values", "why"),
    [
        ({"view.memory": "forever"}, "'sign'"),
        ({"view.memory": "route", "crowd.kind": "fokker-planck"}, "models_individuals"),
    ],
)
def test_bad_memory_is_refused_naming_it(values, why):
    with pytest.raises(ParameterError, match=why) as exc:
        ClosedLoop(_hall(**values))
    assert exc.value.name == "view.memory"
