"""Navigation kernels K(ξ, θ) = K̄(ξ) e(θ): values, analytic Jacobians, radius, custom kernels."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from meanfield import (
    CustomKernel,
    Domain,
    GaussianKernel,
    GaussianPotential,
    Grid,
    NavigationField,
    ParameterError,
    kernel_jacobian_theta,
    kernel_jacobian_xi,
    kernel_value,
    navigation_velocity,
)

PARAMS = [(0.5, 0.03), (1.0, 1.0), (2.5, 0.2), (0.1, 5.0)]


def _points(rng, eta, m=40):
    """Random offsets within about two ranges sqrt(η) of the robot, random headings."""
    r = math.sqrt(eta)
    xi = rng.uniform(-2 * r, 2 * r, size=(m, 2))
    th = rng.uniform(-np.pi, 3 * np.pi, size=m)
    return xi, th


@pytest.mark.parametrize(("c", "eta"), PARAMS)
def test_value_is_closed_form(c, eta, rng):
    k = GaussianKernel(c, eta)
    xi, th = _points(rng, eta)
    kx, ky = kernel_value(k, xi[:, 0], xi[:, 1], th)
    mag = c * np.exp(-(xi**2).sum(1) / eta)
    np.testing.assert_allclose(kx, mag * np.cos(th), rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(ky, mag * np.sin(th), rtol=1e-14, atol=1e-300)


@pytest.mark.parametrize(("c", "eta"), PARAMS)
def test_jacobians_equal_central_differences(c, eta, rng):
    """Central differences with step h = 1e-5·sqrt(η): truncation O(h²) and round-off
    O(ε_mach/h) are both below 1e-8 of the Jacobian's size, so rtol 1e-7 (relative to the
    largest entry at that point) is a genuine check."""
    k = GaussianKernel(c, eta)
    xi, th = _points(rng, eta)
    h = 1e-5 * math.sqrt(eta)
    J = kernel_jacobian_xi(k, xi[:, 0], xi[:, 1], th)
    assert J.shape == (len(th), 2, 2)
    for col, e in enumerate(np.eye(2)):
        p = kernel_value(k, xi[:, 0] + h * e[0], xi[:, 1] + h * e[1], th)
        m = kernel_value(k, xi[:, 0] - h * e[0], xi[:, 1] - h * e[1], th)
        for row in range(2):
            fd = (p[row] - m[row]) / (2 * h)
            scale = np.abs(J).max(axis=(1, 2))
            assert np.all(np.abs(J[:, row, col] - fd) <= 1e-7 * scale)
    ht = 1e-5
    Jt = kernel_jacobian_theta(k, xi[:, 0], xi[:, 1], th)
    p = kernel_value(k, xi[:, 0], xi[:, 1], th + ht)
    m = kernel_value(k, xi[:, 0], xi[:, 1], th - ht)
    scale = np.hypot(*Jt)
    for row in range(2):
        fd = (p[row] - m[row]) / (2 * ht)
        assert np.all(np.abs(Jt[row] - fd) <= 1e-7 * scale)


@pytest.mark.parametrize(("c", "eta"), PARAMS)
def test_jacobians_equal_casadi_symbolic(c, eta, rng):
    """CasADi's symbolic Jacobians of K(ξ,θ) = c exp(-|ξ|²/η)(cos θ, sin θ), to 1e-12."""
    xi_s = ca.SX.sym("xi", 2)
    th_s = ca.SX.sym("theta")
    kbar = c * ca.exp(-ca.dot(xi_s, xi_s) / eta)
    K = ca.vertcat(kbar * ca.cos(th_s), kbar * ca.sin(th_s))
    f = ca.Function("K", [xi_s, th_s], [K, ca.jacobian(K, xi_s), ca.jacobian(K, th_s)])
    k = GaussianKernel(c, eta)
    xi, th = _points(rng, eta, m=25)
    J = kernel_jacobian_xi(k, xi[:, 0], xi[:, 1], th)
    Jt = np.stack(kernel_jacobian_theta(k, xi[:, 0], xi[:, 1], th), axis=-1)
    V = np.stack(kernel_value(k, xi[:, 0], xi[:, 1], th), axis=-1)
    for m in range(len(th)):
        val, jxi, jth = (np.asarray(a) for a in f(xi[m], th[m]))
        scale = max(c, 1.0) * max(1.0, 1.0 / math.sqrt(eta))
        np.testing.assert_allclose(V[m], val.ravel(), rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(J[m], jxi, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(Jt[m], jth.ravel(), rtol=0, atol=1e-12 * scale)


def test_jacobians_equal_complex_step(rng):
    """The kernel functions are complex-safe: Im K(ξ + iεe)/ε equals the analytic Jacobian."""
    k = GaussianKernel(0.7, 0.05)
    xi, th = _points(rng, 0.05)
    eps = 1e-30
    J = kernel_jacobian_xi(k, xi[:, 0], xi[:, 1], th)
    for col, e in enumerate(np.eye(2)):
        kv = kernel_value(k, xi[:, 0] + 1j * eps * e[0], xi[:, 1] + 1j * eps * e[1], th)
        for row in range(2):
            np.testing.assert_allclose(kv[row].imag / eps, J[:, row, col], rtol=1e-13, atol=1e-14)
    kv = kernel_value(k, xi[:, 0], xi[:, 1], th + 1j * eps)
    Jt = kernel_jacobian_theta(k, xi[:, 0], xi[:, 1], th)
    for row in range(2):
        np.testing.assert_allclose(kv[row].imag / eps, Jt[row], rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize(("c", "eta"), PARAMS)
@pytest.mark.parametrize("eps", [1e-3, 0.01, 0.09])
def test_radius_gives_eps_at_the_radius(c, eta, eps):
    k = GaussianKernel(c, eta)
    r = k.radius(eps)
    for a in np.linspace(0, 2 * np.pi, 7):
        assert k.magnitude(r * math.cos(a), r * math.sin(a)) == pytest.approx(eps, rel=1e-12)
    # strictly above ε inside, below outside
    assert k.magnitude(0.99 * r, 0.0) > eps > k.magnitude(1.01 * r, 0.0)


def test_radius_is_zero_when_eps_reaches_the_peak():
    assert GaussianKernel(0.1, 1.0).radius(0.1) == 0.0
    assert GaussianKernel(0.1, 1.0).radius(0.5) == 0.0
    with pytest.raises(ParameterError):
        GaussianKernel(0.1, 1.0).radius(0.0)


@pytest.mark.parametrize(
    ("c", "eta", "name"),
    [
        (0.0, 1.0, "kernel.c"),
        (-1.0, 1.0, "kernel.c"),
        (1.0, 0.0, "kernel.eta"),
        (1.0, -0.5, "kernel.eta"),
        (float("nan"), 1.0, "kernel.c"),
        (1.0, float("inf"), "kernel.eta"),
    ],
)
def test_bad_kernel_parameters_refused(c, eta, name):
    with pytest.raises(ParameterError) as info:
        GaussianKernel(c, eta)
    assert info.value.name == name


def _custom(c, eta):
    """The Gaussian kernel given as two plain callables (non-separable code path)."""

    def mag(x, y):
        return c * np.exp(-(x * x + y * y) / eta)

    def grad(x, y):
        m = mag(x, y)
        return -2.0 / eta * x * m, -2.0 / eta * y * m

    return CustomKernel(mag, grad)


def test_custom_kernel_equals_gaussian_in_navigation_field(rng):
    c, eta = 0.6, 0.04
    gk, ck = GaussianKernel(c, eta), _custom(c, eta)
    for domain in (Domain.box(1.0, 1.3), Domain.disk(0.6, (0.5, 0.5))):
        grid = Grid(domain, (13, 17))
        x0, x1, y0, y1 = domain.bounds
        R = rng.uniform([x0, y0], [x1, y1], size=(5, 2))
        th = rng.uniform(0, 2 * np.pi, 5)
        a, b = NavigationField(gk, grid, R, th), NavigationField(ck, grid, R, th)
        assert a.separable and not b.separable
        for va, vb in zip(a.velocity(), b.velocity(), strict=True):
            np.testing.assert_allclose(va, vb, rtol=1e-12, atol=1e-14)
        u = rng.normal(size=(5, 2))
        w = rng.normal(size=5)
        for va, vb in zip(a.velocity_rate(u, w), b.velocity_rate(u, w), strict=True):
            np.testing.assert_allclose(va, vb, rtol=1e-12, atol=1e-13)
        nx, ny = grid.shape
        F = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
        for ma, mb in zip(a.moments(F), b.moments(F), strict=True):
            np.testing.assert_allclose(ma, mb, rtol=1e-12, atol=1e-13)
        pts = rng.uniform([x0, y0], [x1, y1], size=(50, 2))
        np.testing.assert_allclose(
            navigation_velocity(gk, R, th, pts), navigation_velocity(ck, R, th, pts), rtol=1e-13, atol=1e-15
        )


def test_gaussian_potential_gradient_is_its_derivative(rng):
    pot = GaussianPotential(0.3, 0.2)
    z = rng.uniform(-0.4, 0.4, size=(30, 2))
    eps = 1e-30
    gx, gy = pot.gradient(z[:, 0], z[:, 1])
    np.testing.assert_allclose(pot.value(z[:, 0] + 1j * eps, z[:, 1]).imag / eps, gx, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(pot.value(z[:, 0], z[:, 1] + 1j * eps).imag / eps, gy, rtol=1e-13, atol=1e-15)
    with pytest.raises(ParameterError) as info:
        GaussianPotential(1.0, 0.0)
    assert info.value.name == "interaction.length"


def test_the_cells_a_sign_reaches_are_found_within_its_radius_as_over_the_whole_grid():
    """``reached_cells`` tests only the cells within a kernel's radius (``GaussianKernel.radius``) when the kernel
    has one: the same cells, to the bit, as the test over every cell (a kernel without a radius), for robots inside,
    on the edge of and outside the grid, with a kernel wider and narrower than the room."""
    from meanfield.signs.kernels import REACH_FRACTION, reached_cells

    class WithoutRadius:
        def __init__(self, kernel):
            self.magnitude = kernel.magnitude

    rng = np.random.default_rng(0)
    grid = Grid(Domain.box(30.0, 14.0), (60, 28))
    X, Y = grid.centers
    for _ in range(100):
        k = GaussianKernel(c=float(rng.uniform(0.5, 2.0)), eta=float(rng.uniform(0.2, 400.0)))
        robots = rng.uniform(-3.0, 33.0, (8, 2))
        robots[0] = (0.0, 0.0)  # a corner of the grid
        fast, full = reached_cells(k, robots, grid), reached_cells(WithoutRadius(k), robots, grid)
        assert np.array_equal(fast, full)
        d2 = (X[None] - robots[:, 0, None, None]) ** 2 + (Y[None] - robots[:, 1, None, None]) ** 2
        assert np.array_equal(full, k.c * np.exp(-d2 / k.eta) >= REACH_FRACTION * k.c)  # the test itself
