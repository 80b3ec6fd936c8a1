"""The headway door model's loops, compiled: the nearest person ahead in one's lane, and the contact cone.

:func:`headways` gives every active human ``j`` walking along the unit direction ``e_j`` its *headway*::

    s_j = min{ |X_k − X_j| : k ≠ j active, (X_k − X_j)·e_j > 0, |(X_k − X_j) × e_j| < w, |X_k − X_j| < R }

(``inf`` where nobody is in the lane ahead within the reach ``R``, or ``e_j = 0``): the distance to the
nearest person in front of it whose centre is less than the lane's half width ``w`` off its line of walk
(docs page *Congestion*, "The headway door model", (H1)).

:func:`contact_cone` projects each active human's velocity onto the velocities that do not approach anyone
it touches (closer than the jam spacing ``d``)::

    v_j ← argmin{ |u − v_j| : u·n_jk <= 0 for every k with |X_k − X_j| < d },  n_jk = (X_k − X_j)/|X_k − X_j|

(docs page *Congestion*, "The headway door model", (H2)).  The set is a convex cone of the plane, so the
nearest point is ``v_j`` itself, or its projection on one of the violated contacts' lines that satisfies
every other contact (the one that removes least), or 0: exact, in any order of the contacts.  Then each
steps away from those it touches, the more the deeper the overlap (a soft core, (H3))::

    v_j ← v_j − u Σ_{k : 0 < |X_k − X_j| < d} (1 − |X_k − X_j|/d) n_jk

The compiled loops search a cell list (cells of width ``d`` over the active humans' bounding box, sorted by
:func:`cell_list`); the headway's search widens ring by ring and stops once a ring lies farther than the
nearest found.  The numpy twins list every pair closer than the reach (cells as wide as it, each against its
nine neighbours, vectorised).  Both take the same
minima over the same candidates: the headways agree to the last bit, the velocities to round-off (the
separation is a sum, added in another order).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, inner, prange

__all__ = ["headways", "contact_cone", "cell_list", "CellList"]


class CellList:
    """The active humans sorted into square cells of width ``h`` over their bounding box.

    ``order`` lists the humans cell by cell (row-major, ``cy * nx + cx``), ``starts`` (length ``nx·ny + 1``)
    where each cell's run begins, ``sorted`` (``len(order)``, 2) their positions in that order (the compiled
    loops read neighbours from contiguous memory); ``origin`` is the lattice's lower-left corner.
    """

    __slots__ = ("order", "starts", "sorted", "origin", "h", "nx", "ny")

    def __init__(
        self, order: np.ndarray, starts: np.ndarray, sorted_positions: np.ndarray, origin: tuple[float, float],
        h: float, nx: int, ny: int,
    ):  # fmt: skip
        self.order, self.starts, self.sorted, self.origin = order, starts, sorted_positions, origin
        self.h, self.nx, self.ny = h, nx, ny

    def arrays(self) -> tuple:
        """What the compiled loops take: ``(order, starts, sorted, origin, h, nx, ny)``."""
        return self.order, self.starts, self.sorted, self.origin, self.h, self.nx, self.ny


def cell_list(x: np.ndarray, active: np.ndarray, h: float) -> CellList:
    """Sort the active humans with finite positions into cells of width ``h`` (a stable counting sort; the width
    doubled while there would be more than ``4 m + 64`` cells for ``m`` humans)."""
    ok = active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1])
    idx = np.flatnonzero(ok)
    if not len(idx):
        return CellList(idx.astype(np.int64), np.zeros(2, np.int64), np.zeros((0, 2)), (0.0, 0.0), h, 1, 1)
    p = x[idx]
    x0, y0, h, nx, ny = _lattice(p, h)
    cx = np.minimum(((p[:, 0] - x0) // h).astype(np.int64), nx - 1)
    cy = np.minimum(((p[:, 1] - y0) // h).astype(np.int64), ny - 1)
    key = cy * nx + cx
    sort = np.argsort(key, kind="stable")
    starts = np.zeros(nx * ny + 1, np.int64)
    np.cumsum(np.bincount(key, minlength=nx * ny), out=starts[1:])
    order = idx[sort].astype(np.int64)
    return CellList(order, starts, np.ascontiguousarray(x[order]), (x0, y0), h, nx, ny)


def _lattice(p: np.ndarray, h: float) -> tuple[float, float, float, int, int]:
    """Cells of width at least ``h`` over the points' bounding box, at most ``4 m + 64`` of them for ``m``
    points (the width doubled until they are): ``(x0, y0, h, nx, ny)``."""
    x0, y0 = float(p[:, 0].min()), float(p[:, 1].min())
    wx, wy = float(p[:, 0].max()) - x0, float(p[:, 1].max()) - y0
    while True:
        nx, ny = int(wx // h) + 1, int(wy // h) + 1
        if nx * ny <= 4 * len(p) + 64:
            return x0, y0, h, nx, ny
        h *= 2.0


def _pairs(x: np.ndarray, active: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ordered pair ``(j, k)`` of active humans closer than ``radius`` (``|X_k − X_j|² < radius²``), and
    its squared distance: a cell list of cells at least ``radius`` wide, each cell against its 9 neighbours."""
    ok = active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1])
    idx = np.flatnonzero(ok)
    empty = np.empty(0, np.int64)
    if len(idx) < 2:
        return empty, empty, np.empty(0)
    p = x[idx]
    x0, y0, h, nx, ny = _lattice(p, radius)
    ci = np.minimum(((p[:, 0] - x0) // h).astype(np.int64), nx - 1)
    ck = np.minimum(((p[:, 1] - y0) // h).astype(np.int64), ny - 1)
    cell = ck * nx + ci
    order = np.argsort(cell, kind="stable")
    occupancy = np.bincount(cell, minlength=nx * ny)
    start = np.cumsum(occupancy) - occupancy
    js, ks, r2s = [], [], []
    for di in (-1, 0, 1):
        for dk in (-1, 0, 1):
            ni, nk = ci + di, ck + dk
            a = np.flatnonzero((ni >= 0) & (ni < nx) & (nk >= 0) & (nk < ny))
            nc = nk[a] * nx + ni[a]
            count = occupancy[nc]
            rows = np.repeat(a, count)
            offsets = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
            cand = order[np.repeat(start[nc], count) + offsets]
            dx = p[cand, 0] - p[rows, 0]
            dy = p[cand, 1] - p[rows, 1]
            r2 = dx * dx + dy * dy
            hit = (r2 < radius * radius) & (cand != rows)
            js.append(idx[rows[hit]])
            ks.append(idx[cand[hit]])
            r2s.append(r2[hit])
    return np.concatenate(js), np.concatenate(ks), np.concatenate(r2s)


def _headways_numpy(x, e, active, lane, reach, cells, out):
    """The numpy twin of :func:`headways` (every pair within the reach; ``cells`` unused)."""
    out[:] = np.inf
    j, k, r2 = _pairs(x, active, reach)
    dx, dy = x[k, 0] - x[j, 0], x[k, 1] - x[j, 1]
    ex, ey = e[j, 0], e[j, 1]
    ahead = (dx * ex + dy * ey > 0.0) & (np.abs(dx * ey - dy * ex) < lane)
    np.minimum.at(out, j[ahead], np.sqrt(r2[ahead]))


@compiled(fallback=_headways_numpy, parallel_over="x")
def _headways_compiled(x, e, active, lane, reach, cells, out):
    order, starts, pos, origin, h, nx, ny = cells
    for j in prange(x.shape[0]):
        out[j] = math.inf
    rings = int(math.ceil(reach / h)) + 1
    reach2 = reach * reach
    for t in prange(order.shape[0]):  # the humans in cell order: their neighbours are near in memory
        j = order[t]
        ex = e[j, 0]
        ey = e[j, 1]
        if ex == 0.0 and ey == 0.0:
            continue
        xj = pos[t, 0]
        yj = pos[t, 1]
        cx = min(int((xj - origin[0]) // h), nx - 1)
        cy = min(int((yj - origin[1]) // h), ny - 1)
        best2 = reach2
        for ring in range(rings + 1):
            if ring >= 2 and (ring - 1) * h * ((ring - 1) * h) >= best2:
                break  # every cell of this ring is farther than the nearest found
            for gy in range(cy - ring, cy + ring + 1):
                if gy < 0 or gy >= ny:
                    continue
                step = 1 if (gy == cy - ring or gy == cy + ring) else 2 * ring  # the ring's rows, or its sides
                gx = cx - ring
                while gx <= cx + ring:
                    if 0 <= gx < nx:
                        c = gy * nx + gx
                        for u in range(starts[c], starts[c + 1]):
                            if u == t:
                                continue
                            dx = pos[u, 0] - xj
                            dy = pos[u, 1] - yj
                            r2 = dx * dx + dy * dy
                            if r2 < best2 and dx * ex + dy * ey > 0.0 and abs(dx * ey - dy * ex) < lane:
                                best2 = r2
                    gx += step
        if best2 < reach2:
            out[j] = math.sqrt(best2)


def headways(x: np.ndarray, e: np.ndarray, active: np.ndarray, lane: float, reach: float, cells: CellList,
             out: np.ndarray) -> np.ndarray:  # fmt: skip
    """Each human's headway ``s_j`` (module docstring, (H1)) into ``out`` (m; ``inf``: nobody within ``reach``).

    Parameters
    ----------
    x, e : ndarray, shape (N, 2)
        Positions and unit walking directions (0: standing, no headway).
    active : ndarray of bool, shape (N,)
        Who counts and is counted (non-finite rows are ignored).
    lane : float
        ``w``, the lane's half width (m).
    reach : float
        ``R``: nobody farther counts (m).
    cells : CellList
        The active humans in cells (:func:`cell_list`, any width ``h > 0``; the compiled loop's search).
    out : ndarray, shape (N,)
    """
    _headways_compiled(x, e, active, lane, reach, cells.arrays(), out)
    return out


def _cone_numpy(v, x, active, jam, separation, cells):
    """The numpy twin of :func:`contact_cone` (every pair closer than ``d``; ``cells`` unused): the contacts of
    each human padded to the most any has, then (H2) for all at once, then (H3)."""
    j, k, r2 = _pairs(x, active, jam)
    keep = r2 > 0.0
    j, k, r2 = j[keep], k[keep], r2[keep]
    if not len(j):
        return
    r = np.sqrt(r2)
    nxs, nys = (x[k, 0] - x[j, 0]) / r, (x[k, 1] - x[j, 1]) / r
    srt = np.argsort(j, kind="stable")
    j, nxs, nys, r = j[srt], nxs[srt], nys[srt], r[srt]
    w = separation * (jam - r) / jam
    sep_x, sep_y = np.zeros(len(v)), np.zeros(len(v))
    np.add.at(sep_x, j, -w * nxs)
    np.add.at(sep_y, j, -w * nys)
    who, first, count = np.unique(j, return_index=True, return_counts=True)
    m = int(count.max())
    slot = np.arange(len(j)) - np.repeat(first, count)
    row = np.repeat(np.arange(len(who)), count)
    nx_, ny_ = np.zeros((len(who), m)), np.zeros((len(who), m))
    nx_[row, slot], ny_[row, slot] = nxs, nys
    vx, vy = v[who, 0].copy(), v[who, 1].copy()
    a = vx[:, None] * nx_ + vy[:, None] * ny_  # v·n (0 in the padding)
    bad = (a > 0.0).any(axis=1)
    tol = 1e-12 * np.hypot(vx, vy)
    best = np.full(len(who), np.inf)  # the least removal among the feasible faces
    bx, by = np.zeros(len(who)), np.zeros(len(who))
    for f in range(m):
        af = a[:, f]
        px, py = vx - af * nx_[:, f], vy - af * ny_[:, f]
        ok = (af > 0.0) & ((px[:, None] * nx_ + py[:, None] * ny_) <= tol[:, None]).all(axis=1) & (af < best)
        best = np.where(ok, af, best)
        bx, by = np.where(ok, px, bx), np.where(ok, py, by)
    v[who[bad], 0] = bx[bad]
    v[who[bad], 1] = by[bad]
    v[:, 0] += sep_x
    v[:, 1] += sep_y


@inner
def _approach(pos, starts, nx, x0, x1, y0, y1, t, jam2, ux, uy):
    """The largest ``u·n_tk`` over the contacts of the human in slot ``t`` (closer than ``√jam2``, in the cells
    ``[x0, x1) × [y0, y1)``); ``-inf`` without contacts.  ``u`` approaches none of them iff it is ``<= 0``."""
    worst = -math.inf
    xt = pos[t, 0]
    yt = pos[t, 1]
    for gy in range(y0, y1):
        for gx in range(x0, x1):
            c = gy * nx + gx
            for q in range(starts[c], starts[c + 1]):
                dx = pos[q, 0] - xt
                dy = pos[q, 1] - yt
                r2 = dx * dx + dy * dy
                if q != t and 0.0 < r2 < jam2:
                    r = math.sqrt(r2)
                    worst = max(worst, ux * (dx / r) + uy * (dy / r))
    return worst


@compiled(fallback=_cone_numpy, parallel_over="v")
def _cone_compiled(v, x, active, jam, separation, cells):
    order, starts, pos, origin, h, nx, ny = cells
    jam2 = jam * jam
    for t in prange(order.shape[0]):  # the humans in cell order; the contacts are read again, not stored
        j = order[t]
        xj = pos[t, 0]
        yj = pos[t, 1]
        vx = v[j, 0]
        vy = v[j, 1]
        cx = min(int((xj - origin[0]) // h), nx - 1)
        cy = min(int((yj - origin[1]) // h), ny - 1)
        x0, x1, y0, y1 = max(cx - 1, 0), min(cx + 2, nx), max(cy - 1, 0), min(cy + 2, ny)
        sx = 0.0  # (H3), and whether the walk approaches a contact
        sy = 0.0
        bad = False
        for gy in range(y0, y1):
            for gx in range(x0, x1):
                c = gy * nx + gx
                for u in range(starts[c], starts[c + 1]):
                    dx = pos[u, 0] - xj
                    dy = pos[u, 1] - yj
                    r2 = dx * dx + dy * dy
                    if u != t and 0.0 < r2 < jam2:
                        r = math.sqrt(r2)
                        w = separation * (jam - r) / jam
                        sx -= w * (dx / r)
                        sy -= w * (dy / r)
                        if vx * (dx / r) + vy * (dy / r) > 0.0:
                            bad = True
        if bad:  # (H2): the violated contact whose line's projection satisfies all, removing least; else 0
            tol = 1e-12 * math.hypot(vx, vy)
            best = math.inf
            bx = 0.0
            by = 0.0
            for gy in range(y0, y1):
                for gx in range(x0, x1):
                    c = gy * nx + gx
                    for u in range(starts[c], starts[c + 1]):
                        dx = pos[u, 0] - xj
                        dy = pos[u, 1] - yj
                        r2 = dx * dx + dy * dy
                        if u == t or not (0.0 < r2 < jam2):
                            continue
                        r = math.sqrt(r2)
                        fx = dx / r
                        fy = dy / r
                        af = vx * fx + vy * fy
                        if af <= 0.0 or af >= best:
                            continue
                        px = vx - af * fx
                        py = vy - af * fy
                        ok = _approach(pos, starts, nx, x0, x1, y0, y1, t, jam2, px, py) <= tol
                        if ok:
                            best = af
                            bx = px
                            by = py
            vx = bx
            vy = by
        v[j, 0] = vx + sx
        v[j, 1] = vy + sy


def contact_cone(
    v: np.ndarray, x: np.ndarray, active: np.ndarray, jam: float, separation: float, cells: CellList
) -> np.ndarray:
    """Each active human's velocity projected on the cone of those that approach nobody it touches, then the
    soft core's separation added, in place (module docstring, (H2) and (H3)).

    Parameters
    ----------
    v : ndarray, shape (N, 2)
        Velocities, changed in place.
    x : ndarray, shape (N, 2)
        Positions.
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    jam : float
        ``d``: those closer than this touch (m).
    separation : float
        ``u``, m/s: the speed at which two people at the same point step apart ((H3); 0: none).
    cells : CellList
        The active humans in cells of width at least ``d`` (:func:`cell_list`).
    """
    if cells.h < jam:
        raise ValueError(f"contact_cone needs cells at least {jam} m wide, got {cells.h}")
    _cone_compiled(v, x, active, jam, separation, cells.arrays())
    return v
