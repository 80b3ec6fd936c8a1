"""A region becomes wall during a run (``[[events]] block = "POLYGON (...)"``, issue 31 item 3).

* the routes go round a block: the geodesic distance behind a thin wall equals the shortest path round
  its corner (exact, to the grid's error, which shrinks with the cells);
* in the hall, from the event on nobody and no robot stands in the block; those standing in it at the
  event step out (nobody is lost: in Ω plus out is everyone); the block's cells hold no density;
* the informed crowd, the evacuation controller and coverage plan round it; every declared part runs;
* static signs keep their stations and bearings;
* summary.json lists the block, the figures draw it, a scenario with blocks survives TOML;
* a block may cut the plan in pieces, each with its exits: each piece's people leave by its own
  exits, an exit's routes leave the other pieces alone, every part runs through it;
* bad blocks are refused naming ``events[i].block`` (outside the plan, meeting an exit, covering the
  plan, cutting people off from every exit, a part that does not declare ``changes_walls``), an
  event that shuts people in a piece is refused, and the command line exits with 2.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely

from meanfield.cli.app import main
from meanfield.crowds._cell_list import cell_list
from meanfield.crowds.forward_cell import CELL_REACH, wall_segments
from meanfield.crowds.headway import boundary_walls
from meanfield.errors import ParameterError
from meanfield.geometry.blocking import blocked_region
from meanfield.geometry.domain import Domain
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import ExitRoutes
from meanfield.geometry.grid import Grid
from meanfield.scenarios.scenario import Scenario, builtin_scenarios
from meanfield.simulation.loop import ClosedLoop

BLOCK_AT = 5.0
CENTRE = "POLYGON ((10 3, 20 3, 20 17, 10 17, 10 3))"
"""The middle of the hall (30 m × 20 m, pillars at x = 7-8, 14.5-15.5 and 22-23): a third of it."""


def hall(block: str = CENTRE, **values):
    """The shipped hall (four 2 m doors, 200 people), its middle blocked at 5 s."""
    return builtin_scenarios()["hall"](seed=0).with_values({"events": [{"time": BLOCK_AT, "block": block}], **values})


def run_to(loop: ClosedLoop, t: float) -> None:
    while loop.t < t - 0.5 * loop.dt:
        loop.step()


@pytest.mark.parametrize("cells", [(80, 40), (160, 80)])
def test_routes_go_round_a_block_the_shortest_way(cells):
    """Behind a thin wall (x = 10-10.5, y < 8) of a 20 m × 10 m room with its door at x = 20, y = 4-6, the
    walk from (5, 2) goes to the wall's corner (10, 8), along its top, then straight to the door's end
    (20, 6): √61 + 0.5 + √94.25 = 18.018 m.  Without the wall it is the straight line, √229 = 15.133 m."""
    room = Domain.box(20.0, 10.0, exits=[[[20.0, 4.0], [20.0, 6.0]]])
    walled = blocked_region(room, "POLYGON ((10 -1, 10.5 -1, 10.5 8, 10 8, 10 -1))")
    p = np.array([[5.0, 2.0]])
    around = ExitRoutes(Grid(walled, cells), exit_segments(walled)).distance(p)[0]
    straight = ExitRoutes(Grid(room, cells), exit_segments(room)).distance(p)[0]
    exact, line = np.sqrt(61.0) + 0.5 + np.sqrt(94.25), np.sqrt(229.0)
    h = 20.0 / cells[0]  # the cell's width
    assert abs(around - exact) < 0.6 * h and abs(straight - line) < 0.2 * h
    assert walled.bounds == room.bounds  # the grid's lattice is the room's


@pytest.mark.parametrize("guidance", ["geodesic", "fastest-route"])
def test_nobody_stands_in_the_block_after_it_and_nobody_is_lost(guidance):
    loop = ClosedLoop(hall(**{"crowd.guidance": guidance}))
    block = shapely.from_wkt(CENTRE)
    run_to(loop, BLOCK_AT)
    x = loop.crowd.positions
    here = np.isfinite(x[:, 0])
    caught = int(shapely.contains_xy(block, x[here, 0], x[here, 1]).sum())
    assert caught > 10  # people stood in the middle of the hall when it was blocked
    inside = []
    while loop.t < BLOCK_AT + 5.0:
        loop.step()
        x = loop.crowd.positions
        here = np.isfinite(x[:, 0])
        inside.append(int(shapely.contains_xy(block, x[here, 0], x[here, 1]).sum()))
        inside.append(int(shapely.contains_xy(block, *loop.robots.positions.T).sum()))
    assert max(inside) == 0
    engine = loop.crowd.engine
    assert engine.remaining() + int((engine.exit_index >= 0).sum()) == loop.crowd.n
    cells = loop.grid.volume_fraction == 0
    assert cells.sum() > 0 and np.all(loop.density[cells] == 0)  # the block's cells hold nothing
    assert loop.parts.region.area == pytest.approx(600 - 6 - 10 * 14 + 2, rel=1e-9)  # two pillars are in it


def test_the_informed_crowd_the_evacuation_controller_and_coverage_plan_round_it():
    behind = np.array([[9.5, 10.0]])  # west of the block: the east door (30, 9-11) is now round it
    loop = ClosedLoop(hall(**{"crowd.guidance": "geodesic", "controller.kind": "evacuation"}))
    law = loop.controller
    before = loop.crowd.guidance.routes.distance(behind)[0]
    run_to(loop, BLOCK_AT + loop.dt)
    after = loop.crowd.guidance.routes.distance(behind)[0]
    assert before == pytest.approx(9.5, abs=0.5) and after == pytest.approx(9.5, abs=0.5)  # the west door
    cells = loop.grid.volume_fraction == 0
    assert np.isinf(law.eikonal.distance[cells]).all() and law.grid is loop.grid
    coverage = ClosedLoop(hall(**{"controller.kind": "coverage", "controller.options.coverage.metric": "routed",
                                  "controller.options.coverage.weight": "unswept"}))  # fmt: skip
    run_to(coverage, BLOCK_AT + coverage.dt)
    c = coverage.controller
    assert c.grid is coverage.grid and c.law.grid is coverage.grid
    assert len(c._cells) == int(coverage.grid.active.sum())  # the block's cells are not covered


@pytest.mark.parametrize("door_model", ["forward-cell", "headway"])
def test_the_door_model_reads_the_density_by_the_block_s_walls(door_model):
    """After the block, the door model's walls are the plan's new ones: the forward cell's cells and the headway's
    lanes stop at the block (a person facing it, 0.2 m away, reads the room ahead of it closed off)."""
    loop = ClosedLoop(hall(**{"crowd.door_model": door_model}))
    door = loop.crowd._door
    before = len(door.wall_starts) if door_model == "forward-cell" else len(door.walls.a)
    run_to(loop, BLOCK_AT + loop.dt)
    region = loop.crowd.engine.domain
    if door_model == "forward-cell":
        new = wall_segments(region)
        assert len(door.wall_starts) != before  # the block's walls in, the pillars it covers out
        assert np.array_equal(door.wall_starts, new[0]) and np.array_equal(door.wall_vectors, new[1])
        x, e = np.array([[9.8, 10.0]]), np.array([[1.0, 0.0]])  # west of the block's face x = 10, facing it
        rho, _, _ = door.choose_direction(x, e, np.ones(1, bool), cell_list(x, np.ones(1, bool), door.jam_spacing))
        assert rho[0] >= 0.999 * 0.5 / (0.2 * 2 * CELL_REACH)  # ahead: at most 0.2 m × the square's side (alone: 3 m)
    else:
        assert len(door.walls.a) != before and np.array_equal(door.walls.a, boundary_walls(region).a)


@pytest.mark.parametrize(
    "values",
    [
        {"crowd.guidance": "random-walk"},
        {"view.memory": "sign", "controller.kind": "coverage", "controller.options.coverage.metric": "walking",
         "controller.options.coverage.potential": "balanced"},  # fmt: skip
        {"controller.kind": "guide"},
        {"controller.kind": "evacuation", "sensing.radius": 8.0, "sensing.comm_radius": 8.0},
        {"crowd.compliance": 0.8, "crowd.premovement": {"law": "uniform", "low": 0.0, "high": 4.0}},
        {"controller.kind": "backstepping", "crowd.congestion": "none"},
    ],
)
def test_every_part_that_declares_changes_walls_runs_through_a_block(values):
    loop = ClosedLoop(hall(**values, t_final=8.0))
    result = loop.run(progress=False)
    assert result.summary["status"] == "completed" and result.summary["events"][0]["at"] == BLOCK_AT
    x = loop.crowd.positions
    here = np.isfinite(x[:, 0])
    assert not shapely.contains_xy(shapely.from_wkt(CENTRE), x[here, 0], x[here, 1]).any()


def test_static_signs_keep_their_stations_and_bearings():
    loop = ClosedLoop(hall(**{"controller.kind": "static-signs"}))
    c = loop.controller
    stations, bearings = c.stations.copy(), c.bearings.copy()
    run_to(loop, BLOCK_AT + 2.0)
    assert loop.events_done
    np.testing.assert_array_equal(c.stations, stations)
    np.testing.assert_array_equal(c.bearings, bearings)


def test_a_block_is_reported_drawn_and_survives_toml(tmp_path):
    sc = hall()
    again = Scenario.from_toml(sc.to_toml())
    assert again.events == sc.events and again == sc
    out = tmp_path / "run"
    assert main(["run", "hall", "--out", str(out), "--quiet", "--set", "t_final=8.0",
                 "--set", f'events=[{{time = 5.0, block = "{CENTRE}"}}]']) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    assert summary["events"] == [{"time": 5.0, "at": 5.0, "block": CENTRE}]
    assert (out / "evacuation.png").stat().st_size > 0 and (out / "snapshots.png").stat().st_size > 0


@pytest.mark.parametrize(
    "block, why",
    [
        ("POLYGON ((40 40, 41 40, 41 41, 40 40))", "overlaps the plan"),  # outside the hall
        ("POLYGON ((13 -1, 17 -1, 17 2, 13 2, 13 -1))", "clear of the exits"),  # over the south door
        ("POLYGON ((-1 -1, 31 -1, 31 21, -1 21, -1 -1))", "room to walk"),  # all of it
        ("POLYGON ((-1 15, 6 15, 6 21, 5 21, 5 16, -1 16, -1 15))", "every side still has an exit"),  # the NW corner
        ("POLYGON ((1 1, 2 1, 1 2, 2 2, 1 1))", "valid polygon"),  # a bow tie
        ("LINESTRING (1 1, 2 2)", "polygon in WKT"),
        ("POLYGON ((1 1, 2", "polygon in WKT"),
    ],
)
def test_bad_blocks_are_refused_naming_them(block, why, tmp_path):
    with pytest.raises(ParameterError, match=why) as exc:
        hall(block)
    assert exc.value.name == "events[0].block"
    out = tmp_path / "o"
    event = f'events=[{{time = 1.0, block = "{block}"}}]'
    assert main(["run", "hall", "--out", str(out), "--quiet", "--set", event]) == 2


@pytest.mark.parametrize(
    "values, why",
    [
        ({"crowd.kind": "fokker-planck"}, "crowd.kind among"),
        ({"crowd.kind": "jupedsim"}, "crowd.kind among"),
        ({"controller.kind": "nmpc"}, "controller.kind among"),
        ({"interaction.kind": "gaussian", "interaction.strength": 1.0}, "interaction"),
    ],
)
def test_a_block_with_a_part_that_cannot_change_its_walls_is_refused(values, why):
    with pytest.raises(ParameterError, match=why) as exc:
        hall(**values)
    assert exc.value.name == "events[0].block"


SPLIT = "POLYGON ((10 -1, 11 -1, 11 21, 10 21, 10 -1))"
"""A wall across the hall at x = 10-11: the west piece keeps the west door (exit 2), the east one the others."""


def test_a_block_may_cut_the_plan_in_pieces_each_with_its_exits():
    loop = ClosedLoop(hall(SPLIT, **{"crowd.guidance": "geodesic"}))
    run_to(loop, BLOCK_AT)
    x = loop.crowd.positions.copy()
    west = np.isfinite(x[:, 0]) & (x[:, 0] < 10.0)
    assert west.sum() > 10
    result = loop.run(progress=False)
    engine = loop.crowd.engine
    assert result.summary["status"] == "completed" and engine.remaining() == 0
    assert (engine.exit_index[west] == 2).all()  # the west piece's people leave by its door, and only they do
    assert (engine.exit_index[~west & (engine.exit_time > BLOCK_AT + 1.0)] != 2).all()
    assert loop.parts.region.to_shapely().geom_type == "MultiPolygon"


def test_an_exit_s_routes_leave_the_other_pieces_alone():
    """In a plan in pieces the routes to one exit are infinite, and head nowhere, in a piece without it; the eikonal
    still refuses cells its exits should reach and do not (:func:`meanfield.geometry.geodesic.cut_off`)."""
    from meanfield.geometry.geodesic import ExitEikonal, cut_off

    region = blocked_region(builtin_scenarios()["hall"]().domain, SPLIT)
    grid = Grid(region, (60, 40))
    segs = exit_segments(region)
    west, east = np.array([[5.0, 10.0]]), np.array([[25.0, 10.0]])
    door = ExitRoutes(grid, segs[2:3])  # the west door
    assert np.isfinite(door.distance(west)).all() and np.isinf(door.distance(east)).all()
    np.testing.assert_array_equal(door.heading(east), 0.0)
    reached = np.isfinite(ExitEikonal(grid, segs[2:3]).distance[grid.active])
    assert cut_off(grid, reached, segs[2:3]) == 0 and 0 < reached.sum() < reached.size
    X, _ = grid.centers
    partly = reached & (X[grid.active] < 5.0)  # half of the west piece: a passage the march did not pass
    assert cut_off(grid, partly, segs[2:3]) == int((reached & ~partly).sum())
    assert cut_off(grid, reached, segs) == int((~reached).sum())  # every exit: the east piece should be reached


def test_people_assigned_to_an_exit_of_another_piece_walk_to_their_own():
    from meanfield.geometry.geodesic import AssignedRoutes

    region = blocked_region(builtin_scenarios()["hall"]().domain, SPLIT)
    grid = Grid(region, (60, 40))
    plan = AssignedRoutes(grid, exit_segments(region))
    people = np.array([[5.0, 10.0], [25.0, 5.0]])  # west of the wall, assigned to the east door; east, to the north
    heading = plan.heading(people, np.array([3, 1]))
    np.testing.assert_array_equal(heading[0], plan.nearest.heading(people[:1])[0])  # the west door, its own
    np.testing.assert_array_equal(heading[1], plan.to(1).heading(people[1:])[0])
    assert heading[0, 0] < -0.9  # westwards


def test_every_declared_part_runs_through_a_split_plan():
    office = builtin_scenarios()["office"](seed=0).with_values(
        {"t_final": 20.0, "view.memory": "sign", "controller.kind": "coverage",
         "controller.options.coverage.metric": "routed", "controller.options.coverage.weight": "unswept",
         "controller.options.coverage.potential": "balanced",
         "events": [{"time": 3.0, "block": "POLYGON ((14.5 5.9, 15.5 5.9, 15.5 8.1, 14.5 8.1, 14.5 5.9))"}]}
    )  # fmt: skip  (the corridor blocked across between its two exits)
    loop = ClosedLoop(office)
    result = loop.run(progress=False)
    assert result.summary["status"] == "completed" and loop.parts.region.to_shapely().geom_type == "MultiPolygon"


def test_an_event_that_shuts_people_in_a_piece_is_refused():
    with pytest.raises(ParameterError, match="shut in") as exc:
        hall(events=[{"time": 5.0, "block": SPLIT}, {"time": 8.0, "close_exit": 2}])
    assert exc.value.name == "events[1].close_exit"
    with pytest.raises(ParameterError, match="shut in") as exc:  # the west door closed first, then the wall
        hall(events=[{"time": 1.0, "close_exit": 2}, {"time": 5.0, "block": SPLIT}])
    assert exc.value.name == "events[1].block"
    last = [{"time": 5.0, "block": SPLIT}] + [{"time": 8.0, "close_exit": k} for k in range(4)]
    assert len(hall(events=last).events) == 5  # closing every exit is allowed: "no exit left"


def test_a_block_that_leaves_the_robots_region_in_pieces_is_refused():
    """A wall across the hall with a 0.8 m gap: people pass, but robots kept 0.5 m from the walls could not."""
    gap = "POLYGON ((10 0.8, 11 0.8, 11 21, 10 21, 10 0.8))"
    hall(gap)  # the plan stays one piece
    with pytest.raises(ParameterError, match="robots' region") as exc:
        hall(gap, **{"robots.margin": 0.5})
    assert exc.value.name == "events[0].block"


def test_one_event_is_one_action():
    with pytest.raises(ParameterError, match="one action") as exc:
        builtin_scenarios()["hall"](seed=0).with_values(
            {"events": [{"time": 1.0, "close_exit": 0, "block": CENTRE}]}
        )
    assert exc.value.name == "events[0]"


def test_step_two_s_identity_holds_on_the_plan_a_block_leaves():
    """The guarantee is kept after a block: on the new grid, with φ solved round the block, dV₂/dt = S − Σ k_u|b_i|²
    − Σ k_ω g_i² by complex-step differentiation (as on the plans before, tests/controllers)."""
    from meanfield.controllers.backstepping import MinimumNormBetaGamma, SaturatingAlpha
    from meanfield.controllers.evacuation import EvacuationController
    from meanfield.geometry.blocking import WallsChange
    from meanfield.geometry.geodesic import ExitEikonal
    from meanfield.geometry.region import wkt_polygon
    from meanfield.geometry.sight import SightLines
    from meanfield.geometry.target import gaussian_target
    from meanfield.signs.kernels import GaussianKernel
    from meanfield.signs.robots import NavigationField
    from tests.conftest import lyapunov_v2, smooth_density

    eps = 1e-30
    room = Domain.box(1.0, 1.0, exits=[((0.0, 0.4), (0.0, 0.6)), ((1.0, 0.4), (1.0, 0.6))])
    grid = Grid(room, (20, 20))
    eikonal = ExitEikonal(grid, exit_segments(room))
    ctrl = EvacuationController(
        grid, gaussian_target(grid, (0.2, 0.5), 0.15), 0.003, SaturatingAlpha(0.1, 0.2), 1.0, 2.0,
        MinimumNormBetaGamma(), None, "model", phi=eikonal.distance, v_free=0.3, rho_max=4.0, eikonal=eikonal,
    )  # fmt: skip
    wall = "POLYGON ((0.42 0.2, 0.58 0.2, 0.58 0.8, 0.42 0.8, 0.42 0.2))"
    region = blocked_region(room, wall)
    new = Grid(region, (20, 20))
    target = gaussian_target(new, (0.2, 0.5), 0.15)
    ctrl.walls_changed(WallsChange(region, new, SightLines(region), region, target, wkt_polygon(wall, "block")))
    assert ctrl.grid is new and np.isinf(ctrl.eikonal.distance[~new.active]).all()
    X, _ = new.centers
    rho = np.where(new.active, smooth_density(new) * np.exp(-((X - 0.25) ** 2) / 0.02) + 0.05, 0.0)
    rho /= new.integrate(rho)
    rng = np.random.default_rng(2)
    R, th = rng.uniform(0.1, 0.9, (5, 2)), rng.uniform(0, 2 * np.pi, 5)
    kernel = GaussianKernel(0.5, 0.03)
    field = NavigationField(kernel, new, R, th)
    st = ctrl.robot_inputs(rho, field)
    rho_dot = ctrl.density_rate(rho, field.velocity())
    dV = lyapunov_v2(ctrl, kernel, rho + 1j * eps * rho_dot, R + 1j * eps * st.u, th + 1j * eps * st.omega).imag / eps
    action = (st.b**2).sum() + 2.0 * (st.g**2).sum()
    scale = abs(st.dissipation) + abs(st.A) + action
    assert abs(dV - (-st.dissipation - action)) <= 1e-9 * scale, (dV, -st.dissipation - action)
