"""The agents' local density, compiled: the neighbours within a radius over the disk's area in Ω.

:func:`neighbour_density` gives every active human ``j``

    ρ_j = #{k ≠ j active : |X_k − X_j|² < r²} / (π r² max(s(X_j), s_min))

with ``s`` the share of the disk inside Ω (:mod:`meanfield.geometry.disk_share`, read bilinearly)
or 1 when no table is given (docs page *Congestion*, "The local density").  Given each human's
walking direction ``e_j`` (``directed``), the same pass also counts the density *ahead*, in the
half of the disk in front of it::

    ρ⁺_j = #{k ≠ j active : |X_k − X_j|² < r², (X_k − X_j)·e_j > 0} / (½ π r² max(s(X_j), s_min))

(0 for a human with no direction, ``e_j = 0``): the downwind density of the Godunov twin
(docs page *Congestion*, "The agents' door model"), and each human's share of the overlaps with
the others closer than the jam spacing ``d``, the excluded volume's push::

    P_j = Σ_{k ≠ j active : 0 < |X_k − X_j| < d} (d − |X_k − X_j|)/2 · (X_j − X_k)/|X_k − X_j|

(each pair moved apart by half its overlap, one Jacobi sweep of the contact constraint; a pair at
the same point has no direction and is left alone).

The count is a cell list: the active humans are sorted into the cells of a lattice over their
bounding box (cells at least ``r`` wide, at most about four per human) by a counting sort, and
each pair of humans in the same or neighbouring cells is compared once (a half stencil: the rest
of one's own cell and the cell above it, one contiguous run, then the three cells of the next
column, another).  O(N) for a bounded density.

The humans move a few centimetres a step, so the order of one step is nearly the order of the
next: the caller keeps the permutation (``order``, sorted by cell at the last call, and its
inverse ``slot``), and each human's position is *written* to its last slot (one sequential read
of the positions; the random accesses are writes, which the processor buffers, where a gather
by cell would wait for each read).  The counting sort then moves nearly sorted data, and the
search reads memory in order.  The permutation changes the speed only: the counts are integers,
and each human's density is computed from its own count and position, so every order gives the
same numbers, and the compiled loop and its numpy twin (the same cell list, vectorised, with no
memory of the order) agree to the last bit.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, inlined

__all__ = ["neighbour_density", "DensityWork", "MAX_CELLS_PER_HUMAN", "MAX_HUMANS"]

MAX_CELLS_PER_HUMAN = 4
"""The cell list has at most ``4 m + 64`` cells for ``m`` active humans (its cells grow, by doubling, beyond)."""


MAX_HUMANS = 400_000_000
"""The most humans :func:`neighbour_density` takes: its cell list's indices are 32-bit (``4 m + 65 < 2³¹``)."""


class DensityWork:
    """The arrays :func:`neighbour_density` works in for a crowd of ``n``, kept between calls.

    ``order`` (the humans sorted by cell at the last call, then those not counted) and its
    inverse ``slot`` start as the identity; the rest is scratch.
    """

    def __init__(self, n: int) -> None:
        if n > MAX_HUMANS:
            raise ValueError(f"at most {MAX_HUMANS} humans")
        self.order = np.arange(n, dtype=np.int32)
        self.slot = np.arange(n, dtype=np.int32)
        # last order's x, y; cell order's x, y; last order's direction; cell order's direction; the push (cell order)
        self.positions = np.empty((10, n))
        # cell; humans in cell order; counts; counts ahead
        self.indices = np.empty((4, n), dtype=np.int32)
        self.valid = np.empty(n, dtype=np.bool_)
        self.starts = np.empty(MAX_CELLS_PER_HUMAN * n + 66, dtype=np.int32)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """``(order, slot, positions, indices, valid, starts)``, as :func:`neighbour_density` takes them."""
        return self.order, self.slot, self.positions, self.indices, self.valid, self.starts


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


