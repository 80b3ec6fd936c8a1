"""The finite-volume Fokker–Planck solver (paper, eq. (4)): Scharfetter–Gummel fluxes,
exact discrete eigenmodes and steady states, convergence orders, mass, positivity,
input validation, and its use by the controller (dvd_dt="fokker-planck") and the
KDE's expected value.

Every numerical claim is checked against an exact answer: a closed-form discrete
eigenvalue or amplification factor, an exact discrete steady state (Gibbs), or an
analytic continuum solution with the observed convergence order (2 for O(h²): the error
must fall ~4× per halving of h, so the order log₂(e_h/e_{h/2}) is asserted in [1.8, 2.3]).
"""

from __future__ import annotations

import doctest
import functools
import math

import numpy as np
import pytest

import meanfield.fokker_planck.solver as fp_module
from meanfield import (
    BacksteppingController,
    ConstantAlpha,
    Domain,
    FokkerPlanck,
    GaussianKernel,
    GaussianPotential,
    Grid,
    InteractionField,
    KernelDensityEstimator,
    NavigationField,
    ParameterError,
)
from meanfield.fokker_planck.solver import METHODS, scharfetter_gummel

EPS = np.finfo(float).eps


def _box(n: int, lx: float = 1.0, ly: float = 1.0, origin=(0.0, 0.0), ny: int | None = None) -> Grid:
    return Grid(Domain.box(lx, ly, origin=origin), (n, ny or n))


@functools.cache
def _disk(n: int) -> Grid:
    """Cut-cell disk grids are read-only here: built once and shared."""
    return Grid(Domain.disk(0.5, center=(0.5, 0.5)), (n, n))


def _orders(errors) -> np.ndarray:
    """Observed orders log₂(e_h / e_{h/2}) of successive halvings."""
    e = np.asarray(errors, float)
    return np.log2(e[:-1] / e[1:])


def _bernoulli(z):
    """B(z) = z / (e^z - 1) by its Taylor series, for |z| <= 1e-3 (truncation ~ z⁶/30240)."""
    return 1 - z / 2 + z**2 / 12 - z**4 / 720


# ---------------------------------------------------------------------- 1. Scharfetter–Gummel
def test_sg_coefficients_conserve_drift_and_are_nonnegative():
    """c_left - c_right = a (the flux of a constant state is a ρ), both >= 0, for |P| <= 30."""
    h = 0.05
    sigma = np.array([1e-3, 0.02, 0.4])[:, None]
    P = np.linspace(-30, 30, 241)[None, :]
    a = P * sigma / h
    cl, cr = scharfetter_gummel(a, sigma, h)
    assert cl.shape == cr.shape == a.shape
    assert np.all(cl >= 0) and np.all(cr >= 0)
    # a few ulps of the larger coefficient (≈ max(|a|, σ/h))
    scale = np.maximum(np.abs(a), sigma / h)
    np.testing.assert_array_less(np.abs((cl - cr) - a), 8 * EPS * scale)


def test_sg_ratio_is_exp_of_peclet():
    """c_left / c_right = e^P exactly in real arithmetic: this ratio is what makes the
    discrete Gibbs state stationary, so it is checked to round-off. P is rebuilt inside from
    a = Pσ/h with a few roundings, and e^P amplifies a relative error δ of P into |P|δ:
    the bound is (4|P| + 8) ulps."""
    h, sigma = 0.04, 0.01
    P = np.linspace(-30, 30, 301)
    cl, cr = scharfetter_gummel(P * sigma / h, sigma, h)
    assert np.all(np.abs(cl / cr / np.exp(P) - 1) <= (4 * np.abs(P) + 8) * EPS)


def test_sg_small_peclet_matches_bernoulli_series():
    """No cancellation as P → 0: c_left = (σ/h) B(-P), c_right = (σ/h) B(P) to round-off."""
    h, sigma = 0.1, 0.03
    P = np.array([-1e-3, -1e-7, -1e-12, 0.0, 1e-12, 1e-7, 1e-3])
    cl, cr = scharfetter_gummel(P * sigma / h, sigma, h)
    np.testing.assert_allclose(cl, sigma / h * _bernoulli(-P), rtol=4 * EPS)
    np.testing.assert_allclose(cr, sigma / h * _bernoulli(P), rtol=4 * EPS)


def test_sg_zero_diffusion_is_upwind():
    a = np.array([-2.0, -0.3, 0.0, 0.7, 5.0])
    cl, cr = scharfetter_gummel(a, 0.0, 0.1)
    np.testing.assert_array_equal(cl, np.maximum(a, 0.0))
    np.testing.assert_array_equal(cr, np.maximum(-a, 0.0))
    # σ = 0 on some faces only (array diffusion)
    d = np.array([0.0, 0.1, 0.0, 0.1, 0.0])
    cl, cr = scharfetter_gummel(a, d, 0.1)
    np.testing.assert_array_equal(cl[d == 0], np.maximum(a, 0.0)[d == 0])
    np.testing.assert_array_equal(cr[d == 0], np.maximum(-a, 0.0)[d == 0])


def test_sg_zero_drift_is_pure_diffusion():
    d = np.array([1e-6, 0.01, 0.3, 2.0])
    cl, cr = scharfetter_gummel(np.zeros(4), d, 0.05)
    np.testing.assert_allclose(cl, d / 0.05, rtol=EPS)
    np.testing.assert_allclose(cr, d / 0.05, rtol=EPS)


@pytest.mark.parametrize("P", [1e4, -1e4, 1e6, -1e6])
def test_sg_extreme_peclet_is_finite_upwind(P):
    """|P| = 1e4: e^{|P|} overflows, the coefficients must not; they are the upwind ones
    (the downwind one is (σ/h)|P| e^{-|P|} = 0 in floating point)."""
    h, sigma = 0.1, 0.01
    a = np.array([P * sigma / h])
    cl, cr = scharfetter_gummel(a, sigma, h)
    assert np.all(np.isfinite(cl)) and np.all(np.isfinite(cr))
    np.testing.assert_allclose(cl, np.maximum(a, 0), rtol=4 * EPS)
    np.testing.assert_allclose(cr, np.maximum(-a, 0), rtol=4 * EPS)


