"""The KDE's compiled loops (meanfield.crowds._kde_loops) against their numpy twins, and the estimate's mass.

* :func:`separable_sum` (the exact sum, by the Gaussian recurrence (K1)) and the binned path
  (:func:`linear_binning_into`, then the banded products or the FFT) agree with the numpy
  path to round-off, 1e-12 of the peak, with and without reflecting walls, over crowd sizes,
  bandwidths from a hundredth of a cell to ten domains, grids of several shapes, and points
  on the walls and in the corners; every value is finite.
* the reflecting estimate keeps the crowd's mass; the plain one the kernel mass inside the box.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf

from meanfield import Domain, Grid, KernelDensityEstimator
from meanfield._compiled import core as compiled
from meanfield.crowds._kde_loops import linear_binning_into, separable_sum
from meanfield.geometry.grid import linear_binning

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")

BOXES = {
    "square": ((0.0, 1.0, 0.0, 1.0), (30, 30)),
    "offset": ((-0.2, 1.0, 0.3, 1.2), (24, 18)),
    "fine": ((0.0, 2.0, -1.0, 0.0), (64, 40)),
}


def crowd(bounds, n, rng, walls=True):
    """Uniform points in the box, the first few on its walls and in two corners."""
    x0, x1, y0, y1 = bounds
    pts = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    if walls and n >= 6:
        pts[:6] = [[x0, y0], [x1, y1], [x0, 0.5 * (y0 + y1)], [x1, y0 + 1e-9], [0.5 * (x0 + x1), y1], [x0 + 1e-12, y1]]
    return pts


def both(fn, *args):
    """``fn`` on the compiled path and on the numpy path (a fresh output array for each)."""
    *rest, out = args
    fast, ref = np.empty_like(out), np.empty_like(out)
    fn(*rest, fast)
    with compiled.numpy_path():
        fn(*rest, ref)
    return fast, ref


@needs_numba
@pytest.mark.parametrize("box", sorted(BOXES))
@pytest.mark.parametrize("reflect", [True, False])
@pytest.mark.parametrize("n", [1, 7, 200, 3000])
def test_separable_sum_matches_numpy_to_round_off(box, reflect, n):
    bounds, (nx, ny) = BOXES[box]
    x0, x1, y0, y1 = bounds
    rng = np.random.default_rng(n)
    pts = crowd(bounds, n, rng)
    cell = max((x1 - x0) / nx, (y1 - y0) / ny)
    # from a hundredth of a cell (direct exponentials) to ten domains (64-cell segments)
    for h in (0.01 * cell, 0.4 * cell, 1.0 * cell, 2.4 * cell, 8 * cell, 0.3, 10.0):
        fast, ref = both(separable_sum, pts, x0, x1, nx, y0, y1, ny, h, reflect, 1 << 20, np.empty((nx, ny)))
        assert np.isfinite(fast).all() and (fast >= 0).all()
        assert np.abs(fast - ref).max() <= 1e-12 * ref.max(), (h, np.abs(fast - ref).max() / ref.max())


@needs_numba
@pytest.mark.parametrize("box", sorted(BOXES))
def test_separable_sum_scaled_to_unit_mass_as_the_estimator_normalizes(box):
    bounds, (nx, ny) = BOXES[box]
    x0, x1, y0, y1 = bounds
    area = (x1 - x0) / nx * ((y1 - y0) / ny)
    pts = crowd(bounds, 200, np.random.default_rng(5))
    raw = np.empty((nx, ny))
    separable_sum(pts, x0, x1, nx, y0, y1, ny, 0.1, True, 1 << 20, raw)
    for fn in (separable_sum, separable_sum.fallback):  # the compiled loop and its numpy twin
        unit = np.empty((nx, ny))
        fn(pts, x0, x1, nx, y0, y1, ny, 0.1, True, 1 << 20, unit, area)
        assert abs(area * unit.sum() - 1.0) <= 1e-13  # exact answer: unit mass
        assert np.abs(unit - raw / (area * raw.sum())).max() <= 1e-13 * unit.max()  # the same estimate, rescaled
    # the estimator folds its normalization into this call on a box: the same density as _finish's
    g = Grid(Domain.box(x1 - x0, y1 - y0, (x0, y0)), (nx, ny))
    kde = KernelDensityEstimator(g, bandwidth=0.1)
    folded = kde(pts)
    assert np.abs(folded - kde._finish(kde._separable(pts, 0.1), 0.1)).max() <= 1e-13 * folded.max()


@needs_numba
def test_separable_sum_in_passes_and_outside_points():
    """Small passes (``block``) give the same sum; points beyond the box (plain estimate) too."""
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.5, 1.5, size=(500, 2))  # a third outside the unit box
    for block in (1, 37, 10**6):
        for h in (0.02, 0.1):
            fast, ref = both(separable_sum, pts, 0.0, 1.0, 30, 0.0, 1.0, 30, h, False, block, np.empty((30, 30)))
            assert np.isfinite(fast).all()
            assert np.abs(fast - ref).max() <= 1e-12 * ref.max()


@needs_numba
def test_far_points_give_zeros_not_nans():
    """A point hundreds of bandwidths away: its factors underflow to zero, never inf * 0."""
    pts = np.array([[0.5, 0.5], [-300.0, 0.5], [0.5, 400.0], [-1e6, 1e6]])
    for h in (1e-3, 0.02, 0.5):
        fast, ref = both(separable_sum, pts, 0.0, 1.0, 30, 0.0, 1.0, 30, h, False, 100, np.empty((30, 30)))
        assert np.isfinite(fast).all()
        assert np.abs(fast - ref).max() <= 1e-12 * ref.max()


@needs_numba
@pytest.mark.parametrize("n", [1, 50, 20_000])
def test_linear_binning_matches_the_grid_version(n):
    rng = np.random.default_rng(n)
    pts = np.vstack([rng.uniform(-0.1, 1.1, size=(n, 2)), [[0.0, 0.0], [1.0, 1.0]]])  # some beyond the edges
    counts = linear_binning_into(pts, 0.0, 0.0, 1 / 90, 1 / 60, np.empty((90, 60)))
    ref = linear_binning(pts, (0.0, 0.0), (1 / 90, 1 / 60), (90, 60))
    assert np.abs(counts - ref).max() <= 1e-12 * max(1.0, ref.max())
    assert counts.sum() == pytest.approx(n + 2, rel=1e-14)


@needs_numba
@pytest.mark.parametrize("convolution", ["matrix", "fft"])
@pytest.mark.parametrize("boundary", ["reflect", "none"])
def test_binned_matches_numpy_to_round_off(convolution, boundary):
    for box, n, h, r in (("square", 300, 0.05, 3), ("offset", 5000, 0.08, 2), ("fine", 20_000, 0.02, "auto")):
        bounds, cells = BOXES[box]
        g = Grid(Domain.box(bounds[1] - bounds[0], bounds[3] - bounds[2], origin=(bounds[0], bounds[2])), cells)
        pts = crowd(bounds, n, np.random.default_rng(n))
        est = KernelDensityEstimator(g, h, boundary=boundary, method="binned", oversample=r, convolution=convolution)
        fast = est(pts)
        with compiled.numpy_path():
            ref = est(pts)
        assert np.isfinite(fast).all()
        assert np.abs(fast - ref).max() <= 1e-12 * ref.max()


def test_banded_products_equal_the_dense_product():
    """The matrix convolution leaves out only factor entries below 1e-18 (beyond ~9.1 h)."""
    g = Grid(Domain.box(1.0, 1.0), (96, 96))
    pts = crowd((0.0, 1.0, 0.0, 1.0), 4000, np.random.default_rng(2))
    for h in (0.012, 0.05, 0.3):
        est = KernelDensityEstimator(g, h, method="binned", convolution="matrix", normalize=False, oversample=3)
        rho = est(pts)
        fx, fy, bands, _ = est._fine_factors(h, 3)
        assert sum((b - a) * (c1 - c0) for a, b, c0, c1 in bands) < fx.size or h > 0.1  # banded where narrow
        counts = linear_binning(pts, (0.0, 0.0), (g.dx / 3, g.dy / 3), (288, 288))
        dense = fx @ counts @ fy.T / (2 * math.pi * h * h * len(pts))
        assert np.abs(rho - dense).max() <= 1e-14 * dense.max()


@pytest.mark.parametrize("method", ["separable", "binned"])
@pytest.mark.parametrize("path", ["compiled", "numpy"])
def test_reflecting_estimate_keeps_the_mass(method, path):
    """With the walls' images every point's kernel mass stays in the box: ∫ρ̂ = 1 (midpoint rule,
    exact to round-off here since h is over two cells: its error is ~exp(-2π²h²/Δ²))."""
    g = Grid(Domain.box(1.0, 1.0), (30, 30))
    pts = crowd((0.0, 1.0, 0.0, 1.0), 400, np.random.default_rng(3))
    est = KernelDensityEstimator(g, 0.08, method=method, normalize=False)
    if path == "numpy":
        with compiled.numpy_path():
            rho = est(pts)
    else:
        rho = est(pts)
    assert g.integrate(rho) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("path", ["compiled", "numpy"])
def test_plain_estimate_has_the_kernel_mass_inside_the_box(path):
    """``boundary="none"``: ∫ρ̂ = (1/N) Σ_j ∫_box H_h(x - X_j) dx, a product of error functions,
    up to the midpoint rule's error, whose leading term (Euler–Maclaurin) is Δ²/24 times the
    jump of the kernel's slope across the walls."""
    g = Grid(Domain.box(1.0, 1.0), (40, 40))
    rng = np.random.default_rng(4)
    pts = rng.uniform(0.05, 0.95, size=(300, 2))
    h = 0.06

    def inside(c):
        return 0.5 * (erf((1 - c) / (math.sqrt(2) * h)) + erf(c / (math.sqrt(2) * h)))

    def slope(d):  # |φ_h'(d)|
        return abs(d) * np.exp(-0.5 * d * d / (h * h)) / (math.sqrt(2 * math.pi) * h**3)

    expected = np.mean(inside(pts[:, 0]) * inside(pts[:, 1]))
    walls = [slope(c) + slope(1 - c) for c in (pts[:, 0], pts[:, 1])]
    bound = g.dx**2 / 24 * np.mean(walls[0] + walls[1])
    est = KernelDensityEstimator(g, h, boundary="none", method="separable", normalize=False)
    if path == "numpy":
        with compiled.numpy_path():
            rho = est(pts)
    else:
        rho = est(pts)
    assert abs(g.integrate(rho) - expected) <= 1.2 * bound
    assert 0.5 * bound < abs(g.integrate(rho) - expected)  # the bound is the error's size, not loose