def _counts_numpy(
    p: np.ndarray, radius: float, e: np.ndarray | None = None, spacing: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each of the points ``p`` (M, 2), how many others are closer than ``radius`` (full stencil), how many
    of those lie ahead along the direction ``e`` (M, 2) (``(X_k − X_j)·e_j > 0``; zeros when ``e`` is None), and
    the push ``P_j`` (M, 2) of the others closer than ``spacing`` (module docstring; zeros when ``e`` is None)."""
    m = len(p)
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
    ahead = np.zeros(m, dtype=np.int64)
    push = np.zeros((m, 2))
    c2 = spacing * spacing
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
            if e is not None:
                front = hit & (dx * e[rows, 0] + dy * e[rows, 1] > 0.0)
                ahead += np.bincount(rows[front], minlength=m)
                d2 = dx * dx + dy * dy
                close = hit & (d2 < c2) & (d2 > 0.0)
                dist = np.sqrt(d2[close])
                w = (spacing - dist) / (2.0 * dist)
                push[:, 0] -= np.bincount(rows[close], weights=w * dx[close], minlength=m)
                push[:, 1] -= np.bincount(rows[close], weights=w * dy[close], minlength=m)
    return total, ahead, push


def _neighbour_density_numpy(
    x, active, radius, inv_area, table, ox, oy, spacing, floor, clipped,
    directions, directed, jam_spacing, order, slot, positions, indices, valid, starts, out, out_ahead, out_push,
):  # fmt: skip
    out[:] = 0.0
    if directed:
        out_ahead[:] = 0.0
        out_push[:] = 0.0
    idx = np.flatnonzero(active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1]))
    if len(idx) < 2:
        return
    p = x[idx]
    counts, ahead, push = _counts_numpy(p, radius, directions[idx] if directed else None, jam_spacing)
    share = np.ones(len(idx))
    if clipped:
        nx, ny = table.shape
        fx = (p[:, 0] - ox) / spacing
        fy = (p[:, 1] - oy) / spacing
        i = np.clip(np.floor(fx), 0, nx - 2).astype(np.int64)
        k = np.clip(np.floor(fy), 0, ny - 2).astype(np.int64)
        wx = np.clip(fx - i, 0.0, 1.0)
        wy = np.clip(fy - k, 0.0, 1.0)
        lo = table[i, k] + wy * (table[i, k + 1] - table[i, k])
        hi = table[i + 1, k] + wy * (table[i + 1, k + 1] - table[i + 1, k])
        share = np.maximum(lo + wx * (hi - lo), floor)
        out[idx] = counts * inv_area / share
    else:
        out[idx] = counts * inv_area
    if directed:
        out_ahead[idx] = ahead * (2.0 * inv_area) / share
        out_push[idx] = push


@inlined
def disk_share(table, x, y, ox, oy, spacing, floor):
    """The share of a disk at ``(x, y)`` inside Ω, read bilinearly from ``table`` (origin ``(ox, oy)``, cells of
    ``spacing``) as :meth:`~meanfield.crowds.local_density.DiskShare.at` reads it (exactly 1 among 1s), at least
    ``floor``; the compiled loops' per-human form of :func:`_neighbour_density_numpy`'s arithmetic."""
    tx = table.shape[0]
    ty = table.shape[1]
    fx = (x - ox) / spacing
    fy = (y - oy) / spacing
    i = min(max(math.floor(fx), 0), tx - 2)
    k = min(max(math.floor(fy), 0), ty - 2)
    wx = min(max(fx - i, 0.0), 1.0)
    wy = min(max(fy - k, 0.0), 1.0)
    lo = table[i, k] + wy * (table[i, k + 1] - table[i, k])
    hi = table[i + 1, k] + wy * (table[i + 1, k + 1] - table[i + 1, k])
    return max(lo + wx * (hi - lo), floor)


@compiled(fallback=_neighbour_density_numpy)
def neighbour_density(
    x, active, radius, inv_area, table, ox, oy, spacing, floor, clipped,
    directions, directed, jam_spacing, order, slot, positions, indices, valid, starts, out, out_ahead, out_push,
):  # fmt: skip
    """Each active human's neighbours within ``radius`` over the disk's area in Ω; in place.

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions (rows of humans who are not active, and non-finite rows, are ignored).
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    radius : float
        ``r > 0``: a neighbour is closer than ``r`` (``|X_k − X_j|² < r²``).
    inv_area : float
        ``1 / (π r²)``.
    table, ox, oy, spacing : ndarray (nx >= 2, ny >= 2), float, float, float
        The disk's share in Ω at the cells' centres ``(ox + i spacing, oy + k spacing)``
        (:class:`meanfield.geometry.disk_share.DiskShare`); read only when ``clipped``.
    floor : float
        ``s_min``: the share is taken as at least this.
    clipped : bool
        Divide by the share (else by the whole disk).
    directions : ndarray, shape (N, 2)
        Each human's walking direction ``e_j`` (any length: only its sign along ``X_k − X_j`` matters; 0: none);
        read only when ``directed``.
    directed : bool
        Also count the density ahead, into ``out_ahead``, and the push of the excluded volume, into ``out_push``.
    jam_spacing : float
        ``d``: the others closer than this push (read only when ``directed``; ``d <= radius``).
    order, slot, positions, indices, valid, starts : ndarray
        The work arrays of :class:`DensityWork`.  ``order`` (a permutation of the humans) and its
        inverse ``slot`` carry the last call's order to the next; any permutation will do: it
        changes the speed, not the numbers.  The numpy twin neither reads nor changes them.
    out : ndarray of float, shape (N,)
        ``ρ_j``, persons per unit area; 0 for the humans who are not active.
    out_ahead : ndarray of float, shape (N,)
        ``ρ⁺_j``, the density in the half disk ahead (written only when ``directed``; 0 for those not active).
    out_push : ndarray of float, shape (N, 2)
        ``P_j`` (module docstring; written only when ``directed``; 0 for those not active).  A sum of floats: the
        compiled loop and its numpy twin add the pairs in different orders and agree to round-off.
    """
    n = x.shape[0]
    px = positions[0]
    py = positions[1]
    sx = positions[2]
    sy = positions[3]
    pex = positions[4]
    pey = positions[5]
    sex = positions[6]
    sey = positions[7]
    cell = indices[0]
    ids = indices[1]
    cnt = indices[2]
    fwd = indices[3]
    qx = positions[8]
    qy = positions[9]
    x0 = math.inf
    x1 = -math.inf
    y0 = math.inf
    y1 = -math.inf
    m = 0
    for j in range(n):  # each position to its last slot: a sequential read, scattered writes
        a = x[j, 0]
        b = x[j, 1]
        s = slot[j]
        out[j] = 0.0
        if directed:
            out_ahead[j] = 0.0
            out_push[j, 0] = 0.0
            out_push[j, 1] = 0.0
        if active[j] and math.isfinite(a) and math.isfinite(b):
            px[s] = a
            py[s] = b
            if directed:
                pex[s] = directions[j, 0]
                pey[s] = directions[j, 1]
            valid[s] = True
            m += 1
            x0 = min(x0, a)
            x1 = max(x1, a)
            y0 = min(y0, b)
            y1 = max(y1, b)
        else:
            valid[s] = False
    if m < 2:
        return
    h = radius
    nx = int((x1 - x0) / h) + 1
    ny = int((y1 - y0) / h) + 1
    while nx * ny > 4 * m + 64:  # MAX_CELLS_PER_HUMAN, as _lattice
        h = 2.0 * h
        nx = int((x1 - x0) / h) + 1
        ny = int((y1 - y0) / h) + 1
    nc = nx * ny
    start = starts
    for c in range(nc + 1):
        start[c] = 0
    for p in range(n):  # nearly in cell order already: the histogram's increments are local
        if valid[p]:
            c = min(int((px[p] - x0) / h), nx - 1) * ny + min(int((py[p] - y0) / h), ny - 1)
            cell[p] = c
            start[c + 1] += 1
    for c in range(nc):
        start[c + 1] += start[c]
    for p in range(n):  # the counting sort (stable); start[c] ends as the end of cell c
        if valid[p]:
            c = cell[p]
            q = start[c]
            start[c] = q + 1
            sx[q] = px[p]
            sy[q] = py[p]
            if directed:
                sex[q] = pex[p]
                sey[q] = pey[p]
            ids[q] = order[p]
    for c in range(nc, 0, -1):
        start[c] = start[c - 1]
    start[0] = 0
    for q in range(m):
        cnt[q] = 0
        fwd[q] = 0
        qx[q] = 0.0
        qy[q] = 0.0
    r2 = radius * radius
    c2 = jam_spacing * jam_spacing
    for i in range(nx):  # each pair once: the rest of one's cell and the cell above, then the next column's three
        for k in range(ny):
            c = i * ny + k
            s0 = start[c]
            s1 = start[c + 1]
            if s0 == s1:
                continue
            lo = 0
            hi = 0
            if i + 1 < nx:
                lo = start[(i + 1) * ny + max(k - 1, 0)]
                hi = start[(i + 1) * ny + min(k + 2, ny)]
            up = s1 if k + 1 >= ny else start[c + 2]
            for p in range(s0, s1):
                xp = sx[p]
                yp = sy[p]
                mine = 0
                if directed:  # the same pairs, each also told whether the other is ahead of it, and the pushes
                    ep = sex[p]
                    fp = sey[p]
                    front = 0
                    for q in range(p + 1, up):
                        dx = sx[q] - xp
                        dy = sy[q] - yp
                        d2 = dx * dx + dy * dy
                        if d2 < r2:
                            mine += 1
                            cnt[q] += 1
                            if dx * ep + dy * fp > 0.0:
                                front += 1
                            if dx * sex[q] + dy * sey[q] < 0.0:  # (X_p − X_q)·e_q > 0
                                fwd[q] += 1
                            if 0.0 < d2 < c2:
                                dist = math.sqrt(d2)
                                w = (jam_spacing - dist) / (2.0 * dist)
                                qx[p] -= w * dx
                                qy[p] -= w * dy
                                qx[q] += w * dx
                                qy[q] += w * dy
                    for q in range(lo, hi):
                        dx = sx[q] - xp
                        dy = sy[q] - yp
                        d2 = dx * dx + dy * dy
                        if d2 < r2:
                            mine += 1
                            cnt[q] += 1
                            if dx * ep + dy * fp > 0.0:
                                front += 1
                            if dx * sex[q] + dy * sey[q] < 0.0:
                                fwd[q] += 1
                            if 0.0 < d2 < c2:
                                dist = math.sqrt(d2)
                                w = (jam_spacing - dist) / (2.0 * dist)
                                qx[p] -= w * dx
                                qy[p] -= w * dy
                                qx[q] += w * dx
                                qy[q] += w * dy
                    fwd[p] += front
                    cnt[p] += mine
                    continue
                for q in range(p + 1, up):
                    dx = sx[q] - xp
                    dy = sy[q] - yp
                    hit = 1 if dx * dx + dy * dy < r2 else 0
                    mine += hit
                    cnt[q] += hit
                for q in range(lo, hi):
                    dx = sx[q] - xp
                    dy = sy[q] - yp
                    hit = 1 if dx * dx + dy * dy < r2 else 0
                    mine += hit
                    cnt[q] += hit
                cnt[p] += mine
    for p in range(n):  # (cell[p] is free for those not counted: keep who they are before order is rewritten)
        if not valid[p]:
            cell[p] = order[p]
    for q in range(m):  # in cell order, so the table is read where the last human read it
        rho = cnt[q] * inv_area
        share = 1.0
        if clipped:
            share = disk_share(table, sx[q], sy[q], ox, oy, spacing, floor)
            rho = rho / share
        j = ids[q]
        out[j] = rho
        if directed:
            out_ahead[j] = fwd[q] * (2.0 * inv_area) / share
            out_push[j, 0] = qx[q]
            out_push[j, 1] = qy[q]
        order[q] = j
        slot[j] = q
    t = m
    for p in range(n):  # those not counted go after the others, in their last order
        if not valid[p]:
            order[t] = cell[p]
            slot[cell[p]] = t
            t += 1