@pytest.mark.parametrize("make_grid", [_box, _disk], ids=["box", "disk"])
def test_rhs_is_minus_divergence_of_the_public_flux(make_grid):
    """rhs() (the solver's coefficient path) equals -div of flux() (the public
    scharfetter_gummel) with every drift present: variable σ (and its -∇σ drift), a
    potential, a velocity, an interaction and a face velocity; on a box and on cut cells.
    Round-off relative to the largest face flux over the cell size."""
    grid = make_grid(20)
    X, Y = grid.centers
    rho = grid.normalize(np.where(grid.active, 1 + 0.5 * np.sin(3 * X) * np.cos(2 * Y), 0.0))
    fv = _moving_robots(grid, 3)[1]
    fp = FokkerPlanck(
        grid,
        lambda x, y, t: 0.01 * (1 + 0.5 * x * y + t),
        lambda x, y, t: (0.2 * np.cos(y) + 0 * x, -0.1 + 0 * y),
        potential=_potential,
        interaction=GaussianPotential(0.05, 0.15),
    )
    F = fp.flux(rho, 0.3, fv)
    expected = -grid.divergence(F)
    scale = max(np.abs(F[0]).max(), np.abs(F[1]).max()) / min(grid.dx, grid.dy)
    np.testing.assert_allclose(fp.rhs(rho, 0.3, fv), expected, rtol=0, atol=64 * EPS * scale)
    assert grid.integrate(fp.rhs(rho, 0.3, fv)) == pytest.approx(0.0, abs=64 * EPS * scale)


@pytest.mark.parametrize("method", METHODS)
def test_cached_coefficients_give_the_same_steps(method):
    """time_dependent=False (coefficients and factorisations reused) must reproduce the
    uncached computation of a time-independent problem to round-off."""
    grid = _disk(16)
    X, Y = grid.centers
    rho0 = grid.normalize(np.where(grid.active, np.exp(-((X - 0.4) ** 2 + (Y - 0.6) ** 2) / 0.03), 0.0))

    def velocity(x, y, t):
        return 0.3 * (0.5 - y), 0.3 * (x - 0.5)

    a = FokkerPlanck(grid, 0.01, velocity, potential=_potential, method=method, time_dependent=True)
    b = FokkerPlanck(grid, 0.01, velocity, potential=_potential, method=method, time_dependent=False)
    dt = 0.5 * a.positivity_bound(rho0) if method in ("explicit", "adi") else 0.02
    ra, rb = rho0, rho0
    for k in range(5):
        ra = a.step(ra, k * dt, dt)
        rb = b.step(rb, k * dt, dt)
    np.testing.assert_allclose(rb, ra, rtol=0, atol=1e-13 * ra.max())
    assert np.abs(ra - rho0).max() > 1e-3 * rho0.max()  # something did happen


@pytest.mark.parametrize("sigma", [1e-310, 5e-324])
def test_sg_subnormal_diffusion_is_finite(sigma):
    """σ > 0 is accepted however small; a subnormal σ makes h/σ overflow to inf, and
    |a|·inf (a ≠ 0) or 0·inf (a = 0) must not turn the coefficients into NaN. Exact
    answers: c = (σ/h)B(∓P) + upwind part, i.e. (1, 0) for a = 1, (0, 2) for a = -2 (the
    diffusive part (σ/h)B(|P|) underflows to 0) and (σ/h, σ/h) for a = 0."""
    h = 0.125
    cl, cr = scharfetter_gummel(np.array([1.0, -2.0, 0.0]), sigma, h)
    assert np.all(np.isfinite(cl)) and np.all(np.isfinite(cr))
    np.testing.assert_allclose(cl, [1.0, 0.0, sigma / h], rtol=1e-12, atol=1e-320)
    np.testing.assert_allclose(cr, [0.0, 2.0, sigma / h], rtol=1e-12, atol=1e-320)


# ---------------------------------------------------------------------- 2. Neumann cosine modes
def _mode(grid, k, l):
    X, Y = grid.centers
    x0, x1, y0, y1 = grid.domain.bounds
    return np.cos(k * np.pi * (X - x0) / (x1 - x0)) * np.cos(l * np.pi * (Y - y0) / (y1 - y0))


def _discrete_eigenvalues(grid, sigma, k, l):
    """λx, λy of σ × the cell-centred Neumann Laplacian on the mode cos(kπx/Lx)cos(lπy/Ly)."""
    x0, x1, y0, y1 = grid.domain.bounds
    lx = -sigma * 4 / grid.dx**2 * math.sin(k * math.pi * grid.dx / (2 * (x1 - x0))) ** 2
    ly = -sigma * 4 / grid.dy**2 * math.sin(l * math.pi * grid.dy / (2 * (y1 - y0))) ** 2
    return lx, ly


@pytest.mark.parametrize(("k", "l"), [(1, 0), (0, 3), (2, 3), (5, 1)])
def test_cosine_mode_is_exact_discrete_eigenvector(k, l):
    """For pure diffusion the cosine mode sampled at the cell centres is an exact eigenvector
    of the discrete operator, eigenvalue -σ Σ (4/h²) sin²(kπh/(2L)) (a closed form, not a
    limit); checked on a non-square offset box with nx ≠ ny, to round-off of the largest
    term of the right-hand side (σ (4/dx² + 4/dy²) × max|ρ|)."""
    grid = _box(20, 1.3, 0.8, origin=(-0.4, 0.2), ny=14)
    sigma = 0.07
    mode = _mode(grid, k, l)
    lam = sum(_discrete_eigenvalues(grid, sigma, k, l))
    fp = FokkerPlanck(grid, sigma)
    scale = sigma * (4 / grid.dx**2 + 4 / grid.dy**2)
    np.testing.assert_allclose(fp.rhs(mode), lam * mode, rtol=0, atol=50 * EPS * scale)
    # and on a positive density: the constant part is stationary
    rho = 1 + 0.4 * mode
    np.testing.assert_allclose(fp.rhs(rho), 0.4 * lam * mode, rtol=0, atol=50 * EPS * scale * 1.4)


def _amplification(method, dt, lx, ly):
    """Exact one-step amplification factor of each integrator on a joint eigenvector of the
    x- and y-operators (eigenvalues lx, ly)."""
    z = dt * (lx + ly)
    if method == "explicit":  # Heun: 1 + z + z²/2
        return 1 + z + z * z / 2
    if method == "split":  # backward Euler along x, then along y
        return 1 / ((1 - dt * lx) * (1 - dt * ly))
    if method == "adi":  # Peaceman–Rachford
        h = dt / 2
        return (1 + h * lx) * (1 + h * ly) / ((1 - h * lx) * (1 - h * ly))
    return 1 / (1 - z)  # implicit (backward Euler)


