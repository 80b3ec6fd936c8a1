"""The headway door model's loops, compiled: the nearest person ahead in one's lane, and the fused step.

:func:`headways` gives every active human ``j`` walking along the unit direction ``e_j`` its *headway*::

    s_j = min{ |X_k − X_j| : k ≠ j active, (X_k − X_j)·e_j > 0, |(X_k − X_j) × e_j| < w, |X_k − X_j| < R }

(``inf`` where nobody is in the lane ahead within the reach ``R``, or ``e_j = 0``): the distance to the
nearest person in front of it whose centre is less than the lane's half width ``w`` off its line of walk
(docs page *Congestion*, "The headway door model", (H1)).

(H4) needs the headway along ``K`` turned lanes of every human: :func:`lane_headways` finds all of them in one
walk of each human's neighbours (and cuts the turned lanes at the walls, :class:`LaneWalls`), the numbers of
``K`` calls of :func:`headways`; :func:`choose_lanes` then picks the lane of most progress (docs page
*Congestion*, "The headway door model", (H4)).

The contacts, (H2), (H3) and (H5), are in :mod:`meanfield.crowds._contact_loops`.  A congested step with the
linear diagram is one compiled pass, :func:`headway_step`: the cell list, then each human in turn, its lanes (H4),
their speed factors (H1), its lane and walk, its contact cone (H2), soft core (H3) and share of the noise (H5),
and the count of its neighbours that the model reports as its local density, all from one reading of the cells
round it, in arrays kept between steps (:class:`HeadwayWork`); the numbers of the separate calls, to the last bit
(docs page *Congestion*, section *Cost*).

The compiled loops search a cell list (:func:`meanfield.crowds._cell_list.cell_list`); the headway's search widens
ring by ring and stops once a ring lies farther than the nearest found, the lanes' search row by row.  The numpy
twins list every pair closer than the reach.  Both take the same minima over the same candidates: the headways
agree to the last bit.  The loops over humans run on numba's threads above
:data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans, each human writing its own row: the same numbers on
any number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, inlined, inner, prange
from meanfield.crowds._cell_list import CellList, _cells_numpy, _pairs, _sort_cells
from meanfield.crowds._congestion_loops import _neighbour_density_numpy, disk_share
from meanfield.crowds._contact_loops import (
    _NO_GRADIENT,
    CONTACT_NOISE_POWER,
    CONTACTS,
    _cone,
    _cone_numpy,
    _contact_noise_numpy,
    _noise_share,
    _read_contacts,
)

__all__ = [
    "headways",
    "lane_headways",
    "choose_lanes",
    "headway_step",
    "HeadwayWork",
    "LaneWalls",
    "NO_WALLS",
    "NO_COUNT",
]


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


@inlined
def _wall_cuts(px, py, tx, ty, k, reach, half, a, v, norm, starts, walls, box, cut):
    """``cut[q] = min(cut[q], t_q reach + half)`` for the turned lanes ``1 <= q < k``, ``t_q`` the first wall on the ray
    from ``p`` to ``p + reach (tx_q, ty_q)`` (nothing where none): the walls' first hit's ``t``, without its division
    where it cannot count (a wall whose line is farther than the reach, or than ``cut[q]`` less ``half`` with a
    margin of 1e-6 for round-off, or a ray that points away from it).  ``min`` of the cuts is the cut of the first
    wall (rounding is monotone), so a ``cut[q]`` that is the lane's headway so far, or any bound above its final
    headway, leaves the lane's ``min(headway, first wall's cut)`` as it is."""
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
    most = 0.0  # the farthest a wall can be and still cut a lane: its headway less half, at most the reach
    for q in range(1, k):
        most = max(most, min(far, (cut[q] - half) * (1.0 + 1e-6) + 1e-9))
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
            if not abs(num) <= min(far, (cut[q] - half) * (1.0 + 1e-6) + 1e-9) * norm[w]:
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
                if sw < cut[q]:
                    cut[q] = sw


LANES = 8
"""The lanes' scratch arrays are padded to a multiple of this (lanes that no one is ahead in): the compiled search
tests one neighbour against 8 lanes at once, without a branch (one vector instruction each, where the processor
has them)."""


BLOCK = 2
"""The lanes' search reads the ``(2 BLOCK + 1)²`` cells round a human first, then the walls, then row by row."""


