"""The NMPC baseline (analysis.nmpc): the coarse model against exact answers, the compiled
problem (limits, determinism, improvement over zero input), options and the plugin; the
real-time solver (analysis.nmpc_condensed, nmpc_qp, nmpc_sqp): its derivatives, its QP, the
same optimum as IPOPT, warm starts, move blocking and the limits under early stops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.nmpc import CoarseFokkerPlanck, NMPCController, NMPCOptions, nmpc_controller_for
from analysis.nmpc_condensed import CondensedProblem, block_counts
from analysis.nmpc_qp import InputQP
from meanfield import ClosedLoop, Domain, GaussianKernel, Grid, ParameterError, paper_scenario, plugins
from meanfield.scenarios.scenario import (
    ControllerSpec,
    CrowdSpec,
    GridSpec,
    KernelSpec,
    RobotSpec,
    Scenario,
    TargetSpec,
)
from meanfield.signs.robots import navigation_velocity

BOUNDS = (-0.3, 0.8, 0.7, 1.6)  # an offset, non-square box
KERNEL = GaussianKernel(0.2, 0.05)


def model(cells=(7, 5), sigma=0.02, step=0.3, flux="upwind", n=3) -> CoarseFokkerPlanck:
    return CoarseFokkerPlanck(BOUNDS, cells, sigma, KERNEL, n, step, flux)


def random_density(m: CoarseFokkerPlanck, rng: np.random.Generator) -> np.ndarray:
    rho = rng.uniform(0.1, 2.0, m.shape)
    return rho / m.mass(rho)


def random_robots(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    x0, x1, y0, y1 = BOUNDS
    pos = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    return pos, rng.uniform(0, 2 * np.pi, n)


def zero_velocity(m: CoarseFokkerPlanck) -> tuple[np.ndarray, np.ndarray]:
    nx, ny = m.shape
    return np.zeros((nx - 1, ny)), np.zeros((nx, ny - 1))


# ---------------------------------------------------------------------- the coarse model
@pytest.mark.parametrize("flux", ["upwind", "central"])
def test_coarse_step_conserves_mass_to_round_off(flux, rng):
    m = model(flux=flux, step=1.0)
    rho = random_density(m, rng)
    for _ in range(3):
        vel = m.face_velocity(*random_robots(3, rng))
        assert abs(m.mass(m.rate(rho, vel))) < 1e-14
        rho = m.step_density(rho, vel)
        assert m.mass(rho) == pytest.approx(1.0, abs=1e-13)


def test_walls_carry_no_flux():
    """σ = 0 and a field pushing into the right wall: mass piled against it stays, exactly."""
    m = model(sigma=0.0, step=5.0)
    nx, ny = m.shape
    vx, vy = np.full((nx - 1, ny), 0.3), np.zeros((nx, ny - 1))
    rho = np.zeros(m.shape)
    rho[-1, :] = 1.0
    rho /= m.mass(rho)
    assert np.array_equal(m.rate(rho, (vx, vy)), np.zeros(m.shape))
    assert np.allclose(m.step_density(rho, (vx, vy)), rho, rtol=0, atol=1e-15)
    # and a uniform density is pushed against the wall without losing mass
    flat = np.full(m.shape, 1.0 / m.mass(np.ones(m.shape)))
    after = m.step_density(flat, (vx, vy))
    assert m.mass(after) == pytest.approx(1.0, abs=1e-13)
    assert after[-1].sum() > flat[-1].sum() and after[0].sum() < flat[0].sum()


def test_no_field_no_noise_is_stationary(rng):
    m = model(sigma=0.0)
    rho = random_density(m, rng)
    assert np.array_equal(m.rate(rho, zero_velocity(m)), np.zeros(m.shape))
    assert np.allclose(m.step_density(rho, zero_velocity(m)), rho, rtol=1e-15, atol=0)


@pytest.mark.parametrize(("k", "l"), [(1, 0), (2, 3), (6, 4)])
def test_diffusion_of_a_cosine_mode_has_the_exact_discrete_factor(k, l):
    """Backward Euler on the Neumann Laplacian: the mode cos(πk(i+½)/nx) cos(πl(j+½)/ny)
    is multiplied by 1 / (1 + Δt σ (4/Δx² sin²(πk/2nx) + 4/Δy² sin²(πl/2ny)))."""
    sigma, step = 0.02, 0.3
    m = model(sigma=sigma, step=step)
    nx, ny = m.shape
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    mode = np.cos(np.pi * k * (i + 0.5) / nx) * np.cos(np.pi * l * (j + 0.5) / ny)
    lam = 4 / m.dx**2 * math.sin(math.pi * k / (2 * nx)) ** 2 + 4 / m.dy**2 * math.sin(math.pi * l / (2 * ny)) ** 2
    after = m.step_density(1.0 + 0.5 * mode, zero_velocity(m))
    np.testing.assert_allclose(after - 1.0, 0.5 * mode / (1 + step * sigma * lam), rtol=0, atol=1e-13)


def test_upwind_step_keeps_the_density_positive_for_any_step(rng):
    m = model(sigma=0.001, step=50.0, n=6)
    rho = np.zeros(m.shape)
    rho[3, 2] = 1.0 / m.cell_volume  # a point mass
    vel = m.face_velocity(*random_robots(6, rng))
    assert m.step_density(rho, vel).min() >= -1e-15


def test_face_velocity_is_the_navigation_field_at_the_faces(rng):
    m = model(n=4)
    pos, heads = random_robots(4, rng)
    vx, vy = m.face_velocity(pos, heads)
    X, Y = np.meshgrid(m.x_faces, m.y, indexing="ij")
    ref = navigation_velocity(KERNEL, pos, heads, np.column_stack([X.ravel(), Y.ravel()]))
    np.testing.assert_allclose(vx.ravel(), ref[:, 0], rtol=1e-12, atol=1e-15)
    X, Y = np.meshgrid(m.x, m.y_faces, indexing="ij")
    ref = navigation_velocity(KERNEL, pos, heads, np.column_stack([X.ravel(), Y.ravel()]))
    np.testing.assert_allclose(vy.ravel(), ref[:, 1], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("cells", [(10, 10), (12, 7)])
def test_restriction_averages_and_keeps_unit_mass(cells, rng):
    fine = Grid(Domain.box(1.1, 0.9, origin=(-0.3, 0.7)), cells=(30, 30))
    m = CoarseFokkerPlanck(fine.domain.bounds, cells, 0.01, KERNEL, 1, 0.1)
    rho = fine.normalize(rng.uniform(0.5, 1.5, fine.shape))
    rc = m.restrict(rho, fine)
    assert m.mass(rc) == pytest.approx(1.0, abs=1e-13)
    if cells == (10, 10):  # whole 3×3 blocks: the block means
        np.testing.assert_allclose(rc, rho.reshape(10, 3, 10, 3).mean(axis=(1, 3)), rtol=1e-13)


# ---------------------------------------------------------------------- options
@pytest.mark.parametrize(
    ("options", "key"),
    [
        ({"horizon_steps": 4}, "controller.options.horizon_steps"),
        ({"horizon": -1}, "controller.options.horizon"),
        ({"horizon": 2.5}, "controller.options.horizon"),
        ({"period": 0}, "controller.options.period"),
        ({"r_u": -1.0}, "controller.options.r_u"),
        ({"cells": 2}, "controller.options.cells"),
        ({"flux": "donor"}, "controller.options.flux"),
        ({"hessian": "bfgs"}, "controller.options.hessian"),
        ({"warm_start": "yes"}, "controller.options.warm_start"),
        ({"solver": "snopt"}, "controller.options.solver"),
        ({"max_iter": 0}, "controller.options.max_iter"),
        ({"blocks": [1, 2]}, "controller.options.blocks"),  # does not sum to the horizon (5)
        ({"blocks": [0, 5]}, "controller.options.blocks"),
        ({"blocks": 5}, "controller.options.blocks"),
        ({"solver": "ipopt", "blocks": [2, 3]}, "controller.options.blocks"),  # SQP only
        ({"solver": "ipopt", "hessian": "gauss-newton"}, "controller.options.hessian"),
        ({"hessian": "limited-memory"}, "controller.options.hessian"),  # IPOPT only
        ({"spread": 1}, "controller.options.spread"),
        ({"solver": "ipopt", "spread": True}, "controller.options.spread"),  # SQP only
    ],
)
def test_bad_options_name_the_key(options, key):
    with pytest.raises(ParameterError) as exc:
        NMPCOptions.from_mapping(options)
    assert exc.value.name == key


def test_bad_option_through_the_closed_loop():
    sc = paper_scenario().with_values({"controller.kind": "nmpc", "controller.options.horizon": -3})
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)
    assert exc.value.name == "controller.options.horizon"


def test_options_defaults_and_prediction_step():
    o = NMPCOptions.from_mapping({"cells": 12, "period": 0.1})
    assert o.cells == (12, 12) and o.prediction_step == 0.1
    assert NMPCOptions(step=0.3).prediction_step == 0.3
    assert o.solver == "sqp" and o.iteration_limit == 3 and o.spread and o.input_blocks == (1, 1, 3)
    assert NMPCOptions(horizon=3).input_blocks == (1, 1, 1) and NMPCOptions(horizon=8).input_blocks == (1, 1, 6)
    assert NMPCOptions(blocks=[1] * 5).input_blocks == (1,) * 5
    ipopt = NMPCOptions(solver="ipopt")
    assert ipopt.iteration_limit == 50 and not ipopt.spread


def test_non_box_domain_is_refused():
    sc = (
        paper_scenario()
        .replace(domain=Domain.disk(0.5, (0.5, 0.5)))
        .with_values({"controller.kind": "nmpc", "target.center": [0.5, 0.5]})
    )
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)
    assert exc.value.name == "domain"


# ---------------------------------------------------------------------- the controller
def small_scenario(**options) -> Scenario:
    """A crowd on the left, the target on the right, four robots next to the crowd."""
    opts = {"horizon": 3, "cells": 6, "period": 0.1, **options}
    return Scenario(
        name="nmpc-test",
        seed=3,
        dt=0.05,
        t_final=0.5,
        record_every=2,
        grid=GridSpec((12, 12)),
        crowd=CrowdSpec(n=100, initial="gaussian", initial_center=(0.3, 0.5), initial_std=0.1, sigma=0.01),
        robots=RobotSpec(
            n=4,
            layout="explicit",
            positions=[[0.2, 0.35], [0.2, 0.65], [0.4, 0.35], [0.4, 0.65]],
            headings=[0.0, 1.0, 2.0, 3.0],
            u_max=0.05,
            omega_max=0.5,
        ),
        kernel=KernelSpec(c=0.3, eta=0.05),
        target=TargetSpec(center=(0.8, 0.5), std=0.12),
        controller=ControllerSpec(kind="nmpc", options=opts),
    )


@pytest.fixture(scope="module")
def small_loop() -> ClosedLoop:
    return ClosedLoop(small_scenario())


def test_plugin_is_the_factory():
    assert plugins.load("controller", "nmpc") is nmpc_controller_for
    assert "nmpc" in plugins.available("controller")


# the real-time solver (the default), with move blocking and one QP per period, and IPOPT
SOLVERS = [{}, {"spread": False}, {"blocks": [1, 2], "max_iter": 1}, {"solver": "ipopt"}]
SOLVER_IDS = ["sqp-defaults", "sqp-whole-solves", "sqp-blocked-1-iteration", "ipopt"]


def controller_for(lp: ClosedLoop, **options) -> NMPCController:
    """An NMPC controller on ``lp``'s parts with ``options`` (1.5 s horizon of 3 steps, 6×6 cells)."""
    opts = {"horizon": 3, "cells": 6, "step": 0.5, **options}
    return NMPCController(
        lp.grid,
        lp.target,
        lp.kernel,
        lp.parts.sigma,
        lp.robots,
        lp.controller.backstepping,
        opts,
        lp.parts.robot_region.bounds,
    )