@pytest.mark.parametrize("method", METHODS)
def test_one_step_amplification_is_exact(method):
    """ρ = 1 + ε·mode is advanced to 1 + ε g·mode with g the method's closed-form
    amplification factor (Heun / split backward Euler / Peaceman–Rachford / backward Euler)."""
    grid = _box(16, 1.0, 0.75, ny=12)
    sigma, eps = 0.03, 0.5
    mode = _mode(grid, 2, 1)
    lx, ly = _discrete_eigenvalues(grid, sigma, 2, 1)
    fp = FokkerPlanck(grid, sigma, method=method)
    dt = 0.9 * fp.positivity_bound(1 + eps * mode) if method == "explicit" else 0.05
    rho = fp.step(1 + eps * mode, 0.0, dt)
    g = _amplification(method, dt, lx, ly)
    np.testing.assert_allclose(rho, 1 + eps * g * mode, rtol=0, atol=200 * EPS)
    assert abs(g) < 1  # the mode decays, as in the continuum


def _mode_error(n, method, sigma, T, dt=None):
    """Max error against the continuum solution 1 + ε cos(πx)cos(2πy) e^{-σπ²·5·t}."""
    grid = _box(n)
    mode = _mode(grid, 1, 2)
    eps = 0.5
    fp = FokkerPlanck(grid, sigma, method=method, time_dependent=False)
    rho = fp.solve(1 + eps * mode, T, dt=dt)
    exact = 1 + eps * mode * math.exp(-sigma * math.pi**2 * 5 * T)
    assert grid.integrate(rho) == pytest.approx(1.0, abs=1e-12)  # round-off, ≤ 1e-16 per step
    return np.abs(rho - exact).max()


@pytest.mark.parametrize("method", ["explicit", "adi"])
def test_space_convergence_second_order_automatic_dt(method):
    """Heun and Peaceman–Rachford are second order in time and their automatic step is
    ∝ h², so the total error is O(h²) + O(h⁴): the observed order must be ≈ 2."""
    errors = [_mode_error(n, method, 0.05, 0.5) for n in (16, 32, 64)]
    assert np.all(np.diff(errors) < 0)
    orders = _orders(errors)
    assert np.all((orders > 1.8) & (orders < 2.3)), orders


@pytest.mark.parametrize("method", ["split", "implicit"])
def test_space_convergence_second_order_with_dt_proportional_to_h2(method):
    """First order in time, so dt ∝ h² makes the total error O(h²)."""
    errors = [_mode_error(n, method, 0.05, 0.5, dt=0.005 * (16 / n) ** 2) for n in (16, 32, 64)]
    orders = _orders(errors)
    assert np.all((orders > 1.8) & (orders < 2.3)), orders


@pytest.mark.parametrize(
    ("method", "order", "steps"),
    [("split", 1, (8, 16, 32)), ("implicit", 1, (8, 16, 32)), ("adi", 2, (4, 8, 16)), ("explicit", 2, (32, 64, 128))],
)
def test_time_convergence_order(method, order, steps):
    """Against the exact semi-discrete solution 1 + ε·mode·e^{λ_h T} (the mode is an exact
    eigenvector), the error is purely temporal: order 1 for split/implicit, 2 for adi/explicit."""
    grid = _box(16)
    sigma, eps, T = 0.05, 0.5, 0.5
    mode = _mode(grid, 1, 2)
    exact = 1 + eps * mode * math.exp(sum(_discrete_eigenvalues(grid, sigma, 1, 2)) * T)
    fp = FokkerPlanck(grid, sigma, method=method, time_dependent=False)
    errors = [np.abs(fp.solve(1 + eps * mode, T, dt=T / n) - exact).max() for n in steps]
    orders = _orders(errors)
    assert np.all(np.abs(orders - order) < 0.1 * order), orders


# ---------------------------------------------------------------------- 3. Gibbs steady state
SIGMA_GIBBS = 0.05


def _potential(x, y):
    return 2 * (x - 0.35) ** 2 + (y - 0.6) ** 2 + 0.1 * np.sin(5 * x + 2 * y)


def _gibbs(grid):
    X, Y = grid.centers
    return grid.normalize(np.exp(-_potential(X, Y) / SIGMA_GIBBS))


@pytest.mark.parametrize("make_grid", [_box, _disk], ids=["box", "disk"])
def test_gibbs_state_is_exactly_stationary(make_grid):
    """exp(-U/σ) is stationary for the drift -∇U: the flux vanishes on every open face, to
    round-off relative to the two one-sided terms c_left ρ_L, c_right ρ_R that cancel
    (the state spans ~7 decades and the grid Péclet number reaches ~2.4)."""
    grid = make_grid(24)
    gibbs = _gibbs(grid)
    fp = FokkerPlanck(grid, SIGMA_GIBBS, potential=_potential)
    ax, ay = fp.drift(gibbs)
    assert max(np.abs(ax).max(), np.abs(ay).max()) * grid.dx / SIGMA_GIBBS > 2  # SG regime, not central
    Fx, Fy = fp.flux(gibbs)
    lx, rx = scharfetter_gummel(ax, SIGMA_GIBBS, grid.dx)
    ly, ry = scharfetter_gummel(ay, SIGMA_GIBBS, grid.dy)
    tx = np.maximum(lx * gibbs[:-1, :], rx * gibbs[1:, :])
    ty = np.maximum(ly * gibbs[:, :-1], ry * gibbs[:, 1:])
    open_x, open_y = grid.aperture_x > 0, grid.aperture_y > 0
    assert np.all(np.abs(Fx[open_x]) <= 16 * EPS * tx[open_x])
    assert np.all(np.abs(Fy[open_y]) <= 16 * EPS * ty[open_y])
    # cell rates: the same cancellation, scaled by the largest one-sided term per volume
    scale = max(tx.max(), ty.max()) / grid.dx
    assert np.abs(fp.rhs(gibbs)).max() <= 16 * EPS * scale


@pytest.mark.parametrize("make_grid", [_box, _disk], ids=["box", "disk"])
def test_implicit_reaches_gibbs_from_uniform(make_grid):
    """Backward Euler with dt = 100 ≫ 1/gap contracts the non-Gibbs part by ≥ 100× per step;
    6 steps reach the discrete Gibbs state to round-off (asserted ≤ 1e-10 relative)."""
    grid = make_grid(24)
    fp = FokkerPlanck(grid, SIGMA_GIBBS, potential=_potential, method="implicit", time_dependent=False)
    rho = fp.solve(grid.normalize(np.ones(grid.shape)), 600.0, dt=100.0)
    gibbs = _gibbs(grid)
    assert np.abs(rho - gibbs).max() <= 1e-10 * gibbs.max()
    # each LU solve conserves mass only to eps·cond(V + dt A) ≈ 1e-11 at dt = 100 (cond ≈ 6e4)
    assert grid.integrate(rho) == pytest.approx(1.0, abs=1e-10)


