"""The coverage controller: Lloyd centroids, cells behind walls, idle robots, the heading's Lyapunov statement."""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, Grid, ParameterError, paper_scenario
from meanfield.controllers.coverage import CoverageController
from meanfield.geometry.plan import Plan
from meanfield.geometry.sight import SightLines
from meanfield.signs.robots import NavigationField
from meanfield.simulation.observers import StepRecord

TWO_ROOMS = "POLYGON ((0 0, 0.45 0, 0.45 0.8, 0.55 0.8, 0.55 0, 1 0, 1 1, 0 1, 0 0))"


def _coverage(region, cells=(20, 20), **kw):
    grid = Grid(region, cells)
    return CoverageController(None, grid, SightLines(region), **kw), grid


def test_uniform_weight_on_a_box_puts_each_robot_at_its_voronoi_cell_s_centroid():
    cov, grid = _coverage(Domain.box(1.0, 1.0))
    robots = np.array([[0.2, 0.5], [0.7, 0.5]])  # bisector x = 0.45: a grid line of the 20x20 grid
    c, idle = cov.centroids(robots, np.ones(grid.shape))
    np.testing.assert_allclose(c, [[0.225, 0.5], [0.725, 0.5]], rtol=0, atol=1e-12)
    assert not idle.any()


def test_a_robot_owns_the_cells_it_sees_and_one_that_sees_no_weight_holds_its_place():
    plan = Plan.from_wkt(TWO_ROOMS)
    cov, grid = _coverage(plan)
    robots = np.array([[0.3, 0.3], [0.6, 0.95]])  # the left room; the right room's top, by the door
    X, Y = grid.centers
    owner = np.full(grid.shape, -1)
    owner.ravel()[cov._cells] = cov.owners(robots)
    right_low = grid.active & (X > 0.55) & (Y < 0.7)
    assert (owner[right_low] == 1).all()  # hidden from robot 0 although nearer to it
    weight = np.where((X < 0.45) & (Y < 0.5), 1.0, 0.0)  # people low in the left room, hidden from robot 1
    c, idle = cov.centroids(robots, weight)
    assert idle.tolist() == [False, True]
    np.testing.assert_array_equal(c[1], robots[1])  # no weight in its cells: it holds its place


def test_the_heading_part_descends_the_tracking_error_at_every_step_of_a_pde_run():
    """dV/dt = Σ g_i ω_i = −k Σ g_i² for fixed positions and a frozen v_d, V = ½‖v_r − v_d‖²:
    the formula against a finite difference of V along ω, at every step of a Fokker–Planck run."""
    sc = paper_scenario(seed=1).with_values({"controller.kind": "coverage", "t_final": 0.5, "grid.cells": [20, 20]})
    loop = ClosedLoop(sc, crowd="fokker-planck")
    assert isinstance(loop.controller, CoverageController)
    checked = []

    class HeadingCheck:
        def start(self, loop):
            pass

        def step(self, loop, record: StepRecord):
            st = record.command.state
            positions, headings = record.observation.field.positions, record.observation.field.headings
            h = 1e-7

            def V(theta):
                f = NavigationField(loop.kernel, loop.grid, positions, theta)
                v = f.velocity()
                return 0.5 * loop.grid.face_norm((v[0] - st.v_d[0], v[1] - st.v_d[1])) ** 2

            w = record.command.omega
            fd = (V(headings + h * w) - V(headings - h * w)) / (2 * h)
            formula = float((st.g * w).sum())
            assert formula == pytest.approx(-loop.controller.k_heading * float((st.g**2).sum()), rel=1e-12)
            assert fd == pytest.approx(formula, rel=1e-6, abs=1e-12)
            assert formula <= 0.0
            checked.append(formula)

    loop.attach(HeadingCheck())
    for _ in range(sc.steps):
        loop.step()
    assert len(checked) == sc.steps


def test_a_paper_run_with_coverage_reports_its_idle_robots_and_bad_options_are_refused():
    sc = paper_scenario(seed=0).with_values({"controller.kind": "coverage", "t_final": 0.3})
    s = ClosedLoop(sc).run(progress=False).summary
    assert s["controller"] == "coverage" and 0.0 <= s["coverage_idle_fraction"] <= 1.0
    for option, value in (("weight", "mass"), ("k_position", 0.0), ("v_d", "north"), ("k_heading", -1.0)):
        with pytest.raises(ParameterError) as exc:
            sc.with_values({f"controller.options.coverage.{option}": value})
        assert exc.value.name == f"controller.options.coverage.{option}"
    with pytest.raises(ParameterError) as exc:
        sc.with_values({"controller.options.coverage.gain": 1.0})
    assert exc.value.name == "controller.options.coverage.gain"


def test_coverage_passes_the_potential_to_the_field_its_signs_follow_and_its_metric_to_the_positions():
    from meanfield import ClosedLoop, load_scenario
    from meanfield.controllers.evacuation import EvacuationController

    sc = load_scenario("hall").with_values(
        {"controller.kind": "coverage", "controller.options.coverage.potential": "hughes",
         "controller.options.coverage.metric": "walking", "t_final": 0.2}  # fmt: skip
    )
    loop = ClosedLoop(sc)
    assert isinstance(loop.controller.law, EvacuationController) and loop.controller.law.potential == "hughes"
    assert loop.controller.metric == "walking" and loop.controller.walking is not None
    loop.run(progress=False)
    with pytest.raises(ParameterError, match=r"controller\.options\.coverage\.potential"):
        sc.with_values({"controller.options.coverage.potential": "travel"})


def test_the_unswept_weight_leaves_out_where_a_sign_reached_lately_and_counts_it_again_later():
    """A cell counts as reached when a robot sees it and its kernel there is at least 5 % of its peak; it weighs
    again ``revisit_after`` later; behind a wall nothing is reached; nothing unswept left: the tracking error."""
    from meanfield.signs.kernels import GaussianKernel

    plan = Plan.from_wkt(TWO_ROOMS)
    grid = Grid(plan, (20, 20))
    cov = CoverageController(None, grid, SightLines(plan), weight="unswept", revisit_after=2.0)
    kernel = GaussianKernel(1.0, 0.02)  # 5 % of the peak at r = sqrt(0.02 ln 20) = 0.245
    robots = np.array([[0.2, 0.3]])
    field = NavigationField(kernel, grid, robots, np.zeros(1), SightLines(plan))
    last = cov.sweep(field, 1.0)
    X, Y = grid.centers
    near = np.hypot(X - 0.2, Y - 0.3) <= 0.2
    far = np.hypot(X - 0.2, Y - 0.3) >= 0.3
    assert (last[near & grid.active] == 1.0).all() and np.isinf(last[far]).all()
    behind = grid.active & (X > 0.55) & (Y < 0.5)  # the right room, hidden by the wall, within 0.6 of the robot
    assert np.isinf(last[behind]).all()
    rho = np.ones(grid.shape)

    class State:  # the law's state the weight reads: ṽ = 1 on every face
        v_tilde = (np.ones((19, 20)), np.zeros((20, 19)))
        rho_tilde = None

    w = cov._weight(rho, State, field, 1.5)
    assert (w[near & grid.active] == 0).all() and (w[far & grid.active] > 0).all()
    w = cov._weight(rho, State, NavigationField(kernel, grid, np.array([[0.8, 0.8]]), np.zeros(1)), 3.5)
    assert (w[near & grid.active] > 0).all()  # 2.5 s later: counted again
    with pytest.raises(ParameterError, match=r"controller\.options\.coverage\.revisit_after"):
        CoverageController(None, grid, SightLines(plan), weight="unswept", revisit_after=0.0)
