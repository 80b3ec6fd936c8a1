"""Which wall a step meets first, testing only the walls near it (a plan's reflection and robots).

A floor plan has many wall segments, and every step of every agent is a segment that may
cross one (:meth:`meanfield.plan.Plan.reflect`).  Testing each step against every wall
costs O(N W).  :class:`WallIndex` lays a lattice over the plan and keeps, for each lattice
cell, the walls that meet the 3 × 3 block of cells around it: a step no longer than a
lattice cell stays in that block, so only those walls can stop it, and the answer is the
same as the test against every wall (a step longer than a cell is tested against all).
Few steps (under :data:`FULL_TEST_BELOW` step-wall pairs) are tested against every wall at once.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WallIndex", "segment_hits", "FULL_TEST_BELOW"]

FULL_TEST_BELOW = 50_000
"""Below this many step-wall pairs every step is tested against every wall (numpy's overhead
per call outweighs the look-ups)."""


def segment_hits(start: np.ndarray, d: np.ndarray, a: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fraction ``t`` along each step ``start + t d`` at which it meets each wall ``a + u e``.

    ``start``, ``d``: ``(M, 2)``; ``a``, ``e``: ``(M, K, 2)`` or ``(K, 2)``.  Returns ``t``
    ``(M, K)`` (``inf`` where the step does not meet the wall in ``0 < t <= 1``, ``0 <= u <= 1``).
    """
    cross = d[:, None, 0] * e[..., 1] - d[:, None, 1] * e[..., 0]
    w = a - start[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / cross
        u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / cross
    hit = (cross != 0) & (t > 1e-12) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    return np.where(hit, t, np.inf)


class WallIndex:
    """The walls near each cell of a lattice over a plan.

    Parameters
    ----------
    starts, vectors : ndarray, shape (W, 2)
        Each wall segment as ``start + u vector``, ``0 <= u <= 1``.
    bounds : (float, float, float, float)
        ``(x0, x1, y0, y1)`` of the plan.
    cells : int
        Lattice cells along the longer side.
    """

    def __init__(self, starts: np.ndarray, vectors: np.ndarray, bounds: tuple[float, ...], cells: int = 64):
        import shapely

        self.a, self.e = np.asarray(starts, float), np.asarray(vectors, float)
        x0, x1, y0, y1 = bounds
        self.size = max(x1 - x0, y1 - y0) / cells
        self.origin = np.array([x0, y0])
        self.shape = (int(np.ceil((x1 - x0) / self.size)) + 1, int(np.ceil((y1 - y0) / self.size)) + 1)
        nx, ny = self.shape
        walls = shapely.linestrings(np.stack([self.a, self.a + self.e], axis=1))
        tree = shapely.STRtree(walls)
        I, J = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        lo = self.origin + np.stack([I.ravel() - 1, J.ravel() - 1], -1) * self.size
        blocks = shapely.box(lo[:, 0], lo[:, 1], lo[:, 0] + 3 * self.size, lo[:, 1] + 3 * self.size)
        cell, wall = tree.query(blocks, predicate="intersects")
        counts = np.bincount(cell, minlength=nx * ny)
        k = max(int(counts.max()) if len(counts) else 0, 1)
        self.near = np.full((nx * ny, k), -1, dtype=np.intp)  # -1: no wall in that slot
        order = np.lexsort((wall, cell))  # by cell, then wall: ties go to the lowest wall, as in a full test
        cell, wall = cell[order], wall[order]
        slot = np.arange(len(cell)) - np.repeat(np.cumsum(counts) - counts, counts)
        self.near[cell, slot] = wall

    def first_hit(self, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each step ``start → end``: the fraction of it at the first wall met (``inf``: none)
        and that wall's index."""
        m = len(start)
        t_out = np.full(m, np.inf)
        k_out = np.zeros(m, dtype=np.intp)
        if not m:
            return t_out, k_out
        d = end - start
        if m * len(self.a) <= FULL_TEST_BELOW:  # few pairs: one vectorised test beats the look-ups
            t = segment_hits(start, d, self.a[None], self.e[None])
            j = np.argmin(t, axis=1)
            return t[np.arange(m), j], j
        short = (np.abs(d) <= self.size).all(axis=1)
        ij = np.floor((start - self.origin) / self.size).astype(np.intp)
        inside = (ij >= 0).all(axis=1) & (ij[:, 0] < self.shape[0]) & (ij[:, 1] < self.shape[1])
        local = np.flatnonzero(short & inside)
        if len(local):
            cand = self.near[ij[local, 0] * self.shape[1] + ij[local, 1]]  # (L, K)
            safe = np.maximum(cand, 0)
            t = segment_hits(start[local], d[local], self.a[safe], self.e[safe])
            t = np.where(cand >= 0, t, np.inf)
            j = np.argmin(t, axis=1)
            t_out[local] = t[np.arange(len(local)), j]
            k_out[local] = safe[np.arange(len(local)), j]
        rest = np.flatnonzero(~(short & inside))
        if len(rest):
            t = segment_hits(start[rest], d[rest], self.a[None], self.e[None])
            j = np.argmin(t, axis=1)
            t_out[rest] = t[np.arange(len(rest)), j]
            k_out[rest] = j
        return t_out, k_out
