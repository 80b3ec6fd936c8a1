"""The backstepping controller: Step I (v_d), Step II (robot law), β/γ strategies and the
semi-discrete Lyapunov identities of Theorems 1 and 3, checked by complex-step differentiation."""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import (
    BacksteppingController,
    ConstantAlpha,
    Domain,
    GaussianKernel,
    GaussianPotential,
    Grid,
    InteractionField,
    MinimumNormBetaGamma,
    NavigationField,
    ParameterError,
    SaturatingAlpha,
    UserBetaGamma,
)
from meanfield.geometry.target import gaussian_target
from tests.conftest import lyapunov_v2, smooth_density

EPS = 1e-30  # complex step: Im f(x + iεẋ)/ε = f'(x)ẋ with no cancellation error


def _grid() -> Grid:
    return Grid(Domain.box(1.0, 1.2), (20, 24))


def _controller(grid, alpha, sigma=0.002, k_u=1.0, k_omega=3.0, interaction=False):
    target = gaussian_target(grid, (0.75, 0.9), 0.18)
    inter = InteractionField(grid, GaussianPotential(0.05, 0.15)) if interaction else None
    return BacksteppingController(grid, target, sigma, alpha, k_u, k_omega, MinimumNormBetaGamma(), inter, "model")


def _robots(n, seed=3):
    rng = np.random.default_rng(seed)
    return rng.uniform([0.1, 0.1], [0.9, 1.1], size=(n, 2)), rng.uniform(0, 2 * np.pi, n)


ALPHAS = [SaturatingAlpha(0.1, 0.2), ConstantAlpha(0.05)]


# ---------------------------------------------------------------------- Theorem 3 (semi-discrete)


CASES = [
    # alpha schedule, sigma, n robots, k_u, k_omega, interaction
    (ALPHAS[0], 0.002, 4, 1.0, 3.0, False),
    (ALPHAS[1], 0.002, 5, 0.5, 0.0, False),
    (ALPHAS[0], 0.01, 6, np.array([0.0, 1.0, 2.0, 0.5, 3.0, 1.5]), np.array([1.0, 0.0, 2.0, 4.0, 0.5, 1.0]), False),
    (ALPHAS[0], 0.002, 4, 1.0, 3.0, True),
    (ALPHAS[1], 0.005, 3, 2.0, 1.0, True),
]


@pytest.mark.parametrize(
    ("alpha", "sigma", "n", "k_u", "k_omega", "interaction"),
    CASES,
    ids=["saturating", "constant-no-turning-gain", "per-robot-gains", "interaction", "interaction-constant"],
)
def test_lyapunov_identity_semi_discrete(alpha, sigma, n, k_u, k_omega, interaction):
    """dV₂/dt = -∫α|∇ρ̃|² - Σ k_u|b_i|² - Σ k_ω g_i² for the semi-discrete closed loop
    (ρ̇ = density_rate(ρ, v_r), Ṙ = u, θ̇ = ω; min-norm β/γ, model-based ∂_t v_d).

    dV₂/dt is computed independently by complex-step differentiation of V₂ along
    (ρ̇, u, ω): exact to round-off, so the identity must hold to ~1e-9 relative."""
    g = _grid()
    ctrl = _controller(g, alpha, sigma, k_u, k_omega, interaction)
    kernel = GaussianKernel(0.5, 0.03)
    rho = smooth_density(g)
    R, th = _robots(n)
    field = NavigationField(kernel, g, R, th)
    st = ctrl.robot_inputs(rho, field)
    rho_dot = ctrl.density_rate(rho, field.velocity())
    dV = lyapunov_v2(ctrl, kernel, rho + 1j * EPS * rho_dot, R + 1j * EPS * st.u, th + 1j * EPS * st.omega).imag / EPS
    ku = np.broadcast_to(np.asarray(k_u, float), (n,))
    kw = np.broadcast_to(np.asarray(k_omega, float), (n,))
    expected = -st.dissipation - (ku * (st.b**2).sum(1)).sum() - (kw * st.g**2).sum()
    scale = st.dissipation + abs(st.A) + (ku * (st.b**2).sum(1)).sum() + (kw * st.g**2).sum()
    assert st.shortfall == 0
    assert abs(dV - expected) <= 1e-9 * scale, (dV, expected)


@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize("interaction", [False, True])
def test_theorem1_identity(alpha, interaction):
    """With v_r = v_d exactly, V₁ = ∫ρ̃² decays as dV₁/dt = -2∫α|∇ρ̃|² (complex step along
    ρ̇ = density_rate(ρ, v_d)), and the dissipation is positive."""
    g = _grid()
    ctrl = _controller(g, alpha, 0.004, interaction=interaction)
    rho = smooth_density(g)
    rho_dot = ctrl.density_rate(rho, ctrl.virtual_velocity(rho))
    z = rho + 1j * EPS * rho_dot - ctrl.target
    dV1 = g.inner(z, z).imag / EPS
    diss = ctrl.dissipation(rho)
    assert diss > 0
    assert abs(dV1 + 2 * diss) <= 1e-9 * diss


