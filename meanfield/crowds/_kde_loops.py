"""The kernel density estimate's loops, compiled: the exact separable sum and the linear binning.

Each loop is paired with its numpy twin (the reference, :mod:`meanfield._compiled.core`); both
evaluate the estimate of :mod:`meanfield.crowds.kde` (paper, Section IV-A; docs page
*Discretisation*, "Kernel density estimation")::

    ρ̂(x_a, y_b) = 1/(2π h² N) Σ_j Fx[a, j] Fy[b, j],      Fx[a, j] = Σ_images exp(-(x_a - X_j)²/(2h²))

with the mirror images across the walls within ``IMAGE_REACH`` bandwidths of them when
``reflect`` (as :func:`axis_factors`).

* :func:`separable_sum`: the sum above, exactly.  numpy takes one exponential per cell and
  point; the loop walks the Gaussian along the cell lattice, ``g(c + Δ) = g(c) q(c)`` with
  ``q(c + iΔ) = q(c) exp(-iΔ²/h²)`` (eq. (K1) of :func:`separable_sum`): two multiplications
  per cell, restarted from exact exponentials every ``S`` cells so that the round-off stays
  a few hundred ulps.  Each mirrored cell is added onto the cell it stands for as the walk
  reaches it, and the product ``Fx Fyᵀ`` is one BLAS ``dgemm`` per pass of points, straight
  into the output (:func:`meanfield._compiled.blas.gemm`: some hundredths of a second to compile,
  where numba's ``np.dot`` takes a few tenths).
* :func:`linear_binning_into`: cloud-in-cell weights of the points on a lattice, one pass
  per point (numpy: :func:`meanfield.geometry.grid.linear_binning`, four ``bincount`` scatters).
* :func:`banded_products`: the binned estimate's ``Fx C Fyᵀ`` band by band, the bands on numba's threads, each
  band's product numpy's own (:func:`meanfield._compiled.blas.numpy_gemm`): the numbers of numpy's ``@``.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.blas import gemm, numpy_gemm
from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, prange
from meanfield._compiled.vector_exp import ARG_MAX, exp_inplace
from meanfield.geometry.grid import linear_binning

__all__ = ["axis_factors", "separable_sum", "linear_binning_into", "banded_products", "IMAGE_REACH"]

IMAGE_REACH = 8.0
"""Wall images are kept for the cells within this many bandwidths of a wall (tail ``e^{-32}``)."""
_SEGMENT_BANDWIDTHS = 16.0
"""The recurrence restarts from exact exponentials every ``16 h`` (at most 64 cells, at least 1)."""
_POINTS_PER_PASS = 32768
"""Points per pass: this many entries over the longer extended axis (the factors stay L2-sized)."""


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
def _separable_numpy(points, x0, x1, nx, y0, y1, ny, h, reflect, block, out, cell_area=0.0):
    cx = x0 + (np.arange(nx) + 0.5) * ((x1 - x0) / nx)
    cy = y0 + (np.arange(ny) + 0.5) * ((y1 - y0) / ny)
    out[...] = 0.0
    for k in range(0, len(points), block):  # blocks bound the factors' memory
        part = points[k : k + block]
        out += axis_factors(cx, part[:, 0], h, x0, x1, reflect) @ axis_factors(cy, part[:, 1], h, y0, y1, reflect).T
    out *= 1.0 / (2 * math.pi * h * h * len(points))
    mass = cell_area * out.sum()
    if mass > 0:
        out *= 1.0 / mass


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
    cell_area: float = 0.0,
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
    The exponentials are :func:`meanfield._compiled.vector_exp.exp_inplace` (vectorised, within 1 ulp of
    ``exp``); the x starts carry the normalisation, ``exp(ln(norm) - (d/h)²/2)``.  Each cell of
    the extended lattice is added onto the cell it stands for as soon as the recurrence reaches
    it (its mirror beyond ``lo`` first, then the cell, then its mirror beyond ``hi``), then
    ``out = Fx Fyᵀ``, accumulated over the passes, by BLAS :func:`meanfield._compiled.blas.gemm`.

    Parameters
    ----------
    points : ndarray, shape (N, 2), N >= 1
    x0, x1, y0, y1 : float
        The box's walls; the grid has ``nx`` × ``ny`` cells between them.
    nx, ny : int
    h : float
        Bandwidth.
    reflect : bool
        Add the mirror images across the walls (within ``IMAGE_REACH`` h of them).
    block : int
        At most this many points per pass (the numpy twin's memory bound; the loop also
        keeps its factors L2-sized, ``_POINTS_PER_PASS``).
    out : ndarray, shape (nx, ny), C-contiguous
        ``ρ̂`` at the cell centres, ``1/(2π h² N) Σ_j Fx[:, j] Fy[:, j]ᵀ`` (written here; nothing is returned:
        a returned array costs numba a boxing, a quarter of a microsecond a call).
    cell_area : float
        When > 0, ``out`` is then scaled to unit mass, ``cell_area Σ out = 1`` (the estimator's
        ``normalize`` on a box, folded into the same call; a zero sum stays as it is).
    """
    n_pts = points.shape[0]
    if out.shape[0] != nx or out.shape[1] != ny or out.strides[1] != 8 or out.strides[0] != 8 * ny:
        raise ValueError("separable_sum: out must be a C-contiguous float64 array of shape (nx, ny)")
    norm = 1.0 / (2.0 * math.pi * h * h * n_pts)
    a2 = 0.5 / (h * h)
    sizes = (nx, ny)
    los = (x0, y0)
    his = (x1, y1)
    # per axis: P mirrored cells beyond each wall, segments of S cells (conditional expressions
    # rather than min/max/int, whose overloads numba compiles for each new combination of types)
    wx = IMAGE_REACH * h / ((x1 - x0) / nx)
    wy = IMAGE_REACH * h / ((y1 - y0) / ny)
    pads = (
        (nx if wx >= nx else math.ceil(wx)) if reflect else 0,
        (ny if wy >= ny else math.ceil(wy)) if reflect else 0,
    )
    sx = _SEGMENT_BANDWIDTHS / IMAGE_REACH * wx
    sy = _SEGMENT_BANDWIDTHS / IMAGE_REACH * wy
    segs = (
        64 if sx >= 64.0 else (1 if sx < 1.0 else math.floor(sx)),
        64 if sy >= 64.0 else (1 if sy < 1.0 else math.floor(sy)),
    )
    rx = nx + 2 * pads[0]
    ry = ny + 2 * pads[1]
    per_pass = _POINTS_PER_PASS // (rx if rx > ry else ry)
    per_pass = 1 if per_pass < 1 else (block if per_pass > block else per_pass)
    m = n_pts if n_pts < per_pass else per_pass
    width = m if m > 64 else 64
    n_seg_x = (rx + segs[0] - 1) // segs[0]
    n_seg_y = (ry + segs[1] - 1) // segs[1]
    n_seg = n_seg_x if n_seg_x > n_seg_y else n_seg_y
    # one scratch, by rows: the x factors (nx rows, point j in column j), the y factors (ny),
    # the segments' starts g (n_seg) and ratios q (n_seg), the running row, the table C (2-D
    # indexing: an offset into a flat buffer could be negative for numba, and would not vectorise)
    row_g = nx + ny
    row_cur = row_g + 2 * n_seg
    row_c = row_cur + 1
    work = empty_array((row_c + 1, width), np.float64)
    for first in range(0, n_pts, per_pass):
        cnt = n_pts - first if n_pts - first < per_pass else per_pass
        for ax in range(2):
            n = sizes[ax]
            lo = los[ax]
            step = (his[ax] - lo) / n
            pad = pads[ax]
            seg = segs[ax]
            rows = n + 2 * pad
            ns = (rows + seg - 1) // seg
            row_q = row_g + ns
            g2 = step * step / (h * h)
            lnw = math.log(norm) if ax == 0 else 0.0  # the x factors carry the normalisation
            # the exponentials' arguments, segment by segment, then the exponentials in place
            for j in range(cnt):  # the coordinates, contiguous (in the running row, free until the walk)
                work[row_cur, j] = points[first + j, ax]
            for t in range(ns):
                ck = lo + (t * seg - pad + 0.5) * step
                for j in range(cnt):
                    d = ck - work[row_cur, j]
                    aq = -(2.0 * d * step + step * step) * a2
                    far = aq > ARG_MAX  # the start is zero then (d < -37 h): keep the ratio finite
                    work[row_g + t, j] = -math.inf if far else lnw - d * d * a2
                    work[row_q + t, j] = ARG_MAX if far else aq
                exp_inplace(work[row_g + t], cnt)
                exp_inplace(work[row_q + t], cnt)
            for i in range(seg):
                work[row_c, i] = -i * g2
            exp_inplace(work[row_c], seg)
            # the recurrence (K1) along the extended lattice; row r is cell a's mirror beyond lo
            # (r < pad: the first term of a), the cell itself, or its mirror beyond hi (the last)
            base = 0 if ax == 0 else nx
            for t in range(ns):
                for j in range(cnt):  # a segment's first cell is its exact start, 1 × (g × 1)
                    work[row_cur, j] = 1.0
                for i in range(seg if (t + 1) * seg <= rows else rows - t * seg):
                    r = t * seg + i
                    if r < pad:
                        a = pad - 1 - r
                        add = False
                    elif r < pad + n:
                        a = r - pad
                        add = a < pad
                    else:
                        a = pad + 2 * n - 1 - r
                        add = True
                    a += base
                    mr = row_g + t if i == 0 else row_q + t
                    c = 1.0 if i == 0 else work[row_c, i - 1]
                    if add:  # (two loops: a branch inside one would keep it from vectorising)
                        for j in range(cnt):
                            v = work[row_cur, j] * (work[mr, j] * c)
                            work[row_cur, j] = v
                            work[a, j] += v
                    else:
                        for j in range(cnt):
                            v = work[row_cur, j] * (work[mr, j] * c)
                            work[row_cur, j] = v
                            work[a, j] = v
        # out = Fx Fyᵀ on the first pass, += on the others (BLAS dgemm)
        # (rows as 1-D views, the same pointers, and bools that are not literals: the types of the law's calls,
        # so that one compiled gemm serves both, cached by whichever process compiles it first)
        gemm(nx < 0, nx > 0, nx, ny, cnt, work[0], width, work[nx], width, out[0], ny, first > 0)
    if cell_area > 0.0:
        total = 0.0
        for a in range(nx):
            for b in range(ny):
                total += out[a, b]
        mass = cell_area * total
        if mass > 0.0:
            scale = 1.0 / mass
            for a in range(nx):
                for b in range(ny):
                    out[a, b] *= scale


