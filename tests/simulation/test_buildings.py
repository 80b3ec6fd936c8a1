"""Real buildings: signs in line of sight, routes to the exits, baselines, evacuation measures, shipped plans."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, Grid, ParameterError, paper_scenario
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import ExitRoutes, exit_distance
from meanfield.geometry.plan import Plan
from meanfield.geometry.sight import SightLines
from meanfield.scenarios.scenario import builtin_scenarios
from meanfield.scenarios.sections import TargetSpec
from meanfield.signs.kernels import GaussianKernel
from meanfield.signs.robots import NavigationField, navigation_velocity

# two rooms side by side, a wall 0.1 thick between them, a door at the top of the wall
TWO_ROOMS = "POLYGON ((0 0, 0.45 0, 0.45 0.8, 0.55 0.8, 0.55 0, 1 0, 1 1, 0 1, 0 0))"
L_ROOM = "POLYGON ((0 0, 2 0, 2 1, 1 1, 1 2, 0 2, 0 0))"


def test_a_wall_hides_a_sign_and_a_convex_room_hides_nothing():
    plan = Plan.from_wkt(TWO_ROOMS)
    sight = SightLines(plan)
    kernel = GaussianKernel(1.0, 0.5)
    robot, heading = np.array([[0.3, 0.9]]), np.array([0.0])
    humans = np.array([[0.3, 0.5], [0.8, 0.3], [0.8, 0.9]])  # same room; behind the wall; through the door
    bare = navigation_velocity(kernel, robot, heading, humans)
    for grid in (None, Grid(plan, (20, 20))):  # exact segments; between the cells of a grid
        v = navigation_velocity(kernel, robot, heading, humans, sight.mask(robot, humans, grid))
        np.testing.assert_array_equal(v[[0, 2]], bare[[0, 2]])  # in sight: the paper's field, exactly
        assert bare[1, 0] > 0.05 and v[1, 0] == 0.0  # behind the wall: nothing
    # visibility is symmetric, and the walls on the outline's convex hull never count
    a, b = plan.sample_uniform(300, np.random.default_rng(1)), plan.sample_uniform(300, np.random.default_rng(2))
    np.testing.assert_array_equal(sight.visible(a, b), sight.visible(b, a))
    assert len(sight.walls) == 3  # the wall's two sides and its end under the door
    box = SightLines(Domain.box(1.0, 1.0))
    assert box.trivial and box.mask(robot, humans) is None


def test_the_grid_s_field_hides_the_faces_behind_a_wall_and_keeps_the_step_two_identity():
    """Faces in the other room are dark; the law's identity <ṽ, ∂t v_r> = -Σ b·u + Σ g ω still holds."""
    plan = Plan.from_wkt(TWO_ROOMS)
    grid = Grid(plan, (20, 20))
    sight = SightLines(plan)
    kernel = GaussianKernel(1.0, 0.3)
    R, th = np.array([[0.2, 0.3], [0.8, 0.9]]), np.array([0.3, 2.0])
    field = NavigationField(kernel, grid, R, th, sight)
    vx, _ = field.velocity()
    Xf, Yf = grid.face_points_x
    behind = (Xf > 0.6) & (Yf < 0.6)  # the right room, below the door: robot 0 is hidden there
    only_robot_1 = NavigationField(kernel, grid, R[1:], th[1:], sight).velocity()[0]
    np.testing.assert_allclose(vx[behind], only_robot_1[behind], rtol=0, atol=1e-15)
    rng = np.random.default_rng(0)
    F = (rng.normal(size=vx.shape), rng.normal(size=field.velocity()[1].shape))
    u, w = rng.normal(size=(2, 2)), rng.normal(size=2)
    b, g = field.moments(F)
    lhs = grid.face_inner(F, field.velocity_rate(u, w))
    assert lhs == pytest.approx(-(b * u).sum() + (g * w).sum(), rel=1e-12)


def test_the_route_out_of_an_l_is_its_geodesic_within_a_cell():
    """Round the re-entrant corner (1, 1) to the exit on the far wall: |p − c| + |c − e|."""
    plan = Plan.from_wkt(L_ROOM)
    plan = Plan(plan.polygon, [((2.0, 0.2), (2.0, 0.8))])
    h = 2 / 40
    grid = Grid(plan, (40, 40))
    routes = ExitRoutes(grid, exit_segments(plan))
    p = np.array([[0.5, 1.8], [0.3, 0.5], [1.5, 0.5]])
    exact = np.array([math.hypot(0.5, 0.8) + math.hypot(1.0, 0.2), 1.7, 0.5])
    np.testing.assert_allclose(routes.distance(p), exact, atol=2 * h)
    phi = exit_distance(grid, exit_segments(plan))
    i, j = routes.grid.cell_of(p)
    assert np.all(phi[i, j] <= 1.083 * (exact + 2 * h))  # the 8-neighbour metric: at most 8.3 % longer
    e = routes.heading(p)
    np.testing.assert_allclose(np.hypot(e[:, 0], e[:, 1]), 1.0)
    assert e[0, 0] > 0 and e[0, 1] < 0  # from the upper arm: towards the corner


