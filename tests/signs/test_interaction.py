"""The mean interaction velocity u_W through the grid (FFT convolution)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, GaussianPotential, Grid, InteractionField
from tests.conftest import smooth_density


def _field(domain=None, cells=(13, 11), strength=0.4, length=0.25):
    g = Grid(domain or Domain.box(1.0, 0.8, origin=(0.1, -0.2)), cells)
    pot = GaussianPotential(strength, length)
    return g, pot, InteractionField(g, pot)


def test_on_cells_equals_direct_double_sum(domain):
    """u_W[ρ](x_a) = Σ_c V_c ρ_c ∇W(y_c - x_a) at every cell centre (cut cells too)."""
    g, pot, f = _field(domain)
    rho = smooth_density(g)
    X, Y = g.centers
    m = (rho * g.volume).ravel()
    zx = X.ravel()[None, :] - X.ravel()[:, None]
    zy = Y.ravel()[None, :] - Y.ravel()[:, None]
    gx, gy = pot.gradient(zx, zy)
    ux, uy = f.on_cells(rho)
    scale = np.abs(gx).max() * m.sum()
    np.testing.assert_allclose(ux.ravel(), gx @ m, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(uy.ravel(), gy @ m, rtol=0, atol=1e-13 * scale)


def test_on_faces_equals_direct_double_sum(domain):
    """Normal components at the face midpoints: x on x-faces, y on y-faces."""
    g, pot, f = _field(domain)
    rho = smooth_density(g)
    X, Y = g.centers
    m = (rho * g.volume).ravel()
    fx, fy = f.on_faces(rho)
    Xx, Yx = g.face_points_x
    Xy, Yy = g.face_points_y
    ex = pot.gradient(X.ravel()[None, :] - Xx.ravel()[:, None], Y.ravel()[None, :] - Yx.ravel()[:, None])[0] @ m
    ey = pot.gradient(X.ravel()[None, :] - Xy.ravel()[:, None], Y.ravel()[None, :] - Yy.ravel()[:, None])[1] @ m
    scale = 2 * abs(pot.strength) / pot.length * m.sum()
    np.testing.assert_allclose(fx.ravel(), ex, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(fy.ravel(), ey, rtol=0, atol=1e-13 * scale)


def test_on_faces_is_linear_and_complex_safe(rng):
    """u_W[ρ] is linear in ρ, so u_W[a + i b] = u_W[a] + i u_W[b]; the complex-step checks of
    the controller (∂_t v_d through u_W[ρ̇]) need this."""
    g, _, f = _field()
    a = smooth_density(g)
    b = rng.normal(size=g.shape)
    out = f.on_faces(a + 1j * b)
    for k in range(2):
        np.testing.assert_allclose(out[k].real, f.on_faces(a)[k], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(out[k].imag, f.on_faces(b)[k], rtol=1e-13, atol=1e-15)


def _second_derivative_bounds(s: float, l: float) -> tuple[float, float]:
    """max|∂²_x ∂_xW| and max|∂²_y ∂_xW| for W = s exp(-|z|²/l²) (same for ∂_yW by symmetry).

    ∂_xW = -(2s/l²) g(x) e(y) with g(x) = x e^{-x²/l²}, e(y) = e^{-y²/l²}:
    ∂²_x ∂_xW = -(2s/l²) g''(x) e(y),  ∂²_y ∂_xW = -(2s/l²) g(x) e''(y),
    max|g| = l e^{-1/2}/√2, max|e''| = 2/l², max|g''| from a fine 1-D sample (g'' is smooth)."""
    u = np.linspace(-4, 4, 400001)
    g2 = np.abs((4 * u**3 - 6 * u) * np.exp(-(u**2))).max() / l  # |g''| in units: (4x³/l⁴ - 6x/l²) e^{-x²/l²}
    c = 2 * abs(s) / l**2
    return c * g2 * 1.0001, c * (l * math.exp(-0.5) / math.sqrt(2)) * (2 / l**2)


def test_at_points_matches_pairwise_sum_within_grid_error(rng):
    """at_points bins the agents linearly onto the cells and interpolates bilinearly back.
    Each step is a bilinear interpolation of a smooth function, with error at most
    dx²/8·max|∂²_x| + dy²/8·max|∂²_y| of ∇W; so |error| <= 2·(that) per component.
    Agents stay half a cell away from the walls, where interpolation clamps."""
    s, l = 0.3, 0.2
    g = Grid(Domain.box(1.0, 1.0), (80, 72))
    pot = GaussianPotential(s, l)
    f = InteractionField(g, pot)
    pts = rng.uniform(0.02, 0.98, size=(300, 2))
    got = f.at_points(pts)
    zx = pts[:, 0][None, :] - pts[:, 0][:, None]  # X_k - X_j, row j
    zy = pts[:, 1][None, :] - pts[:, 1][:, None]
    gx, gy = pot.gradient(zx, zy)
    exact = np.column_stack([gx.mean(1), gy.mean(1)])
    mxx, myy = _second_derivative_bounds(s, l)
    bound = 2 * (g.dx**2 / 8 * max(mxx, myy) + g.dy**2 / 8 * max(mxx, myy))
    err = np.abs(got - exact).max()
    assert err <= bound
    # and the approximation is not trivially small-signal: the field itself is much larger
    assert np.abs(exact).max() > 10 * bound


@pytest.mark.parametrize("strength", [0.5, -0.5])
def test_repulsion_pushes_apart_and_attraction_pulls_together(strength):
    """Two humans 0.1 apart along x: s > 0 pushes them apart, s < 0 pulls them together."""
    g = Grid(Domain.box(1.0, 1.0), (40, 40))
    f = InteractionField(g, GaussianPotential(strength, 0.2))
    pts = np.array([[0.45, 0.5], [0.55, 0.5]])
    u = f.at_points(pts)
    # the exact pair velocity: (1/2) ∇W(X_k - X_j), along x only
    z = 0.1
    exact = 0.5 * (-2 / 0.2**2) * (z) * strength * math.exp(-(z**2) / 0.2**2)  # for j = 0, z = X_1 - X_0
    apart = np.sign(strength)
    assert apart * u[0, 0] < 0 < apart * u[1, 0]
    assert u[0, 0] == pytest.approx(exact, rel=0.05)
    assert u[1, 0] == pytest.approx(-exact, rel=0.05)
    assert abs(u[0, 1]) < 1e-3 * abs(exact)