@inner
def _wall_cuts_call(px, py, tx, ty, k, reach, half, a, v, norm, starts, walls, box, cut):
    """:func:`_wall_cuts` as a call, not inlined: for the rare humans the cells do not hold or who stand (their code
    kept out of the loop's)."""
    _wall_cuts(px, py, tx, ty, k, reach, half, a, v, norm, starts, walls, box, cut)


@inlined
def _turned(ex, ey, cos, sin, tx, ty):
    """The lanes' directions ``t_q = (cos_q e_x − sin_q e_y, sin_q e_x + cos_q e_y)``, into ``tx``, ``ty``; the
    padding (``q >= K``) 0."""
    k = cos.shape[0]
    for q in range(tx.shape[0]):
        if q < k:
            tx[q] = cos[q] * ex - sin[q] * ey
            ty[q] = sin[q] * ex + cos[q] * ey
        else:
            tx[q] = 0.0
            ty[q] = 0.0


@inlined
def _nearer_in_lanes(dx, dy, r2, kp, w, tx, ty, best2, lane):
    """A neighbour at the offset ``(dx, dy)``, ``r2`` away squared, tested against each of the ``kp`` lanes
    ``(tx_q, ty_q)`` of :func:`_lane_search`: where it is ahead (``along > 0``) within the lane's half-width and
    nearer than the lane's nearest so far, ``best2[q]``, it is the nearest now (a select, not a branch).  With one
    block of :data:`LANES` lanes the lanes are read from ``w`` at offsets the compiler sees apart, so it
    vectorises."""
    if kp == LANES:
        for q in range(LANES):
            along = dx * w[q] + dy * w[LANES + q]
            across = dx * w[LANES + q] - dy * w[q]
            b2 = w[2 * LANES + q]
            ok = (r2 < b2) & (along > 0.0) & (abs(across) < lane)
            w[2 * LANES + q] = r2 if ok else b2
    else:
        for q in range(kp):
            along = dx * tx[q] + dy * ty[q]
            across = dx * ty[q] - dy * tx[q]
            b2 = best2[q]
            best2[q] = r2 if (r2 < b2) & (along > 0.0) & (abs(across) < lane) else b2


