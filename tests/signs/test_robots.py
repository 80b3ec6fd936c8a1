"""Robots: team state and limits, the navigation field on the grid, its rate and moments."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, GaussianKernel, Grid, NavigationField, ParameterError, RobotTeam, navigation_velocity
from meanfield.signs.kernels import kernel_jacobian_theta, kernel_jacobian_xi
from meanfield.signs.robots import saturate_inputs


def _setup(rng, domain=None, n=4):
    domain = domain or Domain.box(1.0, 1.2)
    grid = Grid(domain, (14, 17))
    R = domain.sample_uniform(n, rng)
    th = rng.uniform(0, 2 * np.pi, n)
    return grid, GaussianKernel(0.5, 0.05), R, th


@pytest.mark.parametrize("block", [None, 7])
def test_navigation_velocity_is_the_sum_over_robots(rng, monkeypatch, block):
    if block is not None:  # blocks of 7 // 3 = 2 points: the blocked evaluation gives the same sum
        monkeypatch.setattr("meanfield.signs.robots._EXACT_BLOCK", block)
    k = GaussianKernel(0.8, 0.1)
    R = rng.uniform(size=(3, 2))
    th = rng.uniform(0, 2 * np.pi, 3)
    pts = rng.uniform(size=(20, 2))
    v = navigation_velocity(k, R, th, pts)
    expected = np.zeros((20, 2))
    for i in range(3):
        m = 0.8 * np.exp(-((pts - R[i]) ** 2).sum(1) / 0.1)
        expected += m[:, None] * np.array([math.cos(th[i]), math.sin(th[i])])
    np.testing.assert_allclose(v, expected, rtol=1e-13, atol=1e-16)


def test_field_velocity_on_faces_equals_pointwise_sum(rng, domain):
    grid, k, R, th = _setup(rng, domain)
    vx, vy = NavigationField(k, grid, R, th).velocity()
    Xx, Yx = grid.face_points_x
    Xy, Yy = grid.face_points_y
    ex = navigation_velocity(k, R, th, np.column_stack([Xx.ravel(), Yx.ravel()]))[:, 0].reshape(Xx.shape)
    ey = navigation_velocity(k, R, th, np.column_stack([Xy.ravel(), Yy.ravel()]))[:, 1].reshape(Xy.shape)
    np.testing.assert_allclose(vx, ex, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(vy, ey, rtol=1e-12, atol=1e-15)


def test_moments_equal_direct_face_sums(rng, domain):
    """b_i = Σ_faces w F·(K_ξ^i column), g_i = Σ_faces w F·K_θ^i, with the analytic Jacobians."""
    grid, k, R, th = _setup(rng, domain)
    nx, ny = grid.shape
    F = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
    b, g = NavigationField(k, grid, R, th).moments(F)
    Xx, Yx = grid.face_points_x
    Xy, Yy = grid.face_points_y
    for i in range(len(th)):
        Jx = kernel_jacobian_xi(k, Xx - R[i, 0], Yx - R[i, 1], th[i])  # x-faces: row 0 (x-component)
        Jy = kernel_jacobian_xi(k, Xy - R[i, 0], Yy - R[i, 1], th[i])  # y-faces: row 1
        bi = [
            (grid.weight_x * F[0] * Jx[..., 0, l]).sum() + (grid.weight_y * F[1] * Jy[..., 1, l]).sum()
            for l in range(2)
        ]
        tx = kernel_jacobian_theta(k, Xx - R[i, 0], Yx - R[i, 1], th[i])[0]
        ty = kernel_jacobian_theta(k, Xy - R[i, 0], Yy - R[i, 1], th[i])[1]
        gi = (grid.weight_x * F[0] * tx).sum() + (grid.weight_y * F[1] * ty).sum()
        scale = (grid.weight_x * np.abs(F[0])).sum() + (grid.weight_y * np.abs(F[1])).sum()
        np.testing.assert_allclose(b[i], bi, rtol=0, atol=1e-13 * scale * k.c / math.sqrt(k.eta))
        assert abs(g[i] - gi) <= 1e-13 * scale * k.c


def test_velocity_rate_is_the_time_derivative(rng, domain):
    """∂_t v_r along (u, ω) equals the complex-step derivative of v_r(R + iεu, θ + iεω)."""
    grid, k, R, th = _setup(rng, domain)
    u = rng.normal(size=R.shape)
    w = rng.normal(size=th.shape)
    eps = 1e-30
    rate = NavigationField(k, grid, R, th).velocity_rate(u, w)
    moved = NavigationField(k, grid, R + 1j * eps * u, th + 1j * eps * w).velocity()
    for a, b in zip(rate, moved, strict=True):
        np.testing.assert_allclose(a, b.imag / eps, rtol=1e-12, atol=1e-14)


def test_moments_are_the_adjoint_of_the_rate(rng):
    """Σ b_i·u_i - Σ g_i ω_i = -<F, ∂_t v_r> (the identity the robot law relies on)."""
    grid, k, R, th = _setup(rng, n=6)
    nx, ny = grid.shape
    F = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
    u = rng.normal(size=R.shape)
    w = rng.normal(size=th.shape)
    f = NavigationField(k, grid, R, th)
    b, g = f.moments(F)
    lhs = (b * u).sum() - (g * w).sum()
    rhs = -grid.face_inner(F, f.velocity_rate(u, w))
    assert lhs == pytest.approx(rhs, rel=1e-12)


# ---------------------------------------------------------------------- the team
def test_step_with_huge_inputs_stays_inside_and_saturated(domain, rng):
    n = 50
    R = domain.sample_uniform(n, rng)
    team = RobotTeam(R, rng.uniform(0, 2 * np.pi, n), u_max=0.5, omega_max=2.0)
    dt = 0.1
    for _ in range(30):
        before_R = team.positions.copy()
        before_th = team.headings.copy()
        u = rng.normal(scale=1e6, size=(n, 2))
        w = rng.normal(scale=1e6, size=n)
        team.step(u, w, dt, domain)
        assert domain.contains(team.positions[:, 0], team.positions[:, 1]).all()
        moved = np.hypot(*(team.positions - before_R).T)
        assert np.all(moved <= 0.5 * dt * (1 + 1e-12))  # projection onto convex Ω is non-expansive
        turn = np.mod(team.headings - before_th + np.pi, 2 * np.pi) - np.pi
        assert np.all(np.abs(turn) <= 2.0 * dt * (1 + 1e-12))


def test_saturate_inputs_keeps_direction(rng):
    u = rng.normal(scale=3.0, size=(20, 2))
    w = rng.normal(scale=5.0, size=20)
    us, ws = saturate_inputs(u, w, 1.0, 2.0)
    speed = np.hypot(*u.T)
    assert np.all(np.hypot(*us.T) <= 1.0)  # never above the limit, not even by round-off
    slow = speed <= 1.0
    np.testing.assert_array_equal(us[slow], u[slow])
    # scaled to the limit, less a few ulps that keep the norm below it
    np.testing.assert_allclose(us[~slow], u[~slow] / speed[~slow, None], rtol=2e-15)
    np.testing.assert_array_equal(ws, np.clip(w, -2.0, 2.0))
    # no limit: unchanged
    us, ws = saturate_inputs(u, w, math.inf, math.inf)
    np.testing.assert_array_equal(us, u)
    np.testing.assert_array_equal(ws, w)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"positions": np.zeros((2, 2)), "headings": np.zeros(3)}, "robots.headings"),
        ({"positions": np.zeros((0, 2)), "headings": np.zeros(0)}, "robots.positions"),
        ({"positions": [[np.nan, 0.0]], "headings": [0.0]}, "robots"),
        ({"positions": [[0.0, 0.0]], "headings": [0.0], "u_max": 0.0}, "robots.u_max"),
        ({"positions": [[0.0, 0.0]], "headings": [0.0], "omega_max": float("nan")}, "robots.omega_max"),
    ],
)
def test_team_refuses_bad_input(kwargs, name):
    with pytest.raises(ParameterError) as info:
        RobotTeam(**kwargs)
    assert info.value.name == name


def test_check_inside_names_the_robot():
    team = RobotTeam([[0.5, 0.5], [1.5, 0.5]], [0.0, 0.0])
    with pytest.raises(ParameterError) as info:
        team.check_inside(Domain.box())
    assert info.value.name == "robots.positions[1]"
