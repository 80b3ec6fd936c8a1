"""The NMPC baseline (analysis.nmpc): the coarse model against exact answers, the compiled
problem (limits, determinism, improvement over zero input), options and the plugin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.nmpc import CoarseFokkerPlanck, NMPCController, NMPCOptions, nmpc_controller_for
from meanfield import ClosedLoop, Domain, GaussianKernel, Grid, ParameterError, paper_scenario, plugins
from meanfield.robots import navigation_velocity
from meanfield.scenario import (
    ControllerSpec,
    CrowdSpec,
    GridSpec,
    KernelSpec,
    RobotSpec,
    Scenario,
    TargetSpec,
)

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


def test_inputs_respect_the_limits_every_step(small_loop):
    loop = ClosedLoop(small_scenario())
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
    assert len(c.stats) >= 5 and all(s["seconds"] > 0 for s in c.stats)
    for s in c.stats:  # IPOPT's own solution, before projection
        assert s["max_speed_solver"] <= u_max * (1 + 1e-6) and s["max_turn_rate_solver"] <= w_max * (1 + 1e-6)
    assert len(c.backstepping_seconds) == result.summary["steps"] + 1  # + the final frame's diagnostics


def test_compiled_function_is_deterministic(small_loop):
    c = small_loop.controller
    rho_c = c.restrict(small_loop.density)
    pos, heads = small_loop.robots.positions.copy(), small_loop.robots.headings.copy()
    guess = c.initial_guess(rho_c, pos, heads)
    a = c.solve(rho_c, pos, heads, guess)
    b = c.solve(rho_c, pos, heads, guess)
    assert a.status == b.status and a.iterations == b.iterations
    for name in ("u", "omega", "positions", "headings", "rho"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.cost == b.cost


def test_plan_improves_its_predicted_cost_over_zero_input(small_loop):
    """Crowd on the left, target on the right, robots at the crowd: over a 1.5 s horizon the
    plan must beat standing still, and turn the signs towards the target."""
    lp = small_loop
    c = NMPCController(
        lp.grid,
        lp.target,
        lp.kernel,
        lp.parts.sigma,
        lp.robots,
        lp.controller.backstepping,
        {"horizon": 3, "cells": 6, "step": 0.5},
    )
    rho_c = c.restrict(lp.crowd.density())
    pos, heads = lp.robots.positions.copy(), lp.robots.headings.copy()
    plan = c.solve(rho_c, pos, heads)
    assert plan.success, plan.status
    H, n = c.options.horizon, c.n
    zero = c.predicted_cost(rho_c, pos, heads, np.zeros((H, n, 2)), np.zeros((H, n)))
    planned = c.predicted_cost(rho_c, pos, heads, plan.u, plan.omega)
    # the compiled problem and the numerical rollout are the same model
    assert planned == pytest.approx(plan.cost, rel=1e-6)
    assert planned < 0.9 * zero
    vx, _ = c.model.face_velocity(plan.positions[-1], plan.headings[-1])
    vx0, _ = c.model.face_velocity(pos, heads)
    assert vx.sum() > max(vx0.sum(), 0.0)  # the field now points towards the target (+x)


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
