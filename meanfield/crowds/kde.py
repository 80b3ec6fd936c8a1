"""Kernel density estimation of the crowd on the grid (paper, Section IV-A).

The paper's estimate::

    ρ̂(x) = 1/(N h²) Σ_j H((x - X_j)/h),     H(z) = exp(-|z|²/2) / (2π)

Two evaluation methods give the same estimate:

* ``"separable"``: exact.  The Gaussian factorises, ``ρ̂ = Gx Gyᵀ / (2π h² N)`` with
  ``Gx[i, j] = exp(-(x_i - X_j)²/(2h²))``; cost O(N (nx + ny) + nx ny N) — the cheapest
  choice for small grids (the paper's 30×30).  The factors come from a compiled loop, a
  Gaussian recurrence along the cells at two multiplications per cell
  (:func:`meanfield.crowds._kde_loops.separable_sum`, eq. (K1)); the numpy twin takes one
  exponential per cell and point.
* ``"binned"``: linear binning of the points onto a lattice ``oversample`` times finer
  than the grid (:func:`meanfield.crowds._kde_loops.linear_binning_into`, one pass per point),
  then the Gaussian applied to the binned counts and read exactly at the
  cell centres; cost O(N) plus a grid-sized convolution, for large crowds.  The
  convolution is either two products with the separable factors (wall images folded
  in, as in ``"separable"``; banded: each block of 16 cells multiplies only the fine
  columns within 9.1 h of it, the rest being below ``1e-18``; fastest up to grids of a
  few hundred cells a side)
  or one FFT (O(G log G), for finer grids; it reads the fine value at the centre for odd
  ``r`` and interpolates between the four nearest ones for even ``r``);
  ``convolution="auto"`` picks the cheaper by an operation count.  The binning error is
  second order in the fine bin size δ: at most ``(δx² + δy²)/(4h²)`` of the kernel's peak ``1/(2πh²)``;
  ``oversample="auto"`` takes the smallest ``r`` with ``δ <= 0.15 h`` (capped at 8),
  which keeps it below about 3e-4 of the density's peak on smooth crowds.

Plain KDE leaks mass through the walls.  ``boundary="reflect"`` adds the mirror images
of the points across the walls of a box (exact zero normal derivative at the walls);
``"renormalize"`` divides by the kernel mass inside Ω, ``∫_Ω H_h(x - y) dy`` (any shape);
``"none"`` is the paper's plain estimate.

Default bandwidth (Silverman's rule in two dimensions, which coincides with Scott's):
``h = σ̂ N^(-1/6)`` with ``σ̂² = (var X + var Y)/2``, floored at one grid cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from meanfield._compiled.blas import numpy_gemm_found, numpy_uses_gemm
from meanfield.crowds._kde_loops import axis_factors, banded_products, linear_binning_into, separable_sum
from meanfield.errors import ParameterError
from meanfield.geometry.grid import Grid

__all__ = ["KernelDensityEstimator", "silverman_bandwidth", "kde_direct", "BinnedLayout", "binned_layout"]

Boundary = Literal["none", "reflect", "renormalize"]
Method = Literal["auto", "separable", "binned"]
Convolution = Literal["auto", "matrix", "fft"]

OVERSAMPLE_BIN_TO_BANDWIDTH = 0.15
"""``oversample="auto"``: the fine bin is at most this fraction of the bandwidth."""
OVERSAMPLE_MAX = 8
"""``oversample="auto"`` never refines the grid more than this."""
_SEPARABLE_CHUNK = 1 << 22
"""Entries of one axis-factor block in ``"separable"`` (32 MB), whatever N is."""
_BAND_CUT = 1e-18
"""``"binned"``, matrix convolution: factor entries below this (beyond ~9.1 h) are left out."""
_BAND_REACH = math.sqrt(2 * math.log(1 / _BAND_CUT))
"""Where the Gaussian factor falls to ``_BAND_CUT``, in bandwidths (9.1)."""
_BAND_ROWS = 16
"""Coarse rows per block of the banded products."""


def _bands(f: np.ndarray) -> list[tuple[int, int, int, int]]:
    """``(a, b, c0, c1)``: rows ``a:b`` of ``f`` exceed ``_BAND_CUT`` only in columns ``c0:c1``."""
    keep = f > _BAND_CUT
    out = []
    for a in range(0, f.shape[0], _BAND_ROWS):
        b = min(f.shape[0], a + _BAND_ROWS)
        cols = np.flatnonzero(keep[a:b].any(axis=0))
        if len(cols):
            out.append((a, b, int(cols[0]), int(cols[-1]) + 1))
        else:
            out.append((a, b, 0, 0))
    return out


_ONES = np.ones(0)


def _ones(n: int) -> np.ndarray:
    """``n`` ones, read-only, from one buffer grown as needed (a sum as a BLAS product, no allocation)."""
    global _ONES
    if len(_ONES) < n:
        _ONES = np.ones(max(n, 2 * len(_ONES)))
        _ONES.flags.writeable = False
    return _ONES[:n]


@dataclass(frozen=True)
class BinnedLayout:
    """How :meth:`KernelDensityEstimator._binned` works at one grid and bandwidth: the fine lattice
    ``mx × my`` (``r`` times the grid's), the kernel's half-widths ``kx, ky`` on it, and the
    convolution it chooses; :meth:`working_bytes` is the memory that takes."""

    nx: int
    ny: int
    r: int
    mx: int
    my: int
    kx: int
    ky: int
    wx: int
    wy: int
    convolution: str

    def working_bytes(self, reflect: bool) -> int:
        """Bytes of the working arrays: the binned counts, and the banded products' factors and
        halves, or the (padded) counts, the kernel and the FFTs' complex arrays (three of them)."""
        if self.convolution == "matrix":
            return 8 * (self.mx * self.my + self.nx * self.wx + self.ny * self.wy + 2 * self.nx * self.my)
        px, py = (min(self.kx, self.mx), min(self.ky, self.my)) if reflect else (0, 0)
        padded = (self.mx + 2 * px) * (self.my + 2 * py)
        kernel = (2 * self.kx + 1) * (2 * self.ky + 1)
        full = (self.mx + 2 * px + 2 * self.kx + 1) * (self.my + 2 * py + 2 * self.ky + 1)
        return 8 * (self.mx * self.my + padded + kernel) + 48 * full


def binned_layout(
    nx: int, ny: int, dx: float, dy: float, h: float, r: int, convolution: str = "auto"
) -> BinnedLayout:
    """The layout of the binned estimate on an ``nx × ny`` grid of cells ``dx × dy`` at bandwidth ``h``
    with refinement ``r`` (``convolution`` ``"auto"``: the cheaper of the banded product and the FFT)."""
    mx, my = nx * r, ny * r
    bx, by = dx / r, dy / r
    # Gaussian on fine-lattice offsets, truncated at 6h (relative tail < 1e-8)
    kx = min(int(math.ceil(6 * h / bx)), 2 * mx)
    ky = min(int(math.ceil(6 * h / by)), 2 * my)
    wx = min(mx, _BAND_ROWS * r + 2 * int(math.ceil(_BAND_REACH * h / bx)) + 2)
    wy = min(my, _BAND_ROWS * r + 2 * int(math.ceil(_BAND_REACH * h / by)) + 2)
    if convolution == "auto":
        # multiply-adds of the two banded products (_BAND_ROWS rows at a time, the factors
        # cut where they fall below _BAND_CUT, ~9.1h) against ~P log2 P of the FFTs, with the
        # constant measured on one core (a dense product runs ~25× faster per operation)
        macs = nx * wx * my + nx * ny * wy
        p = (mx + 4 * kx) * (my + 4 * ky)
        convolution = "matrix" if macs <= 25 * p * math.log2(p) else "fft"
    return BinnedLayout(nx, ny, r, mx, my, kx, ky, wx, wy, convolution)


def silverman_bandwidth(points: np.ndarray, floor: float = 0.0) -> float:
    """Silverman/Scott rule ``h = σ̂ N^(-1/6)`` for a 2-D Gaussian KDE, at least ``floor``."""
    n = len(points)
    if n < 2:
        return max(0.0, floor)
    # σ̂² = ½ (var x + var y) = ½ (Σ|d_j|² - |Σ d_j|²/N)/N with d_j = X_j - X_0: shifted by one of the
    # points, the same variance without cancellation; three array calls where two np.var took ten
    d = points - points[0]
    s = d.sum(axis=0) if n > 4096 else np.dot(_ones(n), d)
    var = 0.5 * (float(np.vdot(d, d)) - float(s[0] * s[0] + s[1] * s[1]) / n) / n
    return max(math.sqrt(max(var, 0.0)) * n ** (-1.0 / 6.0), floor)


def kde_direct(points: np.ndarray, h: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The paper's KDE evaluated term by term at points ``(x, y)`` (reference, O(N·M))."""
    dx = x[..., None] - points[:, 0]
    dy = y[..., None] - points[:, 1]
    return np.exp(-(dx**2 + dy**2) / (2 * h * h)).sum(-1) / (2 * math.pi * h * h * len(points))


class KernelDensityEstimator:
    """Gaussian KDE of a point cloud on ``grid``'s cell centres.

    Parameters
    ----------
    grid : Grid
        Where the estimate lives.
    bandwidth : float or None
        ``h > 0``; None uses :func:`silverman_bandwidth` on each call (floored at one cell).
    boundary : {"reflect", "renormalize", "none"}
        Wall correction (see module docstring); ``"reflect"`` needs a box domain and
        falls back to ``"renormalize"`` on other shapes.
    method : {"auto", "separable", "binned"}
        ``"auto"`` picks ``"separable"`` when ``N * nx * ny <= 5e7``, else ``"binned"``.
    normalize : bool
        Rescale to unit mass on the grid (so ``ρ̂ - ρ_*`` has zero mean, as the
        Poincaré inequality of Theorem 1 needs).
    oversample : int or "auto"
        Refinement ``r`` of the binning lattice for ``"binned"``; ``"auto"`` takes the
        smallest with fine bins at most ``0.15 h`` (at most 8).
    convolution : {"auto", "matrix", "fft"}
        How ``"binned"`` applies the kernel to the binned counts (module docstring).
    """

    def __init__(
        self,
        grid: Grid,
        bandwidth: float | None = None,
        boundary: Boundary = "reflect",
        method: Method = "auto",
        normalize: bool = True,
        oversample: int | Literal["auto"] = "auto",
        convolution: Convolution = "auto",
    ):
        if bandwidth is not None:
            bandwidth = float(bandwidth)
            if not math.isfinite(bandwidth) or bandwidth <= 0:
                raise ParameterError("density.bandwidth", bandwidth, "a number > 0, or None for the rule")
        if boundary not in ("none", "reflect", "renormalize"):
            raise ParameterError("density.boundary", boundary, "'none', 'reflect' or 'renormalize'")
        if method not in ("auto", "separable", "binned"):
            raise ParameterError("density.method", method, "'auto', 'separable' or 'binned'")
        if oversample != "auto":
            if isinstance(oversample, bool) or not isinstance(oversample, (int, np.integer)) or oversample < 1:
                raise ParameterError("density.oversample", oversample, "an integer >= 1, or 'auto'")
            oversample = int(oversample)
        if convolution not in ("auto", "matrix", "fft"):
            raise ParameterError("density.convolution", convolution, "'auto', 'matrix' or 'fft'")
        if boundary == "reflect" and not grid.is_box:  # mirror images need straight axis-aligned walls
            boundary = "renormalize"
        self.grid = grid
        self.bandwidth = bandwidth
        self.boundary: Boundary = boundary
        self.method: Method = method
        self.normalize = normalize
        self.oversample: int | Literal["auto"] = oversample
        self.convolution: Convolution = convolution
        self._mass_cache: dict[float, np.ndarray] = {}
        self._factor_cache: tuple[float, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._half: np.ndarray | None = None  # the banded product's work rows (nx × the fine lattice's my)
        self._bands_are_gemm = False  # whether numpy's `@` is one dgemm for each band (numpy_uses_gemm)

    def bandwidth_for(self, points: np.ndarray) -> float:
        """The bandwidth used for ``points``."""
        if self.bandwidth is not None:
            return self.bandwidth
        return silverman_bandwidth(points, floor=max(self.grid.dx, self.grid.dy))

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Density estimate on the grid, shape ``grid.shape`` (zero outside Ω)."""
        points = np.ascontiguousarray(points, dtype=float)  # one layout for the compiled loops
        if points.ndim != 2 or points.shape[1] != 2 or len(points) == 0:
            raise ParameterError("points", points.shape, "an array of shape (N, 2) with N >= 1")
        h = self.bandwidth_for(points)
        g = self.grid
        method = self.method
        if method == "auto":
            method = "separable" if len(points) * g.cells[0] * g.cells[1] <= 5e7 else "binned"
        if method == "separable":
            if self.normalize and g.is_box and self.boundary != "renormalize":  # _finish's one step, in the call
                return self._separable(points, h, g.dx * g.dy)
            rho = self._separable(points, h)
        else:
            rho = self._binned(points, h)
        return self._finish(rho, h)

    def _finish(self, rho: np.ndarray, h: float) -> np.ndarray:
        """Wall correction (renormalize), zero outside Ω, unit mass: shared by every evaluation."""
        g = self.grid
        if self.boundary == "renormalize":
            rho = rho / self._kernel_mass(h)
        if not g.is_box:
            rho = np.where(g.active, rho, 0.0)
        if self.normalize:
            m = float(np.vdot(g.volume, rho))  # g.integrate(rho), without its temporary (3× faster on 30²)
            if m > 0:
                rho *= 1.0 / m
        return rho

    def expected(self, rho: np.ndarray, bandwidth: float | None = None) -> np.ndarray:
        """The estimator's mean ``E[ρ̂](x) = ∫ H_h(x, y) ρ(y) dy`` for points drawn from ``ρ``.

        ``H_h`` is the kernel the estimator applies, wall images included, and ``ρ`` a
        density on ``grid.shape`` (integrated by the midpoint rule, cut cells weighted by
        volume).  ``ρ̂ - E[ρ̂]`` is the estimator's sampling noise alone, without its
        smoothing bias: the quantity that falls like ``N^(-1/2)``.

        Parameters
        ----------
        rho : ndarray
            Density on ``grid.shape``.
        bandwidth : float, optional
            ``h``; required when the estimator uses the Silverman rule.
        """
        h = self.bandwidth if bandwidth is None else float(bandwidth)
        if h is None or not math.isfinite(h) or h <= 0:
            raise ParameterError("bandwidth", bandwidth, "a number > 0 (the estimator has no fixed bandwidth)")
        g = self.grid
        rho = np.asarray(rho, float)
        if rho.shape != g.shape:
            raise ParameterError("rho", rho.shape, f"an array of grid.shape {g.shape}")
        x0, x1, y0, y1 = g.domain.bounds
        fx = self._axis_factors(g.x, g.x, h, x0, x1)
        fy = self._axis_factors(g.y, g.y, h, y0, y1)
        out = fx @ (np.where(g.active, rho, 0.0) * g.volume) @ fy.T / (2 * math.pi * h * h)
        return self._finish(out, h)

    # ------------------------------------------------------------------ methods
    def _axis_factors(self, centres: np.ndarray, coords: np.ndarray, h: float, lo: float, hi: float):
        """``exp(-(x_i - X_j)²/(2h²))`` for cell centres ``x_i``, plus the wall images (numpy, dense)."""
        return axis_factors(centres, coords, h, lo, hi, self.boundary == "reflect")

    def _separable(self, points: np.ndarray, h: float, cell_area: float = 0.0) -> np.ndarray:
        """The exact sum (:func:`meanfield.crowds._kde_loops.separable_sum`), in blocks of points; with
        ``cell_area`` > 0 scaled to unit mass on a box of cells of that area."""
        g = self.grid
        x0, x1, y0, y1 = g.domain.bounds
        nx, ny = g.cells
        # points in blocks, so the axis factors never hold more than _SEPARABLE_CHUNK entries
        block = max(1, _SEPARABLE_CHUNK // max(nx, ny))
        out = np.empty((nx, ny))
        separable_sum(points, x0, x1, nx, y0, y1, ny, h, self.boundary == "reflect", block, out, cell_area)
        return out

    def oversample_for(self, h: float) -> int:
        """The binning refinement ``r`` used at bandwidth ``h``."""
        if self.oversample != "auto":
            return self.oversample
        cell = max(self.grid.dx, self.grid.dy)
        return int(min(OVERSAMPLE_MAX, max(1, math.ceil(cell / (OVERSAMPLE_BIN_TO_BANDWIDTH * h) - 1e-9))))

    def _binned(self, points: np.ndarray, h: float) -> np.ndarray:
        """Linear binning on the ``r``-times finer lattice, then the Gaussian read at the cell centres."""
        g = self.grid
        r = self.oversample_for(h)
        nx, ny = g.shape
        x0, x1, y0, y1 = g.domain.bounds
        layout = binned_layout(nx, ny, g.dx, g.dy, h, r, self.convolution)
        mx, my, kx, ky, convolution = layout.mx, layout.my, layout.kx, layout.ky, layout.convolution
        bx, by = g.dx / r, g.dy / r
        counts = linear_binning_into(points, x0, y0, bx, by, np.empty((mx, my)))
        norm = 1.0 / (2 * math.pi * h * h * len(points))
        if convolution == "matrix":
            return self._banded_product(counts, h, r) * norm
        ox = np.arange(-kx, kx + 1) * bx
        oy = np.arange(-ky, ky + 1) * by
        ker = np.outer(np.exp(-0.5 * ox**2 / (h * h)), np.exp(-0.5 * oy**2 / (h * h))) * norm
        from scipy.signal import fftconvolve  # 0.35 s to import: only on the fine grids that use it

        if self.boundary == "reflect":
            # mirror images across the walls: pad the counts by reflection
            px, py = min(kx, mx), min(ky, my)
            counts = np.pad(counts, ((px, px), (py, py)), mode="symmetric")
            fine = fftconvolve(counts, ker, mode="same")[px : px + mx, py : py + my]
        else:
            fine = fftconvolve(counts, ker, mode="same")
        if r == 1:
            return fine
        # value at the coarse centre: the middle fine centre (odd r), or the mean of the
        # four fine centres around it (even r, bilinear interpolation at the midpoint)
        blocks = fine.reshape(nx, r, ny, r)
        if r % 2:
            return blocks[:, r // 2, :, r // 2].copy()
        return blocks[:, r // 2 - 1 : r // 2 + 1, :, r // 2 - 1 : r // 2 + 1].mean(axis=(1, 3))

    def working_bytes(self, n_points: int, h: float) -> int:
        """Bytes the estimate's working arrays take at ``n_points`` points and bandwidth ``h`` (an upper
        estimate, for the memory guard before a run: :func:`meanfield.simulation.preflight.check_fits`)."""
        g = self.grid
        nx, ny = g.shape
        method = self.method
        if method == "auto":
            method = "separable" if n_points * nx * ny <= 5e7 else "binned"
        if method == "separable":
            return 8 * (3 * nx * ny + 2 * n_points * (nx + ny))
        return binned_layout(nx, ny, g.dx, g.dy, h, self.oversample_for(h), self.convolution).working_bytes(
            self.boundary == "reflect"
        )

    def _banded_product(self, counts: np.ndarray, h: float, r: int) -> np.ndarray:
        """``Fx counts Fyᵀ`` with the fine-lattice factors, band by band.

        Row ``a`` of ``Fx`` (a coarse centre) is above ``_BAND_CUT`` only on the fine columns
        within ``_BAND_REACH h`` of it (wall images included, which land next to the wall), so
        each block of ``_BAND_ROWS`` rows multiplies only its band of columns: a few times
        fewer operations than the dense product, and the same sum but for terms below
        ``_BAND_CUT`` of a point's weight (``2·10⁻¹⁸`` of the kernel's peak in all).
        """
        fx, fy, bands_x, bands_y = self._fine_factors(h, r)
        nx, ny = self.grid.shape
        if self._half is None or self._half.shape != (nx, counts.shape[1]):
            self._half = np.empty((nx, counts.shape[1]))  # (work, kept between steps)
        out = np.empty((nx, ny))
        # the bands on numba's threads, each numpy's own product (the same numbers); numpy's `@` where its BLAS
        # cannot be called from compiled code, or where numpy would not call dgemm for a band (a size of 1)
        products = banded_products if self._bands_are_gemm and numpy_gemm_found() else banded_products.fallback
        return products(fx, np.ascontiguousarray(counts), bands_x, fy, bands_y, self._half, out)

    def _fine_factors(self, h: float, r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Axis factors from the fine lattice's centres to the cell centres, and their bands (last ``h`` cached)."""
        c = self._factor_cache
        if c is None or c[0] != h or c[1] != r:
            g = self.grid
            x0, x1, y0, y1 = g.domain.bounds
            fine_x = x0 + (np.arange(g.shape[0] * r) + 0.5) * (g.dx / r)
            fine_y = y0 + (np.arange(g.shape[1] * r) + 0.5) * (g.dy / r)
            fx = np.ascontiguousarray(self._axis_factors(g.x, fine_x, h, x0, x1))
            fy = np.ascontiguousarray(self._axis_factors(g.y, fine_y, h, y0, y1))
            bands_x, bands_y = (np.array(_bands(f), np.int64).reshape(-1, 4) for f in (fx, fy))
            c = self._factor_cache = (h, r, fx, fy, bands_x, bands_y)
            nx, my = fx.shape[0], fy.shape[1]
            self._bands_are_gemm = all(numpy_uses_gemm(b - a, my, c1 - c0) for a, b, c0, c1 in bands_x) and all(
                numpy_uses_gemm(nx, b - a, c1 - c0) for a, b, c0, c1 in bands_y
            )
        return c[2], c[3], c[4], c[5]

    def _kernel_mass(self, h: float) -> np.ndarray:
        """``∫_Ω H_h(x - y) dy`` at each cell centre (cached per bandwidth)."""
        if h not in self._mass_cache:
            g = self.grid
            nx, ny = g.shape
            ox = np.arange(-(nx - 1), nx) * g.dx
            oy = np.arange(-(ny - 1), ny) * g.dy
            ker = np.exp(-0.5 * (ox[:, None] ** 2 + oy[None, :] ** 2) / (h * h))
            ker /= 2 * math.pi * h * h
            from scipy.signal import fftconvolve

            m = fftconvolve(g.volume, ker, mode="same")
            self._mass_cache[h] = np.where(g.active, np.maximum(m, 1e-300), 1.0)
        return self._mass_cache[h]


_RENAMED = {"BinnedPlan": "BinnedLayout", "binned_plan": "binned_layout"}
"""Names of this module before 0.2.0 (a floor plan is a ``Plan``): read with a warning until 0.3.0."""


def __getattr__(name: str) -> object:
    if name in _RENAMED:
        from meanfield.errors import deprecated

        deprecated(f"meanfield.crowds.kde.{name}", f"use meanfield.crowds.kde.{_RENAMED[name]}")
        return globals()[_RENAMED[name]]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