@pytest.mark.parametrize("options", SOLVERS, ids=SOLVER_IDS)
def test_inputs_respect_the_limits_every_step(options):
    loop = ClosedLoop(small_scenario(**options))
    c = loop.controller
    assert isinstance(c, NMPCController)
    u_max, w_max = loop.robots.u_max, loop.robots.omega_max
    seen = []

    def check(lp):
        s = lp.last.command.state
        assert np.all(np.hypot(s.u[:, 0], s.u[:, 1]) <= u_max * (1 + 1e-6))
        assert np.all(np.abs(s.omega) <= w_max)
        assert math.isnan(s.shortfall) and np.isfinite(s.A)  # diagnostics from backstepping
        seen.append(np.hypot(s.u[:, 0], s.u[:, 1]).max())

    result = loop.run(progress=False, callback=check)
    assert result.summary["status"] == "completed" and len(seen) == 10
    assert result.summary["saturated_fraction"] == 0.0  # nothing left for the loop to saturate
    assert max(seen) > 0.9 * u_max  # the limit binds: the test is not vacuous
    solves = 5 if not c.options.spread else 3 if c.options.iteration_limit == 1 else 1  # (dt = period / 2)
    assert len(c.stats) >= solves and all(s["seconds"] > 0 for s in c.stats)
    for s in c.stats:  # the solver's own solution, before projection
        assert s["max_speed_solver"] <= u_max * (1 + 1e-6) and s["max_turn_rate_solver"] <= w_max * (1 + 1e-6)
    assert len(c.backstepping_seconds) == result.summary["steps"] + 1  # + the final frame's diagnostics


