"""The navigation field on a lattice, interpolated to the humans: O(N + n M) per step.

Evaluating ``v_r(x) = Σ_i K̄(x − R_i) e(θ_i)`` (paper, eq. (3)) exactly at every human costs
O(N n) kernel evaluations, a second per step for a million humans and 64 robots.  A large
crowd instead samples ``v_r`` on a lattice of ``M`` nodes covering Ω (for the separable
Gaussian kernel, two matrix products of O(n M) work) and interpolates it bilinearly to the
humans (O(N)).

Error bound.  Bilinear interpolation on a cell of size ``h_x × h_y`` errs by at most
``(h_x² max|∂²ₓv| + h_y² max|∂²ᵧv|) / 8`` per component.  For the Gaussian kernel,
``∂²ₓK̄(ξ) = c (4ξₓ²/η² − 2/η) exp(−|ξ|²/η)``, bounded by ``2c/η`` per robot.
:meth:`SampledNavigationField.error_bound` returns this bound with the second derivatives
taken at the nodes (summed over the robots with their headings), so it is the bound for
the field as sampled, not a worst case over every possible layout.  With the lattice
twice as fine as a 128² grid on the unit square and ``η = 0.05``, ``c = 0.2``, one robot
gives ``(2 · 7.6e-6 · 8) / 8 ≈ 1.5e-5``, i.e. 8·10⁻⁵ of the peak speed ``c``.
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.blas import numpy_gemm_found, numpy_uses_gemm
from meanfield.errors import ParameterError
from meanfield.signs._lattice_loops import lattice_products
from meanfield.signs.kernels import NavigationKernel

__all__ = ["SampledNavigationField"]


class SampledNavigationField:
    """``v_r`` on a ``nodes[0] × nodes[1]`` lattice over a bounding box, bilinear in between.

    Parameters
    ----------
    kernel : NavigationKernel
        The signs' kernel; the Gaussian's separability is used when available.
    bounds : tuple of float
        ``(x0, x1, y0, y1)``: the lattice's corners (Ω's bounding box).
    nodes : tuple of int
        Nodes per axis, each >= 2 (spacing ``(x1 − x0) / (nodes − 1)``).
    """

    def __init__(self, kernel: NavigationKernel, bounds: tuple[float, float, float, float], nodes: tuple[int, int]):
        mx, my = (int(v) for v in nodes)
        if mx < 2 or my < 2:
            raise ParameterError("nodes", nodes, "at least 2 nodes per axis")
        x0, x1, y0, y1 = (float(b) for b in bounds)
        if not (x1 > x0 and y1 > y0):
            raise ParameterError("bounds", bounds, "(x0, x1, y0, y1) with x1 > x0 and y1 > y0")
        self.kernel = kernel
        self.origin = (x0, y0)
        self.spacing = ((x1 - x0) / (mx - 1), (y1 - y0) / (my - 1))
        self.xs = x0 + self.spacing[0] * np.arange(mx)
        self.ys = y0 + self.spacing[1] * np.arange(my)
        self.shape = (mx, my)
        self.vx = np.zeros(self.shape)
        self.vy = np.zeros(self.shape)
        self._positions: np.ndarray | None = None
        self._headings: np.ndarray | None = None
        self._work: tuple[np.ndarray, ...] | None = None

    def update(self, positions: np.ndarray, headings: np.ndarray) -> None:
        """Sample ``v_r`` (eq. (3)) at the nodes for robots at ``positions`` (n, 2) with ``headings``."""
        positions = np.asarray(positions, float)
        headings = np.asarray(headings, float)
        cos, sin = np.cos(headings), np.sin(headings)
        k = self.kernel
        if getattr(k, "separable", False) and hasattr(k, "factor"):
            fx = k.factor(self.xs[None, :] - positions[:, 0:1])  # (n, mx)
            fy = np.ascontiguousarray(k.factor(self.ys[None, :] - positions[:, 1:2]))  # (n, my)
            ax = np.ascontiguousarray(k.c * cos[:, None] * fx)
            ay = np.ascontiguousarray(k.c * sin[:, None] * fx)
            self.vx, self.vy = np.empty(self.shape), np.empty(self.shape)  # (new arrays: a reader may hold the last)
            # the two products side by side on numba's threads, each numpy's own (the same numbers as `ax.T @ fy`)
            gemm = numpy_uses_gemm(*self.shape, len(positions)) and numpy_gemm_found()  # (numpy's dgemm: 2+ robots)
            products = lattice_products if gemm else lattice_products.fallback  # (numpy's `@`)
            products(ax, ay, fy, self.vx, self.vy)
        else:
            X, Y = np.meshgrid(self.xs, self.ys, indexing="ij")
            self.vx = np.zeros(self.shape)
            self.vy = np.zeros(self.shape)
            for (rx, ry), c, s in zip(positions, cos, sin, strict=True):
                m = k.magnitude(X - rx, Y - ry)
                self.vx += c * m
                self.vy += s * m
        self._positions, self._headings = positions.copy(), headings.copy()

    def at_points(self, points: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Bilinear interpolation of the sampled ``v_r`` at ``points`` (N, 2); shape (N, 2).

        Points outside the lattice take the value at its nearest edge.  The work arrays
        are kept between calls of the same N (no per-step allocation of N-sized arrays).
        """
        n = len(points)
        mx, my = self.shape
        if self._work is None or self._work[0].shape[0] != n:
            self._work = (np.empty(n), np.empty(n), np.empty(n, np.intp), np.empty(n, np.intp), np.empty(n))
        s, t, i, j, tmp = self._work
        np.subtract(points[:, 0], self.origin[0], out=s)
        s *= 1.0 / self.spacing[0]
        np.maximum(s, 0.0, out=s)
        np.minimum(s, mx - 1.0, out=s)
        np.subtract(points[:, 1], self.origin[1], out=t)
        t *= 1.0 / self.spacing[1]
        np.maximum(t, 0.0, out=t)
        np.minimum(t, my - 1.0, out=t)
        np.minimum(s, mx - 2.0, out=tmp)
        i[:] = tmp  # truncation towards zero = floor (s >= 0)
        np.minimum(t, my - 2.0, out=tmp)
        j[:] = tmp
        s -= i  # now the fractional offsets in [0, 1]
        t -= j
        i *= my
        i += j  # flat index of the lower-left node
        if out is None:
            out = np.empty((n, 2))
        for col, f in enumerate((self.vx.ravel(), self.vy.ravel())):
            # bilinear: lerp in y on both columns, then in x
            lo = np.take(f, i)
            hi = np.take(f, i + 1)
            hi -= lo
            hi *= t
            lo += hi  # column x_i at t
            a = np.take(f, i + my)
            b = np.take(f, i + my + 1)
            b -= a
            b *= t
            a += b  # column x_{i+1} at t
            a -= lo
            a *= s
            lo += a
            out[:, col] = lo
        return out

    def error_bound(self) -> float:
        """Bound on ``|v_r − interpolated v_r|`` per component, ``(h_x² max|∂²ₓv| + h_y² max|∂²ᵧv|)/8``.

        The second derivatives are the Gaussian kernel's exact ones at the nodes, summed
        over the robots (module docstring); for another kernel they are estimated by
        second differences of the sampled field.
        """
        if self._positions is None:
            raise RuntimeError("update() the field before asking for its error bound")
        hx, hy = self.spacing
        k = self.kernel
        if getattr(k, "separable", False) and hasattr(k, "factor"):
            eta = k.eta
            dx = self.xs[None, :] - self._positions[:, 0:1]
            dy = self.ys[None, :] - self._positions[:, 1:2]
            fx, fy = k.factor(dx), k.factor(dy)
            fxx = (4 * dx * dx / eta**2 - 2 / eta) * fx
            fyy = (4 * dy * dy / eta**2 - 2 / eta) * fy
            worst = 0.0
            for e in (np.cos(self._headings), np.sin(self._headings)):
                dxx = (k.c * e[:, None] * fxx).T @ fy
                dyy = (k.c * e[:, None] * fx).T @ fyy
                worst = max(worst, (hx * hx * np.abs(dxx).max() + hy * hy * np.abs(dyy).max()) / 8)
            return float(worst)
        worst = 0.0
        for f in (self.vx, self.vy):
            dxx = np.abs(np.diff(f, 2, axis=0)).max() / (hx * hx) if self.shape[0] > 2 else 0.0
            dyy = np.abs(np.diff(f, 2, axis=1)).max() / (hy * hy) if self.shape[1] > 2 else 0.0
            worst = max(worst, (hx * hx * dxx + hy * hy * dyy) / 8)
        return float(worst)