# ---------------------------------------------------------------------- 4. mass conservation
def _moving_robots(grid, n_frames):
    """Face velocities of 3 robots circling the centre, turning as they go (one per step,
    cycled with period n_frames, so the drift changes at every step)."""
    kernel = GaussianKernel(0.5, 0.05)
    out = []
    for k in range(n_frames):
        s = 2 * np.pi * k / n_frames
        ang = np.array([0.0, 2 * np.pi / 3, 4 * np.pi / 3]) + s
        R = np.column_stack([0.5 + 0.25 * np.cos(ang), 0.5 + 0.25 * np.sin(ang)])
        th = ang + np.pi / 2 + 0.3 * np.sin(3 * s)
        out.append(NavigationField(kernel, grid, R, th).velocity())
    return out


@pytest.mark.parametrize(("make_grid", "steps"), [(_box, 10_000), (_disk, 2_500)], ids=["box", "disk"])
def test_mass_conserved_over_many_steps_with_moving_drift(make_grid, steps):
    """Zero flux through the walls and a flux-form update: the total mass changes only by
    round-off, ≤ 1e-16 relative per step (1e-12 after 10⁴ steps on the box; the disk, whose
    cut cells are what could leak, runs 2500 steps against 2.5e-13 to keep the test fast)."""
    grid = make_grid(24)
    X, Y = grid.centers
    rho0 = grid.normalize(1 + np.exp(-((X - 0.3) ** 2 + (Y - 0.6) ** 2) / 0.02))
    frames = _moving_robots(grid, 101)
    m0 = grid.integrate(rho0)
    dt = 0.005  # below the explicit and ADI positivity bounds of every frame (≥ 0.0179)
    for method in ("split", "adi", "explicit"):
        fp = FokkerPlanck(grid, 0.01, method=method)
        rho = rho0
        for k in range(steps):  # the public, validated step: it would refuse a dt above the bound
            rho = fp.step(rho, k * dt, dt, face_velocity=frames[k % len(frames)])
        assert abs(grid.integrate(rho) - m0) <= 1e-16 * steps * m0, method
        assert rho.min() >= 0, method


# ---------------------------------------------------------------------- 5. positivity stress
SIGMA_STRESS = 1e-3


def _converging_swirl(x, y, t):
    """|v| = 0.5 everywhere, spiralling into (0.5, 0.5): grid Péclet 0.5·(1/64)/1e-3 ≈ 7.8."""
    dx, dy = x - 0.5, y - 0.5
    ux, uy = -dy - 0.5 * dx, dx - 0.5 * dy
    n = np.hypot(ux, uy) + 1e-300
    return 0.5 * ux / n, 0.5 * uy / n


def _stress_setup():
    grid = _box(64)
    X, Y = grid.centers
    rho0 = grid.normalize(0.01 + np.exp(-((X - 0.3) ** 2 + (Y - 0.5) ** 2) / (2 * 0.05**2)))
    return grid, rho0


@pytest.mark.parametrize(("method", "dt"), [("split", 0.05), ("implicit", 0.05), ("explicit", None), ("adi", None)])
def test_positivity_at_high_peclet(method, dt):
    grid, rho0 = _stress_setup()
    fp = FokkerPlanck(grid, SIGMA_STRESS, _converging_swirl, method=method, time_dependent=False)
    ax, ay = fp.drift(rho0)
    assert 7 < max(np.abs(ax).max(), np.abs(ay).max()) * grid.dx / SIGMA_STRESS < 9
    minima = []
    rho = fp.solve(rho0, 2.0, dt=dt, callback=lambda t, r: minima.append(r.min()))
    assert len(minima) >= 36
    assert min(minima) >= 0.0
    assert grid.integrate(rho) == pytest.approx(1.0, abs=1e-12)
    assert rho.max() > 5 * rho0.max()  # the drift does concentrate the crowd: a hard case


def test_central_flux_goes_negative_on_the_stress_case():
    """Contrast: the central flux a(ρ_L+ρ_R)/2 - σ(ρ_R-ρ_L)/h with forward Euler at a step
    inside its von Neumann stability limits (dt ≤ 2σ/|a|², dt ≤ h²/(4σ)) is not monotone at
    cell Péclet > 2 and produces negative densities on the same problem (so the positivity
    test above can fail)."""
    grid, rho0 = _stress_setup()
    fp = FokkerPlanck(grid, SIGMA_STRESS, _converging_swirl)
    ax, ay = fp.drift(rho0)
    h = grid.dx
    amax = max(np.abs(ax).max(), np.abs(ay).max())
    dt = 0.5 * min(2 * SIGMA_STRESS / amax**2, h * h / (4 * SIGMA_STRESS))

    def central(rho):
        Fx = ax * 0.5 * (rho[:-1] + rho[1:]) - SIGMA_STRESS * (rho[1:] - rho[:-1]) / h
        Fy = ay * 0.5 * (rho[:, :-1] + rho[:, 1:]) - SIGMA_STRESS * (rho[:, 1:] - rho[:, :-1]) / h
        return -grid.divergence((Fx, Fy))

    rho = rho0.copy()
    lowest = np.inf
    for _ in range(100):
        rho = rho + dt * central(rho)
        lowest = min(lowest, rho.min())
    assert lowest < -0.1
    assert grid.integrate(rho) == pytest.approx(1.0, abs=1e-12)  # conservative, just not monotone


# ---------------------------------------------------------------------- 6. explicit stability
def test_explicit_refuses_dt_above_the_bound():
    grid = _box(16)
    X, Y = grid.centers
    rho = grid.normalize(1 + 0.8 * np.cos(np.pi * X) * np.sin(np.pi * Y))
    fp = FokkerPlanck(grid, 0.01, lambda x, y, t: (0.4 + 0 * x, -0.3 + 0 * y), method="explicit")
    bound = fp.positivity_bound(rho)
    assert 0 < bound < math.inf
    with pytest.raises(ParameterError, match="dt") as info:
        fp.step(rho, 0.0, 1.01 * bound)
    assert info.value.name == "dt"
    out = fp.step(rho, 0.0, 0.99 * bound)
    assert out.min() >= 0
    assert grid.integrate(out) == pytest.approx(1.0, abs=1e-14)