@pytest.mark.parametrize("options", SOLVERS, ids=SOLVER_IDS)
def test_compiled_function_is_deterministic(small_loop, options):
    c = controller_for(small_loop, **options)
    rho_c = c.restrict(small_loop.density)
    pos, heads = small_loop.robots.positions.copy(), small_loop.robots.headings.copy()
    guess = c.initial_guess(rho_c, pos, heads)
    a = c.solve(rho_c, pos, heads, guess)
    b = c.solve(rho_c, pos, heads, guess)
    assert a.status == b.status and a.iterations == b.iterations
    for name in ("u", "omega", "positions", "headings", "rho"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.cost == b.cost


@pytest.mark.parametrize("options", [{"max_iter": 100}, {"solver": "ipopt"}], ids=["sqp", "ipopt"])
def test_plan_improves_its_predicted_cost_over_zero_input(small_loop, options):
    """Crowd on the left, target on the right, robots at the crowd: over a 1.5 s horizon the
    plan must beat standing still, and turn the signs towards the target."""
    lp = small_loop
    c = controller_for(lp, **options)
    rho_c = c.restrict(lp.crowd.density())
    pos, heads = lp.robots.positions.copy(), lp.robots.headings.copy()
    plan = c.solve(rho_c, pos, heads)
    assert plan.success, plan.status
    H, n = c.options.horizon, c.n
    zero = c.predicted_cost(rho_c, pos, heads, np.zeros((H, n, 2)), np.zeros((H, n)))
    planned = c.predicted_cost(rho_c, pos, heads, plan.u, plan.omega)
    # the compiled problem and the numerical rollout are the same model
    assert planned == pytest.approx(plan.cost, rel=1e-6)
    np.testing.assert_allclose(plan.rho, c.model.predict(rho_c, pos, heads, plan.u, plan.omega)[0], atol=1e-10)
    assert planned < 0.9 * zero
    vx, _ = c.model.face_velocity(plan.positions[-1], plan.headings[-1])
    vx0, _ = c.model.face_velocity(pos, heads)
    assert vx.sum() > max(vx0.sum(), 0.0)  # the field now points towards the target (+x)


# ---------------------------------------------------------------------- the real-time solver
def solved_instance(lp: ClosedLoop, **options):
    """The small instance solved to a tight tolerance: the controller, its data and the plan."""
    c = controller_for(lp, **{"max_iter": 300, "tol": 1e-12, **options})
    rho_c = c.restrict(lp.crowd.density())
    pos, heads = lp.robots.positions.copy(), lp.robots.headings.copy()
    return c, rho_c, pos, heads, c.solve(rho_c, pos, heads)


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


def test_a_spread_solve_gives_the_plan_of_the_whole_solve_applied_from_its_start(small_loop):
    """``spread``: the robots hold still until the first plan, one slice per control step, and
    the plan is the one solving at once gives, applied from the time the solve started."""
    obs = ClosedLoop(small_scenario()).observe()
    whole = controller_for(small_loop, step=0.1, period=0.6, spread=False)
    whole.robot_inputs(obs.density, obs.field, 0.0)
    spread = controller_for(small_loop, step=0.1, period=0.6)  # spread: the default
    inputs = [spread.robot_inputs(obs.density, obs.field, 0.05 * i) for i in range(12)]
    first = spread.stats[0]
    assert first["slices"] >= 3 and first["t"] == 0.0 and first["slowest_slice"] <= first["seconds"]
    for state in inputs[: first["slices"] - 1]:  # before the plan is adopted
        assert not state.u.any() and not state.omega.any()
    for name in ("u", "omega", "positions", "headings", "rho"):
        assert np.array_equal(getattr(spread.plan, name), getattr(whole.plan, name)), name
    assert len(spread.stats) == 1  # the next solve is due at t = 0.6
    for i in range(first["slices"] - 1, 12):  # index by the time since the solve started (step 0.1)
        assert np.array_equal(inputs[i].u, whole.plan.u[min(int(0.05 * i / 0.1 + 1e-9), 2)])


@pytest.mark.parametrize(("flux", "blocks"), [("upwind", (1, 1, 1)), ("central", (2, 1))])
def test_condensed_derivatives_are_exact(flux, blocks, rng):
    """The adjoint gradient and the exact reduced Hessian against central differences of the
    cost and of the gradient; the Gauss–Newton variant has the same gradient."""
    m = model(cells=(5, 4), sigma=0.02, step=0.3, flux=flux, n=3)
    p = CondensedProblem(m, blocks, r_u=0.1, r_omega=1e-3, terminal=1.0)
    rho0, target = random_density(m, rng), random_density(m, rng)
    R0, th0 = random_robots(3, rng)
    z = rng.uniform(-0.3, 0.3, (len(blocks), 3, 3))
    J, g, H = p.derivatives(rho0, R0, th0, z, target)
    u, w = z[p.beta, :, :2], z[p.beta, :, 2]
    P, _, _ = m.predict(rho0, R0, th0, u, w)
    e = P[1:] - target
    ref = m.step * (m.cell_volume * np.sum(e * e) + 0.1 * np.sum(u * u) + 1e-3 * np.sum(w * w))
    assert J == pytest.approx(ref + m.cell_volume * np.sum(e[-1] ** 2), rel=1e-12)  # the cost of docs/nmpc.md
    assert p.cost(rho0, R0, th0, z, target) == pytest.approx(J, rel=1e-12)
    eps = 1e-6
    for i in range(z.size):
        dz = np.zeros(z.size)
        dz[i] = eps
        fd = (p.cost(rho0, R0, th0, z.ravel() + dz, target) - p.cost(rho0, R0, th0, z.ravel() - dz, target)) / (2 * eps)
        assert g[i] == pytest.approx(fd, rel=1e-5, abs=1e-9)
        col = (
            p.derivatives(rho0, R0, th0, z.ravel() + dz, target)[1]
            - p.derivatives(rho0, R0, th0, z.ravel() - dz, target)[1]
        ) / (2 * eps)
        np.testing.assert_allclose(H[:, i], col, rtol=1e-4, atol=1e-7 * np.abs(H).max())
    _, g_gn, H_gn = p.derivatives(rho0, R0, th0, z, target, exact=False)
    np.testing.assert_allclose(g_gn, g, rtol=1e-14, atol=1e-15)
    assert np.linalg.eigvalsh(H_gn).min() > 0


def test_the_qp_solver_matches_a_conic_solver(rng):
    """The dense interior point of InputQP against Clarabel (through cvxpy) on the same QP,
    with speed disks, turn-rate bounds and region bounds active."""
    cp = pytest.importorskip("cvxpy")
    blocks, n, h = (1, 2), 3, 0.5
    N = block_counts(blocks)
    qp = InputQP(N, n, h, 0.2, 1.0, (0.0, 1.0, 0.0, 1.0))
    A = rng.normal(size=(30, 18))
    P, q = A.T @ A / 30 + 1e-3 * np.eye(18), rng.normal(0.0, 0.5, 18)
    R0 = np.array([[0.0, 0.0], [0.5, 0.5], [0.95, 0.98]])
    res = qp.solve(P, q, np.zeros(18), R0)
    assert res.converged and qp.constraints(res.x, R0).max() <= 1e-8
    x = cp.Variable((2 * n, 3))  # rows (block, robot), as InputQP's (B, n, 3)
    blk = [x[b * n : (b + 1) * n] for b in range(2)]
    cons = [cp.abs(x[:, 2]) <= 1.0, cp.norm(x[:, :2], axis=1) <= 0.2]
    for k in range(3):
        pos = R0 + h * sum(N[k, b] * blk[b][:, :2] for b in range(2))
        cons += [pos >= 0, pos <= 1]
    flat = cp.vec(x, order="C")
    cp.Problem(cp.Minimize(0.5 * cp.quad_form(flat, cp.psd_wrap(P)) + q @ flat), cons).solve(solver="CLARABEL")
    np.testing.assert_allclose(res.x, flat.value, atol=1e-6)
    assert np.sum(qp.constraints(res.x, R0) > -1e-7) >= 3  # not vacuous: constraints are active


def test_paper_scenario_runs_with_nmpc():
    sc = paper_scenario().with_values(
        {"controller.kind": "nmpc", "t_final": 0.2, "controller.options.horizon": 2, "controller.options.cells": 6}
    )
    loop = ClosedLoop(sc)
    result = loop.run(progress=False)
    assert result.summary["status"] == "completed"
    assert result.summary["max_robot_speed"] <= 0.2 * (1 + 1e-12)
    assert np.isfinite(result.dataset["V2"].values[1:]).all()
    summary = loop.controller.summary()
    assert summary["solves"] >= 1 and summary["ratio_solve_over_backstepping"] > 0
