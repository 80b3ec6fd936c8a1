"""The kernel density estimate's loops, compiled: the exact separable sum and the linear binning.

Each loop is paired with its numpy twin (the reference, :mod:`meanfield.compiled`); both
evaluate the estimate of :mod:`meanfield.density` (paper, Section IV-A; docs page
*Discretisation*, "Kernel density estimation")::

    ρ̂(x_a, y_b) = 1/(2π h² N) Σ_j Fx[a, j] Fy[b, j],      Fx[a, j] = Σ_images exp(-(x_a - X_j)²/(2h²))

with the mirror images across the walls within ``IMAGE_REACH`` bandwidths of them when
``reflect`` (as :func:`axis_factors`).

* :func:`separable_sum`: the sum above, exactly.  numpy takes one exponential per cell and
  point; the loop walks the Gaussian along the cell lattice, ``g(c + Δ) = g(c) q(c)`` with
  ``q(c + iΔ) = q(c) exp(-iΔ²/h²)`` (eq. (K1) of :func:`separable_sum`): two multiplications
  per cell, restarted from exact exponentials every ``S`` cells so that the round-off stays
  a few hundred ulps.
* :func:`linear_binning_into`: cloud-in-cell weights of the points on a lattice, one pass
  per point (numpy: :func:`meanfield.grid.linear_binning`, four ``bincount`` scatters).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield.compiled import compiled
from meanfield.grid import linear_binning
from meanfield.vector_exp import ARG_MAX, exp_inplace

__all__ = ["axis_factors", "separable_sum", "linear_binning_into", "IMAGE_REACH"]

IMAGE_REACH = 8.0
"""Wall images are kept for the cells within this many bandwidths of a wall (tail ``e^{-32}``)."""
_SEGMENT_BANDWIDTHS = 16.0
"""The recurrence restarts from exact exponentials every ``16 h`` (at most 64 cells, at least 1)."""
_POINTS_PER_PASS = 32768
"""The loop treats points in passes whose lattice buffers hold about this many entries (L2-sized)."""


# ----------------------------------------------------------------------------- axis factors
def axis_factors(centres: np.ndarray, coords: np.ndarray, h: float, lo: float, hi: float, reflect: bool) -> np.ndarray:
    """``F[a, j] = exp(-(x_a - X_j)²/(2h²))`` plus the wall images (numpy, dense).

    With reflection, the image of ``X`` across ``lo`` seen from ``x_a`` equals ``X`` seen from
    the mirrored centre ``2 lo - x_a``: one exponential on the centres extended by their
    mirrors (as far as the kernel reaches, ``IMAGE_REACH`` h) then a fold gives all three terms.

    Parameters
    ----------
    centres : ndarray, shape (n,)
        Uniformly spaced cell centres ``x_a`` between the walls ``lo`` and ``hi``.
    coords : ndarray, shape (N,)
        The points' coordinates ``X_j`` along the same axis.
    h : float
        Bandwidth.
    lo, hi : float
        The walls.
    reflect : bool
        Add the mirror images across both walls.

    Returns
    -------
    ndarray, shape (n, N)
    """
    s = -0.5 / (h * h)
    if not reflect:
        d = centres[:, None] - coords[None, :]
        return np.exp(s * d * d)
    n = len(centres)
    step = centres[1] - centres[0]
    pad = min(n, int(math.ceil(IMAGE_REACH * h / step)))
    ext = np.concatenate([2 * lo - centres[:pad][::-1], centres, 2 * hi - centres[n - pad :][::-1]])
    d = ext[:, None] - coords[None, :]
    e = np.exp(s * d * d)
    f = e[pad : pad + n].copy()
    f[:pad] += e[:pad][::-1]
    f[n - pad :] += e[pad + n :][::-1]
    return f


# ----------------------------------------------------------------------------- the exact sum
def _separable_numpy(points, x0, x1, nx, y0, y1, ny, h, reflect, block, out):
    cx = x0 + (np.arange(nx) + 0.5) * ((x1 - x0) / nx)
    cy = y0 + (np.arange(ny) + 0.5) * ((y1 - y0) / ny)
    out[...] = 0.0
    for k in range(0, len(points), block):  # blocks bound the factors' memory
        part = points[k : k + block]
        out += axis_factors(cx, part[:, 0], h, x0, x1, reflect) @ axis_factors(cy, part[:, 1], h, y0, y1, reflect).T
    out *= 1.0 / (2 * math.pi * h * h * len(points))
    return out


@compiled(fallback=_separable_numpy)
def separable_sum(
    points: np.ndarray,
    x0: float,
    x1: float,
    nx: int,
    y0: float,
    y1: float,
    ny: int,
    h: float,
    reflect: bool,
    block: int,
    out: np.ndarray,
) -> np.ndarray:
    """The paper's KDE on the cell centres, summed exactly over the points, into ``out`` (nx, ny).

    Along an axis with centres ``c_k = lo + (k + ½)Δ`` (``k`` running over the cells and, with
    ``reflect``, over ``P = min(n, ⌈8h/Δ⌉)`` mirrored cells beyond each wall), the factor of
    point ``X`` obeys, with ``d_k = c_k - X``::

        g_{k+1} = g_k q_k,   q_k = exp(-(2 d_k Δ + Δ²)/(2h²)) = q_{k0} C[k - k0],   C[i] = exp(-i Δ²/h²)   (K1)

    so a segment of ``S`` cells needs the two exact exponentials ``g_{k0}``, ``q_{k0}`` per point
    and ``S`` table entries, then two multiplications per cell; each step rounds ``q`` afresh
    from the table, so the relative error grows linearly along a segment.  ``S = ⌊16 h/Δ⌋``
    (1 to 64) bounds the error by a few hundred ulps: the start's argument ``(d/h)²/2 <= 128``
    where the values matter, and at most ``1.5 S + (SΔ/h)²/4`` from the steps.  A start below
    ``exp(-708)`` is zero: the point is ``37 h`` away, ``21 h`` at least over the segment.
    The exponentials are :func:`meanfield.vector_exp.exp_inplace` (vectorised, within 1 ulp of ``exp``).
    Mirror cells are folded back onto the cells they mirror, then ``out = norm Fx Fyᵀ`` by BLAS.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    x0, x1, y0, y1 : float
        The box's walls; the grid has ``nx`` × ``ny`` cells between them.
    nx, ny : int
    h : float
        Bandwidth.
    reflect : bool
        Add the mirror images across the walls (within ``IMAGE_REACH`` h of them).
    block : int
        At most this many points per pass (the numpy twin's memory bound; the loop also
        keeps its lattice buffers L2-sized).
    out : ndarray, shape (nx, ny)
        ``ρ̂`` at the cell centres, ``1/(2π h² N) Σ_j Fx[:, j] Fy[:, j]ᵀ``.
    """
    n_pts = points.shape[0]
    norm = 1.0 / (2.0 * math.pi * h * h * n_pts)
    sizes = (nx, ny)
    los = (x0, y0)
    his = (x1, y1)
    dx = (x1 - x0) / nx
    dy = (y1 - y0) / ny
    pads = (
        min(nx, int(math.ceil(IMAGE_REACH * h / dx))) if reflect else 0,
        min(ny, int(math.ceil(IMAGE_REACH * h / dy))) if reflect else 0,
    )
    segs = (
        int(min(64.0, max(1.0, math.floor(_SEGMENT_BANDWIDTHS * h / dx)))),
        int(min(64.0, max(1.0, math.floor(_SEGMENT_BANDWIDTHS * h / dy)))),
    )
    n_ext = max(nx + 2 * pads[0], ny + 2 * pads[1])
    per_pass = max(1, min(block, _POINTS_PER_PASS // n_ext))
    m = min(per_pass, n_pts)
    ext = np.empty((n_ext, m))
    fac_x = np.empty((nx, m))
    fac_y = np.empty((ny, m))
    n_seg = (n_ext + min(segs) - 1) // min(segs)
    vals = np.empty(2 * n_seg * m + 64)  # the exponentials' arguments, then (in place) their values
    bits = np.empty(2 * n_seg * m + 64, np.int64)
    single = m == n_pts  # one pass: the product goes straight into out
    part = out if single else np.empty((nx, ny))
    for first in range(0, n_pts, per_pass):
        cnt = min(per_pass, n_pts - first)
        if cnt < m:  # the last, shorter pass
            fac_x = np.empty((nx, cnt))
            fac_y = np.empty((ny, cnt))
        for ax in range(2):
            n = sizes[ax]
            lo = los[ax]
            step = (his[ax] - lo) / n
            pad = pads[ax]
            seg = segs[ax]
            rows = n + 2 * pad
            ns = (rows + seg - 1) // seg
            a2 = 0.5 / (h * h)
            g2 = step * step / (h * h)
            # arguments: segment starts g (ns × cnt), ratios q (ns × cnt), then the table C (seg)
            for t in range(ns):
                ck = lo + (t * seg - pad + 0.5) * step
                for j in range(cnt):
                    d = ck - points[first + j, ax]
                    aq = -(2.0 * d * step + step * step) * a2
                    ag = -d * d * a2
                    if aq > ARG_MAX:  # the start is zero then (d < -37 h): keep the ratio finite
                        aq = ARG_MAX
                        ag = -math.inf
                    vals[t * cnt + j] = ag
                    vals[(ns + t) * cnt + j] = aq
            base = 2 * ns * cnt
            for i in range(seg):
                vals[base + i] = -i * g2
            total = base + seg
            exp_inplace(vals, bits, total)  # vectorised (meanfield.vector_exp)
            # the recurrence (K1), segment by segment, on the extended lattice (2-D indexing:
            # a row view per cell would cost two reference-count updates)
            for t in range(ns):
                r0 = t * seg
                for j in range(cnt):
                    ext[r0, j] = vals[t * cnt + j]
                qb = (ns + t) * cnt
                for i in range(1, min(seg, rows - r0)):
                    ci = vals[base + i - 1]
                    r = r0 + i
                    for j in range(cnt):
                        ext[r, j] = ext[r - 1, j] * (vals[qb + j] * ci)
            # fold the mirrored cells back (norm folded into the x factor)
            fac = fac_x if ax == 0 else fac_y
            w = norm if ax == 0 else 1.0
            for a in range(n):  # cell a: itself, its mirror beyond lo (a < pad), beyond hi (a >= n - pad)
                r = pad + a
                left = pad - 1 - a
                right = pad + 2 * n - 1 - a
                if a < pad and a >= n - pad:
                    for j in range(cnt):
                        fac[a, j] = w * (ext[r, j] + ext[left, j] + ext[right, j])
                elif a < pad:
                    for j in range(cnt):
                        fac[a, j] = w * (ext[r, j] + ext[left, j])
                elif a >= n - pad:
                    for j in range(cnt):
                        fac[a, j] = w * (ext[r, j] + ext[right, j])
                else:
                    for j in range(cnt):
                        fac[a, j] = w * ext[r, j]
        np.dot(fac_x, fac_y.T, part)
        if not single:  # element loops: an array slice assignment costs seconds of compilation
            for a in range(nx):
                for b in range(ny):
                    out[a, b] = part[a, b] if first == 0 else out[a, b] + part[a, b]
    return out


# ----------------------------------------------------------------------------- linear binning
def _binning_numpy(points, x0, y0, bx, by, counts):
    counts[...] = linear_binning(points, (x0, y0), (bx, by), counts.shape)
    return counts


@compiled(fallback=_binning_numpy)
def linear_binning_into(
    points: np.ndarray, x0: float, y0: float, bx: float, by: float, counts: np.ndarray
) -> np.ndarray:
    """Cloud-in-cell (bilinear) weights of the points on a lattice, into ``counts`` (mx, my).

    The lattice has centres ``(x0 + (i + ½) bx, y0 + (j + ½) by)``; a point at fractional
    lattice position ``(i + s, j + t)`` puts ``(1-s)(1-t)``, ``s(1-t)``, ``(1-s)t`` and ``st``
    on its four nearest centres (points beyond the outer centres go to the nearest edge), as
    :func:`meanfield.grid.linear_binning`, in one pass per point.  The binning error of the
    estimate is second order in the lattice spacing (docs page *Discretisation*).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    x0, y0 : float
        The lattice's lower-left corner.
    bx, by : float
        Its spacings.
    counts : ndarray, shape (mx, my)
        Overwritten with the weights (each point's sum to 1).
    """
    mx, my = counts.shape
    flat = counts.reshape(mx * my)
    flat[:] = 0.0
    ix = 1.0 / bx
    iy = 1.0 / by
    for p in range(points.shape[0]):
        s = min(max((points[p, 0] - x0) * ix - 0.5, 0.0), mx - 1.0)
        t = min(max((points[p, 1] - y0) * iy - 0.5, 0.0), my - 1.0)
        i = min(int(s), mx - 2)
        j = min(int(t), my - 2)
        s -= i
        t -= j
        w11 = s * t
        w10 = s - w11
        w01 = t - w11
        b = i * my + j
        flat[b] += ((1.0 - w11) - w10) - w01
        flat[b + 1] += w01
        flat[b + my] += w10
        flat[b + my + 1] += w11
    return counts
