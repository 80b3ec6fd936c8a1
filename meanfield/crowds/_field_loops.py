"""The signs' field at each human, compiled: one pass over the humans (paper, eq. (3)).

* :func:`gaussian_field_at`: ``v_r(X_j) = Σ_i K̄(X_j - R_i) e(θ_i)`` for the paper's Gaussian
  ``K̄(ξ) = c exp(-|ξ|²/η)`` (eq. (3); docs page *The model*), optionally masked by which robot
  each human sees (plans, :mod:`meanfield.geometry.sight`);
* :func:`bilinear_at`: the same field sampled on a lattice and interpolated to the humans
  (:mod:`meanfield.signs.sampled_field`).

Both loops also flag the humans a sign *reaches* (``|v_r| >= reach``, used for the
stragglers).  Each is paired with its numpy twin, the reference (:mod:`meanfield._compiled`).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, prange
from meanfield._compiled.vector_exp import exp_inplace

__all__ = ["gaussian_field_at", "bilinear_at"]


_FIELD_BLOCK = 256
"""Humans per block of :func:`gaussian_field_at` (its buffers stay in L1)."""


# ----------------------------------------------------------------------------- v_r, exact
def _gaussian_field_numpy(points, robots, headings, c, inv_eta, visible, reach, out, reached):
    rx, ry = robots[:, 0], robots[:, 1]
    ex, ey = c * np.cos(headings), c * np.sin(headings)
    block = max(1, (1 << 20) // max(len(rx), 1))
    for a in range(0, len(points), block):
        p = points[a : a + block]
        dx = p[None, :, 0] - rx[:, None]
        dy = p[None, :, 1] - ry[:, None]
        k = np.exp(-(dx * dx + dy * dy) * inv_eta)
        if visible.shape[1]:
            k *= visible[:, a : a + block]
        out[a : a + block, 0] = ex @ k
        out[a : a + block, 1] = ey @ k
    np.greater_equal(out[:, 0] * out[:, 0] + out[:, 1] * out[:, 1], reach * reach, out=reached)


@compiled(fallback=_gaussian_field_numpy, parallel_over="points")
def gaussian_field_at(points, robots, headings, c, inv_eta, visible, reach, out, reached):
    """``v_r`` of eq. (3) at every human for the Gaussian kernel, into ``out`` (N, 2).

    Chunks of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans run on numba's threads (each
    human's value is its own: the same on any number of threads).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        The humans.
    robots : ndarray, shape (n, 2)
        The robots' positions ``R_i``.
    headings : ndarray, shape (n,)
        Their headings ``θ_i``.
    c : float
        The kernel's strength.
    inv_eta : float
        ``1 / η``.
    visible : ndarray of bool, shape (n, N) or (n, 0)
        Which robot each human sees; an empty second axis means every robot is seen.
    reach : float
        ``reached[j] = |v_r(X_j)| >= reach``.
    out : ndarray, shape (N, 2)
    reached : ndarray of bool, shape (N,)
    """
    n = robots.shape[0]
    rx, ry = empty_array(n, np.float64), empty_array(n, np.float64)
    ex, ey = empty_array(n, np.float64), empty_array(n, np.float64)
    for i in range(n):
        rx[i] = robots[i, 0]
        ry[i] = robots[i, 1]
        ex[i] = c * math.cos(headings[i])
        ey[i] = c * math.sin(headings[i])
    masked = visible.shape[1] > 0
    r2 = reach * reach
    total = points.shape[0]
    for chunk in prange((total + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        lo = chunk * PARALLEL_CHUNK
        hi = total if total < lo + PARALLEL_CHUNK else lo + PARALLEL_CHUNK
        xs, ys = empty_array(_FIELD_BLOCK, np.float64), empty_array(_FIELD_BLOCK, np.float64)  # (each chunk its own)
        sx, sy = empty_array(_FIELD_BLOCK, np.float64), empty_array(_FIELD_BLOCK, np.float64)
        k = empty_array(_FIELD_BLOCK, np.float64)
        for first in range(lo, hi, _FIELD_BLOCK):  # blocks of humans, robot by robot: the exp vectorises
            m = _FIELD_BLOCK if hi - first > _FIELD_BLOCK else hi - first
            for j in range(m):
                xs[j] = points[first + j, 0]
                ys[j] = points[first + j, 1]
                sx[j] = 0.0
                sy[j] = 0.0
            for i in range(n):
                for j in range(m):
                    dx = xs[j] - rx[i]
                    dy = ys[j] - ry[i]
                    k[j] = -(dx * dx + dy * dy) * inv_eta
                exp_inplace(k, m)
                if masked:
                    for j in range(m):
                        if not visible[i, first + j]:
                            k[j] = 0.0
                for j in range(m):
                    sx[j] += ex[i] * k[j]
                    sy[j] += ey[i] * k[j]
            for j in range(m):
                out[first + j, 0] = sx[j]
                out[first + j, 1] = sy[j]
                reached[first + j] = sx[j] * sx[j] + sy[j] * sy[j] >= r2


# ----------------------------------------------------------------------------- v_r, sampled
def _bilinear_numpy(vx, vy, x0, y0, inv_hx, inv_hy, points, reach, out, reached):
    mx, my = vx.shape
    s = np.clip((points[:, 0] - x0) * inv_hx, 0.0, mx - 1.0)
    t = np.clip((points[:, 1] - y0) * inv_hy, 0.0, my - 1.0)
    i = np.minimum(s, mx - 2.0).astype(np.intp)
    j = np.minimum(t, my - 2.0).astype(np.intp)
    s -= i
    t -= j
    for col, f in enumerate((vx, vy)):
        lo = f[i, j] + (f[i, j + 1] - f[i, j]) * t
        hi = f[i + 1, j] + (f[i + 1, j + 1] - f[i + 1, j]) * t
        out[:, col] = lo + (hi - lo) * s
    np.greater_equal(out[:, 0] * out[:, 0] + out[:, 1] * out[:, 1], reach * reach, out=reached)
    return out


@compiled(fallback=_bilinear_numpy, parallel_over="points")
def bilinear_at(vx, vy, x0, y0, inv_hx, inv_hy, points, reach, out, reached):
    """Bilinear interpolation of a lattice field ``(vx, vy)`` at every human, into ``out`` (N, 2).

    Node ``(a, b)`` of the lattice sits at ``(x0 + a h_x, y0 + b h_y)``; a point outside
    the lattice takes the value at its nearest edge.  The interpolation error is bounded
    in :mod:`meanfield.signs.sampled_field`.

    Chunks of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans run on numba's threads (each
    human's value is its own: the same on any number of threads).

    Parameters
    ----------
    vx, vy : ndarray, shape (mx, my)
        The field's components at the nodes.
    x0, y0, inv_hx, inv_hy : float
        The lattice's origin and inverse spacings.
    points : ndarray, shape (N, 2)
    reach : float
        ``reached[j] = |v_r(X_j)| >= reach``.
    out : ndarray, shape (N, 2)
    reached : ndarray of bool, shape (N,)
    """
    mx, my = vx.shape
    r2 = reach * reach
    n = points.shape[0]
    for chunk in prange((n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        for p in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, n)):
            s = min(max((points[p, 0] - x0) * inv_hx, 0.0), mx - 1.0)
            t = min(max((points[p, 1] - y0) * inv_hy, 0.0), my - 1.0)
            i = int(min(s, mx - 2.0))
            j = int(min(t, my - 2.0))
            s -= i
            t -= j
            lo = vx[i, j] + (vx[i, j + 1] - vx[i, j]) * t
            hi = vx[i + 1, j] + (vx[i + 1, j + 1] - vx[i + 1, j]) * t
            ux = lo + (hi - lo) * s
            lo = vy[i, j] + (vy[i, j + 1] - vy[i, j]) * t
            hi = vy[i + 1, j] + (vy[i + 1, j + 1] - vy[i + 1, j]) * t
            uy = lo + (hi - lo) * s
            out[p, 0] = ux
            out[p, 1] = uy
            reached[p] = ux * ux + uy * uy >= r2
    return out
