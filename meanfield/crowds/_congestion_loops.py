"""The agents' local density, compiled: how many neighbours each human has within a radius.

:func:`count_neighbours` counts, for every active human ``j``, the other active humans ``k``
with ``|X_k − X_j|² < r²``, by a cell list: the active humans are sorted into the cells of a
lattice over their bounding box (cells at least ``r`` wide, at most about four per human),
and each human looks at the humans of its own cell and of the eight around it.  O(N) for a
bounded density: a counting sort by cell (the humans' positions copied in cell order), then the
cells in memory order, each human's candidates three contiguous runs of the sorted copy (so
the search reads memory in order; the random accesses are the sort's scatter and the counts'
write-back, one pass each).  The count is an integer, so the compiled loop and its numpy
twin (the same cell list, vectorised) agree exactly, whatever order they visit the pairs in.
The caller turns the count into persons/m² (:func:`meanfield.crowds.agent_crowd.local_density`).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["count_neighbours", "MAX_CELLS_PER_HUMAN", "MAX_HUMANS"]

MAX_CELLS_PER_HUMAN = 4
"""The cell list has at most ``4 m + 64`` cells for ``m`` active humans (its cells grow, by doubling, beyond)."""


MAX_HUMANS = 400_000_000
"""The most humans :func:`count_neighbours` takes: its cell list's indices are 32-bit (``4 m + 65 < 2³¹``)."""


def _lattice(x0: float, x1: float, y0: float, y1: float, radius: float, m: int) -> tuple[float, int, int]:
    """Cell width ``h >= radius`` and the counts ``(nx, ny)`` over the box, at most ``4 m + 64`` cells."""
    h = radius
    nx = int((x1 - x0) / h) + 1
    ny = int((y1 - y0) / h) + 1
    while nx * ny > MAX_CELLS_PER_HUMAN * m + 64:
        h = 2.0 * h
        nx = int((x1 - x0) / h) + 1
        ny = int((y1 - y0) / h) + 1
    return h, nx, ny


def _count_neighbours_numpy(x, active, radius, out):
    out[:] = 0
    idx = np.flatnonzero(active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1]))
    m = len(idx)
    if m < 2:
        return
    p = x[idx]
    x0, y0 = float(p[:, 0].min()), float(p[:, 1].min())
    h, nx, ny = _lattice(x0, float(p[:, 0].max()), y0, float(p[:, 1].max()), radius, m)
    ci = np.minimum(((p[:, 0] - x0) / h).astype(np.int64), nx - 1)
    ck = np.minimum(((p[:, 1] - y0) / h).astype(np.int64), ny - 1)
    cell = ci * ny + ck
    order = np.argsort(cell, kind="stable")
    occupancy = np.bincount(cell, minlength=nx * ny)
    start = np.cumsum(occupancy) - occupancy
    r2 = radius * radius
    total = np.zeros(m, dtype=np.int64)
    for di in (-1, 0, 1):
        for dk in (-1, 0, 1):
            ni, nk = ci + di, ck + dk
            a = np.flatnonzero((ni >= 0) & (ni < nx) & (nk >= 0) & (nk < ny))
            nc = ni[a] * ny + nk[a]
            k = occupancy[nc]
            rows = np.repeat(a, k)
            offsets = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)
            cand = order[np.repeat(start[nc], k) + offsets]
            dx = p[cand, 0] - p[rows, 0]
            dy = p[cand, 1] - p[rows, 1]
            hit = (dx * dx + dy * dy < r2) & (cand != rows)
            total += np.bincount(rows[hit], minlength=m)
    out[idx] = total


@compiled(fallback=_count_neighbours_numpy)
def count_neighbours(x, active, radius, out):
    """For each active human, how many other active humans are closer than ``radius``; in place.

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions (rows of humans who are not active, NaN or not, are ignored; so is a
        non-finite row).
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    radius : float
        ``r > 0``: a neighbour is closer than ``r`` (``|X_k − X_j|² < r²``).
    out : ndarray of int64, shape (N,)
        The counts; 0 for the humans who are not active.
    """
    n = x.shape[0]
    m = 0
    x0 = math.inf
    x1 = -math.inf
    y0 = math.inf
    y1 = -math.inf
    use = np.zeros(n, dtype=np.bool_)
    for j in range(n):
        out[j] = 0
        if active[j] and math.isfinite(x[j, 0]) and math.isfinite(x[j, 1]):
            use[j] = True
            m += 1
            x0 = min(x0, x[j, 0])
            x1 = max(x1, x[j, 0])
            y0 = min(y0, x[j, 1])
            y1 = max(y1, x[j, 1])
    if m < 2:
        return
    h = radius
    nx = int((x1 - x0) / h) + 1
    ny = int((y1 - y0) / h) + 1
    while nx * ny > 4 * m + 64:  # MAX_CELLS_PER_HUMAN, as _lattice
        h = 2.0 * h
        nx = int((x1 - x0) / h) + 1
        ny = int((y1 - y0) / h) + 1
    cell = np.empty(n, dtype=np.int32)  # 32-bit indices: half the memory traffic (MAX_HUMANS keeps them in range)
    start = np.zeros(nx * ny + 1, dtype=np.int32)
    for j in range(n):
        if use[j]:
            c = min(int((x[j, 0] - x0) / h), nx - 1) * ny + min(int((x[j, 1] - y0) / h), ny - 1)
            cell[j] = c
            start[c + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(m, dtype=np.int32)
    px = np.empty(m)
    py = np.empty(m)
    for j in range(n):  # a counting sort by cell: each cell's humans contiguous, their positions copied beside them
        if use[j]:
            q = fill[cell[j]]
            order[q] = j
            px[q] = x[j, 0]
            py[q] = x[j, 1]
            fill[cell[j]] += 1
    r2 = radius * radius
    for i in range(nx):  # cell by cell, so that the candidates are read in memory order
        for k in range(ny):
            c = i * ny + k
            if start[c] == start[c + 1]:
                continue
            for p in range(start[c], start[c + 1]):
                xp = px[p]
                yp = py[p]
                count = 0
                for a in range(max(i - 1, 0), min(i + 2, nx)):
                    lo = start[a * ny + max(k - 1, 0)]  # the three cells (a, k-1..k+1) are one contiguous run
                    hi = start[a * ny + min(k + 2, ny)]
                    for q in range(lo, hi):
                        dx = px[q] - xp
                        dy = py[q] - yp
                        if dx * dx + dy * dy < r2:
                            count += 1
                out[order[p]] = count - 1  # itself, at distance 0 < r