# ----------------------------------------------------------------------------- linear binning
def _binning_numpy(points, x0, y0, bx, by, counts):
    counts[...] = linear_binning(points, (x0, y0), (bx, by), counts.shape)
    return counts


BINNING_PARTS = 8
"""At most this many parts of the points are binned on lattices of their own by :func:`linear_binning_into`
(one per thread at a time), and no more parts than points per cell of the lattice (each part costs a
lattice to clear and to add, and adds at most as many cells as points); their number depends on the
points and the lattice only, never on the threads."""


@compiled(fallback=_binning_numpy, parallel_over="points")
def linear_binning_into(
    points: np.ndarray, x0: float, y0: float, bx: float, by: float, counts: np.ndarray
) -> np.ndarray:
    """Cloud-in-cell (bilinear) weights of the points on a lattice, into ``counts`` (mx, my).

    The lattice has centres ``(x0 + (i + ½) bx, y0 + (j + ½) by)``; a point at fractional
    lattice position ``(i + s, j + t)`` puts ``(1-s)(1-t)``, ``s(1-t)``, ``(1-s)t`` and ``st``
    on its four nearest centres (points beyond the outer centres go to the nearest edge), as
    :func:`meanfield.geometry.grid.linear_binning`, in one pass per point.  The binning error of the
    estimate is second order in the lattice spacing (docs page *Discretisation*).

    With more than one chunk of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` points and more
    points than cells, up to :data:`BINNING_PARTS` consecutive parts of the points are binned on
    lattices of their own, on numba's threads, then added cell by cell in the parts' order: the
    parts depend on ``N`` and the lattice alone, so the counts are the same on any number of threads.

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
    n = points.shape[0]
    cells = mx * my
    flat = counts.reshape(cells)
    parts = min((n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK, BINNING_PARTS, max(1, n // cells))
    size = (n + parts - 1) // parts
    partial = np.empty((parts if parts > 1 else 0, cells))  # one part: straight into the counts
    ix = 1.0 / bx
    iy = 1.0 / by
    for q in prange(parts):  # each part of the points on its own lattice
        lattice = flat if parts == 1 else partial[q]
        lattice[:] = 0.0
        for p in range(q * size, min((q + 1) * size, n)):
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
            lattice[b] += ((1.0 - w11) - w10) - w01
            lattice[b + 1] += w01
            lattice[b + my] += w10
            lattice[b + my + 1] += w11
    if parts > 1:
        for r in prange((cells + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the parts added in their order
            for c in range(r * PARALLEL_CHUNK, min((r + 1) * PARALLEL_CHUNK, cells)):
                total = partial[0, c]
                for q in range(1, parts):
                    total += partial[q, c]
                flat[c] = total
    return counts


# ----------------------------------------------------------------------------- the binned estimate's products
def _banded_numpy(fx, counts, bands_x, fy, bands_y, half, out):
    for a, b, c0, c1 in bands_x:
        np.matmul(fx[a:b, c0:c1], counts[c0:c1], out=half[a:b])
    for a, b, c0, c1 in bands_y:
        out[:, a:b] = half[:, c0:c1] @ fy[a:b, c0:c1].T
    return out


@compiled(fallback=_banded_numpy, parallel=True)
def banded_products(fx, counts, bands_x, fy, bands_y, half, out):
    """``out = Fx counts Fyᵀ`` band by band (docs page *Discretisation*, "Kernel density estimation": the binned
    estimate): ``half[a:b] = Fx[a:b, c0:c1] counts[c0:c1]`` for each row ``(a, b, c0, c1)`` of ``bands_x``, then
    ``out[:, a:b] = half[:, c0:c1] Fy[a:b, c0:c1]ᵀ`` for each of ``bands_y``.

    Each band is one call of numpy's own ``dgemm`` with the operands numpy's ``@`` passes
    (:func:`~meanfield._compiled.blas.numpy_gemm`), so ``out`` is the numpy twin's to the bit; the bands of each
    stage run on numba's threads (each writes its own rows, then its own columns): the same numbers on any number
    of threads.

    Parameters
    ----------
    fx, fy : ndarray, shape (nx, mx), (ny, my), C-contiguous
        The axis factors from the fine lattice to the cell centres.
    counts : ndarray, shape (mx, my), C-contiguous
        The binned weights.
    bands_x, bands_y : ndarray of int64, shape (B, 4)
        ``(a, b, c0, c1)``: rows ``a:b`` of the factor are kept in columns ``c0:c1`` only.
    half : ndarray, shape (nx, my), C-contiguous
        Work (overwritten).
    out : ndarray, shape (nx, ny), C-contiguous
        Overwritten with the product.
    """
    mx, my = counts.shape
    nx, ny = out.shape
    no = my < 0  # (not literals: one compilation of numpy_gemm for both stages)
    yes = my >= 0
    fxf = fx.reshape(fx.size)  # (1-D views: a band's first entry is an offset; every offset is inside its array)
    cf = counts.reshape(counts.size)
    hf = half.reshape(half.size)
    fyf = fy.reshape(fy.size)
    of = out.reshape(out.size)
    for t in prange(bands_x.shape[0]):  # half[a:b] = Fx[a:b, c0:c1] counts[c0:c1]
        a = bands_x[t, 0]
        c0 = bands_x[t, 2]
        numpy_gemm(no, no, bands_x[t, 1] - a, my, bands_x[t, 3] - c0, fxf[a * mx + c0 :], mx, cf[c0 * my :], my,
                   hf[a * my :], my)  # fmt: skip
    for t in prange(bands_y.shape[0]):  # out[:, a:b] = half[:, c0:c1] Fy[a:b, c0:c1]ᵀ
        a = bands_y[t, 0]
        c0 = bands_y[t, 2]
        numpy_gemm(no, yes, nx, bands_y[t, 1] - a, bands_y[t, 3] - c0, hf[c0:], my, fyf[a * my + c0 :], my,
                   of[a:], ny)  # fmt: skip
    return out