def test_adi_refuses_a_dt_that_makes_the_density_negative():
    """Peaceman–Rachford is positive up to 2 min(V/Σ_out^x, V/Σ_out^y); far above it (20×, on
    the high-Péclet stress case, where the unchecked result reaches ≈ -37) the step is refused
    naming dt, while 0.99× the bound is accepted and positive. Split and implicit are
    unconditionally positive: their bound is inf."""
    grid, rho0 = _stress_setup()
    fp = FokkerPlanck(grid, SIGMA_STRESS, _converging_swirl, method="adi")
    bound = fp.positivity_bound(rho0)
    assert fp.step(rho0, 0.0, 0.99 * bound).min() >= 0
    with pytest.raises(ParameterError) as info:
        fp.step(rho0, 0.0, 20 * bound)
    assert info.value.name == "dt"
    for method in ("split", "implicit"):
        assert FokkerPlanck(grid, SIGMA_STRESS, _converging_swirl, method=method).positivity_bound(rho0) == math.inf


@pytest.mark.parametrize("method", ["explicit", "adi"])
def test_automatic_dt_with_a_drift_that_grows_in_time(method):
    """solve() with dt=None chooses the step itself and must never refuse it.

    A uniform drift v = (2t, 0) on a 16² box, σ = 0.01: a step taken from the bound at time t
    is too large for Heun's second stage (at t + dt) and for Peaceman–Rachford's coefficients
    (at t + dt/2), which see a larger drift and a smaller bound (regression: solve raised
    "invalid dt" although the caller passed no dt)."""
    grid = _box(16)
    fp = FokkerPlanck(grid, 0.01, lambda x, y, t: (2.0 * t + 0 * x, 0 * y), method=method)
    rho = fp.solve(grid.normalize(np.ones(grid.shape)), 1.0)
    assert rho.min() >= 0
    assert grid.integrate(rho) == pytest.approx(1.0, abs=1e-12)


# ---------------------------------------------------------------------- 7. bad input
def _grid7():
    return _box(8)


def _ok_rho():
    return np.ones((8, 8))


def _bad_calls():
    g = _grid7()
    rho = _ok_rho()
    neg = rho.copy()
    neg[2, 3] = -1e-3
    nan = rho.copy()
    nan[1, 1] = np.nan
    disk = Grid(Domain.disk(0.5, center=(0.5, 0.5)), (8, 8))
    outside_only = np.where(disk.active, 0.0, 1.0)  # mass only outside Ω: zero mass
    bad_fx = (np.zeros((8, 8)), np.zeros((8, 7)))
    calls = {
        "solve-negative": ("rho0", lambda: FokkerPlanck(g, 0.1).solve(neg, 1.0)),
        "solve-nan": ("rho0", lambda: FokkerPlanck(g, 0.1).solve(nan, 1.0)),
        "solve-shape": ("rho0", lambda: FokkerPlanck(g, 0.1).solve(np.ones((8, 9)), 1.0)),
        "solve-zero-mass": ("rho0", lambda: FokkerPlanck(g, 0.1).solve(np.zeros((8, 8)), 1.0)),
        "solve-mass-outside": ("rho0", lambda: FokkerPlanck(disk, 0.1).solve(outside_only, 1.0)),
        "step-negative": ("rho", lambda: FokkerPlanck(g, 0.1).step(neg, 0.0, 0.01)),
        "step-nan": ("rho", lambda: FokkerPlanck(g, 0.1).step(nan, 0.0, 0.01)),
        "step-shape": ("rho", lambda: FokkerPlanck(g, 0.1).step(np.ones(64), 0.0, 0.01)),
        "step-zero-mass": ("rho", lambda: FokkerPlanck(g, 0.1).step(np.zeros((8, 8)), 0.0, 0.01)),
        "sigma-negative": ("sigma", lambda: FokkerPlanck(g, -0.1)),
        "sigma-nan": ("sigma", lambda: FokkerPlanck(g, float("nan"))),
        "sigma-callable-negative": (
            "sigma",
            lambda: FokkerPlanck(g, lambda x, y, t: 0.1 - x, method="split").solve(rho, 0.1, dt=0.01),
        ),
        "sigma-callable-negative-rhs": ("sigma", lambda: FokkerPlanck(g, lambda x, y, t: -0.1 + 0 * x).rhs(rho)),
        "velocity-wrong-shape": (
            "velocity",
            lambda: FokkerPlanck(g, 0.1, lambda x, y, t: (np.zeros(3), np.zeros(3))).solve(rho, 0.1),
        ),
        "velocity-not-a-pair": ("velocity", lambda: FokkerPlanck(g, 0.1, lambda x, y, t: np.zeros(3)).solve(rho, 0.1)),
        "velocity-nan": (
            "velocity",
            lambda: FokkerPlanck(g, 0.1, lambda x, y, t: (np.nan * x, 0 * y)).step(rho, 0.0, 0.01),
        ),
        "velocity-not-callable": ("velocity", lambda: FokkerPlanck(g, 0.1, (0.1, 0.2))),
        "step-dt-zero": ("dt", lambda: FokkerPlanck(g, 0.1, method="split").step(rho, 0.0, 0.0)),
        "step-dt-negative": ("dt", lambda: FokkerPlanck(g, 0.1, method="split").step(rho, 0.0, -0.1)),
        "step-dt-nan": ("dt", lambda: FokkerPlanck(g, 0.1, method="split").step(rho, 0.0, float("nan"))),
        "solve-dt-zero": ("dt", lambda: FokkerPlanck(g, 0.1).solve(rho, 1.0, dt=0.0)),
        "solve-dt-nan": ("dt", lambda: FokkerPlanck(g, 0.1).solve(rho, 1.0, dt=float("nan"))),
        "method": ("method", lambda: FokkerPlanck(g, 0.1, method="crank-nicolson")),
        "cfl-zero": ("cfl", lambda: FokkerPlanck(g, 0.1, cfl=0.0)),
        "cfl-above-one": ("cfl", lambda: FokkerPlanck(g, 0.1, cfl=1.5)),
        "cfl-nan": ("cfl", lambda: FokkerPlanck(g, 0.1, cfl=float("nan"))),
        "step-face-velocity": ("face_velocity", lambda: FokkerPlanck(g, 0.1).step(rho, 0.0, 0.01, bad_fx)),
        "solve-face-velocity": ("face_velocity", lambda: FokkerPlanck(g, 0.1).solve(rho, 1.0, face_velocity=bad_fx)),
        "solve-face-velocity-callable": (
            "face_velocity",
            lambda: FokkerPlanck(g, 0.1).solve(rho, 1.0, face_velocity=lambda t: bad_fx),
        ),
        "t_final-before-t0": ("t_final", lambda: FokkerPlanck(g, 0.1).solve(rho, 0.5, t0=1.0)),
        "t_final-nan": ("t_final", lambda: FokkerPlanck(g, 0.1).solve(rho, float("nan"))),
    }
    return calls


