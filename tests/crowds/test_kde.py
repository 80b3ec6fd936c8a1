"""Kernel density estimation on the grid (paper, Section IV-A)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, Grid, KernelDensityEstimator, ParameterError, silverman_bandwidth
from meanfield.crowds.kde import kde_direct


def _box_grid():
    return Grid(Domain.box(1.2, 0.9, origin=(-0.2, 0.3)), (24, 18))


def test_separable_equals_direct_sum(rng):
    g = _box_grid()
    pts = g.domain.sample_uniform(300, rng)
    h = 0.07
    est = KernelDensityEstimator(g, h, boundary="none", normalize=False, method="separable")(pts)
    X, Y = g.centers
    ref = kde_direct(pts, h, X, Y)
    np.testing.assert_allclose(est, ref, rtol=1e-12, atol=1e-12 * ref.max())


def test_kde_direct_is_the_paper_formula():
    """One point at the origin: ρ̂(x) = exp(-|x|²/(2h²)) / (2π h²)."""
    x = np.array([0.0, 0.1, 0.3])
    y = np.array([0.0, -0.2, 0.05])
    h = 0.15
    out = kde_direct(np.zeros((1, 2)), h, x, y)
    np.testing.assert_allclose(out, np.exp(-(x**2 + y**2) / (2 * h * h)) / (2 * math.pi * h * h), rtol=1e-15)


@pytest.mark.parametrize("h", [0.03, 0.08, 0.2])
def test_reflect_equals_nine_mirror_images(h, rng):
    """With boundary="reflect" on a box the estimate is the plain KDE of the points and their
    8 mirror images across the 4 walls and 4 corners (9N points, so ×9 for the normalisation)."""
    g = _box_grid()
    x0, x1, y0, y1 = g.domain.bounds
    pts = g.domain.sample_uniform(250, rng)
    # put some points right next to the walls and a corner
    pts[:5] = [[x0 + 1e-3, 0.5], [x1 - 2e-3, 0.6], [0.1, y0 + 1e-4], [0.4, y1], [x0, y0]]
    xs = [pts[:, 0], 2 * x0 - pts[:, 0], 2 * x1 - pts[:, 0]]
    ys = [pts[:, 1], 2 * y0 - pts[:, 1], 2 * y1 - pts[:, 1]]
    images = np.concatenate([np.column_stack([a, b]) for a in xs for b in ys])
    X, Y = g.centers
    ref = 9 * kde_direct(images, h, X, Y)
    est = KernelDensityEstimator(g, h, boundary="reflect", normalize=False, method="separable")(pts)
    np.testing.assert_allclose(est, ref, rtol=1e-12, atol=1e-12 * ref.max())


def test_normalize_gives_unit_mass(domain, rng):
    g = Grid(domain, (20, 20))
    pts = domain.sample_uniform(400, rng)
    for boundary in ("none", "reflect", "renormalize"):
        rho = KernelDensityEstimator(g, 0.1, boundary=boundary)(pts)
        assert g.integrate(rho) == pytest.approx(1.0, rel=1e-13)
        assert np.all(rho >= 0)
        assert np.all(rho[~g.active] == 0)


def test_renormalize_divides_by_kernel_mass_in_omega(rng):
    """On a box, renormalize = plain estimate / ∫_Ω H_h(x - y) dy at the centres, where the
    integral factorises into error functions (compared with the grid's midpoint rule)."""
    from scipy.special import erf

    g = Grid(Domain.box(1.0, 1.0), (40, 40))
    h = 0.05
    pts = rng.uniform(size=(200, 2))
    plain = KernelDensityEstimator(g, h, boundary="none", normalize=False, method="separable")(pts)
    ren = KernelDensityEstimator(g, h, boundary="renormalize", normalize=False, method="separable")(pts)

    def mass_1d(c):
        return 0.5 * (erf((1 - c) / (math.sqrt(2) * h)) + erf(c / (math.sqrt(2) * h)))

    mass = np.outer(mass_1d(g.x), mass_1d(g.y))
    # the code integrates H_h with the midpoint rule on the cells: error O(dx²/h²) ~ 1e-2 relative
    np.testing.assert_allclose(plain / ren, mass, rtol=2e-2)


def _binning_bound(g: Grid, h: float, r: int) -> float:
    """Error bound of linear binning on bins dx/r, dy/r, then recentring on the coarse centres.

    Linear binning replaces H_h(x - X) by its bilinear interpolant in X, so per point the
    error is at most (δx² + δy²)/8 · max|∂²H_h| = (δx² + δy²)/(8h²) · 1/(2πh²); moving from
    the fine to the coarse centres is a second interpolation of the same size.  Both bounds
    hold for the average over the points, hence for the estimate; the 6h truncation adds
    e^{-18}/(2πh²)."""
    dx, dy = g.dx / r, g.dy / r
    peak = 1.0 / (2 * math.pi * h * h)
    return 2 * (dx * dx + dy * dy) / (8 * h * h) * peak + math.exp(-18) * peak


@pytest.mark.parametrize("convolution", ["matrix", "fft"])
@pytest.mark.parametrize("boundary", ["none", "reflect"])
def test_binned_agrees_with_separable_within_the_binning_error(boundary, convolution, rng):
    g = Grid(Domain.box(1.0, 1.0), (30, 30))
    h = 0.08
    pts = rng.uniform(0.15, 0.85, size=(500, 2)) if boundary == "none" else rng.uniform(size=(500, 2))
    exact = KernelDensityEstimator(g, h, boundary=boundary, normalize=False, method="separable")(pts)
    errors = []
    for r in (2, 4, 8, 16):
        est = KernelDensityEstimator(
            g, h, boundary=boundary, normalize=False, method="binned", oversample=r, convolution=convolution
        )(pts)
        err = np.abs(est - exact).max()
        assert err <= _binning_bound(g, h, r)
        errors.append(err)
    # second order in the bin size: about 4× smaller per doubling of `oversample`
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.0) & (ratios < 5.5)), ratios


