"""Sight lines in a floor plan, compiled: which walls hide a robot from a point.

* :func:`segments_clear`: whether each segment ``p_k q_k`` crosses no wall;
* :func:`sight_row`: one robot's sight of every cell centre, the walls tried nearest first;
* :func:`cell_index`: the grid cell of each point.

Each is paired with its numpy twin, the reference (:mod:`meanfield._compiled`); the callers are
:mod:`meanfield.geometry.sight`'s classes.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, inner

__all__ = ["SIGHT_EPS", "segments_clear", "sight_row", "cell_index"]


SIGHT_EPS = 1e-9
"""A segment that only touches a wall within this fraction of its ends is not hidden by it."""


# ----------------------------------------------------------------------------- sight lines
def _segments_clear_numpy(p, q, a, e, out):
    step = max(1, (1 << 18) // max(len(a), 1))
    eps = SIGHT_EPS
    for s in range(0, len(p), step):
        ps, d = p[s : s + step], q[s : s + step] - p[s : s + step]
        cross = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
        w = a[None] - ps[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / cross
            u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / cross
        hit = (cross != 0) & (t > eps) & (t < 1 - eps) & (u >= -eps) & (u <= 1 + eps)
        out[s : s + step] = ~hit.any(axis=1)
    return out


@inner
def _crosses(px, py, dx, dy, ax, ay, ex, ey, eps):
    """Whether the segment ``p + t d`` crosses the wall ``a + s e`` inside both: ``eps < t < 1 - eps``
    and ``-eps <= s <= 1 + eps`` (a touch at either end of the segment does not count)."""
    cross = dx * ey - dy * ex
    if cross == 0.0:
        return False
    wx, wy = ax - px, ay - py
    t = (wx * ey - wy * ex) / cross
    if t <= eps or t >= 1 - eps:
        return False
    u = (wx * dy - wy * dx) / cross
    return u >= -eps and u <= 1 + eps


@compiled(fallback=_segments_clear_numpy)
def segments_clear(p, q, a, e, out):
    """``out[k]``: the segment ``p[k] → q[k]`` crosses no wall ``a_w + s e_w``, ``s ∈ [0, 1]``.

    A segment that only touches a wall at one of its ends is clear; one through a wall's
    interior or one of its corners is not (:data:`SIGHT_EPS` of slack on each parameter).

    Parameters
    ----------
    p, q : ndarray, shape (M, 2)
        The segments' ends.
    a, e : ndarray, shape (W, 2)
        Each wall's start and its vector to the end.
    out : ndarray of bool, shape (M,)
    """
    eps = SIGHT_EPS
    for k in range(p.shape[0]):
        px, py = p[k, 0], p[k, 1]
        dx, dy = q[k, 0] - px, q[k, 1] - py
        clear = True
        for w in range(a.shape[0]):
            if _crosses(px, py, dx, dy, a[w, 0], a[w, 1], e[w, 0], e[w, 1], eps):
                clear = False
                break
        out[k] = clear
    return out


def _sight_row_numpy(p, q, a, e, order, wall, out):
    start = np.empty_like(q)
    start[:] = p
    return _segments_clear_numpy(start, q, a, e, out)


@compiled(fallback=_sight_row_numpy)
def sight_row(p, q, a, e, order, wall, out):
    """``out[k]``: the segment ``p → q[k]`` crosses no wall (:func:`segments_clear` from one point).

    From one point four things are cheap. The wall that hid the previous point is tried first
    (neighbouring cells are mostly hidden by the same wall), then the walls nearest first (the
    nearest hides most). A wall whose line has ``p`` and ``q[k]`` well on the same side cannot be
    crossed, which two products decide before any division. A wall more than ``|q - p| + M``
    from ``p`` is out of the segment's reach, and so are the walls after it: they are not tried.
    "Well" and ``M`` are ``10⁻⁶`` of the products' and the lengths' size, far above their
    round-off, so that the answer is :func:`segments_clear`'s: the walls whose line passes within
    that of ``p`` (``p`` on a wall's line, a cut cell's point on its wall) are always tried, since
    there a nearly parallel segment's crossing rests on round-off; for every other wall, a
    crossing :func:`segments_clear` finds lies within ``|q - p| + ε|e|`` of ``p`` to ``10⁻⁸`` of the
    size (the divisor of its parameters is then at least the margin).

    Parameters
    ----------
    p : ndarray, shape (2,)
    q : ndarray, shape (M, 2)
    a, e : ndarray, shape (W, 2)
        Each wall's start and its vector to the end.
    order, wall : ndarray, shapes (W,) of int and (W, 7)
        Work arrays (the walls sorted; allocations inside would add to the first call's compilation).
    out : ndarray of bool, shape (M,)
    """
    eps = SIGHT_EPS
    nw = a.shape[0]
    px, py = p[0], p[1]
    for w in range(nw):  # the squared distance from p to each wall, in column 6 of wall
        ee = e[w, 0] * e[w, 0] + e[w, 1] * e[w, 1]
        s = ((px - a[w, 0]) * e[w, 0] + (py - a[w, 1]) * e[w, 1]) / ee if ee > 0 else 0.0
        s = 0.0 if 0.0 > s else s  # min(max(s, 0), 1) as numba's select (no overload of numba's to compile)
        s = 1.0 if 1.0 < s else s
        dx, dy = a[w, 0] + s * e[w, 0] - px, a[w, 1] + s * e[w, 1] - py
        wall[w, 6] = dx * dx + dy * dy
    for w in range(nw):  # by insertion (a few dozen walls; np.argsort costs a second of compilation)
        k = w
        while k > 0 and wall[order[k - 1], 6] > wall[w, 6]:
            order[k] = order[k - 1]
            k -= 1
        order[k] = w
    lo_x, hi_x, lo_y, hi_y = px, px, py, py  # the box of the points and walls: the margins' scale
    for k in range(q.shape[0]):  # (min and max as numba selects: v if v < m else m)
        lo_x = q[k, 0] if q[k, 0] < lo_x else lo_x
        hi_x = q[k, 0] if q[k, 0] > hi_x else hi_x
        lo_y = q[k, 1] if q[k, 1] < lo_y else lo_y
        hi_y = q[k, 1] if q[k, 1] > hi_y else hi_y
    e_max = 0.0
    for w in range(nw):
        bx, by = a[w, 0] + e[w, 0], a[w, 1] + e[w, 1]
        v = bx if bx < a[w, 0] else a[w, 0]
        lo_x = v if v < lo_x else lo_x
        v = bx if bx > a[w, 0] else a[w, 0]
        hi_x = v if v > hi_x else hi_x
        v = by if by < a[w, 1] else a[w, 1]
        lo_y = v if v < lo_y else lo_y
        v = by if by > a[w, 1] else a[w, 1]
        hi_y = v if v > hi_y else hi_y
        v = abs(e[w, 0]) + abs(e[w, 1])
        e_max = v if v > e_max else e_max
    span = hi_y - lo_y if hi_y - lo_y > hi_x - lo_x else hi_x - lo_x
    reach = 1e-6 * span + 2.0 * eps * e_max  # M: a wall this much farther than q is out of the segment's reach
    # columns 0-5 of wall: a, e, the side of p, the margin; column 6: the squared distance beyond which q is
    # out of reach (-1: never). Rows: first the walls whose line passes by p (always tried), then the others,
    # nearest first (their column 6 grows)
    near = 0
    for k in range(nw):
        w = order[k]
        ex, ey = e[w, 0], e[w, 1]
        side = ex * (py - a[w, 1]) - ey * (px - a[w, 0])
        near += abs(side) <= 1e-6 * (abs(ex) + abs(ey)) * 6.0 * span
    i_near, i_far = 0, near
    for k in range(nw):  # (rows are overwritten in sorted order: the distance is computed again, not read)
        w = order[k]
        ax, ay, ex, ey = a[w, 0], a[w, 1], e[w, 0], e[w, 1]
        side = ex * (py - ay) - ey * (px - ax)
        tol = 1e-6 * (abs(ex) + abs(ey)) * 6.0 * span  # ≥ 10⁻⁶ of every product below
        if abs(side) <= tol:
            r, i_near = i_near, i_near + 1
            key = -1.0
        else:
            r, i_far = i_far, i_far + 1
            ee = ex * ex + ey * ey
            s = ((px - ax) * ex + (py - ay) * ey) / ee if ee > 0 else 0.0
            s = 0.0 if 0.0 > s else s
            s = 1.0 if 1.0 < s else s
            gap = math.hypot(ax + s * ex - px, ay + s * ey - py) - reach
            key = gap * gap if gap > 0.0 else -1.0
        wall[r, 0], wall[r, 1], wall[r, 2], wall[r, 3], wall[r, 4], wall[r, 5], wall[r, 6] = ax, ay, ex, ey, side, \
            tol, key  # fmt: skip
    last = -1  # the wall that hid the previous point: neighbouring points are mostly hidden by the same
    for k in range(q.shape[0]):
        qx, qy = q[k, 0], q[k, 1]
        dx, dy = qx - px, qy - py
        if last >= 0 and _crosses(px, py, dx, dy, wall[last, 0], wall[last, 1], wall[last, 2], wall[last, 3], eps):
            out[k] = False
            continue
        d2 = dx * dx + dy * dy
        clear = True
        for w in range(nw):
            if w >= near and wall[w, 6] > d2:
                break  # this wall and every later one lie beyond the segment's reach
            ax, ay, ex, ey, side_p, tol = wall[w, 0], wall[w, 1], wall[w, 2], wall[w, 3], wall[w, 4], wall[w, 5]
            side_q = ex * (qy - ay) - ey * (qx - ax)
            if (side_p > tol and side_q > tol) or (side_p < -tol and side_q < -tol):
                continue  # p and q on the same side of the wall's line
            if _crosses(px, py, dx, dy, ax, ay, ex, ey, eps):
                clear = False
                last = w
                break
        out[k] = clear
    return out


# ----------------------------------------------------------------------------- cells and owners
def _cell_index_numpy(points, x0, y0, dx, dy, ii, jj, out):
    nx, ny = ii.shape
    s = (points[:, 0] - x0) / dx
    t = (points[:, 1] - y0) / dy
    i = np.where(s >= 0, np.minimum(s, nx - 1), 0).astype(np.intp)  # NaN: 0 (some cell, never read)
    j = np.where(t >= 0, np.minimum(t, ny - 1), 0).astype(np.intp)
    out[:, 0] = ii[i, j]
    out[:, 1] = jj[i, j]
    return out


@compiled(fallback=_cell_index_numpy)
def cell_index(points, x0, y0, dx, dy, ii, jj, out):
    """The cell with volume of each point into ``out`` (M, 2): its grid cell, or the nearest edge cell outside the grid.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
    x0, y0, dx, dy : float
        The grid's lower-left corner and cell sizes.
    ii, jj : ndarray of int, shape (nx, ny)
        The cell with volume that stands for each cell (itself when it has some volume).
    out : ndarray of int, shape (M, 2)
    """
    nx, ny = ii.shape
    for k in range(points.shape[0]):
        s = (points[k, 0] - x0) / dx
        t = (points[k, 1] - y0) / dy
        i = np.int64(nx - 1.0 if nx - 1.0 < s else s) if s >= 0 else 0  # NaN: 0 (some cell, never read)
        j = np.int64(ny - 1.0 if ny - 1.0 < t else t) if t >= 0 else 0
        out[k, 0] = ii[i, j]
        out[k, 1] = jj[i, j]
    return out
