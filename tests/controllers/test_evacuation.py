"""Step I towards the exits: the geodesic distance, Hughes' potential; Step II's identity for Hughes' v_d on a plan
(issues 17 and 30)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, GaussianKernel, Grid, NavigationField, ParameterError, paper_scenario
from meanfield.controllers.backstepping import MinimumNormBetaGamma, SaturatingAlpha
from meanfield.controllers.evacuation import SPEED_FLOOR, EvacuationController, exit_distance
from meanfield.errors import MeanfieldDeprecationWarning
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import ExitEikonal
from meanfield.geometry.plan import Plan
from meanfield.geometry.target import gaussian_target
from tests.conftest import lyapunov_v2, smooth_density

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
    assert ratio.min() >= 1 - 0.005 and ratio.max() <= 1 + 0.001  # fast marching (the 8-neighbour metric: +8 %)
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


@pytest.mark.parametrize("potential", ["distance", "hughes"])
@pytest.mark.parametrize("rho_max", [math.inf, 4.0])
def test_step_two_identity_holds_for_hughes_v_d_on_a_plan(rho_max, potential):
    """dV₂/dt = S − Σ k_u|b_i|² − Σ k_ω g_i² (S = −dissipation), by complex-step differentiation of V₂
    along (ρ̇, u, ω) of the semi-discrete closed loop: Step II does not care which v_d it tracks.

    Hughes' potential: the complex step sees the law's own φ̇ (a forward difference of two fast marches), so the
    identity holds to round-off for the chain rule of ``f f̂ ∇φ``; a real central difference of V₂ along the
    loop, through the fast marches themselves, agrees to 2e-5 of the terms (measured; the φ̇ term is 3e-3 of
    them when ρ_max = 4, so a missing or wrong φ̇ fails)."""
    grid = Grid(L_PLAN, (24, 24))
    target = gaussian_target(grid, (0.8, 0.2), 0.15)
    eikonal = ExitEikonal(grid, exit_segments(L_PLAN))
    ctrl = EvacuationController(
        grid, target, 0.003, SaturatingAlpha(0.1, 0.2), 1.0, 2.0, MinimumNormBetaGamma(), None, "model",
        phi=eikonal.distance, v_free=0.3, rho_max=rho_max, potential=potential, eikonal=eikonal,
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
        return lyapunov_v2(ctrl, kernel, r, pos, head)

    dV = V2(rho + 1j * EPS * rho_dot, R + 1j * EPS * st.u, th + 1j * EPS * st.omega).imag / EPS
    action = (st.b**2).sum() + 2.0 * (st.g**2).sum()
    expected = -st.dissipation - action
    scale = abs(st.dissipation) + abs(st.A) + action
    assert st.shortfall == 0
    assert abs(dV - expected) <= 1e-9 * scale, (dV, expected)
    if potential == "hughes":
        h = 1e-4
        up, down = (V2(rho + s * h * rho_dot, R + s * h * st.u, th + s * h * st.omega) for s in (1, -1))
        assert abs((up - down) / (2 * h) - expected) <= 1e-4 * scale


def test_hughes_potential_with_nobody_is_the_distance_over_the_free_speed():
    """ρ = 0: f = v_free everywhere, so φ = distance / v_free exactly and v_d is the distance field's."""
    grid = Grid(L_PLAN, (24, 24))
    eikonal = ExitEikonal(grid, exit_segments(L_PLAN))
    args = (grid, gaussian_target(grid, (0.8, 0.2), 0.15), 0.003, SaturatingAlpha(0.1, 0.2))
    hughes = EvacuationController(*args, phi=eikonal.distance, v_free=1.34, rho_max=4.0, potential="hughes",
                                  eikonal=eikonal)  # fmt: skip
    plain = EvacuationController(*args, phi=eikonal.distance, v_free=1.34, rho_max=4.0)
    empty = np.zeros(grid.shape)
    np.testing.assert_array_equal(hughes.hughes_potential(empty), exit_distance(grid, exit_segments(L_PLAN)) / 1.34)
    for a, b in zip(hughes.virtual_velocity(empty), plain.virtual_velocity(empty), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)
    assert np.abs(a).max() == pytest.approx(1.34)