def test_silverman_bandwidth_formula(rng):
    pts = rng.normal(scale=[0.1, 0.3], size=(729, 2))
    var = 0.5 * (pts[:, 0].var() + pts[:, 1].var())
    assert silverman_bandwidth(pts) == pytest.approx(math.sqrt(var) / 3.0, rel=1e-14)  # 729^(-1/6) = 1/3
    assert silverman_bandwidth(pts, floor=10.0) == 10.0


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"bandwidth": 0.0}, "density.bandwidth"),
        ({"bandwidth": float("nan")}, "density.bandwidth"),
        ({"boundary": "mirror"}, "density.boundary"),
        ({"method": "fft"}, "density.method"),
        ({"oversample": 0}, "density.oversample"),
        ({"oversample": 2.5}, "density.oversample"),
        ({"oversample": "fine"}, "density.oversample"),
        ({"convolution": "direct"}, "density.convolution"),
    ],
)
def test_bad_parameters_refused(kwargs, name):
    with pytest.raises(ParameterError) as info:
        KernelDensityEstimator(_box_grid(), **kwargs)
    assert info.value.name == name


def test_empty_point_set_refused():
    with pytest.raises(ParameterError):
        KernelDensityEstimator(_box_grid(), 0.1)(np.zeros((0, 2)))


def test_auto_oversample_keeps_the_fine_bin_within_the_stated_fraction_of_h():
    g = Grid(Domain.box(1.0, 1.0), (256, 256))
    for h, expected in ((0.0127, 3), (0.03, 1), (0.004, 7), (1e-4, 8)):
        r = KernelDensityEstimator(g, h, method="binned").oversample_for(h)
        assert r == expected
        # the smallest r with δ <= 0.15 h, unless capped
        assert r == 8 or (g.dx / r <= 0.15 * h < g.dx / (r - 1) if r > 1 else g.dx <= 0.15 * h)


@pytest.mark.parametrize("convolution", ["matrix", "fft"])
def test_large_crowd_binned_kde_within_1e3_of_the_peak(convolution):
    """Issue 7's accuracy figure on its 256² grid, at the rule bandwidth of a 10⁶ crowd.

    Exact reference: the separable sum (identical to the term-by-term formula, tested
    above).  2·10⁴ points keep the reference cheap; the binning error is a property of
    δ/h, not of N.
    """
    g = Grid(Domain.box(1.0, 1.0), (256, 256))
    rng = np.random.default_rng(7)
    law = ([0.4, 0.6], [0.15, 0.1])
    h = silverman_bandwidth(np.clip(rng.normal(*law, size=(10**6, 2)), 0.001, 0.999))
    pts = np.clip(rng.normal(*law, size=(20_000, 2)), 0.001, 0.999)
    exact = KernelDensityEstimator(g, h, method="separable")(pts)
    est = KernelDensityEstimator(g, h, method="binned", convolution=convolution)(pts)
    assert np.abs(est - exact).max() <= 1e-3 * exact.max()


def test_separable_is_evaluated_in_blocks_with_the_same_result(rng, monkeypatch):
    import meanfield.crowds.kde as density

    g = _box_grid()
    pts = g.domain.sample_uniform(1000, rng)
    whole = KernelDensityEstimator(g, 0.07, method="separable")(pts)
    monkeypatch.setattr(density, "_SEPARABLE_CHUNK", 24 * 37)  # blocks of 37 points
    blocks = KernelDensityEstimator(g, 0.07, method="separable")(pts)
    np.testing.assert_allclose(blocks, whole, rtol=1e-12)


@pytest.mark.parametrize("cells", [(32, 24), (17, 33)])
def test_the_banded_products_are_numpys_whichever_path_runs_them(cells, rng):
    """The binned estimate's ``Fx C Fyᵀ`` is numpy's band by band to the bit (issue 45: the bands on threads by numpy's
    own ``dgemm``); with 17 rows the last band has one row, which numpy computes without ``dgemm``, and the estimate
    keeps numpy's ``@`` for every band."""
    from meanfield.crowds._kde_loops import _banded_numpy

    g = Grid(Domain.box(1.0, 1.0), cells)
    h, r = 0.05, 2
    est = KernelDensityEstimator(g, h, method="binned", oversample=r, convolution="matrix")
    counts = rng.poisson(3.0, (cells[0] * r, cells[1] * r)).astype(float)
    got = est._banded_product(counts, h, r)
    fx, fy, bands_x, bands_y = est._fine_factors(h, r)
    assert est._bands_are_gemm == (cells[0] % 16 != 1)
    want = _banded_numpy(fx, counts, bands_x, fy, bands_y, np.empty((cells[0], counts.shape[1])), np.empty(cells))
    assert np.array_equal(got, want)
