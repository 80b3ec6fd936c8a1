"""A floor plan's walls, compiled: the first wall a step meets, and what the step does there.

Every step of every agent is a segment ``p → q`` that may cross a wall of the plan
(docs page *Buildings*, ``docs/buildings.md``: walls reflect the humans and stop the
robots).  The walls are the segments ``a_w + u e_w``, ``0 <= u <= 1``; the step meets wall
``w`` at the fraction

.. math::  t = \\frac{(a_w - p) \\times e_w}{d \\times e_w}, \\qquad
           u = \\frac{(a_w - p) \\times d}{d \\times e_w}, \\qquad d = q - p,

and counts when ``d × e_w != 0``, ``1e-12 < t <= 1`` and ``0 <= u <= 1``; the first wall
is the smallest such ``t``, ties to the lowest wall index.  Only the walls listed for the
step's lattice cell (:class:`meanfield.geometry.walls.WallIndex`, the 3 × 3 block of cells
around it) are tested when the step is no longer than a cell in each direction and starts
on the lattice; the others are tested against every wall.  The answer is the same.

Each loop is paired with its numpy twin (the reference, :mod:`meanfield._compiled.core`) and
does one pass per step:

* :func:`first_hits`: the fraction ``t`` and the wall ``k`` of each step's first crossing
  (:meth:`meanfield.geometry.walls.WallIndex.first_hit`);
* :func:`reflect_steps`: the humans' bounce (:meth:`meanfield.geometry.plan.Plan.reflect`): at the
  first wall the rest of the step is mirrored across it and followed again, up to
  :data:`BOUNCES` times;
* :func:`robot_steps`: the robots' steps, cut just before their first wall
  (:meth:`meanfield.geometry.plan.Plan.stop_at_walls`), or slid along it
  (:meth:`meanfield.geometry.plan.Plan.slide_along_walls`).

The lattice is described by ``box = (x0, y0, size, nx, ny)``: the lattice's origin, its
cell's side and its number of cells along x and y; ``near`` is ``(nx ny, K)`` wall indices
per cell ``i ny + j``, ascending, filled from the first slot, ``-1`` after the last.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, inner, prange

__all__ = ["first_hits", "reflect_steps", "robot_steps", "segment_hits", "BOUNCES", "FULL_TEST_BELOW"]

BOUNCES = 8
"""A step is mirrored at most this many times; what is still outside is then projected."""

FULL_TEST_BELOW = 50_000
"""numpy path: below this many step-wall pairs every step is tested against every wall
(numpy's overhead per call outweighs the look-ups; the answer is the same)."""

STOP_BEFORE = 1e-9
"""A stopped robot's step is cut this fraction of the step before the wall."""


# ----------------------------------------------------------------------------- numpy twins
def segment_hits(start: np.ndarray, d: np.ndarray, a: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Fraction ``t`` along each step ``start + t d`` at which it meets each wall ``a + u e``.

    Parameters
    ----------
    start, d : ndarray, shape (M, 2)
        The steps' starts and vectors.
    a, e : ndarray, shape (M, K, 2) or (1, K, 2)
        The walls' starts and vectors (each step's own candidates, or the same for all).

    Returns
    -------
    ndarray, shape (M, K)
        ``t``, ``inf`` where the step does not meet the wall in ``1e-12 < t <= 1``, ``0 <= u <= 1``
        (the module's equation).
    """
    cross = d[:, None, 0] * e[..., 1] - d[:, None, 1] * e[..., 0]
    w = a - start[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / cross
        u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / cross
    hit = (cross != 0) & (t > 1e-12) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    return np.where(hit, t, np.inf)


def _first_hits_numpy(start, end, a, e, near, box, t_out, k_out):
    m = len(start)
    t_out[:] = np.inf
    k_out[:] = 0
    if not m:
        return t_out, k_out
    d = end - start
    if m * len(a) <= FULL_TEST_BELOW:  # few pairs: one vectorised test beats the look-ups
        t = segment_hits(start, d, a[None], e[None])
        j = np.argmin(t, axis=1)
        t_out[:] = t[np.arange(m), j]
        k_out[:] = np.where(np.isfinite(t_out), j, 0)
        return t_out, k_out
    size, nx, ny = box[2], int(box[3]), int(box[4])
    short = (np.abs(d) <= size).all(axis=1)
    with np.errstate(invalid="ignore"):
        f = np.floor((start - box[:2]) / size)
        inside = (f >= 0).all(axis=1) & (f[:, 0] < nx) & (f[:, 1] < ny)
    local = np.flatnonzero(short & inside)
    if len(local):
        ij = f[local].astype(np.intp)
        cand = near[ij[:, 0] * ny + ij[:, 1]]  # (L, K)
        safe = np.maximum(cand, 0)
        t = segment_hits(start[local], d[local], a[safe], e[safe])
        t = np.where(cand >= 0, t, np.inf)
        j = np.argmin(t, axis=1)
        t_out[local] = t[np.arange(len(local)), j]
        k_out[local] = safe[np.arange(len(local)), j]
    rest = np.flatnonzero(~(short & inside))
    if len(rest):
        t = segment_hits(start[rest], d[rest], a[None], e[None])
        j = np.argmin(t, axis=1)
        t_out[rest] = t[np.arange(len(rest)), j]
        k_out[rest] = j
    k_out[~np.isfinite(t_out)] = 0
    return t_out, k_out


def _first_numpy(start, end, a, e, near, box):
    m = len(start)
    return _first_hits_numpy(start, end, a, e, near, box, np.empty(m), np.empty(m, dtype=np.intp))


def _reflect_steps_numpy(previous, points, a, e, near, box):
    start = previous.copy()
    for _ in range(BOUNCES):
        moved = np.flatnonzero(np.any(points != start, axis=1))
        if not len(moved):
            break
        first, k = _first_numpy(start[moved], points[moved], a, e, near, box)
        bounce = np.isfinite(first)
        start[moved[~bounce]] = points[moved[~bounce]]  # those steps are done
        if not bounce.any():
            break
        rows, k, tb = moved[bounce], k[bounce], first[bounce]
        impact = start[rows] + tb[:, None] * (points[rows] - start[rows])
        n = np.stack([-e[k, 1], e[k, 0]], axis=1)
        n /= np.hypot(n[:, 0], n[:, 1])[:, None]
        rest = points[rows] - impact
        points[rows] = impact + rest - 2.0 * (rest * n).sum(1)[:, None] * n
        start[rows] = impact
    return points


def _stopped_numpy(start, end, a, e, near, box):
    first, _ = _first_numpy(start, end, a, e, near, box)
    hit = np.isfinite(first)
    if hit.any():
        t = np.maximum(first[hit] - STOP_BEFORE, 0.0)[:, None]
        end[hit] = start[hit] + t * (end[hit] - start[hit])
    return end


def _slid_numpy(start, end, a, e, near, box):
    first, k = _first_numpy(start, end, a, e, near, box)
    hit = np.flatnonzero(np.isfinite(first))
    if not len(hit):
        return end
    t = np.maximum(first[hit] - STOP_BEFORE, 0.0)[:, None]
    stop = start[hit] + t * (end[hit] - start[hit])
    along = e[k[hit]] / np.hypot(e[k[hit], 0], e[k[hit], 1])[:, None]
    rest = ((end[hit] - stop) * along).sum(1)[:, None] * along
    slid = _stopped_numpy(stop, stop + rest, a, e, near, box)
    # keep a slide only if the straight move to it crosses no wall either (past a corner it may)
    clear = ~np.isfinite(_first_numpy(start[hit], slid, a, e, near, box)[0])
    end[hit] = np.where(clear[:, None], slid, stop)
    return end


def _robot_steps_numpy(start, end, a, e, near, box, slide):
    return (_slid_numpy if slide else _stopped_numpy)(start, end, a, e, near, box)


# ----------------------------------------------------------------------------- compiled helpers
@inner
def _crossing(px, py, dx, dy, a, e, w):
    """``t`` of the step ``p + t d`` at wall ``w`` (the module's equation), ``inf`` if it does not count."""
    ex, ey = e[w, 0], e[w, 1]
    cross = dx * ey - dy * ex
    if cross == 0.0:
        return np.inf
    wx, wy = a[w, 0] - px, a[w, 1] - py
    t = (wx * ey - wy * ex) / cross
    if not (t > 1e-12 and t <= 1.0):
        return np.inf
    u = (wx * dy - wy * dx) / cross
    if u >= 0.0 and u <= 1.0:
        return t
    return np.inf


@inner
def _first_wall(px, py, qx, qy, a, e, near, box):
    """``(t, k)`` of the step ``p → q``'s first wall (``(inf, 0)``: none); the cell's walls for a short step."""
    dx, dy = qx - px, qy - py
    size = box[2]
    fx, fy = (px - box[0]) / size, (py - box[1]) / size
    best, k = np.inf, 0
    if abs(dx) <= size and abs(dy) <= size and fx >= 0.0 and fy >= 0.0 and fx < box[3] and fy < box[4]:
        c = math.floor(fx) * np.int64(box[4]) + math.floor(fy)  # (math.floor's integers; no int overload)
        for s in range(near.shape[1]):
            w = near[c, s]
            if w < 0:
                break
            t = _crossing(px, py, dx, dy, a, e, w)
            if t < best:
                best, k = t, w
    else:
        for w in range(a.shape[0]):
            t = _crossing(px, py, dx, dy, a, e, w)
            if t < best:
                best, k = t, w
    return best, k


# ----------------------------------------------------------------------------- compiled loops
@compiled(fallback=_first_hits_numpy)
def first_hits(start, end, a, e, near, box, t_out, k_out):
    """``t_out[i]``, ``k_out[i]``: fraction and wall of step ``start[i] → end[i]``'s first crossing.

    Parameters
    ----------
    start, end : ndarray, shape (M, 2)
        The steps.
    a, e : ndarray, shape (W, 2)
        Each wall's start and its vector to the end.
    near : ndarray of int, shape (nx ny, K)
        The walls near each lattice cell (the module's doc).
    box : ndarray, shape (5,)
        ``(x0, y0, size, nx, ny)`` of the lattice.
    t_out : ndarray, shape (M,)
        ``t`` of the first wall met (the module's equation), ``inf`` where none.
    k_out : ndarray of int, shape (M,)
        That wall's index (the lowest of equal ``t``), 0 where none.
    """
    for i in range(start.shape[0]):
        t, k = _first_wall(start[i, 0], start[i, 1], end[i, 0], end[i, 1], a, e, near, box)
        t_out[i] = t
        k_out[i] = k
    return t_out, k_out


@compiled(fallback=_reflect_steps_numpy, parallel_over="points")
def reflect_steps(previous, points, a, e, near, box):
    """Mirror, in place, each step ``previous[i] → points[i]`` at the walls it meets, in order.

    At the first wall met the rest of the step ``r = q - x`` (``x`` the impact) becomes
    ``r - 2 (r·n) n``, ``n`` the wall's unit normal, and is followed again from ``x``, at
    most :data:`BOUNCES` times (docs/buildings.md: walls reflect).  A point still outside
    the plan after that is the caller's to project.  ``previous`` is not changed; the other
    arguments are those of :func:`first_hits`.  Chunks of
    :data:`~meanfield._compiled.core.PARALLEL_CHUNK` steps run on numba's threads (each step is its own).
    """
    n = points.shape[0]
    for chunk in prange((n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        end = (chunk + 1) * PARALLEL_CHUNK  # (not min: numba compiles its overload in every process)
        for i in range(chunk * PARALLEL_CHUNK, n if n < end else end):
            sx, sy = previous[i, 0], previous[i, 1]
            px, py = points[i, 0], points[i, 1]
            for _ in range(BOUNCES):
                if px == sx and py == sy:
                    break
                t, k = _first_wall(sx, sy, px, py, a, e, near, box)
                if not t < np.inf:
                    break
                ix, iy = sx + t * (px - sx), sy + t * (py - sy)
                nx, ny = -e[k, 1], e[k, 0]
                h = math.hypot(nx, ny)
                nx, ny = nx / h, ny / h
                rx, ry = px - ix, py - iy
                twice = 2.0 * (rx * nx + ry * ny)
                px, py = ix + rx - twice * nx, iy + ry - twice * ny
                sx, sy = ix, iy
            points[i, 0] = px
            points[i, 1] = py
    return points


@inner
def _stop_at(sx, sy, qx, qy, a, e, near, box):
    """The end of the step ``s → q`` cut :data:`STOP_BEFORE` before its first wall (``q`` if none)."""
    t, _ = _first_wall(sx, sy, qx, qy, a, e, near, box)
    if t < np.inf:
        t = t - STOP_BEFORE  # max(t - STOP_BEFORE, 0), as numba's max selects
        t = 0.0 if 0.0 > t else t
        return sx + t * (qx - sx), sy + t * (qy - sy)
    return qx, qy


@compiled(fallback=_robot_steps_numpy)
def robot_steps(start, end, a, e, near, box, slide):
    """Stop, in place, each step ``start[i] → end[i]`` at its first wall; with ``slide``, then go along it.

    The step stops :data:`STOP_BEFORE` of it before the wall, at ``x`` (a head-on step;
    :meth:`meanfield.geometry.plan.Plan.stop_at_walls`).  With ``slide``, what it had left,
    projected on the wall's direction ``ê``, ``((q - x)·ê) ê``, is followed from ``x`` and
    stopped at the next wall; the slide is kept only if the straight move from the start to
    its end crosses no wall (past a corner it may), else the step ends at ``x``
    (:meth:`meanfield.geometry.plan.Plan.slide_along_walls`; docs/buildings.md: no robot's step
    crosses a wall).  ``slide`` is a bool; the other arguments are those of :func:`first_hits`.
    """
    for i in range(start.shape[0]):
        sx, sy, qx, qy = start[i, 0], start[i, 1], end[i, 0], end[i, 1]
        t, k = _first_wall(sx, sy, qx, qy, a, e, near, box)
        if not t < np.inf:
            continue
        t = t - STOP_BEFORE
        t = 0.0 if 0.0 > t else t
        xx, xy = sx + t * (qx - sx), sy + t * (qy - sy)
        if not slide:
            end[i, 0] = xx
            end[i, 1] = xy
            continue
        h = math.hypot(e[k, 0], e[k, 1])
        ax, ay = e[k, 0] / h, e[k, 1] / h
        along = (qx - xx) * ax + (qy - xy) * ay
        gx, gy = _stop_at(xx, xy, xx + along * ax, xy + along * ay, a, e, near, box)
        back, _ = _first_wall(sx, sy, gx, gy, a, e, near, box)
        if back < np.inf:
            gx, gy = xx, xy
        end[i, 0] = gx
        end[i, 1] = gy
    return end
