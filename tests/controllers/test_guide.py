"""The guide (``controller.kind = "guide"``, :mod:`meanfield.controllers.guide`).

* :func:`allocate` gives every share with people a robot while robots last, the rest by the shares' weights;
* a sign that names an exit sends whoever reads it there, whatever its arrow; an arrow alone is read as before;
* a human reads the strongest sign it sees on its own (two arrows pointing apart do not hide each other);
* on the hall with its crowd by the west door the guide sends a share east and beats the informed crowd;
* no sign names a closed exit; a region that becomes wall is planned round; the same seed gives the same run;
* bad options and a plan without exits are refused, naming the field.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meanfield import ClosedLoop, Grid, ParameterError, run
from meanfield.controllers._guide_loops import share_moments
from meanfield.controllers.coverage import _NOTHING_HIDDEN
from meanfield.controllers.guide import GuideController, GuideOptions, allocate
from meanfield.crowds.memory import RouteMemory
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import ExitRoutes
from meanfield.scenarios.scenario import builtin_scenarios

GUIDE = {"controller.kind": "guide", "view.memory": "sign", "controller.options": {}}


def test_allocate_gives_each_share_with_people_a_robot_and_the_rest_by_weight():
    assert allocate(np.array([3.0, 1.0, 0.0, 0.0]), 8).tolist() == [6, 2, 0, 0]
    assert allocate(np.array([1.0, 2.0, 3.0]), 2).tolist() == [0, 1, 1]  # fewer robots than shares: the heaviest
    assert allocate(np.zeros(3), 4).tolist() == [0, 0, 0]
    assert allocate(np.array([1.0, 1.0]), 0).tolist() == [0, 0]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 1e3), min_size=1, max_size=6), st.integers(0, 20))
def test_allocate_uses_every_robot_and_follows_the_weights(weights, robots):
    w = np.array(weights)
    n = allocate(w, robots)
    live = w > 0
    if not live.any() or robots == 0:
        assert not n.any()
        return
    assert n.sum() == robots and not n[~live].any()
    if robots >= live.sum():
        assert (n[live] >= 1).all()
    heavier = w[:, None] > w[None, :]  # a share never gets fewer robots than a lighter one, but for the first robot
    assert (n[:, None] >= n[None, :] - 1)[heavier].all()


def _hall_memory(n):
    sc = builtin_scenarios()["hall"](seed=0)
    grid = Grid(sc.domain, sc.grid.cells)
    segs = exit_segments(sc.domain)  # 0 south (15, 0), 1 north (15, 20), 2 west (0, 10), 3 east (30, 10)
    return RouteMemory(n, grid, segs, 1.34, shown=True), grid, segs


def test_a_sign_that_names_an_exit_sends_its_readers_there_whatever_its_arrow():
    memory, grid, segs = _hall_memory(3)
    positions = np.array([[5.0, 5.0], [25.0, 15.0], [20.0, 3.0]])
    felt = np.array([[0.0, -0.5], [0.3, 0.0], [-0.2, 0.0]])  # south, east, west
    velocity = felt.copy()
    memory.walk(velocity, positions, np.array([True, True, True]), named=np.array([1, 1, -1]))
    # the first two read "north" under arrows pointing south and east; the third reads an arrow alone (the south
    # door, as without names: the nearer of the two within 45° of west)
    assert memory.exit.tolist() == [1, 1, 0]
    north = ExitRoutes(grid, segs[1:2])
    np.testing.assert_allclose(velocity[:2], 1.34 * north.heading(positions[:2]), rtol=0, atol=1e-15)
    memory.exits_closed(np.array([True, False, True, True]))  # a name of a closed exit is read as its arrow
    velocity = felt.copy()
    memory.walk(velocity, positions, np.array([True, False, False]), named=np.array([1, -1, -1]))
    assert memory.exit[0] == 0  # the south door: the arrow's (no open exit within 45°: the one most along it)


def test_a_human_reads_the_strongest_sign_it_sees_even_where_two_arrows_cancel():
    sc = builtin_scenarios()["hall-crowded-west"](seed=0).with_values(
        {**GUIDE, "robots.n": 2, "robots.layout": "explicit", "robots.positions": [[10.0, 4.0], [12.0, 4.0]],
         "robots.headings": [0.0, np.pi], "crowd.n": 1, "crowd.initial": "gaussian",
         "crowd.initial_center": [11.0, 4.0], "crowd.initial_std": 1e-3, "t_final": 0.1,
         "crowd.sigma": 1e-6}  # fmt: skip
    )
    loop = ClosedLoop(sc)
    loop.robots.shows = np.array([1, 0])  # the east sign names the east door; the west sign the west one
    drift = loop.crowd.drift(loop.robots, 0.0, sc.dt)
    assert np.hypot(*drift[0]) > 1.0  # walks to a door at the free speed
    assert bool(loop.crowd.reached[0])  # the arrows sum to nothing there, yet each sign is read
    assert loop.crowd.memory.exit[0] in (0, 1)


@pytest.fixture(scope="module")
def crowded_west():
    def rset(values):
        sc = builtin_scenarios()["hall-crowded-west"](seed=0).with_values({"controller.options": {}})
        return run(sc.with_values(values), progress=False).summary

    return rset(GUIDE), rset({"crowd.guidance": "geodesic"})


def test_on_the_hall_crowded_west_the_guide_sends_a_share_east_and_beats_the_informed_crowd(crowded_west):
    guide, informed = crowded_west
    assert informed["evacuated_per_exit"] == [200, 0]
    assert guide["everyone_out"] and guide["evacuated_per_exit"][1] >= 40  # Step I's share of the east door
    # measured on seeds 0-19: 0.66-0.77 of the informed crowd's RSET (docs page Buildings, "The guide")
    assert guide["evacuation_time_100"] <= 0.8 * informed["evacuation_time_100"]


def test_no_sign_names_a_closed_exit_and_the_run_is_the_same_for_the_same_seed():
    sc = builtin_scenarios()["hall"](seed=1).with_values(
        {**GUIDE, "t_final": 8.0, "events": [{"time": 2.0, "close_exit": 0}]}
    )
    shown = []
    loop = ClosedLoop(sc)
    loop.run(progress=False, callback=lambda lp: shown.append((lp.t, lp.robots.shows.copy())))
    after = np.concatenate([s for t, s in shown if t > 2.0 + 1e-9])
    assert len(after) and not (after == 0).any()
    assert {int(k) for t, s in shown if t <= 2.0 for k in s} >= {0}  # before, the south door was named
    again = ClosedLoop(sc)
    shown_again = []
    again.run(progress=False, callback=lambda lp: shown_again.append(lp.robots.shows.copy()))
    np.testing.assert_array_equal(np.concatenate([s for _, s in shown]), np.concatenate(shown_again))
    np.testing.assert_array_equal(loop.crowd.positions, again.crowd.positions)


def test_a_region_that_becomes_wall_is_planned_round():
    sc = builtin_scenarios()["hall"](seed=0).with_values(
        {**GUIDE, "t_final": 4.0, "events": [{"time": 1.0, "block": "POLYGON ((24 2, 27 2, 27 18, 24 18, 24 2))"}]}
    )
    loop = ClosedLoop(sc)
    loop.run(progress=False)
    g = loop.controller
    assert g.grid is loop.grid and np.isfinite(g.assignment.arrival).any()
    blocked = ~loop.grid.active.ravel()[g._cells]
    assert not blocked.any()  # the covered cells are the new grid's


def test_in_a_room_no_wall_divides_each_robot_drives_straight_at_its_centroid():
    # rimea-9 (a 30 m x 20 m room, four exits): nothing hides a centroid, so no robot walks round a wall (the guide
    # used to take every pull along its walking tree there, as if a wall hid the centroid)
    sc = builtin_scenarios()["rimea-9"](seed=0).with_values(
        {"controller.kind": "guide", "crowd.guidance": "signs", "robots.n": 8, "controller.options": {},
         "t_final": 1.0}  # fmt: skip
    )
    loop = ClosedLoop(sc)
    for _ in range(10):
        loop.step()
    g = loop.controller
    assert g.sight is None and not g.walking._trees  # no tree planted
    robots = np.asarray(loop.robots.positions, float)
    w = g.weight(loop.density, loop.t)
    pull = g.pulls(robots, g._share, w)
    moving = np.hypot(pull[:, 0], pull[:, 1]) > 0
    assert moving.any()
    # the pull is the offset to the weighted centroid of the robot's cells of its share (its moments)
    _, m, px, py = share_moments(g._xy, np.ascontiguousarray(robots), g.team, g._share, w, _NOTHING_HIDDEN, g._cells,
                                 False, np.empty(len(g._share), np.intp), *np.empty((3, len(robots))))  # fmt: skip
    held = m > 0
    np.testing.assert_array_equal(moving, held)
    centroid = np.column_stack([px[held] / m[held], py[held] / m[held]])
    np.testing.assert_allclose(pull[held], centroid - robots[held], rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"controller.options.guide.rebalance_period": -1.0}, "controller.options.guide.rebalance_period"),
        ({"controller.options.guide.k_position": 2.0}, "controller.options.guide.k_position"),
        ({"controller.options.guide.revisit_after": "5"}, "controller.options.guide.revisit_after"),
        ({"controller.options.guide.weight": "unswept"}, "controller.options.guide.weight"),
    ],
)
def test_bad_options_are_refused_naming_the_field(values, field):
    with pytest.raises(ParameterError) as exc:  # refused as the scenario is read
        builtin_scenarios()["hall"](seed=0).with_values({**GUIDE, **values})
    assert exc.value.name == field


def test_a_plan_without_exits_is_refused_naming_controller_kind():
    sc = builtin_scenarios()["paper"](seed=0).with_values({"controller.kind": "guide"})
    with pytest.raises(ParameterError, match=r"controller\.kind"):
        ClosedLoop(sc)


def test_the_guide_is_registered_and_declares_what_it_can_do():
    from meanfield import plugins

    assert "guide" in plugins.available("controller")
    assert plugins.load("controller", "guide") == GuideController.from_parts
    can = plugins.capabilities("controller", "guide")
    assert can.changes_walls and not can.accepts_sensing and can.options is GuideOptions