def test_density_rate_is_the_fokker_planck_right_hand_side():
    """Pure diffusion (v_r = 0, W = 0, constant σ): ρ̇ = σ Δ_h ρ with the 5-point Laplacian
    and zero-flux walls, written out by hand."""
    g = Grid(Domain.box(1.0, 1.2), (9, 11))
    sigma = 0.3
    ctrl = BacksteppingController(g, np.full(g.shape, 1 / g.area), sigma, ConstantAlpha(1.0))
    rho = smooth_density(g)
    zero = (np.zeros((8, 11)), np.zeros((9, 10)))
    p = np.pad(rho, 1, mode="edge")  # ghost cells equal to the wall cells: zero normal flux
    lap = (p[2:, 1:-1] - 2 * rho + p[:-2, 1:-1]) / g.dx**2 + (p[1:-1, 2:] - 2 * rho + p[1:-1, :-2]) / g.dy**2
    np.testing.assert_allclose(ctrl.density_rate(rho, zero), sigma * lap, rtol=1e-11, atol=1e-11 * np.abs(lap).max())


def test_density_rate_transports_along_the_velocity():
    """A uniform velocity (+1, 0) on an x-linear density: mass leaves the upwind (left)
    column and arrives in the right column; the rate conserves mass."""
    g = Grid(Domain.box(1.0, 1.0), (6, 5))
    ctrl = BacksteppingController(g, np.full(g.shape, 1.0), 0.0, ConstantAlpha(1.0))
    rho = np.ones(g.shape)
    v = (np.ones((5, 5)), np.zeros((6, 4)))
    rate = ctrl.density_rate(rho, v)
    expected = np.zeros(g.shape)
    expected[0] = -1.0 / g.dx
    expected[-1] = 1.0 / g.dx
    np.testing.assert_allclose(rate, expected, rtol=0, atol=1e-12)
    assert abs(g.integrate(rate)) < 1e-12


@pytest.mark.parametrize("alpha", ALPHAS)
def test_virtual_velocity_rate_is_the_derivative_of_v_d(alpha, rng):
    """The model-based ∂_t v_d (chain rule) equals the complex-step derivative of v_d along ρ̇."""
    g = _grid()
    ctrl = _controller(g, alpha, 0.003)
    rho = smooth_density(g)
    rho_dot = rng.normal(size=g.shape)
    rate = ctrl.virtual_velocity_rate(rho, rho_dot)
    cs = ctrl.virtual_velocity(rho + 1j * EPS * rho_dot)
    for a, b in zip(rate, cs, strict=True):
        np.testing.assert_allclose(a, b.imag / EPS, rtol=1e-11, atol=1e-11 * np.abs(a).max())


