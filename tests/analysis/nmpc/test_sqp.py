"""The real-time SQP of the NMPC (analysis.nmpc.sqp): the same optimum as IPOPT, warm starts, early
stops within the limits, steps without speed limits, move blocking."""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ClosedLoop
from tests.analysis.nmpc.conftest import controller_for, small_scenario, solved_instance


def test_sqp_and_ipopt_reach_the_same_optimum(small_loop):
    """One problem, two solvers: the condensed SQP lands on IPOPT's full-space minimiser."""
    c, rho_c, pos, heads, sqp = solved_instance(small_loop)
    ipopt = controller_for(small_loop, solver="ipopt", tol=1e-10).solve(rho_c, pos, heads)
    assert sqp.success and ipopt.success, (sqp.status, ipopt.status)
    assert sqp.cost == pytest.approx(ipopt.cost, rel=1e-6)
    np.testing.assert_allclose(sqp.u, ipopt.u, atol=1e-5)
    np.testing.assert_allclose(sqp.omega, ipopt.omega, atol=1e-4)
    assert np.hypot(sqp.u[..., 0], sqp.u[..., 1]).max() == pytest.approx(0.05, rel=1e-9)  # a limit is active


@pytest.mark.parametrize("solver", ["sqp", "ipopt"])
def test_a_warm_start_converges_to_the_cold_optimum(small_loop, solver):
    """Warm starts only change where the solver starts: from the previous plan shifted by one
    step, and (SQP) from a perturbed guess, the solve ends at the cold solve's optimum."""
    extra = {"solver": "ipopt", "tol": 1e-10} if solver == "ipopt" else {}
    c, rho_c, pos, heads, cold = solved_instance(small_loop, **extra)
    guesses = [c.initial_guess(rho_c, pos, heads, cold, shift=1)]
    if solver == "sqp":
        g = c.initial_guess(rho_c, pos, heads)
        rng = np.random.default_rng(4)
        g["ux"] = g["ux"] + rng.normal(0.0, 0.02, g["ux"].shape)
        g["omega"] = g["omega"] + rng.normal(0.0, 0.3, g["omega"].shape)
        guesses.append(g)
    for guess in guesses:
        warm = c.solve(rho_c, pos, heads, guess)
        assert warm.success, warm.status
        assert warm.cost == pytest.approx(cold.cost, rel=1e-8)
        np.testing.assert_allclose(warm.u, cold.u, atol=1e-5)
        np.testing.assert_allclose(warm.omega, cold.omega, atol=1e-4)


def test_an_early_stop_returns_a_feasible_plan_that_improves_the_guess(small_loop):
    """Real-time iterations stop after one QP: the plan is within the speed limits and the
    region (exactly, not to a tolerance) and no worse than the (made feasible) guess."""
    c = controller_for(small_loop, max_iter=1, cells=[6, 5])
    rho_c = c.restrict(small_loop.crowd.density())
    pos, heads = small_loop.robots.positions.copy(), small_loop.robots.headings.copy()
    pos[0] = [0.0, 1.0]  # a robot in a corner of the region
    g = c.initial_guess(rho_c, pos, heads)
    g["ux"][:] = -1.0  # far outside the limits and pushing out of the region
    g["omega"][:] = 7.0
    plan = c.solve(rho_c, pos, heads, g)
    assert plan.iterations == 1 and not plan.success
    assert np.hypot(plan.u[..., 0], plan.u[..., 1]).max() <= c.u_max * (1 + 1e-12)
    assert np.abs(plan.omega).max() <= c.omega_max
    lo, hi = np.array(c.region[0::2]), np.array(c.region[1::2])
    assert np.all(plan.positions >= lo - 1e-12) and np.all(plan.positions <= hi + 1e-12)
    start = c.solver.feasible(np.stack([g["ux"], g["uy"], g["omega"]], axis=-1).transpose(1, 0, 2), pos)
    assert plan.cost <= c.solver.problem.cost(rho_c, pos, heads, start, c.target_coarse) + 1e-12


def test_without_speed_limits_three_qps_still_improve_on_standing_still():
    """No disks to bound the steps: the trust region and the backtracking keep the SQP's steps useful."""
    lp = ClosedLoop(small_scenario().with_values({"robots.u_max": "none", "robots.omega_max": "none"}))
    c = controller_for(lp)
    rho_c = c.restrict(lp.density)
    pos, heads = lp.robots.positions.copy(), lp.robots.headings.copy()
    plan = c.solve(rho_c, pos, heads)
    H, n = c.options.horizon, c.n
    assert plan.iterations == 3 and np.abs(plan.u).max() > 0
    assert plan.cost < 0.95 * c.predicted_cost(rho_c, pos, heads, np.zeros((H, n, 2)), np.zeros((H, n)))
    lo, hi = np.array(c.region[0::2]), np.array(c.region[1::2])
    assert np.all(plan.positions >= lo - 1e-12) and np.all(plan.positions <= hi + 1e-12)


def test_move_blocking_holds_each_input_over_its_block(small_loop):
    c, rho_c, pos, heads, plan = solved_instance(small_loop, blocks=[1, 2])
    assert plan.success
    assert np.array_equal(plan.u[1], plan.u[2]) and np.array_equal(plan.omega[1], plan.omega[2])
    assert not np.array_equal(plan.u[0], plan.u[1])
    assert c.predicted_cost(rho_c, pos, heads, plan.u, plan.omega) == pytest.approx(plan.cost, rel=1e-9)
    # fewer freedoms: never better than the unblocked optimum
    assert plan.cost >= solved_instance(small_loop)[-1].cost - 1e-9