def _corridor(guidance: str, **extra):
    room = Plan.from_wkt("POLYGON ((0 0, 10 0, 10 2, 0 2, 0 0))")
    room = Plan(room.polygon, [((10.0, 0.0), (10.0, 2.0))])
    target = TargetSpec(center=(10.0, 1.0), std=2.0)
    sc = builtin_scenarios()["l-room"](seed=3).replace(domain=room, target=target, t_final=15.0)
    values = {
        "grid.cells": [20, 4],
        "crowd.n": 50,
        "crowd.sigma": 0.0,
        "crowd.guidance": guidance,
        "crowd.congestion": "none",  # free walking: the speeds and times below are the free speed's
        "robots.n": 2,
        "controller.kind": "static-signs",
        "record_every": 1,
        **extra,
    }
    return sc.with_values(values)


def test_the_informed_crowd_walks_out_at_its_free_speed_and_the_measures_say_so():
    """No noise, a straight corridor: the last one out is the farthest, at distance / speed."""
    sc = _corridor("geodesic", **{"crowd.free_speed": 1.25})
    loop = ClosedLoop(sc)
    x0 = loop.crowd.positions.copy()
    result = loop.run(progress=False)
    s = result.summary
    farthest = (10.0 - x0[:, 0]).max()
    dt = sc.dt
    assert s["fraction_evacuated"] == 1.0
    assert s["evacuation_time_100"] == pytest.approx(math.ceil(farthest / (1.25 * dt) - 1e-9) * dt, abs=1e-9)
    assert s["lower_bound_walk"] == pytest.approx(farthest / 1.25, rel=0.05)  # the route: within a cell
    assert s["lower_bound_flow"] == pytest.approx(50 / (2.0 * 2.5))  # the largest measured specific flow
    assert s["design_flow_time"] == pytest.approx(50 / (2.0 * 1.3))  # the design guides' (not a bound)
    assert s["evacuation_lower_bound"] == max(s["lower_bound_walk"], s["lower_bound_flow"])
    assert s["rset_over_bound"] == pytest.approx(s["evacuation_time_100"] / s["evacuation_lower_bound"])
    assert s["evacuation_time_95"] <= s["evacuation_time_100"]
    (flow,) = s["exit_flows"]
    assert flow["persons"] == 50 and flow["width"] == 2.0
    assert flow["persons_per_metre_second"] == pytest.approx(flow["persons_per_second"] / 2.0)
    curve = result.dataset["fraction_evacuated"].values
    assert curve[0] == 0.0 and np.all(np.diff(curve) >= 0) and curve[-1] == 1.0
    assert result.dataset["fraction_evacuated"].attrs["units"] == "1"


def test_the_uninformed_crowd_walks_at_random_and_a_seed_gives_the_same_walk():
    sc = _corridor("random-walk", **{"view.walk_speed": 0.7, "view.turning_rate": 0.2, "t_final": 3.0})
    a, b = ClosedLoop(sc), ClosedLoop(sc)
    x0 = a.crowd.positions.copy()
    for _ in range(5):
        a.step(), b.step()
    np.testing.assert_array_equal(a.crowd.positions, b.crowd.positions)
    step = np.hypot(*(a.crowd.positions - x0).T) / (5 * sc.dt)
    assert np.all(step <= 0.7 + 1e-9) and np.median(step) > 0.5  # walking, not diffusing (σ = 0)


def test_static_signs_park_on_the_lattice_and_point_along_the_route():
    sc = builtin_scenarios()["l-room"](seed=0).with_values({"controller.kind": "static-signs", "crowd.n": 20})
    loop = ClosedLoop(sc)
    for _ in range(60):
        loop.step()
    c = loop.controller
    np.testing.assert_allclose(loop.robots.positions, c.stations, atol=1e-6)
    turn = np.angle(np.exp(1j * (loop.robots.headings - c.bearings)))
    np.testing.assert_allclose(turn, 0.0, atol=1e-3)
    e = ExitRoutes(loop.grid, exit_segments(sc.domain)).heading(c.stations)
    np.testing.assert_allclose(c.bearings, np.arctan2(e[:, 1], e[:, 0]))


@pytest.mark.parametrize("name", ["l-room", "office", "hall"])
def test_every_shipped_plan_is_metres_reaches_its_exits_and_runs(name):
    sc = builtin_scenarios()[name](seed=0)
    assert sc.units == "SI" and sc.domain.kind == "plan" and len(sc.domain.exits) >= 1
    grid = Grid(sc.domain, sc.grid.cells)
    phi = exit_distance(grid, exit_segments(sc.domain))  # raises if a cell reaches no exit
    assert np.isfinite(phi[grid.active]).all()
    loop = ClosedLoop(sc.with_values({"crowd.n": 30}))
    for _ in range(3):
        loop.step()
    assert loop.crowd.remaining() <= 30