def test_hughes_field_goes_round_a_jam_to_the_other_exit():
    """A corridor with an exit at each end and a jam in front of the nearer one: the distance's field heads into
    the jam, Hughes' to the far exit, and west of the jam φ is the travel time x/f(ρ) to the west exit, exactly."""
    corridor = Domain.box(4.0, 1.0, exits=[((0.0, 0.0), (0.0, 1.0)), ((4.0, 0.0), (4.0, 1.0))])
    grid = Grid(corridor, (40, 10))
    X, _ = grid.centers
    eikonal = ExitEikonal(grid, exit_segments(corridor))
    rho = np.where((X > 3.0) & (X < 3.8), 3.0, 0.1)  # ρ ≥ ρ_max = 2 in the jam: f = 0, f̂ = SPEED_FLOOR v_free
    args = (grid, np.full(grid.shape, 0.25), 0.003, SaturatingAlpha(0.1, 0.2))
    opts = {"phi": eikonal.distance, "v_free": 1.0, "rho_max": 2.0, "eikonal": eikonal}
    here = (grid.x_faces > 2.25) & (grid.x_faces < 2.35)  # the x-faces at x = 2.3: 1.7 m from the east exit
    assert (EvacuationController(*args, **opts).virtual_velocity(rho)[0][here] > 0).all()
    hughes = EvacuationController(*args, potential="hughes", **opts)
    assert (hughes.virtual_velocity(rho)[0][here] < 0).all()
    np.testing.assert_allclose(hughes.virtual_velocity(rho)[0][here], -0.95, rtol=1e-12)  # |v_d| = f(0.1)
    phi = hughes.hughes_potential(rho)
    west = X < 2.9
    np.testing.assert_allclose(phi[west], X[west] / 0.95, rtol=1e-12)
    # inside the jam, reached from the east: a cell takes dx / (SPEED_FLOOR v_free) = 2 s to cross (measured 1.9998,
    # 1.9983 between the cells at x = 3.35, 3.45, 3.55: the speed is the cells' mean at the lattice's faces)
    np.testing.assert_allclose(np.diff(phi[33:36, 5]), -grid.dx / SPEED_FLOOR, rtol=1e-3)


def test_an_unknown_potential_is_refused_naming_it():
    room = Domain.box(1.0, 1.0, exits=[((1.0, 0.8), (1.0, 1.0))])
    sc = paper_scenario(seed=0).replace(domain=room, t_final=1.0).with_values(
        {"controller.kind": "evacuation"}
    )
    with pytest.raises(ParameterError) as exc:  # refused as the scenario is read
        sc.with_values({"controller.options.evacuation.potential": "geodesic"})
    assert exc.value.name == "controller.options.evacuation.potential" and "'hughes'" in str(exc.value)
    grid = Grid(room, (10, 10))
    args = (grid, np.full(grid.shape, 1.0), 0.003, SaturatingAlpha(0.1, 0.2))
    with pytest.raises(ParameterError) as exc:
        EvacuationController(*args, phi=exit_distance(grid, exit_segments(room)), potential="hughes")  # no solver
    assert exc.value.name == "eikonal"


def test_a_closed_loop_with_hughes_potential_runs_on_the_l_room():
    from meanfield.scenarios.scenario import builtin_scenarios

    values = {"crowd.n": 30, "t_final": 3.0, "controller.kind": "evacuation",
              "controller.options.evacuation.potential": "hughes",
              "controller.options.evacuation.rho_max": 0.01}  # fmt: skip
    loop = ClosedLoop(builtin_scenarios()["l-room"](seed=0).with_values(values))
    assert loop.controller.potential == "hughes" and loop.controller.compiled_step_one() is None
    assert loop.controller.rho_max == 0.01
    s = loop.run(progress=False).summary
    assert s["status"] == "completed" and s["controller"] == "evacuation" and s["time_final"] == pytest.approx(3.0)
    assert 0 <= s["fraction_evacuated"] <= 1


def test_the_evacuation_controller_runs_from_a_scenario():
    room = Domain.box(1.0, 1.0, exits=[((1.0, 0.8), (1.0, 1.0))])
    sc = paper_scenario(seed=0).replace(domain=room, t_final=3.0).with_values(
        {"controller.kind": "evacuation", "crowd.free_speed": 0.2}
    )
    loop = ClosedLoop(sc)
    assert isinstance(loop.controller, EvacuationController)
    s = loop.run(progress=False).summary
    assert s["status"] == "completed" and s["controller"] == "evacuation" and 0 <= s["fraction_evacuated"] <= 1
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(paper_scenario(seed=0).with_values({"controller.kind": "evacuation"}))  # no exits
    assert exc.value.name == "domain.exits"


def test_the_walking_speed_of_the_law_is_the_crowd_s_unless_set():
    from meanfield import ClosedLoop
    from meanfield.scenarios.scenario import builtin_scenarios

    sc = builtin_scenarios()["hall"](seed=0).with_values(
        {"controller.kind": "evacuation", "controller.options": {}, "crowd.free_speed": 1.1}
    )
    assert ClosedLoop(sc).controller.v_free == 1.1
    with pytest.warns(MeanfieldDeprecationWarning, match="controller.options.evacuation.v_free"):
        old = sc.with_values(
            {"controller.options.evacuation.v_free": 1.5, "controller.options.evacuation.rho_max": 0.1}
        )
    assert ClosedLoop(old).controller.v_free == 1.5 and ClosedLoop(old).controller.rho_max == 0.1
