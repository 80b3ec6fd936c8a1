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

:func:`contact_noise` gives each the share ``φ_j = Π_k (|X_k − X_j|/d)^m`` of the noise it keeps among those it
touches, and its gradient (H5).

(H4) needs the headway along ``K`` turned lanes of every human: :func:`lane_headways` finds all of them in one
walk of each human's neighbours (and cuts the turned lanes at the walls, :class:`LaneWalls`), the numbers of
``K`` calls of :func:`headways`; :func:`choose_lanes` then picks the lane of most progress (docs page
*Congestion*, "The headway door model", (H4)).

The compiled loops search a cell list (cells of width ``d`` over the active humans' bounding box, sorted by
:func:`cell_list`, itself compiled); the headway's search widens ring by ring and stops once a ring lies farther
than the nearest found, the lanes' search row by row.  The numpy twins list every pair closer than the reach
(cells as wide as it, each against its nine neighbours, vectorised).  Both take the same
minima over the same candidates: the headways agree to the last bit, the velocities to round-off (the
separation is a sum, added in another order).  The loops over humans run on numba's threads above
:data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans, each human writing its own row: the same numbers on
any number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, inner, prange

__all__ = [
    "headways",
    "lane_headways",
    "choose_lanes",
    "contact_cone",
    "contact_noise",
    "CONTACT_NOISE_POWER",
    "cell_list",
    "CellList",
    "LaneWalls",
    "NO_WALLS",
]


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
    doubled while there would be more than ``4 m + 64`` cells for ``m`` humans).

    One compiled pass finds them and their bounding box, a second sorts them (the same arrays as its numpy twin's
    stable ``argsort``, to the last bit; docs page *Congestion*, "The headway door model").
    """
    order, starts, sorted_positions, x0, y0, h, nx, ny = _cells_compiled(x, active, float(h))
    return CellList(order, starts, sorted_positions, (x0, y0), h, int(nx), int(ny))


def _cells_numpy(x, active, h):
    """The numpy twin of :func:`cell_list`'s loop: ``(order, starts, sorted, x0, y0, h, nx, ny)``."""
    ok = active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1])
    idx = np.flatnonzero(ok)
    if not len(idx):
        return idx.astype(np.int64), np.zeros(2, np.int64), np.zeros((0, 2)), 0.0, 0.0, h, 1, 1
    p = x[idx]
    x0, y0, h, nx, ny = _lattice(p, h)
    cx = np.minimum(((p[:, 0] - x0) // h).astype(np.int64), nx - 1)
    cy = np.minimum(((p[:, 1] - y0) // h).astype(np.int64), ny - 1)
    key = cy * nx + cx
    sort = np.argsort(key, kind="stable")
    starts = np.zeros(nx * ny + 1, np.int64)
    np.cumsum(np.bincount(key, minlength=nx * ny), out=starts[1:])
    order = idx[sort].astype(np.int64)
    return order, starts, np.ascontiguousarray(x[order]), x0, y0, h, nx, ny


@compiled(fallback=_cells_numpy)
def _cells_compiled(x, active, h):
    n = x.shape[0]
    m = 0
    x0 = math.inf
    y0 = math.inf
    x1 = -math.inf
    y1 = -math.inf
    for j in range(n):  # who, and their bounding box
        if active[j] and math.isfinite(x[j, 0]) and math.isfinite(x[j, 1]):
            m += 1
            x0 = min(x0, x[j, 0])
            x1 = max(x1, x[j, 0])
            y0 = min(y0, x[j, 1])
            y1 = max(y1, x[j, 1])
    if m == 0:
        return np.zeros(0, np.int64), np.zeros(2, np.int64), np.zeros((0, 2)), 0.0, 0.0, h, 1, 1
    wx = x1 - x0
    wy = y1 - y0
    nx = int(wx // h) + 1
    ny = int(wy // h) + 1
    while nx * ny > 4 * m + 64:  # (_lattice)
        h *= 2.0
        nx = int(wx // h) + 1
        ny = int(wy // h) + 1
    key = np.empty(m, np.int64)
    idx = np.empty(m, np.int64)
    starts = np.zeros(nx * ny + 1, np.int64)
    i = 0
    for j in range(n):
        if active[j] and math.isfinite(x[j, 0]) and math.isfinite(x[j, 1]):
            c = min(int((x[j, 1] - y0) // h), ny - 1) * nx + min(int((x[j, 0] - x0) // h), nx - 1)
            key[i] = c
            idx[i] = j
            starts[c + 1] += 1
            i += 1
    for c in range(nx * ny):
        starts[c + 1] += starts[c]
    cursor = starts[:-1].copy()
    order = np.empty(m, np.int64)
    pos = np.empty((m, 2))
    for i in range(m):  # stable: each cell's humans in their order
        slot = cursor[key[i]]
        cursor[key[i]] = slot + 1
        j = idx[i]
        order[slot] = j
        pos[slot, 0] = x[j, 0]
        pos[slot, 1] = x[j, 1]
    return order, starts, pos, x0, y0, h, nx, ny


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


SLACK = 1e-6
"""m: :func:`lane_headways` leaves out a row or a cell only when its box, this much wider on every side, holds
nobody nearer than every lane's nearest so far, or lies outside the lanes' bounding box (round-off in the cells'
edges is far below it)."""


class LaneWalls:
    """The walls :func:`lane_headways` casts the turned lanes' rays at, and the walls near each cell of a lattice.

    Each wall is the segment ``a_w + u v_w``, ``0 <= u <= 1``.  A cell of the lattice (side ``size`` over
    ``bounds``) lists, in ``starts``/``walls`` (``walls[starts[c]:starts[c + 1]]``, ascending), every wall whose
    bounding box comes within ``reach`` (and a margin) of the cell: a ray no longer than ``reach`` from a point of
    the cell meets no other.  A ray from outside the lattice is tested against every wall.

    Parameters
    ----------
    a, v : ndarray, shape (W, 2)
        The walls' starts and vectors (``W = 0``: no walls).
    bounds : (float, float, float, float)
        ``(x0, x1, y0, y1)`` that the lattice covers.
    reach : float
        The longest ray, m.
    """

    __slots__ = ("a", "v", "norm", "starts", "walls", "box")

    def __init__(self, a: np.ndarray, v: np.ndarray, bounds: tuple[float, ...], reach: float):
        self.a = np.ascontiguousarray(a, float).reshape(-1, 2)
        self.v = np.ascontiguousarray(v, float).reshape(-1, 2)
        self.norm = np.hypot(self.v[:, 0], self.v[:, 1])
        x0, x1, y0, y1 = (float(b) for b in bounds)
        size = max(reach / 8, (x1 - x0) / 512, (y1 - y0) / 512, 1e-9)
        nx, ny = int((x1 - x0) // size) + 1, int((y1 - y0) // size) + 1
        margin = reach + 1e-6 * (1.0 + reach)  # a ray's end is p + reach·t, |t| = 1 to round-off
        lo = np.minimum(self.a, self.a + self.v) - margin
        hi = np.maximum(self.a, self.a + self.v) + margin
        i0 = np.clip(np.floor((lo[:, 0] - x0) / size), 0, nx - 1).astype(np.int64)
        i1 = np.clip(np.floor((hi[:, 0] - x0) / size), 0, nx - 1).astype(np.int64)
        j0 = np.clip(np.floor((lo[:, 1] - y0) / size), 0, ny - 1).astype(np.int64)
        j1 = np.clip(np.floor((hi[:, 1] - y0) / size), 0, ny - 1).astype(np.int64)
        cell, wall = [], []
        for w in range(len(self.a)):  # each wall in the cells its box, widened by the reach, meets
            gx, gy = np.meshgrid(np.arange(i0[w], i1[w] + 1), np.arange(j0[w], j1[w] + 1), indexing="ij")
            cell.append((gy * nx + gx).ravel())
            wall.append(np.full(gx.size, w, np.int64))
        cell_arr = np.concatenate(cell) if cell else np.empty(0, np.int64)
        wall_arr = np.concatenate(wall) if wall else np.empty(0, np.int64)
        order = np.lexsort((wall_arr, cell_arr))
        self.walls = np.ascontiguousarray(wall_arr[order])
        self.starts = np.zeros(nx * ny + 1, np.int64)
        np.cumsum(np.bincount(cell_arr, minlength=nx * ny), out=self.starts[1:])
        self.box = np.array([x0, y0, size, nx, ny], float)

    def arrays(self) -> tuple:
        """What :func:`lane_headways` takes: ``(a, v, norm, starts, walls, box)`` (``norm``: each ``|v_w|``)."""
        return self.a, self.v, self.norm, self.starts, self.walls, self.box


NO_WALLS = LaneWalls(np.empty((0, 2)), np.empty((0, 2)), (0.0, 1.0, 0.0, 1.0), 1.0)
"""No walls: :func:`lane_headways` gives the headways alone."""


def _wall_hits_numpy(p, d, a, v):
    """The smallest fraction ``t`` at which each ray ``p + t d`` (``t`` in ``(1e-12, 1]``) meets a wall ``a + u v``
    (``u`` in [0, 1]; ``inf``: none), every wall tested; the arithmetic of the walls' first hit
    (:mod:`meanfield.geometry._wall_loops`)."""
    out = np.full(len(p), np.inf)
    for w in range(len(a)):
        cross = d[:, 0] * v[w, 1] - d[:, 1] * v[w, 0]
        wx, wy = a[w, 0] - p[:, 0], a[w, 1] - p[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (wx * v[w, 1] - wy * v[w, 0]) / cross
            u = (wx * d[:, 1] - wy * d[:, 0]) / cross
        hit = (cross != 0.0) & (t > 1e-12) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
        np.minimum(out, np.where(hit, t, np.inf), out=out)
    return out


def _lanes_numpy(x, e, active, cos, sin, lane, reach, half, cells, walls, out):
    """The numpy twin of :func:`lane_headways`: one :func:`headways` per lane (its numpy twin), then every turned
    ray against every wall (``cells`` and the walls' lattice unused)."""
    a, v = walls[0], walls[1]
    col = np.empty(len(x))
    for q in range(len(cos)):
        turned = np.empty((len(x), 2))
        turned[:, 0] = cos[q] * e[:, 0] - sin[q] * e[:, 1]
        turned[:, 1] = sin[q] * e[:, 0] + cos[q] * e[:, 1]
        _headways_numpy(x, turned, active, lane, reach, cells, col)
        if q >= 1 and len(a):
            with np.errstate(invalid="ignore"):  # (non-finite rows meet nothing)
                d = (x + reach * turned) - x
            t = _wall_hits_numpy(x, d, a, v)
            np.minimum(col, t * reach + half, out=col)
        out[:, q] = col


@inner
def _walls_ahead(j, px, py, tx, ty, reach, half, a, v, norm, starts, walls, box, out):
    """``out[j, q] = min(out[j, q], t_q reach + half)`` for the turned lanes ``q >= 1``, ``t_q`` the first wall on
    the ray from ``p`` to ``p + reach (tx_q, ty_q)`` (nothing where none): the walls' first hit's ``t``, without its
    division where it cannot count (a wall whose line is farther than the reach, or than the lane's headway less
    ``half`` with a margin of 1e-6 for round-off, or a ray that points away from it)."""
    size = box[2]
    fx = (px - box[0]) / size
    fy = (py - box[1]) / size
    nx = int(box[3])
    inside = fx >= 0.0 and fy >= 0.0 and fx < box[3] and fy < box[4]
    lo = 0
    hi = a.shape[0]
    if inside:
        c = int(fy) * nx + int(fx)
        lo = starts[c]
        hi = starts[c + 1]
    far = reach * (1.0 + 1e-9)
    k = tx.shape[0]
    most = 0.0  # the farthest a wall can be and still cut a lane: its headway less half, at most the reach
    for q in range(1, k):
        most = max(most, min(far, (out[j, q] - half) * (1.0 + 1e-6) + 1e-9))
    for s in range(lo, hi):
        w = walls[s] if inside else s
        ex = v[w, 0]
        ey = v[w, 1]
        wx = a[w, 0] - px
        wy = a[w, 1] - py
        num = wx * ey - wy * ex  # |num| / |v_w|: the distance from p to the wall's line
        if not abs(num) <= most * norm[w]:
            continue  # no ray gets there within the reach (t > 1), or it cuts no lane shorter than it is
        for q in range(1, k):
            if not abs(num) <= min(far, (out[j, q] - half) * (1.0 + 1e-6) + 1e-9) * norm[w]:
                continue
            dx = (px + reach * tx[q]) - px
            dy = (py + reach * ty[q]) - py
            cross = dx * ey - dy * ex
            if not ((num > 0.0 and cross > 0.0) or (num < 0.0 and cross < 0.0)):
                continue  # t <= 0 (or no crossing)
            t = num / cross
            if not (t > 1e-12 and t <= 1.0):
                continue
            u = (wx * dy - wy * dx) / cross
            if u >= 0.0 and u <= 1.0:  # the smallest t, times the reach plus half, is the smallest of the cuts
                sw = t * reach + half
                if sw < out[j, q]:
                    out[j, q] = sw


@compiled(fallback=_lanes_numpy, parallel_over="x")
def _lanes_compiled(x, e, active, cos, sin, lane, reach, half, cells, walls, out):
    order, starts, pos, origin, h, nx, ny = cells
    wa, wv, wnorm, wstarts, wlist, wbox = walls
    n = x.shape[0]
    k = cos.shape[0]
    reach2 = reach * reach
    rings = int(math.ceil(reach / h)) + 1
    chunks = (n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    for chunk in prange(chunks):  # everyone: no one ahead; the walls of those the cells do not hold
        tx = np.empty(k)
        ty = np.empty(k)
        for j in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, n)):
            for q in range(k):
                out[j, q] = math.inf
            xj = x[j, 0]
            yj = x[j, 1]
            if wa.shape[0] and not (active[j] and math.isfinite(xj) and math.isfinite(yj)):
                ex = e[j, 0]
                ey = e[j, 1]
                for q in range(k):
                    tx[q] = cos[q] * ex - sin[q] * ey
                    ty[q] = sin[q] * ex + cos[q] * ey
                _walls_ahead(j, xj, yj, tx, ty, reach, half, wa, wv, wnorm, wstarts, wlist, wbox, out)
    m = order.shape[0]
    chunks = (m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    for chunk in prange(chunks):  # the humans in cell order: their neighbours are near in memory
        tx = np.empty(k)
        ty = np.empty(k)
        best2 = np.empty(k)
        for t in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m)):
            j = order[t]
            ex = e[j, 0]
            ey = e[j, 1]
            xj = pos[t, 0]
            yj = pos[t, 1]
            far2 = -1.0  # the largest of the lanes' nearest so far: the search stops beyond it
            for q in range(k):
                tx[q] = cos[q] * ex - sin[q] * ey
                ty[q] = sin[q] * ex + cos[q] * ey
                if tx[q] == 0.0 and ty[q] == 0.0:
                    best2[q] = math.nan  # a standing human: no lane, no headway
                else:
                    best2[q] = reach2
                    far2 = reach2
            if far2 > 0.0:
                cx = min(int((xj - origin[0]) // h), nx - 1)
                cy = min(int((yj - origin[1]) // h), ny - 1)
                lo_x = 0.0  # the lanes' bounding box, from X_j
                hi_x = 0.0
                lo_y = 0.0
                hi_y = 0.0
                for q in range(k):
                    if best2[q] == best2[q]:
                        lo_x = min(lo_x, reach * tx[q] - lane * abs(ty[q]), -lane * abs(ty[q]))
                        hi_x = max(hi_x, reach * tx[q] + lane * abs(ty[q]), lane * abs(ty[q]))
                        lo_y = min(lo_y, reach * ty[q] - lane * abs(tx[q]), -lane * abs(tx[q]))
                        hi_y = max(hi_y, reach * ty[q] + lane * abs(tx[q]), lane * abs(tx[q]))
                gx0 = min(max(int(math.floor((xj + max(lo_x, -reach) - SLACK - origin[0]) / h)), 0), nx - 1)
                gx1 = min(max(int(math.floor((xj + min(hi_x, reach) + SLACK - origin[0]) / h)), 0), nx - 1)
                gy0 = min(max(int(math.floor((yj + max(lo_y, -reach) - SLACK - origin[1]) / h)), 0), ny - 1)
                gy1 = min(max(int(math.floor((yj + min(hi_y, reach) + SLACK - origin[1]) / h)), 0), ny - 1)
                # the 3 × 3 cells round X_j first, then row by row, nearest rows first, in each row the cells within
                # every lane's nearest so far: a row's humans are contiguous in the cell order (one run, or two
                # beside the block already seen), so no loop over cells
                for phase in range(2):
                    for dr in range(2 if phase == 0 else rings + 1):
                        if dr >= 2 and (dr - 1) * h * ((dr - 1) * h) >= far2:
                            break  # every row from here is farther than every lane's nearest found
                        for side in range(2):
                            if dr == 0 and side == 1:
                                continue
                            gy = cy - dr if side == 0 else cy + dr
                            if gy < gy0 or gy > gy1:
                                continue
                            by0 = origin[1] + gy * h - yj - SLACK  # the row's band, from X_j, a little wider
                            by1 = by0 + h + 2.0 * SLACK
                            dy2 = by0 * by0 if by0 > 0.0 else (by1 * by1 if by1 < 0.0 else 0.0)
                            if dy2 >= far2:
                                continue
                            if phase == 0:
                                ga = max(gx0, cx - 1)
                                gb = min(gx1, cx + 1)
                                runs = 1
                            else:
                                wide = math.sqrt(far2 - dy2) + SLACK
                                ga = max(gx0, min(max(int(math.floor((xj - wide - origin[0]) / h)), 0), nx - 1))
                                gb = min(gx1, min(max(int(math.floor((xj + wide - origin[0]) / h)), 0), nx - 1))
                                runs = 2 if dr <= 1 else 1  # beside the block, or the whole row
                            for run in range(runs):
                                a = ga
                                b = gb
                                if phase == 1 and dr <= 1:
                                    if run == 0:
                                        b = min(gb, cx - 2)
                                    else:
                                        a = max(ga, cx + 2)
                                if a > b:
                                    continue
                                for u in range(starts[gy * nx + a], starts[gy * nx + b + 1]):
                                    if u == t:
                                        continue
                                    dx = pos[u, 0] - xj
                                    dy = pos[u, 1] - yj
                                    r2 = dx * dx + dy * dy
                                    if r2 >= far2:
                                        continue
                                    found = False
                                    for q in range(k):  # (&: no branch per test, one per hit)
                                        along = dx * tx[q] + dy * ty[q]
                                        across = dx * ty[q] - dy * tx[q]
                                        if (r2 < best2[q]) & (along > 0.0) & (abs(across) < lane):
                                            best2[q] = r2
                                            found = True
                                    if found:
                                        far2 = -1.0
                                        for q in range(k):
                                            if best2[q] > far2:
                                                far2 = best2[q]
                for q in range(k):
                    if best2[q] < reach2:
                        out[j, q] = math.sqrt(best2[q])
            if wa.shape[0]:
                _walls_ahead(j, x[j, 0], x[j, 1], tx, ty, reach, half, wa, wv, wnorm, wstarts, wlist, wbox, out)


def lane_headways(
    x: np.ndarray, e: np.ndarray, active: np.ndarray, cos: np.ndarray, sin: np.ndarray, lane: float, reach: float,
    cells: CellList, out: np.ndarray, walls: LaneWalls = NO_WALLS, half: float = 0.0,
) -> np.ndarray:  # fmt: skip
    """Each human's headway along each of ``K`` turned lanes at once, into ``out`` (N, K) (m; ``inf``: nobody).

    Lane ``q`` of human ``j`` is its direction ``e_j`` turned by the angle whose cosine and sine are ``cos[q]``,
    ``sin[q]``::

        t_jq = (cos_q e_jx − sin_q e_jy,  sin_q e_jx + cos_q e_jy),   out[j, q] = s_j along t_jq

    with ``s_j`` the headway of :func:`headways` (module docstring, (H1)): the same numbers, to the last bit, as
    ``K`` calls of :func:`headways` with the turned directions (the same minima over the same candidates).  The
    compiled loop walks each human's neighbours in the cell list once for all the lanes: the rows of cells
    nearest first, in each row one contiguous run of the cell order over the cells within every lane's nearest so
    far and within the lanes' bounding box, until a row lies beyond every lane's nearest.  Each human writes its
    own row of ``out`` only, so the numbers do not depend on numba's threads (docs page *Congestion*, "The
    headway door model"; its section *Cost* for what it costs).  The numpy twin is ``K`` calls of
    :func:`headways`' twin and every ray against every wall.

    With ``walls``, each turned lane ``q >= 1`` (the route's own, ``q = 0``, is never turned off a wall) is also
    cut at its first wall: ``out[j, q] = min(s, t R + half)``, ``t`` the fraction of the ray from ``X_j`` to
    ``X_j + R t_jq`` at the first wall it meets (the arithmetic of
    :meth:`~meanfield.geometry.walls.WallIndex.first_hit`), for every human, active or not.  Only the walls
    near enough to cut a lane shorter than its headway are tested; ``min`` of the cuts is the cut of the first
    wall (rounding is monotone), so nothing else changes.

    Parameters
    ----------
    x, e : ndarray, shape (N, 2)
        Positions and unit walking directions (0: standing, no headway).
    active : ndarray of bool, shape (N,)
        Who counts and is counted (non-finite rows are ignored).
    cos, sin : ndarray, shape (K,)
        The turns' cosines and sines.
    lane : float
        ``w``, the lane's half width (m).
    reach : float
        ``R``: nobody farther counts, and no wall (m).
    cells : CellList
        The active humans in cells (:func:`cell_list`, any width ``h > 0``).
    out : ndarray, shape (N, K)
        C-contiguous.
    walls : LaneWalls, optional
        The walls that cut the turned lanes (default :data:`NO_WALLS`).
    half : float
        What a wall adds to its distance (m; (H4): ``d/2``).
    """
    _lanes_compiled(x, e, active, cos, sin, lane, reach, half, cells.arrays(), walls.arrays(), out)
    return out


def _choose_numpy(f, s, e, cos, sin, best_s, best_f, walk):
    """The numpy twin of :func:`choose_lanes`."""
    best = np.argmax(f * cos, axis=1)  # the first of equal gains: the smallest turn
    pick = np.arange(len(f))
    best_s[:] = s[pick, best]
    best_f[:] = f[pick, best]
    c, sn = cos[best], sin[best]
    walk[:, 0] = c * e[:, 0] - sn * e[:, 1]
    walk[:, 1] = sn * e[:, 0] + c * e[:, 1]


@compiled(fallback=_choose_numpy, parallel_over="f")
def _choose_compiled(f, s, e, cos, sin, best_s, best_f, walk):
    n = f.shape[0]
    k = f.shape[1]
    for chunk in prange((n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        for j in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, n)):
            b = 0
            top = f[j, 0] * cos[0]
            if top == top:  # (numpy's argmax: the first nan, if any, else the first of the largest)
                for q in range(1, k):
                    g = f[j, q] * cos[q]
                    if g != g:
                        b = q
                        break
                    if g > top:
                        top = g
                        b = q
            best_s[j] = s[j, b]
            best_f[j] = f[j, b]
            walk[j, 0] = cos[b] * e[j, 0] - sin[b] * e[j, 1]
            walk[j, 1] = sin[b] * e[j, 0] + cos[b] * e[j, 1]


def choose_lanes(
    f: np.ndarray, s: np.ndarray, e: np.ndarray, cos: np.ndarray, sin: np.ndarray, best_s: np.ndarray,
    best_f: np.ndarray, walk: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """(H4)'s choice: each human's lane of largest progress ``f cos θ`` (the first of equal ones, the smallest
    turn), its headway, its speed factor and its unit direction (docs page *Congestion*, "The headway door
    model").

    Parameters
    ----------
    f, s : ndarray, shape (N, K)
        Each lane's speed factor and headway.
    e : ndarray, shape (N, 2)
        The routes' directions.
    cos, sin : ndarray, shape (K,)
        The turns' cosines and sines.
    best_s, best_f : ndarray, shape (N,)
        The chosen lane's headway and speed factor (written).
    walk : ndarray, shape (N, 2)
        The chosen lane's direction, ``e`` turned (written).
    """
    _choose_compiled(f, s, e, cos, sin, best_s, best_f, walk)
    return walk


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


CONTACT_NOISE_POWER = 4.0
"""``m`` of :func:`contact_noise`: each contact at ``r < d`` scales a human's diffusion by ``(r/d)^m``."""


def _contact_noise_numpy(x, active, jam, power, phi, grad, cells):
    """The numpy twin of :func:`contact_noise`'s loop (every pair closer than ``d``; ``cells`` unused)."""
    phi[:] = 1.0
    grad[:] = 0.0
    j, k, r2 = _pairs(x, active, jam)
    keep = r2 > 0.0
    j, k, r2 = j[keep], k[keep], r2[keep]
    if not len(j):
        return
    r = np.sqrt(r2)
    log_phi = np.zeros(len(x))
    np.add.at(log_phi, j, power * np.log(r / jam))
    np.add.at(grad[:, 0], j, -power * (x[k, 0] - x[j, 0]) / r2)
    np.add.at(grad[:, 1], j, -power * (x[k, 1] - x[j, 1]) / r2)
    touched = np.unique(j)
    phi[touched] = np.exp(log_phi[touched])
    grad[touched] *= phi[touched, None]


@compiled(fallback=_contact_noise_numpy, parallel_over="x")
def _contact_noise_compiled(x, active, jam, power, phi, grad, cells):
    order, starts, pos, origin, h, nx, ny = cells
    jam2 = jam * jam
    for j in prange(x.shape[0]):
        phi[j] = 1.0
        grad[j, 0] = 0.0
        grad[j, 1] = 0.0
    for t in prange(order.shape[0]):
        j = order[t]
        xj = pos[t, 0]
        yj = pos[t, 1]
        cx = min(int((xj - origin[0]) // h), nx - 1)
        cy = min(int((yj - origin[1]) // h), ny - 1)
        log_phi = 0.0
        gx = 0.0
        gy = 0.0
        touched = False
        for gy_ in range(max(cy - 1, 0), min(cy + 2, ny)):
            for gx_ in range(max(cx - 1, 0), min(cx + 2, nx)):
                c = gy_ * nx + gx_
                for u in range(starts[c], starts[c + 1]):
                    dx = pos[u, 0] - xj
                    dy = pos[u, 1] - yj
                    r2 = dx * dx + dy * dy
                    if u != t and 0.0 < r2 < jam2:
                        log_phi += power * math.log(math.sqrt(r2) / jam)
                        gx -= power * dx / r2
                        gy -= power * dy / r2
                        touched = True
        if touched:
            f = math.exp(log_phi)
            phi[j] = f
            grad[j, 0] = f * gx
            grad[j, 1] = f * gy


def contact_noise(x: np.ndarray, active: np.ndarray, jam: float, cells: CellList, phi: np.ndarray, grad: np.ndarray,
                  power: float = CONTACT_NOISE_POWER) -> np.ndarray:  # fmt: skip
    """The noise's share ``φ_j`` that each active human keeps among those it touches, and its gradient, in place
    (docs page *Congestion*, "The headway door model").

    A human's diffusion is ``σ φ_j``, each contact closer than the jam spacing ``d`` scaling it by ``(r/d)^m``::

        φ_j = Π_{k : 0 < |X_k − X_j| < d} (|X_k − X_j|/d)^m,    ∇_j φ_j = −m φ_j Σ_k (X_k − X_j)/|X_k − X_j|²

    (1 and 0 for a human who touches nobody, or is not active).  The crowd's step adds ``σ ∇_j φ_j`` to the drift:
    the noise is then the divergence ``∇·(σ φ ∇p)`` of the density ``p``, not Itô's ``Δ(σ φ p)``, which would
    drift everyone down the gradient of its own noise, into its contacts.  With it, two people who touch and
    only step apart by (H3) at ``u (1 − r/d)`` each keep their separation ``r < d`` at the stationary law::

        p(r) / p(d) = exp(−∫_r^d u (1 − s/d) / (σ (s/d)^m) ds)

    whose overlap shrinks as ``(r/d)^m`` falls, instead of the Ornstein–Uhlenbeck pair's ``√(σ d / u)``; at the
    jam spacing and beyond, nobody's noise changes, so a queue standing at ``d`` keeps its noise and no jam is
    frozen.

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions.
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    jam : float
        ``d``: those closer than this touch (m).
    cells : CellList
        The active humans in cells of width at least ``d`` (:func:`cell_list`).
    phi : ndarray, shape (N,)
        ``φ``, written.
    grad : ndarray, shape (N, 2)
        ``∇_j φ_j``, 1/m, written.
    power : float
        ``m`` (:data:`CONTACT_NOISE_POWER`).

    Returns
    -------
    phi : ndarray
    """
    if cells.h < jam:
        raise ValueError(f"contact_noise needs cells at least {jam} m wide, got {cells.h}")
    _contact_noise_compiled(x, active, float(jam), float(power), phi, grad, cells.arrays())
    return phi