@pytest.mark.parametrize(
    "name", ["l-room", "office", "hall", "hall-crowded-west", "bottleneck", "rimea-9", "rimea-10", "rimea-12"]
)
def test_no_congested_crowd_on_a_shipped_plan_beats_the_flow_bound(name):
    """The informed crowd, the fastest there is, with the plans' default congestion (the linear diagram,
    the local density cut by the walls): everyone out, and not sooner than the whole crowd takes through
    the exits at 2.5 persons/(m·s), the most measured (docs page *Congestion*).  Without the walls' cut
    rimea-9's doors passed 2.9–3.6 persons/(m·s) and its RSET was 0.80 of the bound."""
    sc = builtin_scenarios()[name](seed=0)
    assert sc.congestion_model == "linear"
    s = ClosedLoop(sc.with_values({"crowd.guidance": "geodesic"})).run(progress=False).summary
    assert s["evacuation_time_100"] is not None, "somebody was left behind"
    assert s["rset_over_bound"] >= 1.0, s["rset_over_bound"]
    flows = [f["persons_per_metre_second"] for f in s["exit_flows"] if f["persons_per_metre_second"] is not None]
    assert flows and max(flows) <= 2.5 * 1.2  # no door far above it (a door nobody took has no flow)


def test_baselines_are_refused_where_they_mean_nothing():
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(paper_scenario(seed=0).with_values({"crowd.guidance": "geodesic"}))  # no exits
    assert exc.value.name == "crowd.guidance"
    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({"crowd.guidance": "follow-the-leader"})
    assert exc.value.name == "crowd.guidance" and "random-walk" in str(exc.value)
    # (the density takes the baselines too: tests/crowds/test_density_guidance.py)


def test_a_robot_driven_into_a_pillar_at_an_angle_slides_round_it():
    from meanfield.signs.robots import RobotTeam

    hall = builtin_scenarios()["hall"](seed=0).domain  # pillar [7, 8] x [6, 7]
    team = RobotTeam(np.array([[6.5, 6.2]]), np.zeros(1), 10.0, 10.0)
    for _ in range(40):
        team.advance(np.array([[1.0, 0.5]]), np.zeros(1), 0.1, hall)
    x, y = team.positions[0]
    assert x > 8.0 and y > 7.0  # round the pillar's corner, not stuck at its face
    assert hall.contains(np.array([x]), np.array([y]))[0]


def test_a_plan_run_saves_its_evacuation_figure(tmp_path):
    from meanfield.plotting.figures import save_run_figures

    sc = builtin_scenarios()["l-room"](seed=0).with_values({"crowd.n": 30, "t_final": 2.0})
    result = ClosedLoop(sc).run(progress=False)
    paths = save_run_figures(result, tmp_path)
    assert set(paths) == {"target_and_error", "snapshots", "evacuation"}
    assert all(p.stat().st_size > 10_000 for p in paths.values())


@pytest.mark.parametrize("name", ["office", "hall"])
def test_the_wall_index_finds_the_same_first_wall_as_testing_every_wall(name):
    from meanfield.geometry.walls import WallIndex, segment_hits

    plan = builtin_scenarios()[name](seed=0).domain
    a, e = plan._edges
    index = WallIndex(a, e, plan.bounds)
    rng = np.random.default_rng(7)
    start = plan.sample_uniform(30_000, rng)  # above FULL_TEST_BELOW pairs: the look-ups are used
    for scale in (0.05, 0.3, 3.0):  # steps shorter and longer than a lattice cell
        end = start + scale * rng.normal(size=start.shape)
        t, k = index.first_hit(start, end)
        full = segment_hits(start, end - start, a[None], e[None])
        j = np.argmin(full, axis=1)
        np.testing.assert_array_equal(t, full[np.arange(len(start)), j])
        hit = np.isfinite(t)
        assert hit.any() and np.array_equal(k[hit], j[hit])


def test_a_robot_or_a_crowd_centre_in_a_pillar_is_refused_naming_it():
    hall = builtin_scenarios()["hall"](seed=0)  # pillar [7, 8] x [6, 7]
    with pytest.raises(ParameterError) as exc:
        hall.with_values({"robots.n": 2, "robots.layout": "explicit", "robots.positions": [[3.0, 3.0], [7.5, 6.5]]})
    assert exc.value.name == "robots.positions[1]"
    with pytest.raises(ParameterError) as exc:
        hall.with_values({"crowd.initial": "gaussian", "crowd.initial_center": [7.5, 6.5]})
    assert exc.value.name == "crowd.initial_center"


def test_a_density_run_stops_when_less_than_half_a_person_is_left():
    """The density's mass never reaches 0 exactly: its run stops, as the evacuation measures say, once
    ``1 − 0.5/N`` of it is out, at the step where ``evacuation_time_100`` is reached."""
    sc = _corridor("geodesic", **{"t_final": 40.0, "crowd.sigma": 0.05})
    result = ClosedLoop(sc, crowd="fokker-planck").run(progress=False)
    s = result.summary
    assert s["status"] == "completed" and "everyone left" in s["message"]
    assert s["evacuation_time_100"] is not None and s["time_final"] == pytest.approx(s["evacuation_time_100"])
    assert s["time_final"] < sc.t_final
    assert (1.0 - s["fraction_evacuated"]) * sc.crowd.n < 0.5
