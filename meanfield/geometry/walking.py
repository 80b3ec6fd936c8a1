"""Walking distances from a few points to every cell: geodesic Voronoi cells and first legs.

A robot in a building reaches a cell by walking round walls and through doors, not along
the straight line.  This module gives, for points ``R_1 … R_n`` (the robots) and every
active cell ``c`` of the grid:

* ``d_i(c)``, the walking distance from ``R_i`` to ``c``: straight to the *anchor*
  ``a_i(c)``, the last cell of the route that ``R_i`` sees, then along the route::

      d_i(c) = |x_{a_i(c)} − R_i| + D_i(c) − D_i(a_i(c)),

  with ``D_i`` Dijkstra's distance from the cell of ``R_i`` over the cells' 8-neighbour
  links (:func:`meanfield.geometry.geodesic.cell_links`: through open faces, diagonally
  where a path along two faces is open).  Where ``R_i`` sees ``c``, ``a_i(c) = c`` and
  ``d_i(c) = |x_c − R_i|`` exactly; behind a wall the route's part beyond the anchor is the
  8-neighbour path (at most 8 % long, docs page *Buildings*, "Routes to the exits");
* ``e_i(c)``, the unit vector from ``R_i`` towards the anchor: the first leg of the route,
  the direction in which ``d_i(c)`` falls fastest as ``R_i`` moves (``−∇_{R_i} d_i(c)``);
* the geodesic Voronoi cells ``V_i = {c : d_i(c) ≤ d_j(c) for all j}``.

The anchor is found on Dijkstra's trees: ``a_i(c) = c`` where ``R_i``
sees ``c`` or ``c`` is next to its start on the route (through an open face or diagonal, as
the informed walker's next cell), else ``a_i(pred_i(c))``; by pointer jumping (the numpy twin: the chain halves at
each pass, so a route of ``L`` cells needs ``log₂ L`` passes) or, compiled, each path walked up once
(:func:`meanfield.geometry._walking_loops.tree_anchors`).  Sight is the grid's (:meth:`SightLines.cell_rows`), the
same the signs and the coverage controller use.

Reference: A. Bhattacharya, R. Ghrist, V. Kumar, "Multi-robot coverage and exploration on
Riemannian manifolds with boundaries", *Int. J. Robotics Research* 33(1), 2014: Lloyd's
coverage in the geodesic metric, whose cost gradient is the one used by
:mod:`meanfield.controllers.coverage` with ``metric = "walking"``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from meanfield.geometry._walking_loops import nearest_walk, tree_anchors
from meanfield.geometry.grid import Grid
from meanfield.geometry.sight import SightLines

__all__ = ["WalkingDistances", "WalkingField"]

KEPT_BYTES = 256e6
"""At most about this many bytes of kept trees (a tree and its anchors per start cell); then they are planted again."""


@dataclasses.dataclass(frozen=True)
class WalkingField:
    """The walking distances from ``n`` points to the ``M`` active cells (module docstring).

    Attributes
    ----------
    distance : ndarray, shape (n, M)
        ``d_i(c)``, metres of the grid; ``inf`` for a cell no route reaches.
    leg : ndarray, shape (n, M, 2)
        ``e_i(c)``: unit vectors of the routes' first legs (0 where ``R_i`` stands on the anchor).
    anchor : ndarray of int, shape (n, M)
        ``a_i(c)``, as an index into the active cells.
    """

    distance: np.ndarray
    leg: np.ndarray
    anchor: np.ndarray

    def owners(self) -> np.ndarray:
        """For each active cell, the point whose walking distance is least (ties: the first): ``(M,)``."""
        return np.argmin(self.distance, axis=0)


class WalkingDistances:
    """Walking distances on a grid's cells from any points (module docstring).

    Parameters
    ----------
    grid : Grid
        The cells; their region's walls block the routes and the sight lines.
    sight : SightLines, optional
        The walls that hide a cell (built from ``grid.domain`` when omitted).
    """

    def __init__(self, grid: Grid, sight: SightLines | None = None):
        from scipy import ndimage
        from scipy.sparse import coo_matrix

        from meanfield.geometry.geodesic import cell_links

        self.grid = grid
        self.sight = SightLines(grid.domain) if sight is None else sight
        active = grid.active
        self.cells = np.flatnonzero(active.ravel())
        m = len(self.cells)
        index = -np.ones(grid.shape, dtype=np.int64)
        index[active] = np.arange(m)
        a, b, w = cell_links(grid, index)
        self.graph = coo_matrix((np.r_[w, w], (np.r_[a, b], np.r_[b, a])), shape=(m, m)).tocsr()
        X, Y = grid.centers
        self.xy = np.column_stack([X[active], Y[active]])
        # a point in a cell without volume starts from the nearest cell that has some
        _, (ii, jj) = ndimage.distance_transform_edt(~active, return_indices=True)
        self._nearest = index[ii, jj]
        self.keep = max(64, int(KEPT_BYTES // (16 * max(m, 1))))
        self._trees: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def _plant(self, starts: np.ndarray, points: np.ndarray) -> None:
        """Dijkstra's trees from the cells ``starts`` and their anchors, kept: both depend on the start cell only."""
        from scipy.sparse.csgraph import dijkstra

        n, m = len(starts), len(self.cells)
        # (the graph holds each link both ways: as a directed graph, the undirected one's trees, without its transpose)
        D, pred = dijkstra(self.graph, directed=True, indices=starts, return_predecessors=True)
        D, pred = D.reshape(n, m), pred.reshape(n, m)
        seen = self.sight.cell_rows(self.grid, points).reshape(n, -1)[:, self.cells]
        seen[np.arange(n), starts] = True  # a point sees the cell it starts from,
        seen |= pred == starts[:, None]  # and walks to its neighbours on the routes (open faces or diagonals)
        # the nearest ancestor in sight (pointer jumping, compiled: meanfield.geometry._walking_loops.tree_anchors)
        anchor = tree_anchors(np.ascontiguousarray(pred), seen, np.empty((n, m), np.int64))
        for k, d, a in zip(starts, D, anchor, strict=True):
            self._trees[int(k)] = (d, a)

    def cell_of(self, points: np.ndarray) -> np.ndarray:
        """The active cell (index into :attr:`cells`) each point starts from: ``(n,)``."""
        return self._nearest[self.grid.cell_of(np.asarray(points, float).reshape(-1, 2))]

    def walk_to(self, point: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The walking distance ``d(c)`` and first leg ``e(c)`` from one point to each of ``cells`` (indices into the
        active cells): the columns ``cells`` of :meth:`from_points` for that point, the same numbers, without the
        others.

        Returns
        -------
        distance : ndarray, shape (m,)
        leg : ndarray, shape (m, 2)
        """
        p = np.real(np.asarray(point, float)).reshape(1, 2)
        D, anchor = self._trees[int(self._planted(p)[0])]
        cells = np.asarray(cells, np.intp)
        a = anchor[cells]
        return _walks(self.xy[a] - p, D[cells], D[a])

    def walk_to_nearest(self, point: np.ndarray, owner: np.ndarray, robot: int,
                        target: np.ndarray) -> tuple[float, np.ndarray]:  # fmt: skip
        """The walk from one point to the cell, of those with ``owner[c] == robot`` that a route reaches, nearest
        ``target`` (straight, ties: the first): :meth:`walk_to`'s numbers for that cell, without the others
        (one compiled pass, :func:`meanfield.geometry._walking_loops.nearest_walk`).

        Returns
        -------
        distance : float
            ``d(c)`` (``inf`` when no such cell is reached).
        leg : ndarray, shape (2,)
            ``e(c)`` (0 when no such cell is reached).
        """
        distance, leg = self.walks_to_nearest(point, owner, np.array([robot]), target)
        return float(distance[0]), leg[0]

    def walks_to_nearest(self, points: np.ndarray, owner: np.ndarray, robots: np.ndarray,
                         targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """:meth:`walk_to_nearest` from each of ``points`` (``(n, 2)``) to the cells of ``robots[i]`` nearest
        ``targets[i]``, the trees of the points' start cells planted at once.

        Returns
        -------
        distance : ndarray, shape (n,)
        leg : ndarray, shape (n, 2)
        """
        p = np.real(np.asarray(points, float)).reshape(-1, 2)
        targets = np.asarray(targets, float).reshape(-1, 2)
        owner = np.ascontiguousarray(owner, np.intp)
        out = np.empty((len(p), 3))
        for i, k in enumerate(self._planted(p)):
            D, anchor = self._trees[int(k)]
            nearest_walk(self.xy, D, anchor, owner, int(robots[i]), p[i], targets[i], out[i])
        return out[:, 0], out[:, 1:]

    def from_points(self, points: np.ndarray) -> WalkingField:
        """The walking distances, first legs and anchors from each of ``points`` (``(n, 2)``) to every active cell.

        Dijkstra's tree and the anchors depend only on the cell a point starts from: they are computed the first
        time a point stands in a cell and kept (the straight first leg is the point's own).
        """
        p = np.real(np.asarray(points, float)).reshape(-1, 2)
        start = self._planted(p)
        D = np.stack([self._trees[int(k)][0] for k in start])
        anchor = np.stack([self._trees[int(k)][1] for k in start])
        distance, leg = _walks(self.xy[anchor] - p[:, None, :], D, np.take_along_axis(D, anchor, axis=1))
        return WalkingField(distance, leg, anchor)

    def _planted(self, p: np.ndarray) -> np.ndarray:
        """The start cell of each of the points ``p`` (``(n, 2)``), each with its tree kept (planted when new; a full
        store starts again, planting every cell needed now)."""
        start = self.cell_of(p)
        cells, first = np.unique(start, return_index=True)
        new = np.array([int(k) not in self._trees for k in cells], dtype=bool)
        if new.any():
            if len(self._trees) + int(new.sum()) > self.keep:
                self._trees.clear()
                new[:] = True
            self._plant(cells[new], p[first[new]])
        return start


def _walks(to_anchor: np.ndarray, D: np.ndarray, D_anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``d = |x_a − R| + D(c) − D(a)`` (``inf`` where no route reaches ``c``) and the unit first leg ``e`` towards the
    anchor (0 on it), from the offsets ``x_a − R`` (``(..., 2)``) and the tree's distances at the cells and their
    anchors (the module docstring)."""
    straight = np.hypot(to_anchor[..., 0], to_anchor[..., 1])
    with np.errstate(invalid="ignore"):  # inf − inf where no route reaches a cell
        distance = np.where(np.isfinite(D), straight + D - D_anchor, np.inf)
    leg = np.divide(to_anchor, straight[..., None], out=np.zeros_like(to_anchor), where=straight[..., None] > 0)
    return distance, leg
