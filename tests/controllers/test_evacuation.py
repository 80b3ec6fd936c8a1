"""Step I towards the exits: the geodesic distance; Step II's identity for Hughes' v_d on a plan (issue 17)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, GaussianKernel, Grid, NavigationField, ParameterError, paper_scenario
from meanfield.controllers.backstepping import MinimumNormBetaGamma, SaturatingAlpha
from meanfield.controllers.evacuation import EvacuationController, exit_distance
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.plan import Plan
from meanfield.geometry.target import gaussian_target
from tests.conftest import smooth_density

EPS = 1e-30  # complex step
L_PLAN = Plan(Plan.from_wkt("POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0))").polygon, [((1, 0), (1, 0.4))])


def test_the_distance_to_an_exit_across_a_box_is_exact():
    box = Domain.box(1.0, 0.5, exits=[((1.0, 0.0), (1.0, 0.5))])
    grid = Grid(box, (20, 10))
    X, _ = grid.centers
    np.testing.assert_allclose(exit_distance(grid, exit_segments(box)), 1.0 - X, rtol=0, atol=1e-14)


def test_the_distance_goes_around_the_corner_of_an_l():
    grid = Grid(L_PLAN, (40, 40))
    phi = exit_distance(grid, exit_segments(L_PLAN))
    X, Y = grid.centers
    hidden = grid.active & (Y > 0.45) & (X < 0.35)  # behind the re-entrant corner (0.4, 0.4)
    geodesic = np.hypot(0.4 - X, 0.4 - Y) + 0.6  # to the corner, then straight to the exit x = 1
    ratio = phi[hidden] / geodesic[hidden]
    assert ratio.min() >= 1 - 0.02 and ratio.max() <= 1 / math.cos(math.pi / 8) + 0.02  # the 8-neighbour metric
    far = hidden & (Y > 0.7)
    assert (phi[far] > (1 - X[far]) + 0.1).all()  # far longer than the straight line through the wall


def test_a_cell_that_reaches_no_exit_is_refused_naming_the_grid():
    grid = Grid(Domain.box(1.0, 1.0), (10, 10))
    grid.aperture_x[4, :] = 0.0  # a wall the grid cannot cross, across the whole room
    segs = np.array([[[1.0, 0.2], [1.0, 0.4]]])
    with pytest.raises(ParameterError) as exc:
        exit_distance(grid, segs)
    assert exc.value.name == "grid.cells" and "50 cells do not" in str(exc.value)


def test_a_thin_wall_along_a_grid_line_closes_the_faces_on_it():
    # a wall 0.05 thick from x = 0.45 to 0.5, the grid's lines at multiples of 0.05: its left face
    # lies on the line x = 0.45; the faces there must not let anything through the wall
    two = Plan.from_wkt("POLYGON ((0 0, 0.45 0, 0.45 0.8, 0.5 0.8, 0.5 0, 1 0, 1 1, 0 1, 0 0))")
    grid = Grid(two, (20, 20))
    assert (grid.aperture_x[8, :16] == 0).all()  # between the columns [0.40, 0.45] and [0.45, 0.50]
    np.testing.assert_allclose(grid.aperture_x[8, 16:], 1.0, rtol=1e-12)  # above the wall: open


@pytest.mark.parametrize("rho_max", [math.inf, 4.0])
def test_step_two_identity_holds_for_hughes_v_d_on_a_plan(rho_max):
    """dV₂/dt = S − Σ k_u|b_i|² − Σ k_ω g_i² (S = −dissipation), by complex-step differentiation of V₂
    along (ρ̇, u, ω) of the semi-discrete closed loop: Step II does not care which v_d it tracks."""
    grid = Grid(L_PLAN, (24, 24))
    target = gaussian_target(grid, (0.8, 0.2), 0.15)
    phi = exit_distance(grid, exit_segments(L_PLAN))
    ctrl = EvacuationController(
        grid, target, 0.003, SaturatingAlpha(0.1, 0.2), 1.0, 2.0, MinimumNormBetaGamma(), None, "model",
        phi=phi, v_free=0.3, rho_max=rho_max,
    )
    kernel = GaussianKernel(0.5, 0.03)
    rho = np.where(grid.active, smooth_density(grid), 0.0) + 0.05 * grid.active
    rng = np.random.default_rng(2)
    R = L_PLAN.sample_uniform(5, rng)
    th = rng.uniform(0, 2 * np.pi, 5)
    field = NavigationField(kernel, grid, R, th)
    st = ctrl.robot_inputs(rho, field)
    rho_dot = ctrl.density_rate(rho, field.velocity())

    def V2(r, pos, head):
        v_r = NavigationField(kernel, grid, pos, head).velocity()
        v_d = ctrl.virtual_velocity(r)
        vt = (v_r[0] - v_d[0], v_r[1] - v_d[1])
        rt = r - target
        return 0.5 * grid.inner(rt, rt) + 0.5 * grid.face_inner(vt, vt)

    dV = V2(rho + 1j * EPS * rho_dot, R + 1j * EPS * st.u, th + 1j * EPS * st.omega).imag / EPS
    action = (st.b**2).sum() + 2.0 * (st.g**2).sum()
    expected = -st.dissipation - action
    scale = abs(st.dissipation) + abs(st.A) + action
    assert st.shortfall == 0
    assert abs(dV - expected) <= 1e-9 * scale, (dV, expected)


def test_the_evacuation_controller_runs_from_a_scenario():
    room = Domain.box(1.0, 1.0, exits=[((1.0, 0.8), (1.0, 1.0))])
    sc = paper_scenario(seed=0).replace(domain=room, t_final=3.0).with_values(
        {"controller.kind": "evacuation", "controller.options.v_free": 0.2}
    )
    loop = ClosedLoop(sc)
    assert isinstance(loop.controller, EvacuationController)
    s = loop.run(progress=False).summary
    assert s["status"] == "completed" and s["controller"] == "evacuation" and 0 <= s["fraction_evacuated"] <= 1
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(paper_scenario(seed=0).with_values({"controller.kind": "evacuation"}))  # no exits
    assert exc.value.name == "domain.exits"