BAD = _bad_calls()


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_refused_naming_the_argument(case):
    name, call = BAD[case]
    with pytest.raises(ParameterError) as info:
        call()
    assert info.value.name == name
    assert name in str(info.value)


def test_solve_with_t_final_equal_t0_returns_the_initial_state():
    g = _grid7()
    rho = g.normalize(np.arange(64.0).reshape(8, 8) + 1)
    out = FokkerPlanck(g, 0.1).solve(rho, 0.3, t0=0.3)
    np.testing.assert_array_equal(out, rho)


# ---------------------------------------------------------------------- 8. variable diffusion
def _sigma_variable(x, y, t):
    return 0.05 * (1 + 0.5 * np.sin(2.3 * x + 0.4) * np.cos(1.7 * y - 0.2) + 0.3 * x * y)


def test_variable_sigma_steady_state_is_one_over_sigma_second_order():
    """∂_t ρ = Δ(σρ) with zero flux: the steady state is ρ ∝ 1/σ (the flux -∇(σρ) vanishes).
    The discrete steady state (backward Euler with dt = 10⁴, LU cached) converges to it at
    second order in h."""
    errors = []
    for n in (16, 32, 64, 128):
        grid = _box(n)
        X, Y = grid.centers
        fp = FokkerPlanck(grid, _sigma_variable, method="implicit", time_dependent=False)
        rho = grid.normalize(np.ones(grid.shape))
        for _ in range(6):
            rho = fp.step(rho, 0.0, 1e4)
        assert np.abs(fp.rhs(rho)).max() < 1e-9  # it is the discrete steady state
        exact = grid.normalize(1 / _sigma_variable(X, Y, 0.0))
        errors.append(np.abs(rho - exact).max() / exact.max())
    orders = _orders(errors)
    assert np.all((orders > 1.8) & (orders < 2.3)), orders


# ---------------------------------------------------------------------- 9. interaction sign
S_BUMP, W_STRENGTH, W_LENGTH, SIGMA_W = 0.08, 0.05, 0.2, 0.002


def _bump(grid):
    X, Y = grid.centers
    r2 = (X - 0.5) ** 2 + (Y - 0.5) ** 2
    return r2, np.exp(-r2 / (2 * S_BUMP**2)) / (2 * np.pi * S_BUMP**2)


def test_repulsion_spreads_the_crowd_faster():
    """Second moment about the centre: pure diffusion adds exactly 4σt in free space (the
    discrete Laplacian maps |x|² to 4 exactly away from the walls, where the bump's density
    is ~1e-5 of its peak); a repulsive W (strength > 0) adds more, an attractive one less."""
    grid = _box(32)
    r2, rho0 = _bump(grid)
    T = 0.5
    m2 = {}
    for label, W in (("free", None), ("repulsive", W_STRENGTH), ("attractive", -W_STRENGTH)):
        inter = None if W is None else GaussianPotential(W, W_LENGTH)
        rho = FokkerPlanck(grid, SIGMA_W, interaction=inter).solve(grid.normalize(rho0), T)
        m2[label] = grid.integrate(r2 * rho) - grid.integrate(r2 * grid.normalize(rho0))
    assert m2["free"] == pytest.approx(4 * SIGMA_W * T, rel=1e-4)  # wall tail ~1e-5 relative
    assert m2["repulsive"] > 1.5 * m2["free"]
    assert m2["attractive"] < m2["free"]


def test_interaction_rate_of_second_moment_matches_closed_form():
    """For a Gaussian bump N(c, s²I) and W = S e^{-|z|²/ℓ²} (the SDE's sign, u_W = ∇W * ρ with
    ∇W(y - x)), d/dt ∫|x-c|²ρ = 4σ + 2 (S/ℓ²) E[|z|² e^{-|z|²/ℓ²}], z ~ N(0, 2s²I), i.e.
    4σ + 4 (S/ℓ²) v / (1 + 2v/ℓ²)² with v = 2s². The discrete rate converges at second order."""
    v = 2 * S_BUMP**2
    exact = 4 * SIGMA_W + 4 * (W_STRENGTH / W_LENGTH**2) * v / (1 + 2 * v / W_LENGTH**2) ** 2
    errors = []
    for n in (32, 64, 128):
        grid = _box(n)
        r2, rho0 = _bump(grid)
        fp = FokkerPlanck(grid, SIGMA_W, interaction=GaussianPotential(W_STRENGTH, W_LENGTH))
        errors.append(abs(grid.integrate(r2 * fp.rhs(rho0)) - exact))
    orders = _orders(errors)
    assert np.all((orders > 1.8) & (orders < 2.3)), orders
    assert errors[-1] < 0.05 * exact
    # an InteractionField is accepted as well and gives the same drift
    grid = _box(32)
    _, rho0 = _bump(grid)
    W = GaussianPotential(W_STRENGTH, W_LENGTH)
    a = FokkerPlanck(grid, SIGMA_W, interaction=W).rhs(rho0)
    b = FokkerPlanck(grid, SIGMA_W, interaction=InteractionField(grid, W)).rhs(rho0)
    np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------------- 10. documented example
def test_docstring_example_runs():
    finder = doctest.DocTestFinder()
    tests = [t for t in finder.find(fp_module) if t.name.endswith("FokkerPlanck") and t.examples]
    assert tests
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for t in tests:
        runner.run(t)
    assert runner.failures == 0 and runner.tries >= 4


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("scalar", [True, False], ids=["scalar-velocity", "array-velocity"])
def test_public_shape_solve_each_method(method, scalar):
    """fp = FokkerPlanck(grid, sigma=0.01, velocity=lambda x, y, t: (vx, vy));
    rho = fp.solve(rho0, t_final=2.0): unit mass, ρ >= 0, and the crowd moved downstream
    (+x: its mean x grew)."""
    grid = _box(32)
    X, _ = grid.centers
    if scalar:
        velocity = lambda x, y, t: (0.1, 0.0)  # noqa: E731
    else:
        velocity = lambda x, y, t: (0.1 + 0 * x, 0 * y)  # noqa: E731
    fp = FokkerPlanck(grid, sigma=0.01, velocity=velocity, method=method)
    rho0 = grid.normalize(np.ones(grid.shape))
    rho = fp.solve(rho0, t_final=2.0)
    assert grid.integrate(rho) == pytest.approx(1.0, abs=1e-12)
    assert rho.min() >= 0
    assert grid.integrate(X * rho) > grid.integrate(X * rho0) + 0.05