@inlined
def _lane_search(t, k, w, tx, ty, best2, lane, reach, half, pos, starts, ox, oy, h, nx, ny, wa, wv, wnorm, wstarts,
                 wlist, wbox, cut, s, radius2, contact2, cdx, cdy, cr2):  # fmt: skip
    """The headways of the human in slot ``t`` of the cell list along its ``k`` lanes ``(tx_q, ty_q)``, into ``s``
    (m; ``inf``: nobody within the reach), each turned lane cut at its first wall (:func:`lane_headways`); and,
    from the same reading of its neighbours, how many others are closer than ``√radius2`` and its contacts, those
    at ``0 < r² < contact2``, into ``cdx``, ``cdy``, ``cr2`` (their offsets and squared distances, in the order
    of the cells: row by row, each row's cells in turn).  Returns ``(count, contacts)``; more contacts than the
    buffers hold are counted, not all kept (the caller reads them again).

    The ``(2 BLOCK + 1)²`` cells round it first, all of them (they hold everyone within ``BLOCK h``: the count's
    disk and the contacts when ``√radius2``, ``√contact2 <= BLOCK h``); then the walls, each turned lane cut at
    its first (a wall nearer than the lane's nearest so far bounds the rest of that lane's search: nobody beyond
    its cut changes ``min(s, cut)``); then, unless every lane's nearest lies within the block, row by row, nearest
    rows first, in each row the cells within every lane's nearest so far: a row's humans are contiguous in the cell
    order (one run, or two beside the block already seen), so no loop over cells.  ``pos``, ``starts``,
    ``(ox, oy)``, ``h``, ``nx``, ``ny``: the cell list's arrays (:meth:`CellList.arrays`), the ``w*``: the walls'
    (:meth:`LaneWalls.arrays`); ``w``: the lanes' ``tx``, ``ty`` (0 beyond ``k``) and nearest so far, one after the
    other, each of a length that :data:`LANES` divides, as ``cut`` and ``s``.  Every neighbour is tested against
    every lane, a lane's nearest replaced by a select, not a branch: the same minima over the same candidates."""
    kp = tx.shape[0]
    reach2 = reach * reach
    cap = cdx.shape[0]
    xj = pos[t, 0]
    yj = pos[t, 1]
    far2 = -1.0  # the largest of the lanes' nearest so far: the search stops beyond it
    for q in range(kp):
        s[q] = math.inf
        if q >= k:
            best2[q] = -1.0  # the padding: nobody is nearer than this, and it is below every lane's nearest
        elif tx[q] == 0.0 and ty[q] == 0.0:
            best2[q] = math.nan  # a standing human: no lane, no headway
        else:
            best2[q] = reach2
            far2 = reach2
    searched = far2 > 0.0
    cx = min(int((xj - ox) // h), nx - 1)
    cy = min(int((yj - oy) // h), ny - 1)
    count = 0
    contacts = 0
    for gy in range(max(cy - BLOCK, 0), min(cy + BLOCK, ny - 1) + 1):  # the block: rows up, each row's cells in turn
        for u in range(starts[gy * nx + max(cx - BLOCK, 0)], starts[gy * nx + min(cx + BLOCK, nx - 1) + 1]):
            dx = pos[u, 0] - xj  # (X_j itself, dx = dy = 0, is ahead in no lane and no contact; it is counted)
            dy = pos[u, 1] - yj
            r2 = dx * dx + dy * dy
            count += r2 < radius2
            c = min(contacts, cap - 1)
            cdx[c] = dx
            cdy[c] = dy
            cr2[c] = r2
            contacts += (r2 > 0.0) & (r2 < contact2)
            _nearer_in_lanes(dx, dy, r2, kp, w, tx, ty, best2, lane)
    if radius2 > 0.0:
        count -= 1  # (X_j itself)
    if searched:
        far2 = -1.0
        for q in range(k):
            far2 = max(far2, best2[q])
        if wa.shape[0] and k > 1:  # the walls: a lane cut short is searched no farther
            for q in range(k):
                cut[q] = math.sqrt(best2[q]) if best2[q] < reach2 else math.inf
            _wall_cuts(xj, yj, tx, ty, k, reach, half, wa, wv, wnorm, wstarts, wlist, wbox, cut)
            far2 = -1.0
            for q in range(k):
                if q >= 1 and cut[q] < math.inf:
                    b = cut[q] * (1.0 + 1e-9)  # sqrt(b²) > cut[q]: nobody this far changes min(s, cut)
                    if b * b < best2[q]:
                        best2[q] = b * b
                far2 = max(far2, best2[q])
        # the nearest anyone outside the block can be (nobody beyond the lattice's edge)
        gap = math.inf
        if cx - BLOCK > 0:
            gap = min(gap, xj - (ox + (cx - BLOCK) * h))
        if cx + BLOCK < nx - 1:
            gap = min(gap, ox + (cx + BLOCK + 1) * h - xj)
        if cy - BLOCK > 0:
            gap = min(gap, yj - (oy + (cy - BLOCK) * h))
        if cy + BLOCK < ny - 1:
            gap = min(gap, oy + (cy + BLOCK + 1) * h - yj)
        gap -= SLACK
        if not (gap > 0.0 and far2 < gap * gap):  # someone outside the block may be nearer: row by row
            rings = int(math.ceil(reach / h)) + 1
            lo_x = 0.0  # the lanes' bounding box, from X_j
            hi_x = 0.0
            lo_y = 0.0
            hi_y = 0.0
            for q in range(k):
                if best2[q] != best2[q]:
                    continue
                lo_x = min(lo_x, reach * tx[q] - lane * abs(ty[q]), -lane * abs(ty[q]))
                hi_x = max(hi_x, reach * tx[q] + lane * abs(ty[q]), lane * abs(ty[q]))
                lo_y = min(lo_y, reach * ty[q] - lane * abs(tx[q]), -lane * abs(tx[q]))
                hi_y = max(hi_y, reach * ty[q] + lane * abs(tx[q]), lane * abs(tx[q]))
            gx0 = min(max(int(math.floor((xj + max(lo_x, -reach) - SLACK - ox) / h)), 0), nx - 1)
            gx1 = min(max(int(math.floor((xj + min(hi_x, reach) + SLACK - ox) / h)), 0), nx - 1)
            gy0 = min(max(int(math.floor((yj + max(lo_y, -reach) - SLACK - oy) / h)), 0), ny - 1)
            gy1 = min(max(int(math.floor((yj + min(hi_y, reach) + SLACK - oy) / h)), 0), ny - 1)
            for dr in range(rings + 1):
                if dr >= 2 and (dr - 1) * h * ((dr - 1) * h) >= far2:
                    break  # every row from here is farther than every lane's nearest found
                for side in range(2):
                    if dr == 0 and side == 1:
                        continue
                    gy = cy - dr if side == 0 else cy + dr
                    if gy < gy0 or gy > gy1:
                        continue
                    by0 = oy + gy * h - yj - SLACK  # the row's band, from X_j, a little wider
                    by1 = by0 + h + 2.0 * SLACK
                    dy2 = by0 * by0 if by0 > 0.0 else (by1 * by1 if by1 < 0.0 else 0.0)
                    if dy2 >= far2:
                        continue
                    wide = math.sqrt(far2 - dy2) + SLACK
                    ga = max(gx0, min(max(int(math.floor((xj - wide - ox) / h)), 0), nx - 1))
                    gb = min(gx1, min(max(int(math.floor((xj + wide - ox) / h)), 0), nx - 1))
                    for run in range(2 if dr <= BLOCK else 1):  # beside the block, or the whole row
                        a = ga
                        b = gb
                        if dr <= BLOCK:
                            if run == 0:
                                b = min(gb, cx - BLOCK - 1)
                            else:
                                a = max(ga, cx + BLOCK + 1)
                        if a > b:
                            continue
                        for u in range(starts[gy * nx + a], starts[gy * nx + b + 1]):
                            dx = pos[u, 0] - xj
                            dy = pos[u, 1] - yj
                            r2 = dx * dx + dy * dy
                            _nearer_in_lanes(dx, dy, r2, kp, w, tx, ty, best2, lane)
                        far2 = -1.0  # (once a run: a bound of the search, not of the minima)
                        for q in range(k):
                            far2 = max(far2, best2[q])
        for q in range(k):
            if best2[q] < reach2:
                s[q] = math.sqrt(best2[q])
    if wa.shape[0] and k > 1:
        if searched:
            for q in range(1, k):  # the first wall's cut, if any is nearer than the headway
                if cut[q] < s[q]:
                    s[q] = cut[q]
        else:
            _wall_cuts_call(xj, yj, tx, ty, k, reach, half, wa, wv, wnorm, wstarts, wlist, wbox, s)
    return count, contacts


@compiled(fallback=_lanes_numpy, parallel_over="x")
def _lanes_compiled(x, e, active, cos, sin, lane, reach, half, cells, walls, out):
    order, starts, pos, origin, h, nx, ny = cells
    ox = origin[0]
    oy = origin[1]
    wa, wv, wnorm, wstarts, wlist, wbox = walls
    n = x.shape[0]
    k = cos.shape[0]
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
                _turned(e[j, 0], e[j, 1], cos, sin, tx, ty)
                _wall_cuts_call(xj, yj, tx, ty, k, reach, half, wa, wv, wnorm, wstarts, wlist, wbox, out[j])
    m = order.shape[0]
    kp = (k + LANES - 1) // LANES * LANES
    chunks = (m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    for chunk in prange(chunks):  # the humans in cell order: their neighbours are near in memory
        w = np.empty(3 * kp)
        tx = w[:kp]
        ty = w[kp : 2 * kp]
        best2 = w[2 * kp :]
        cut = np.empty(kp)
        s = np.empty(kp)
        none = np.empty(1)  # (no count, no contacts)
        for t in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m)):
            j = order[t]
            _turned(e[j, 0], e[j, 1], cos, sin, tx, ty)
            _lane_search(t, k, w, tx, ty, best2, lane, reach, half, pos, starts, ox, oy, h, nx, ny, wa, wv, wnorm,
                         wstarts, wlist, wbox, cut, s, -1.0, -1.0, none, none, none)  # fmt: skip
            for q in range(k):
                out[j, q] = s[q]


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
            b = _best_turn(f[j], cos, k)
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


@inlined
def _best_turn(f, cos, k):
    """numpy's ``argmax`` of ``f_q cos_q`` over the ``k`` lanes: the first nan, if any, else the first of the
    largest (the smallest turn: (H4)'s ties)."""
    b = 0
    top = f[0] * cos[0]
    if top == top:
        for q in range(1, k):
            g = f[q] * cos[q]
            if g != g:
                b = q
                break
            if g > top:
                top = g
                b = q
    return b


@inlined
def _unit(vx, vy):
    """``(|v|, e)``: the walk's length and direction, ``e = v/|v|`` (0 for ``|v| = 0``; ``v`` itself where ``|v|`` is
    nan), numpy's ``hypot`` and division."""
    norm = math.hypot(vx, vy)
    if norm > 0.0:
        return norm, vx / norm, vy / norm
    if norm == 0.0:
        return norm, 0.0, 0.0
    return norm, vx, vy


@inlined
def _linear_factors(s, f, k, jam, rho_max):
    """(H1) with the linear diagram, ``f_q = clip(1 − ρ(s_q)/ρ_max, 0, 1)``, ``ρ(s) = ρ_max (d/s)²``, for the ``k``
    lanes: the operations of :meth:`~meanfield.crowds.headway.Headway.choose_direction` and
    :meth:`~meanfield.crowds.congestion.Linear.speed_factor`, in their order."""
    for q in range(k):
        rho = jam / s[q]
        rho = rho * rho
        rho = rho * rho_max
        g = rho / -rho_max
        g = g + 1.0
        if g < 0.0:  # (np.maximum, np.minimum: a nan stays)
            g = 0.0
        if g > 1.0:
            g = 1.0
        f[q] = g


@inlined
def _count_one(pos, starts, ox, oy, h, nx, ny, t, radius):
    """How many others are closer than ``radius`` to the human in slot ``t`` (read from the cells of any width)."""
    xj = pos[t, 0]
    yj = pos[t, 1]
    r2 = radius * radius
    ga = min(max(int(math.floor((xj - radius - SLACK - ox) / h)), 0), nx - 1)
    gb = min(max(int(math.floor((xj + radius + SLACK - ox) / h)), 0), nx - 1)
    gc = min(max(int(math.floor((yj - radius - SLACK - oy) / h)), 0), ny - 1)
    gd = min(max(int(math.floor((yj + radius + SLACK - oy) / h)), 0), ny - 1)
    count = 0
    for gy in range(gc, gd + 1):  # each row's cells: one run of the cell order
        for u in range(starts[gy * nx + ga], starts[gy * nx + gb + 1]):
            dx = pos[u, 0] - xj
            dy = pos[u, 1] - yj
            count += dx * dx + dy * dy < r2
    return count - 1  # (X_j itself)


@inlined
def _density_of(count, xj, yj, inv_area, table, tox, toy, spacing, floor, clipped):
    """The local density of a human at ``(xj, yj)`` with ``count`` others in its disk: the arithmetic of
    :func:`~meanfield.crowds._congestion_loops.neighbour_density` (the count over the disk's area, then over its
    share in Ω, read bilinearly)."""
    rho = count * inv_area
    if clipped:
        rho = rho / disk_share(table, xj, yj, tox, toy, spacing, floor)
    return rho


class HeadwayWork:
    """The arrays :func:`headway_step` works in for a crowd of ``n``, allocated once and kept between steps: the
    cell list's (``order``, ``starts``, ``sorted``), the counting sort's scratch, and each human's headway."""

    __slots__ = ("n", "order", "starts", "sorted", "key", "idx", "cursor", "headway")

    def __init__(self, n: int) -> None:
        self.n = int(n)
        self.order = np.empty(n, np.int64)
        self.starts = np.empty(4 * n + 66, np.int64)
        self.sorted = np.empty((n, 2))
        self.key = np.empty(n, np.int64)
        self.idx = np.empty(n, np.int64)
        self.cursor = np.empty(4 * n + 66, np.int64)
        self.headway = np.empty(n)

    def arrays(self) -> tuple:
        """``(order, starts, sorted, key, idx, cursor)``, as :func:`headway_step`'s loop takes them."""
        return self.order, self.starts, self.sorted, self.key, self.idx, self.cursor


NO_COUNT = (1.0, 0.0, np.ones((2, 2)), 0.0, 0.0, 1.0, 0.0, False)
""":func:`headway_step` without the count (``(radius, 1/(π r²), share table, its origin x, y, its spacing, s_min,
clipped)``)."""


def _step_numpy(v, x, active, cos, sin, lane, reach, half, walls, jam, separation, rho_max, power, count, counting,
                work, s_out, rho_out, phi, grad):  # fmt: skip
    """The numpy twin of :func:`headway_step`: the numpy twins of the cell list, the lanes, the choice, the contact
    cone, the count and (H5), one after the other (``work`` unused)."""
    n = len(x)
    norm = np.hypot(v[:, 0], v[:, 1])
    e = v.copy()
    np.divide(e, norm[:, None], out=e, where=norm[:, None] > 0)
    e[norm == 0] = 0.0
    order, starts, pos, x0, y0, h, nx, ny = _cells_numpy(x, active, jam)
    cells = (order, starts, pos, (x0, y0), h, nx, ny)
    s = np.empty((n, len(cos)))
    _lanes_numpy(x, e, active, cos, sin, lane, reach, half, cells, walls, s)
    with np.errstate(divide="ignore"):
        rho = np.divide(jam, s)
    np.square(rho, out=rho)
    rho *= rho_max
    f = rho / -rho_max
    f += 1.0
    np.maximum(f, 0.0, out=f)
    np.minimum(f, 1.0, out=f)
    best_f, walk = np.empty(n), np.empty((n, 2))
    _choose_numpy(f, s, e, cos, sin, s_out, best_f, walk)
    v[:] = (norm * best_f)[:, None] * walk
    _cone_numpy(v, x, active, jam, separation, cells)
    if counting:
        radius, inv_area, table, tox, toy, spacing, floor, clipped = count
        none = np.empty(1)
        _neighbour_density_numpy(
            x, active, radius, inv_area, table, tox, toy, spacing, floor, clipped, np.zeros((1, 2)), False, 0.0,
            None, None, None, None, None, None, rho_out, none, np.empty((1, 2)),
        )  # fmt: skip
    if power != 0.0:
        _contact_noise_numpy(x, active, jam, power, phi, grad, cells)


@compiled(fallback=_step_numpy, parallel_over="x")
def _step_compiled(v, x, active, cos, sin, lane, reach, half, walls, jam, separation, rho_max, power, count,
                   counting, work, s_out, rho_out, phi, grad):  # fmt: skip
    wa, wv, wnorm, wstarts, wlist, wbox = walls
    radius, inv_area, table, tox, toy, spacing, floor, clipped = count
    order, starts, pos, key, idx, cursor = work
    n = x.shape[0]
    k = cos.shape[0]
    kp = (k + LANES - 1) // LANES * LANES
    m, ox, oy, h, nx, ny = _sort_cells(x, active, jam, order, starts, pos, key, idx, cursor)
    jam2 = jam * jam
    in_block = radius * radius if counting and radius + SLACK <= BLOCK * h else -1.0  # (the count's disk in the block)
    chunks = (n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    noise = power != 0.0
    for chunk in prange(chunks):  # those the cells do not hold: nobody ahead, the walls; no contact, no count
        tx = np.empty(k)
        ty = np.empty(k)
        sl = np.empty(k)
        fl = np.empty(k)
        for j in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, n)):
            if counting:
                rho_out[j] = 0.0
            if noise:
                phi[j] = 1.0
                grad[j, 0] = 0.0
                grad[j, 1] = 0.0
            xj = x[j, 0]
            yj = x[j, 1]
            if active[j] and math.isfinite(xj) and math.isfinite(yj):
                continue
            norm, ex, ey = _unit(v[j, 0], v[j, 1])
            _turned(ex, ey, cos, sin, tx, ty)
            for q in range(k):
                sl[q] = math.inf
            if wa.shape[0]:
                _wall_cuts_call(xj, yj, tx, ty, k, reach, half, wa, wv, wnorm, wstarts, wlist, wbox, sl)
            _linear_factors(sl, fl, k, jam, rho_max)
            b = _best_turn(fl, cos, k)
            s_out[j] = sl[b]
            speed = norm * fl[b]
            v[j, 0] = speed * (cos[b] * ex - sin[b] * ey)
            v[j, 1] = speed * (sin[b] * ex + cos[b] * ey)
    chunks = (m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    for chunk in prange(chunks):  # the humans in cell order: (H4), (H1), (H2), (H3), the count and (H5), one at a time
        w = np.empty(3 * kp)
        tx = w[:kp]
        ty = w[kp : 2 * kp]
        best2 = w[2 * kp :]
        cut = np.empty(kp)
        sl = np.empty(kp)
        fl = np.empty(k)
        cdx = np.empty(CONTACTS)
        cdy = np.empty(CONTACTS)
        cr2 = np.empty(CONTACTS)
        for t in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m)):
            j = order[t]
            norm, ex, ey = _unit(v[j, 0], v[j, 1])
            _turned(ex, ey, cos, sin, tx, ty)
            count, contacts = _lane_search(t, k, w, tx, ty, best2, lane, reach, half, pos, starts, ox, oy, h, nx, ny,
                                           wa, wv, wnorm, wstarts, wlist, wbox, cut, sl, in_block, jam2, cdx, cdy,
                                           cr2)  # fmt: skip
            _linear_factors(sl, fl, k, jam, rho_max)
            b = _best_turn(fl, cos, k)
            s_out[j] = sl[b]
            speed = norm * fl[b]
            vx = speed * (cos[b] * ex - sin[b] * ey)
            vy = speed * (sin[b] * ex + cos[b] * ey)
            if contacts <= CONTACTS:
                vx, vy = _cone(cdx, cdy, cr2, contacts, vx, vy, jam, separation)
                if noise:
                    phi[j], grad[j, 0], grad[j, 1] = _noise_share(cdx, cdy, cr2, contacts, jam, power)
            else:  # (more contacts than the buffers hold: read again)
                contacts, bdx, bdy, br2 = _read_contacts(pos, starts, ox, oy, h, nx, ny, t, jam2, cdx, cdy, cr2)
                vx, vy = _cone(bdx, bdy, br2, contacts, vx, vy, jam, separation)
                if noise:
                    phi[j], grad[j, 0], grad[j, 1] = _noise_share(bdx, bdy, br2, contacts, jam, power)
            v[j, 0] = vx
            v[j, 1] = vy
            if counting:
                if in_block < 0.0:  # (a disk wider than the block: counted on its own)
                    count = _count_one(pos, starts, ox, oy, h, nx, ny, t, radius)
                rho_out[j] = _density_of(count, pos[t, 0], pos[t, 1], inv_area, table, tox, toy, spacing, floor,
                                         clipped)  # fmt: skip


def headway_step(
    v: np.ndarray, x: np.ndarray, active: np.ndarray, cos: np.ndarray, sin: np.ndarray, lane: float, reach: float,
    half: float, walls: LaneWalls, jam: float, separation: float, rho_max: float, work: HeadwayWork,
    count: tuple = NO_COUNT, rho: np.ndarray | None = None, noise: tuple[np.ndarray, np.ndarray] | None = None,
    power: float = CONTACT_NOISE_POWER,
) -> np.ndarray:  # fmt: skip
    """A congested step of the headway door model with the linear diagram, (H1) to (H5), in one compiled pass:
    each human's velocity in place, and its chosen lane's headway (returned: ``work.headway``).

    The numbers, to the last bit, of :func:`cell_list` (cells of width ``jam``), :func:`lane_headways`, (H1)'s
    density and :meth:`~meanfield.crowds.congestion.Linear.speed_factor` of every lane, :func:`choose_lanes`, the
    walk ``|v| f`` along the chosen lane, :func:`contact_cone` and, with ``rho``, the count of
    :func:`~meanfield.crowds._congestion_loops.neighbour_density` and, with ``noise``, of :func:`contact_noise`
    (docs page *Congestion*, "The headway door model"; its section *Cost*).  The cell list is sorted once into
    ``work``; then each human, in cell order, finds its lanes' headways (H4), their speed factors (H1), its lane,
    its walk, its contacts, read once for its contact cone (H2), its soft core (H3) and its share of the noise
    (H5), and its count, writing only its own row: the same numbers on any number of threads.  Those the cells do
    not hold (not active, or not finite) walk as :meth:`~meanfield.crowds.headway.Headway.choose_direction` has
    them walk (nobody ahead; the walls), with no contact, a count of 0 and ``φ = 1``.

    Parameters
    ----------
    v : ndarray, shape (N, 2)
        Each human's walk before congestion (its direction is the line of walk; 0: standing); C-contiguous,
        changed in place.
    x : ndarray, shape (N, 2)
        Positions, C-contiguous.
    active : ndarray of bool, shape (N,)
    cos, sin : ndarray, shape (K,)
        The turns' cosines and sines (the route's own first).
    lane, reach, half : float
        ``w``, ``R`` and what a wall adds to its distance (:func:`lane_headways`).
    walls : LaneWalls
    jam : float
        ``d``: the cells' width and the contacts' distance (m).
    separation : float
        ``u`` of (H3), m/s.
    rho_max : float
        The linear diagram's jam density (persons/m²).
    work : HeadwayWork
        For ``N`` humans.
    count : tuple
        ``(radius, 1/(π r²), share table, its origin x, y, its spacing, s_min, clipped)``: the count's
        (:class:`~meanfield.crowds.local_density.LocalDensity`); read only with ``rho``.
    rho : ndarray, shape (N,), optional
        The local density of each human (written; 0 for those not active).
    noise : (ndarray, ndarray), shapes (N,) and (N, 2), optional
        ``φ`` and ``∇φ`` of (H5) (written, as :func:`contact_noise` writes them; None: not computed).
    power : float
        ``m`` of (H5) (:data:`CONTACT_NOISE_POWER`; read only with ``noise``).

    Returns
    -------
    ndarray, shape (N,)
        The chosen lane's headway (m), ``work.headway``.
    """
    counting = rho is not None
    phi, grad = (work.headway, _NO_GRADIENT) if noise is None else noise
    _step_compiled(v, x, active, cos, sin, float(lane), float(reach), float(half), walls.arrays(), float(jam),
                   float(separation), float(rho_max), 0.0 if noise is None else float(power), count, counting,
                   work.arrays(), work.headway, rho if counting else work.headway, phi, grad)  # fmt: skip
    return work.headway

