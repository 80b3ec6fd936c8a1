"""Which wall a step meets first, testing only the walls near it (a plan's reflection and robots).

A floor plan has many wall segments, and every step of every agent is a segment that may
cross one (:meth:`meanfield.geometry.plan.Plan.reflect`).  Testing each step against every wall
costs O(N W).  :class:`WallIndex` lays a lattice over the plan and keeps, for each lattice
cell, the walls that meet the 3 × 3 block of cells around it: a step no longer than a
lattice cell stays in that block, so only those walls can stop it, and the answer is the
same as the test against every wall (a step longer than a cell is tested against all).
The test itself is one compiled pass per step (:mod:`meanfield.geometry._wall_loops`); its numpy twin
tests few steps (under :data:`FULL_TEST_BELOW` step-wall pairs) against every wall at once.
"""

from __future__ import annotations

import numpy as np

from meanfield.geometry._wall_loops import FULL_TEST_BELOW, first_hits, segment_hits

__all__ = ["WallIndex", "segment_hits", "FULL_TEST_BELOW"]


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

        self.a, self.e = np.ascontiguousarray(starts, float), np.ascontiguousarray(vectors, float)
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
        self.box = np.array([x0, y0, self.size, nx, ny], float)  # the lattice, as wall_loops takes it
        self._tables = (self.a, self.e, self.near, self.box)

    def tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(a, e, near, box)``: the walls, the walls near each cell and the lattice
        ``(x0, y0, size, nx, ny)``, as the loops of :mod:`meanfield.geometry._wall_loops` take them."""
        return self._tables

    def first_hit(self, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each step ``start → end``: the fraction of it at the first wall met (``inf``: none)
        and that wall's index (the lowest of equal fractions; 0 where none), one compiled pass
        (:func:`meanfield.geometry._wall_loops.first_hits`)."""
        start = np.ascontiguousarray(start, float)
        end = np.ascontiguousarray(end, float)
        m = len(start)
        t_out, k_out = np.empty(m), np.empty(m, dtype=np.intp)
        if not m:
            return t_out, k_out
        return first_hits(start, end, *self.tables(), t_out, k_out)