# ---------------------------------------------------------------------- 11. controller
def _controller_case(dvd_dt, sigma=0.004, interaction=None):
    grid = _box(20, 1.0, 1.2, ny=24)
    X, Y = grid.centers
    rho = grid.normalize(1 + 0.6 * np.exp(-((X - 0.3) ** 2 + (Y - 0.7) ** 2) / 0.05))
    target = grid.normalize(np.exp(-((X - 0.75) ** 2 + (Y - 0.9) ** 2) / (2 * 0.18**2)))
    inter = None if interaction is None else InteractionField(grid, interaction)
    ctrl = BacksteppingController(grid, target, sigma, ConstantAlpha(0.1), 1.0, 2.0, interaction=inter, dvd_dt=dvd_dt)
    rng = np.random.default_rng(5)
    R = rng.uniform([0.1, 0.1], [0.9, 1.1], size=(4, 2))
    th = rng.uniform(0, 2 * np.pi, 4)
    field = NavigationField(GaussianKernel(0.3, 0.05), grid, R, th)
    return grid, ctrl, rho, field


@pytest.mark.parametrize(
    ("sigma", "interaction"),
    [(0.004, None), (lambda x, y, t: 0.004 * (1 + 0.5 * x * y), None), (0.004, GaussianPotential(0.05, 0.15))],
    ids=["constant-sigma", "variable-sigma", "interaction"],
)
def test_controller_fokker_planck_dvd_dt_is_chain_rule_of_fp_rhs(sigma, interaction):
    """∂_t v_d = d/dε v_d(ρ + ε ρ̇) with ρ̇ = FokkerPlanck(grid, σ, W).rhs(ρ, face_velocity=v_r).

    The directional derivative is taken independently of the controller's chain rule, by
    complex-step differentiation (Im v_d(ρ + iερ̇)/ε, exact to round-off: no subtraction),
    and A (eq. (8)) rebuilt from it must match the controller's to round-off."""
    grid, ctrl, rho, field = _controller_case("fokker-planck", sigma, interaction)
    t = 0.0
    v_r = field.velocity()
    rho_dot = FokkerPlanck(grid, sigma, interaction=interaction).rhs(rho, t, face_velocity=v_r)
    e = 1e-30
    vc = ctrl.virtual_velocity(rho + 1j * e * rho_dot, t)
    dvd = [vc[k].imag / e for k in range(2)]
    v_d = ctrl.virtual_velocity(rho, t)
    vt = (v_r[0] - v_d[0], v_r[1] - v_d[1])
    rf = grid.face_average(rho)
    grt = grid.gradient(rho - ctrl.target)
    A = grid.face_inner(vt, (rf[0] * grt[0] - dvd[0], rf[1] * grt[1] - dvd[1]))
    state = ctrl.robot_inputs(rho, field, t)
    assert state.A == pytest.approx(A, rel=1e-11)
    # the option changes the result: "model" (central fluxes) gives another A
    _, model, _, _ = _controller_case("model", sigma, interaction)
    assert abs(model.robot_inputs(rho, field, t).A - state.A) > 1e-6 * abs(state.A)


def test_controller_rejects_unknown_dvd_dt():
    grid = _box(8)
    with pytest.raises(ParameterError) as info:
        BacksteppingController(grid, grid.normalize(np.ones(grid.shape)), 0.01, ConstantAlpha(0.1), dvd_dt="fp")
    assert info.value.name == "controller.dvd_dt"


def test_fp_rhs_agrees_with_central_density_rate_to_second_order():
    """At small cell Péclet (≤ 0.94 here), Scharfetter–Gummel differs from the central flux
    by O(a²h²/σ); both approximate the continuum -∇·(vρ) + σΔρ at O(h²). Smooth fields that
    satisfy the zero-flux walls exactly (ρ even, v·n odd across them) avoid boundary layers."""
    pi, sigma, c = np.pi, 0.02, 0.3

    def rho_f(x, y):
        return 1 + 0.5 * np.cos(pi * x) * np.cos(2 * pi * y)

    def v_f(x, y):
        return c * np.sin(pi * x) * np.cos(pi * y), -c * np.cos(2 * pi * x) * np.sin(pi * y)

    def exact(x, y):
        r = rho_f(x, y)
        rx = -0.5 * pi * np.sin(pi * x) * np.cos(2 * pi * y)
        ry = -pi * np.cos(pi * x) * np.sin(2 * pi * y)
        vx, vy = v_f(x, y)
        div_v = c * pi * np.cos(pi * x) * np.cos(pi * y) - c * pi * np.cos(2 * pi * x) * np.cos(pi * y)
        lap = -0.5 * 5 * pi**2 * np.cos(pi * x) * np.cos(2 * pi * y)
        return -(vx * rx + vy * ry + r * div_v) + sigma * lap

    err_fp, err_central, diff = [], [], []
    for n in (16, 32, 64, 128):
        grid = _box(n)
        X, Y = grid.centers
        rho = rho_f(X, Y)
        v_r = (v_f(*grid.face_points_x)[0], v_f(*grid.face_points_y)[1])
        fp_rate = FokkerPlanck(grid, sigma).rhs(rho, 0.0, face_velocity=v_r)
        ctrl = BacksteppingController(grid, grid.normalize(np.ones(grid.shape)), sigma, ConstantAlpha(0.2))
        central = ctrl.density_rate(rho, v_r)
        ex = exact(X, Y)
        err_fp.append(np.abs(fp_rate - ex).max())
        err_central.append(np.abs(central - ex).max())
        diff.append(np.abs(fp_rate - central).max())
    for errors in (err_fp, err_central, diff):
        orders = _orders(errors)
        assert np.all((orders > 1.8) & (orders < 2.3)), orders