def test_virtual_velocity_formula_constant_alpha():
    """v_d = -(α∇ρ̃ - σ∇ρ)/ρ_f on the faces, written out for the box."""
    g = Grid(Domain.box(1.0, 1.0), (7, 6))
    X, Y = g.centers
    target = g.normalize(1 + X)
    sigma, a0 = 0.02, 0.3
    ctrl = BacksteppingController(g, target, sigma, ConstantAlpha(a0))
    rho = smooth_density(g)
    vx, vy = ctrl.virtual_velocity(rho)
    rt = rho - target
    rfx = 0.5 * (rho[1:] + rho[:-1])
    ex = -(a0 * (rt[1:] - rt[:-1]) / g.dx - sigma * (rho[1:] - rho[:-1]) / g.dx) / rfx
    rfy = 0.5 * (rho[:, 1:] + rho[:, :-1])
    ey = -(a0 * (rt[:, 1:] - rt[:, :-1]) / g.dy - sigma * (rho[:, 1:] - rho[:, :-1]) / g.dy) / rfy
    np.testing.assert_allclose(vx, ex, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(vy, ey, rtol=1e-12, atol=1e-12)


def test_at_the_target_v_d_is_the_equilibrium_drift():
    """ρ = ρ_*: v_d balances diffusion, so density_rate(ρ_*, v_d) = 0."""
    g = _grid()
    ctrl = _controller(g, ALPHAS[0], 0.01, interaction=True)
    rate = ctrl.density_rate(ctrl.target, ctrl.virtual_velocity(ctrl.target))
    assert np.abs(rate).max() <= 1e-12 * np.abs(ctrl.target).max()


# ---------------------------------------------------------------------- β/γ
def test_minimum_norm_cancels_A(rng):
    b = rng.normal(size=(5, 2))
    g = rng.normal(size=5)
    A = 0.37
    ex = MinimumNormBetaGamma()(b, g, A)
    Z = (b**2).sum() + (g**2).sum()
    assert (b * ex.du).sum() - (g * ex.domega).sum() == pytest.approx(A, rel=1e-14)
    assert ex.shortfall == 0
    # β = b²/Z, γ = g²/Z: non-negative, summing to 1; δu = βA/b, δω = -γA/g
    beta, gamma = b**2 / Z, g**2 / Z
    assert beta.sum() + gamma.sum() == pytest.approx(1.0, rel=1e-14)
    np.testing.assert_allclose(ex.du, beta * A / b, rtol=1e-13)
    np.testing.assert_allclose(ex.domega, -gamma * A / g, rtol=1e-13)


def test_minimum_norm_with_nothing_to_act_on():
    ex = MinimumNormBetaGamma()(np.zeros((3, 2)), np.zeros(3), 0.5)
    assert np.all(ex.du == 0) and np.all(ex.domega == 0)
    assert ex.shortfall == 0.5


def test_user_beta_gamma(rng):
    b = rng.normal(size=(3, 2))
    g = rng.normal(size=3)
    A = -0.8

    def equal_split(b, g, A):
        return np.full(b.shape, 1 / 9), np.full(g.shape, 1 / 9)

    ex = UserBetaGamma(equal_split)(b, g, A)
    np.testing.assert_allclose(ex.du, A / (9 * b), rtol=1e-14)
    np.testing.assert_allclose(ex.domega, -A / (9 * g), rtol=1e-14)
    assert abs(ex.shortfall) < 1e-15
    with pytest.raises(ParameterError):
        UserBetaGamma(lambda b, g, A: (np.full(b.shape, 0.1), np.zeros(g.shape)))(b, g, A)
    b0 = b.copy()
    b0[0, 0] = 0.0
    with pytest.raises(ParameterError):
        UserBetaGamma(equal_split)(b0, g, A)


# ---------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"sigma": -0.1}, "sigma"),
        ({"sigma": float("nan")}, "sigma"),
        ({"k_u": -1.0}, "controller.k_u"),
        ({"k_omega": np.array([1.0, -0.1])}, "controller.k_omega"),
        ({"target": np.ones((3, 3))}, "target"),
        ({"dvd_dt": "guess"}, "controller.dvd_dt"),
    ],
)
def test_controller_refuses_bad_input(kwargs, name):
    g = Grid(Domain.box(), (6, 6))
    args = {"grid": g, "target": np.ones(g.shape), "sigma": 0.1, "alpha": ConstantAlpha(0.1)}
    args.update(kwargs)
    with pytest.raises(ParameterError) as info:
        BacksteppingController(**args)
    assert info.value.name == name


@pytest.mark.parametrize(
    ("make", "name"),
    [
        (lambda: ConstantAlpha(0.0), "controller.alpha"),
        (lambda: SaturatingAlpha(0.1, -1.0), "controller.rho_floor"),
        (lambda: SaturatingAlpha(float("nan"), 1.0), "controller.alpha"),
    ],
)
def test_alpha_schedules_refuse_bad_input(make, name):
    with pytest.raises(ParameterError) as info:
        make()
    assert info.value.name == name


def test_saturating_alpha_bounds_alpha_over_rho(rng):
    a = SaturatingAlpha(0.1, 0.2)
    r = rng.uniform(0, 10, size=100)
    np.testing.assert_allclose(a.over_rho(r) * r, a.alpha(r), rtol=1e-14)
    assert np.all(a.over_rho(r) <= 0.1 / 0.2)
    # derivative of α/ρ by complex step
    np.testing.assert_allclose(a.over_rho(r + 1j * EPS).imag / EPS, a.over_rho_derivative(r), rtol=1e-13)
    c = ConstantAlpha(0.3)
    r = r + 0.1
    np.testing.assert_allclose(c.over_rho(r + 1j * EPS).imag / EPS, c.over_rho_derivative(r), rtol=1e-13)


def test_the_law_and_the_scenario_agree_on_every_default():
    """One set of defaults: a BacksteppingController built without gains is the scenario's law."""
    import inspect

    from meanfield.scenarios.scenario import ControllerSpec

    spec = ControllerSpec()
    params = inspect.signature(BacksteppingController).parameters
    for name in ("k_u", "k_omega", "dvd_dt"):
        assert params[name].default == getattr(spec, name), name
    from meanfield.controllers.backstepping import DVD_DT_OPTIONS

    assert spec.dvd_dt in DVD_DT_OPTIONS


def test_the_paper_law_refuses_options_it_does_not_take():
    """``[controller.options] alpah = 5`` ran unnoticed with the default controller (issue "Nothing
    lost", item 7): every controller now refuses an option it does not know."""
    from meanfield import ParameterError, paper_scenario

    for options in ({"alpah": 5}, {"k_u": "banana"}):
        with pytest.raises(ParameterError) as exc:  # refused as the scenario is read
            paper_scenario(seed=0).with_values({f"controller.options.backstepping.{k}": v for k, v in options.items()})
        assert exc.value.name == "controller.options.backstepping" and "[controller]" in str(exc.value)

