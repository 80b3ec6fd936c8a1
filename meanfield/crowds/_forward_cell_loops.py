"""The forward-cell door model's loop, compiled: the part of each human's Voronoi cell that lies ahead of it.

:func:`forward_cells` gives every active human ``j`` and every turn ``θ_q`` of its route's direction ``e_j`` the
area (m²) of its forward cell::

    A_jq = | V_j ∩ { y : (y − X_j)·t_q >= 0 } |,   t_q = e_j turned by θ_q                                  (C1)

where ``V_j`` is its Voronoi cell among the active humans: the points nearer ``X_j`` than any other human, cut by
the walls (each wall segment whose foot of the perpendicular from ``X_j`` falls on it cuts ``V_j`` along its own
line, the bisector of ``X_j`` and its mirror image) and by the square of half-side ``R`` (the reach) centred on
``X_j``.  The door model reads the density ``1 / (2 A_jq)`` (docs page *Congestion*, "The forward-cell door
model").  ``V_j`` is the intersection of half-planes, built by clipping the square by each bisector in turn
(Sutherland–Hodgman); a neighbour farther than twice the cell's farthest vertex cannot cut it, so the compiled
loop reads its neighbours from a cell list ring by ring and stops at the first ring beyond that.  For a standing
human (``e_j = 0``) every turn reads half the cell.

The numpy twin clips by every neighbour within twice the square's half-diagonal, in the order of their index;
the cell is the same set, so the areas agree to round-off.  The loop over humans runs on numba's threads above
:data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans, each writing its own row: the same numbers on any number
of threads.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, inlined, prange

__all__ = ["forward_cells", "CELL_VERTICES"]

CELL_VERTICES = 64
"""The most vertices a cell's polygon holds; a cell with more (none in a crowd: a Voronoi cell has about six)
stops clipping there, keeping the larger polygon it has."""


def _clip_numpy(poly: np.ndarray, nx: float, ny: float, c: float) -> np.ndarray:
    """``poly`` (m, 2), convex, cut to ``{y : y·(nx, ny) <= c}`` (Sutherland–Hodgman)."""
    if len(poly) == 0:
        return poly
    a = poly[:, 0] * nx + poly[:, 1] * ny - c
    out = []
    m = len(poly)
    for i in range(m):
        k = (i + 1) % m
        if a[i] <= 0.0:
            out.append(poly[i])
        if (a[i] < 0.0 < a[k]) or (a[k] < 0.0 < a[i]):
            t = a[i] / (a[i] - a[k])
            out.append(poly[i] + t * (poly[k] - poly[i]))
    return np.array(out).reshape(-1, 2)


def _area_numpy(poly: np.ndarray) -> float:
    """The shoelace area of a polygon (m, 2)."""
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def _cells_numpy(x, e, active, cos, sin, reach, wall_a, wall_v, cells, out):
    """The numpy twin of :func:`forward_cells` (every neighbour within ``2√2 R``; ``cells`` unused)."""
    out[:] = np.inf
    ok = active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1])
    idx = np.flatnonzero(ok)
    far2 = 8.0 * reach * reach
    square = np.array([[-reach, -reach], [reach, -reach], [reach, reach], [-reach, reach]])
    for j in idx:
        poly = square.copy()
        t = np.einsum("ij,ij->i", x[j] - wall_a, wall_v) / np.einsum("ij,ij->i", wall_v, wall_v)
        for w in np.flatnonzero((t >= 0.0) & (t <= 1.0)):
            f = wall_a[w] + t[w] * wall_v[w] - x[j]
            h2 = float(f @ f)
            if h2 > 0.0:
                poly = _clip_numpy(poly, f[0], f[1], h2)
        d = x[idx] - x[j]
        d2 = np.einsum("ij,ij->i", d, d)
        for k in np.flatnonzero((d2 > 0.0) & (d2 < far2)):
            poly = _clip_numpy(poly, d[k, 0], d[k, 1], 0.5 * d2[k])
        for q in range(len(cos)):
            tx = cos[q] * e[j, 0] - sin[q] * e[j, 1]
            ty = sin[q] * e[j, 0] + cos[q] * e[j, 1]
            if tx == 0.0 and ty == 0.0:
                out[j, q] = 0.5 * _area_numpy(poly)
            else:
                out[j, q] = _area_numpy(_clip_numpy(poly, -tx, -ty, 0.0))


@inlined
def _clip(px, py, m, nx, ny, c, qx, qy):
    """The polygon ``(px, py)[:m]``, convex, cut to ``{y : y·(nx, ny) <= c}`` into ``(qx, qy)``; returns its
    number of vertices (Sutherland–Hodgman, the twin's arithmetic)."""
    k = 0
    for i in range(m):
        i1 = i + 1 if i + 1 < m else 0
        a = px[i] * nx + py[i] * ny - c
        b = px[i1] * nx + py[i1] * ny - c
        if a <= 0.0:
            qx[k] = px[i]
            qy[k] = py[i]
            k += 1
        if (a < 0.0 and b > 0.0) or (b < 0.0 and a > 0.0):
            t = a / (a - b)
            qx[k] = px[i] + t * (px[i1] - px[i])
            qy[k] = py[i] + t * (py[i1] - py[i])
            k += 1
    return k


@inlined
def _area(px, py, m):
    """The shoelace area of the polygon ``(px, py)[:m]`` (the twin's arithmetic)."""
    if m < 3:
        return 0.0
    s = 0.0
    for i in range(m):
        i1 = i + 1 if i + 1 < m else 0
        s += px[i] * py[i1] - px[i1] * py[i]
    return 0.5 * abs(s)


@inlined
def _cut(px, py, m, nx, ny, c, qx, qy):
    """:func:`_clip` in place on ``(px, py)`` (``qx``, ``qy`` scratch); returns the new vertex count and the
    squared distance of its farthest vertex from the origin."""
    m = _clip(px, py, m, nx, ny, c, qx, qy)
    far2 = 0.0
    for i in range(m):
        px[i] = qx[i]
        py[i] = qy[i]
        far2 = max(far2, qx[i] * qx[i] + qy[i] * qy[i])
    return m, far2


@compiled(fallback=_cells_numpy, parallel_over="x")
def _cells_compiled(x, e, active, cos, sin, reach, wall_a, wall_v, cells, out):
    order, starts, pos, origin, h, nx, ny = cells
    ox = origin[0]
    oy = origin[1]
    for j in prange(x.shape[0]):
        for q in range(cos.shape[0]):
            out[j, q] = math.inf
    n_walls = wall_a.shape[0]
    m_all = order.shape[0]
    cap = CELL_VERTICES
    for chunk in prange((m_all + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the humans in cell order
        px = np.empty(cap + 2)
        py = np.empty(cap + 2)
        qx = np.empty(cap + 2)
        qy = np.empty(cap + 2)
        for t in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m_all)):
            j = order[t]
            xj = pos[t, 0]
            yj = pos[t, 1]
            px[0] = -reach
            py[0] = -reach
            px[1] = reach
            py[1] = -reach
            px[2] = reach
            py[2] = reach
            px[3] = -reach
            py[3] = reach
            m = 4
            far2 = 2.0 * reach * reach
            for w in range(n_walls):  # the walls first: their mirror images' bisectors
                vx = wall_v[w, 0]
                vy = wall_v[w, 1]
                u = ((xj - wall_a[w, 0]) * vx + (yj - wall_a[w, 1]) * vy) / (vx * vx + vy * vy)
                if u < 0.0 or u > 1.0:
                    continue
                fx = wall_a[w, 0] + u * vx - xj
                fy = wall_a[w, 1] + u * vy - yj
                h2 = fx * fx + fy * fy
                if h2 > 0.0 and m < cap:
                    m, far2 = _cut(px, py, m, fx, fy, h2, qx, qy)
            cx = min(int((xj - ox) // h), nx - 1)
            cy = min(int((yj - oy) // h), ny - 1)
            ring = 0
            while True:  # the neighbours ring by ring, until no farther one can cut the cell
                if ring > 0 and (ring - 1) * h * ((ring - 1) * h) >= 4.0 * far2:
                    break
                if ring > max(cx, nx - 1 - cx, cy, ny - 1 - cy):
                    break
                for gy in range(max(cy - ring, 0), min(cy + ring, ny - 1) + 1):
                    edge = gy == cy - ring or gy == cy + ring
                    step = 1 if edge else 2 * ring
                    gx = cx - ring
                    while gx <= cx + ring:
                        if 0 <= gx < nx:
                            c = gy * nx + gx
                            for s in range(starts[c], starts[c + 1]):
                                dx = pos[s, 0] - xj
                                dy = pos[s, 1] - yj
                                d2 = dx * dx + dy * dy
                                if d2 > 0.0 and 0.25 * d2 < far2 and m < cap:
                                    m, far2 = _cut(px, py, m, dx, dy, 0.5 * d2, qx, qy)
                        gx += step
                ring += 1
            ex = e[j, 0]
            ey = e[j, 1]
            for q in range(cos.shape[0]):
                tx = cos[q] * ex - sin[q] * ey
                ty = sin[q] * ex + cos[q] * ey
                if tx == 0.0 and ty == 0.0:
                    out[j, q] = 0.5 * _area(px, py, m)
                else:
                    k = _clip(px, py, m, -tx, -ty, 0.0, qx, qy)
                    out[j, q] = _area(qx, qy, k)


def forward_cells(
    x: np.ndarray, e: np.ndarray, active: np.ndarray, cos: np.ndarray, sin: np.ndarray, reach: float,
    wall_starts: np.ndarray, wall_vectors: np.ndarray, cells: Any, out: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """(C1): each active human's forward cell along each turn of its route's direction, its area in ``out``
    (module docstring; ``inf`` for those not active).

    Parameters
    ----------
    x, e : ndarray, shape (N, 2)
        Positions (m) and the routes' unit directions (0 for one standing).
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    cos, sin : ndarray, shape (K,)
        The turns' cosines and sines (the route's own direction first).
    reach : float
        ``R``, m: the square of half-side ``R`` round each human that bounds its cell.
    wall_starts, wall_vectors : ndarray, shape (W, 2)
        The walls that cut the cells, the segments ``a_w + u v_w``, ``0 <= u <= 1`` (exits are not walls here: a
        door does not crowd those in front of it).
    cells : CellList
        The active humans in cells (:func:`~meanfield.crowds._headway_loops.cell_list`).
    out : ndarray, shape (N, K)
        Written: ``A_jq``, m².
    """
    if not reach > 0.0:
        raise ValueError(f"forward_cells needs a reach > 0 m, got {reach!r}")
    a = np.ascontiguousarray(wall_starts, dtype=float).reshape(-1, 2)
    v = np.ascontiguousarray(wall_vectors, dtype=float).reshape(-1, 2)
    _cells_compiled(x, e, active, cos, sin, float(reach), a, v, cells.arrays(), out)
    return out
