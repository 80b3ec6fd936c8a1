"""The humans near each human: the active humans sorted into square cells, compiled (a cell list).

:func:`cell_list` sorts the active humans with finite positions into cells of width ``h`` over their bounding box
(a stable counting sort, the width doubled while there would be more than ``4 m + 64`` cells for ``m`` humans), in
compiled passes over runs of the humans, one run per thread (:func:`_cells_compiled`: each run counts its own
humans per cell and writes them into its own slots; a million humans sort in 85–97 ms on two threads against
121 ms in one run); its numpy twin is numpy's stable ``argsort``, the same arrays to the last bit for any number of
runs.  The door models' compiled loops search it for their neighbours: the headway and the
contacts (:mod:`meanfield.crowds._headway_loops`, :mod:`meanfield.crowds._contact_loops`) and the forward cell
(:mod:`meanfield.crowds._forward_cell_loops`).

Their numpy twins list every pair closer than a radius instead, :func:`_pairs` (cells as wide as the radius, each
against its nine neighbours, vectorised): the same candidates, so the same minima (docs page *Congestion*, "The
headway door model").
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, empty_array, inlined, inner, prange
from meanfield._compiled.threads import loop_threads

__all__ = ["cell_list", "CellList"]


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

    Compiled passes over runs of the humans, on numba's threads, find them and their bounding box, count them per
    cell and sort them (the same arrays as its numpy twin's stable ``argsort``, to the last bit; docs page
    *Congestion*, "The headway door model").
    """
    parts = loop_threads() or 1  # (the sort's parts: any number gives the same arrays)
    order, starts, sorted_positions, x0, y0, h, nx, ny = _cells_compiled(x, active, float(h), parts)
    return CellList(order, starts, sorted_positions, (x0, y0), h, int(nx), int(ny))


def _cells_numpy(x, active, h, parts=1):
    """The numpy twin of :func:`cell_list`'s loop: ``(order, starts, sorted, x0, y0, h, nx, ny)`` (``parts`` is the
    compiled loop's)."""
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


@inlined
def _sorted(x, active, j):
    """Whether human ``j`` goes into the cell list: active, with a finite position."""
    return active[j] and math.isfinite(x[j, 0]) and math.isfinite(x[j, 1])


@inlined
def _box(x, active, lo, hi):
    """How many of the humans ``lo`` to ``hi - 1`` go into the cell list, and their bounding box:
    ``(m, x0, x1, y0, y1)`` (infinities for none)."""
    m = 0
    x0 = math.inf
    x1 = -math.inf
    y0 = math.inf
    y1 = -math.inf
    for j in range(lo, hi):
        if _sorted(x, active, j):
            m += 1  # (min, max and int as numba's select and cast: no overload of numba's to compile)
            x0 = x[j, 0] if x[j, 0] < x0 else x0
            x1 = x[j, 0] if x[j, 0] > x1 else x1
            y0 = x[j, 1] if x[j, 1] < y0 else y0
            y1 = x[j, 1] if x[j, 1] > y1 else y1
    return m, x0, x1, y0, y1