# ---------------------------------------------------------------------- 12. KDE expected value
@pytest.mark.parametrize("normalize", [True, False])
def test_kde_expected_preserves_constants(normalize):
    """Reflection preserves constants on a box: E[ρ̂] of a uniform density is uniform. With
    h = 0.08 ≥ 1.6 cells the lattice sum of the Gaussian equals its integral up to
    2e^{-2π²(h/Δ)²} ≈ 1e-22 and the kernel reaches 8h < the box size, so the answer is exact
    to round-off. On a disk, "renormalize" divides by the kernel mass: exact for constants too."""
    grid = Grid(Domain.box(1.2, 0.9, origin=(-0.2, 0.3)), (24, 18))
    u = np.full(grid.shape, 1 / grid.area)
    out = KernelDensityEstimator(grid, 0.08, "reflect", normalize=normalize).expected(u)
    np.testing.assert_allclose(out, u, rtol=1e-12)
    disk = Grid(Domain.disk(0.8, center=(0.2, -0.1)), (20, 20))
    u = np.where(disk.active, 1 / disk.area, 0.0)
    out = KernelDensityEstimator(disk, 0.1, "renormalize", normalize=normalize).expected(u)
    np.testing.assert_allclose(out, u, rtol=1e-12, atol=1e-12 / disk.area)


@pytest.mark.parametrize("normalize", [False, True])
def test_kde_expected_is_the_mean_of_the_estimator(normalize):
    """Points drawn from the density at the cell centres (probability V_c ρ_c, the law whose
    midpoint integral expected() computes): the mean of M independent estimates approaches
    expected(ρ). Each cell's deviation is compared with its standard error (sample std /
    √M); max |z| over 432 cells must stay below 5 (P ≈ 432 × 6e-7 ≈ 3e-4 for a correct mean)."""
    grid = Grid(Domain.box(1.2, 0.9, origin=(-0.2, 0.3)), (24, 18))
    X, Y = grid.centers
    rho = grid.normalize(1 + np.exp(-((X - 0.2) ** 2 + (Y - 0.6) ** 2) / 0.02) + 0.5 * X)
    p = (grid.volume * rho).ravel()
    p /= p.sum()
    centres = np.column_stack([X.ravel(), Y.ravel()])
    kde = KernelDensityEstimator(grid, 0.08, "reflect", normalize=normalize)
    rng = np.random.default_rng(11)
    M, N = 400, 500
    est = np.array([kde(centres[rng.choice(len(p), N, p=p)]) for _ in range(M)])
    se = est.std(0, ddof=1) / math.sqrt(M)
    z = (est.mean(0) - kde.expected(rho)) / se
    assert np.abs(z).max() < 5
    # the test can fail: the plain (un-reflected) kernel's mean is far off near the walls
    plain = KernelDensityEstimator(grid, 0.08, "none", normalize=normalize).expected(rho)
    assert np.abs((est.mean(0) - plain) / se).max() > 20


def test_kde_expected_needs_a_bandwidth():
    grid = _box(12)
    kde = KernelDensityEstimator(grid, None)
    with pytest.raises(ParameterError) as info:
        kde.expected(grid.normalize(np.ones(grid.shape)))
    assert info.value.name == "bandwidth"
    with pytest.raises(ParameterError) as info:
        KernelDensityEstimator(grid, 0.1).expected(np.ones((12, 11)))
    assert info.value.name == "rho"


# ---------------------------------------------------------------- the benchmark problem
def _benchmark_velocity(x, y, t):
    """Three Gaussian arrow fields of benchmarks/fp_competitors.py (c = 0.5, η = 0.05)."""
    vx = np.zeros_like(x)
    vy = np.zeros_like(y)
    for (px, py), th in (((0.30, 0.30), 0.0), ((0.70, 0.40), 0.5 * math.pi), ((0.45, 0.72), 1.25 * math.pi)):
        k = 0.5 * np.exp(-((x - px) ** 2 + (y - py) ** 2) / 0.05)
        vx += k * math.cos(th)
        vy += k * math.sin(th)
    return vx, vy


def test_benchmark_problem_self_convergence_is_second_order():
    """Differences between successive grids (32², 64², 128²) on the benchmark problem
    (σ = 0.01, uniform start, T shortened to 0.5) fall 4× per halving: second order in
    space.  ADI with dt = 0.005 (its time error is far below the space error here, see
    docs/fokker_planck.md).  Coarse solutions are compared with the fine one averaged
    over 2×2 blocks (exact cell averages)."""
    sols = {}
    for n in (32, 64, 128):
        g = Grid(Domain.box(1.0, 1.0), cells=(n, n))
        fp = FokkerPlanck(g, 0.01, _benchmark_velocity, method="adi", time_dependent=False)
        sols[n] = fp.solve(g.normalize(np.ones(g.shape)), 0.5, dt=0.005)

    def diff(coarse, fine):
        n = coarse.shape[0]
        restricted = fine.reshape(n, 2, n, 2).mean(axis=(1, 3))
        return math.sqrt(((coarse - restricted) ** 2).sum() / n**2)

    d1 = diff(sols[32], sols[64])
    d2 = diff(sols[64], sols[128])
    order = math.log2(d1 / d2)
    assert 1.8 <= order <= 2.3, (d1, d2, order)


def test_polygon_gibbs_state_and_default_method():
    """On a convex polygon (cut cells) the default method is the unconditionally positive
    "split", its automatic step is not set by the smallest cut cell, and the discrete
    Gibbs state of a gradient drift is reached to round-off (exact steady state)."""
    g = Grid(Domain.polygon([(0.0, 0.0), (1.0, 0.0), (0.3, 0.9)]), cells=(40, 40))
    U = lambda x, y: 3 * (x - 0.4) ** 2 + 2 * (y - 0.3) ** 2  # noqa: E731
    fp = FokkerPlanck(g, 0.05, potential=U, time_dependent=False)
    assert fp.method == "split"
    rho0 = g.normalize(np.ones(g.shape))
    full = g.volume_fraction >= 0.5
    # the step is 0.9 × 4 × the explicit bound of the full cells: h²/(4σ) on this grid
    assert fp.automatic_dt(rho0) > 0.5 * g.dx**2 / (4 * 0.05)
    assert g.volume_fraction[g.active].min() < 0.5 * full.mean()  # there are small cut cells
    X, Y = g.centers
    gibbs = np.where(g.active, np.exp(-U(X, Y) / 0.05), 0.0)
    gibbs /= g.integrate(gibbs)
    rho = FokkerPlanck(g, 0.05, potential=U, method="implicit", time_dependent=False).solve(rho0, 200.0, dt=5.0)
    assert np.abs(rho - gibbs).max() <= 1e-10 * gibbs.max()
    assert rho.min() >= 0.0