@inlined
def _lattice_size(wx, wy, h, m):
    """:func:`_lattice`'s cells over a box ``wx`` × ``wy`` for ``m`` humans: ``(h, nx, ny)``, the width doubled while
    there would be more than ``4 m + 64`` cells."""
    nx = np.int64(wx // h) + 1
    ny = np.int64(wy // h) + 1
    while nx * ny > 4 * m + 64:
        h *= 2.0
        nx = np.int64(wx // h) + 1
        ny = np.int64(wy // h) + 1
    return h, nx, ny


@inlined
def _cell_of(px, py, x0, y0, h, nx, ny):
    """The row-major cell (``cy * nx + cx``) of the point ``(px, py)``, the lattice's last row and column taking
    what lies on its far edge."""
    gy = np.int64((py - y0) // h)
    gx = np.int64((px - x0) // h)
    return (ny - 1 if ny - 1 < gy else gy) * nx + (nx - 1 if nx - 1 < gx else gx)


@inner
def _sort_cells(x, active, h, order, starts, pos, key, idx, cursor):
    """:func:`cell_list`'s counting sort into the given arrays (``order``, ``key``, ``idx``: at least ``N``;
    ``pos``: at least (N, 2); ``starts``, ``cursor``: at least ``4 N + 65``): returns ``(m, x0, y0, h, nx, ny)``,
    ``order[:m]``, ``starts[:nx·ny + 1]`` and ``pos[:m]`` the cell list's arrays (``starts[:2]`` zero for
    ``m = 0``)."""
    n = x.shape[0]
    m, x0, x1, y0, y1 = _box(x, active, 0, n)  # who, and their bounding box
    if m == 0:
        starts[0] = 0
        starts[1] = 0
        return 0, 0.0, 0.0, h, 1, 1
    h, nx, ny = _lattice_size(x1 - x0, y1 - y0, h, m)
    for c in range(nx * ny + 1):
        starts[c] = 0
    i = 0
    for j in range(n):
        if _sorted(x, active, j):
            c = _cell_of(x[j, 0], x[j, 1], x0, y0, h, nx, ny)
            key[i] = c
            idx[i] = j
            starts[c + 1] += 1
            i += 1
    for c in range(nx * ny):
        starts[c + 1] += starts[c]
    for c in range(nx * ny):
        cursor[c] = starts[c]
    for i in range(m):  # stable: each cell's humans in their order
        slot = cursor[key[i]]
        cursor[key[i]] = slot + 1
        j = idx[i]
        order[slot] = j
        pos[slot, 0] = x[j, 0]
        pos[slot, 1] = x[j, 1]
    return m, x0, y0, h, nx, ny


@inlined
def _run_end(r, size, n):
    """One past the last human of run ``r`` (runs of ``size`` consecutive humans of ``n``)."""
    return n if n < (r + 1) * size else (r + 1) * size


@compiled(fallback=_cells_numpy, parallel_over="x")
def _cells_compiled(x, active, h, parts):
    """:func:`_sort_cells`'s stable counting sort in ``parts`` runs of the humans, each on a thread above
    :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans: each run counts its humans per cell, the runs' counts
    are laid out cell by cell (in each cell the first run's humans, then the second's), and each run writes its
    humans into its own slots.  The runs are consecutive, so each cell holds its humans in their order whatever
    ``parts`` is: the same arrays as the one-run sort, to the last bit."""
    n = x.shape[0]
    parts = 1 if parts < 1 else parts
    size = (n + parts - 1) // parts
    size = 1 if size < 1 else size
    runs = (n + size - 1) // size
    runs = 1 if runs < 1 else runs
    box = empty_array((runs, 5), np.float64)  # each run's count and bounding box
    for r in prange(runs):  # who, and their bounding box
        c, a0, a1, b0, b1 = _box(x, active, r * size, _run_end(r, size, n))
        box[r, 0] = c
        box[r, 1] = a0
        box[r, 2] = a1
        box[r, 3] = b0
        box[r, 4] = b1
    m = 0
    x0 = math.inf
    x1 = -math.inf
    y0 = math.inf
    y1 = -math.inf
    for r in range(runs):  # (min and max: the same whatever the runs)
        m += np.int64(box[r, 0])
        x0 = box[r, 1] if box[r, 1] < x0 else x0
        x1 = box[r, 2] if box[r, 2] > x1 else x1
        y0 = box[r, 3] if box[r, 3] < y0 else y0
        y1 = box[r, 4] if box[r, 4] > y1 else y1
    if m == 0:
        none = empty_array(2, np.int64)
        none[0] = 0
        none[1] = 0
        return empty_array(0, np.int64), none, empty_array((0, 2), np.float64), 0.0, 0.0, h, 1, 1
    h, nx, ny = _lattice_size(x1 - x0, y1 - y0, h, m)
    cells = nx * ny
    if runs * cells > 8 * n + 64:  # each run counts into a row of every cell: at most about 8 N counts in all
        runs = (8 * n + 64) // cells
        runs = 1 if runs < 1 else runs
        size = (n + runs - 1) // runs
        runs = (n + size - 1) // size
    key = empty_array(n, np.int64)  # each human's cell (-1: not sorted)
    count = empty_array((runs, cells), np.int64)  # each run's humans per cell
    for r in prange(runs):
        for c in range(cells):
            count[r, c] = 0
        for j in range(r * size, _run_end(r, size, n)):
            if _sorted(x, active, j):
                c = _cell_of(x[j, 0], x[j, 1], x0, y0, h, nx, ny)
                key[j] = c
                count[r, c] += 1
            else:
                key[j] = -1
    starts = empty_array(cells + 1, np.int64)
    total = 0
    for c in range(cells):  # each cell's run, and in it each run's first slot (count becomes the cursor)
        starts[c] = total
        for r in range(runs):
            k = count[r, c]
            count[r, c] = total
            total += k
    starts[cells] = total
    order = empty_array(m, np.int64)
    pos = empty_array((m, 2), np.float64)
    for r in prange(runs):  # stable: each cell's humans in their order
        for j in range(r * size, _run_end(r, size, n)):
            c = key[j]
            if c >= 0:
                slot = count[r, c]
                count[r, c] = slot + 1
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
