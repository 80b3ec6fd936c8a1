"""Geodesic routes to the exits: the distance ``φ`` and the way each cell goes (docs page *Buildings*).

* :func:`exit_distance` — ``φ``, the length of the shortest path from each cell to an exit
  inside Ω (around walls and pillars): Dijkstra's algorithm on the grid's cells, each joined
  to its 8 neighbours through open faces (a diagonal only when a path along the two faces is
  open), an exit cell starting at its centre's distance to the exit.  The 8-neighbour metric
  is exact along the axes and the diagonals and overestimates other directions by at most
  8.2 % (``1/cos 22.5°``).
* :class:`ExitRoutes` — the route an informed walker takes from each cell: the farthest of
  the next cells of its shortest path (up to :data:`LOOK_AHEAD`) that its centre sees in a
  straight line (:mod:`meanfield.geometry.sight`), or the exit itself when it is in sight ("string
  pulling"), which removes the 8-neighbour zig-zag; the route's length from any point
  (:meth:`ExitRoutes.distance`) is what the evacuation lower bound uses.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry.grid import Grid
from meanfield.geometry.sight import SightLines

__all__ = ["exit_distance", "ExitRoutes", "routes_for", "LOOK_AHEAD"]

LOOK_AHEAD = 16
"""How many cells ahead along its shortest path a cell looks for the farthest one in sight."""


def exit_distance(grid: Grid, segs: np.ndarray) -> np.ndarray:
    """``φ`` on the cells: the shortest path inside Ω to the nearest exit (``inf`` on inactive cells).

    Raises
    ------
    ParameterError
        Named ``domain.exits`` without exits, or ``grid.cells`` when some cell of Ω reaches
        no exit on this grid (a passage narrower than a cell: refine the grid).
    """
    dist, _, index = _exit_tree(grid, segs)
    phi = np.full(grid.shape, np.inf)
    phi[grid.active] = dist
    return phi


def _exit_tree(grid: Grid, segs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dijkstra from the exits over the cell graph: distances, predecessors and the cells' node indices.

    Raises
    ------
    ParameterError
        Named ``domain.exits`` without exits, or ``grid.cells`` when some cell of Ω reaches
        no exit on this grid (a passage narrower than a cell: refine the grid).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    from meanfield.geometry.exits import ExitSink, distance_to_segments

    if not len(segs):
        raise ParameterError("domain.exits", "none", "at least one exit (the geodesic Step I leads to them)")
    nx, ny = grid.shape
    active = grid.active
    index = -np.ones(grid.shape, dtype=np.int64)
    index[active] = np.arange(int(active.sum()))
    n = int(active.sum())
    ox = grid.aperture_x > 0  # open x-faces between (i, j) and (i+1, j)
    oy = grid.aperture_y > 0  # open y-faces between (i, j) and (i, j+1)
    rows, cols, w = [], [], []

    def link(a: np.ndarray, b: np.ndarray, length: float) -> None:
        rows.append(a)
        cols.append(b)
        w.append(np.full(len(a), length))

    i, j = np.nonzero(ox)
    link(index[i, j], index[i + 1, j], grid.dx)
    i, j = np.nonzero(oy)
    link(index[i, j], index[i, j + 1], grid.dy)
    diag = math.hypot(grid.dx, grid.dy)
    # (i, j) -> (i+1, j+1): along x then y, or y then x
    up = (ox[:, :-1] & oy[1:, :]) | (oy[:-1, :] & ox[:, 1:])
    i, j = np.nonzero(up)
    link(index[i, j], index[i + 1, j + 1], diag)
    # (i, j+1) -> (i+1, j): along x then down, or down then x
    down = (ox[:, 1:] & oy[1:, :]) | (oy[:-1, :] & ox[:, :-1])
    i, j = np.nonzero(down)
    link(index[i, j + 1], index[i + 1, j], diag)
    # the exits: a source node joined to each exit cell by the centre's distance to its exit
    sink = ExitSink(grid, segs, 1.0)
    exit_cells = (sink.total_rate > 0) & active
    X, Y = grid.centers
    rows.append(np.full(int(exit_cells.sum()), n))
    cols.append(index[exit_cells])
    w.append(distance_to_segments(np.column_stack([X[exit_cells], Y[exit_cells]]), segs).min(axis=1))
    a, b, length = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    graph = coo_matrix((np.r_[length, length], (np.r_[a, b], np.r_[b, a])), shape=(n + 1, n + 1)).tocsr()
    dist, pred = dijkstra(graph, directed=False, indices=n, return_predecessors=True)
    dist, pred = dist[:n], pred[:n]
    if not np.isfinite(dist).all():
        cut = int((~np.isfinite(dist)).sum())
        raise ParameterError(
            "grid.cells",
            grid.cells,
            f"a grid on which every cell of Ω reaches an exit ({cut} cells do not: a passage is narrower than a cell)",
        )
    return dist, pred, index


class ExitRoutes:
    """The informed walker's route from every cell of the grid to the nearest exit.

    Parameters
    ----------
    grid : Grid
        The cells (their region is Ω).
    segs : ndarray, shape (E, 2, 2)
        The exits (:func:`meanfield.geometry.exits.exit_segments`).
    sight : SightLines, optional
        The walls that block a straight line (built from ``grid.domain`` when omitted).

    Attributes
    ----------
    waypoint : ndarray, shape (nx, ny, 2)
        Where a walker in each cell heads (a cell centre down its route, or a point of the exit).
    remaining : ndarray, shape (nx, ny)
        The route's length from each cell's waypoint to the exit.
    """

    def __init__(self, grid: Grid, segs: np.ndarray, sight: SightLines | None = None):
        from scipy import ndimage

        from meanfield.geometry.exits import distance_to_segments

        dist, pred, index = _exit_tree(grid, segs)
        sight = SightLines(grid.domain) if sight is None else sight
        self.grid = grid
        n = len(dist)
        X, Y = grid.centers
        centre = np.column_stack([X[grid.active], Y[grid.active]])
        # each exit cell's exit point: the nearest point of its nearest exit, kept off the exit's ends
        d = distance_to_segments(centre, segs)
        k = d.argmin(axis=1)
        a, b = segs[k, 0], segs[k, 1]
        t = np.clip(((centre - a) * (b - a)).sum(1) / ((b - a) ** 2).sum(1), 0.05, 0.95)
        exit_point = a + t[:, None] * (b - a)
        # the chain of next cells, LOOK_AHEAD deep; n is the exits' node
        pred = np.where(pred < 0, n, pred)
        pred = np.r_[pred, n]
        chain = [np.arange(n)]
        for _ in range(LOOK_AHEAD):
            chain.append(pred[chain[-1]])
        chain = np.stack(chain, axis=1)  # (n, LOOK_AHEAD + 1)
        reached = chain[:, 1:] == n
        last_cell = chain[:, 1:].copy()  # past the exit: the last cell before it
        for k in range(LOOK_AHEAD):
            last_cell[:, k] = np.where(reached[:, k], chain[:, 0] if k == 0 else last_cell[:, k - 1], last_cell[:, k])
        points = np.where(reached[..., None], exit_point[last_cell], np.r_[centre, [[0.0, 0.0]]][chain[:, 1:]])
        seen = sight.visible(np.broadcast_to(centre[:, None, :], points.shape), points)
        seen[:, 0] = True  # the next cell is always reachable (a face or a diagonal is open)
        # the farthest in sight; past the exit every entry repeats the exit point
        pick = LOOK_AHEAD - 1 - np.argmax(seen[:, ::-1], axis=1)
        rows = np.arange(n)
        target = points[rows, pick]
        via = np.where(reached[rows, pick], n, chain[rows, pick + 1])  # the cell the waypoint is, or the exits
        # route lengths, from the exits outwards (a waypoint's cell is nearer the exit than its own)
        remaining = np.zeros(n + 1)
        for c in np.argsort(dist, kind="stable"):
            v = via[c]
            remaining[c] = np.hypot(*(target[c] - centre[c])) + (0.0 if v == n else remaining[v])
        waypoint = np.full((*grid.shape, 2), np.nan)
        waypoint[grid.active] = target
        rest = np.full(grid.shape, np.nan)
        rest[grid.active] = np.where(via == n, 0.0, remaining[np.minimum(via, n)])
        # a point in a cell without volume (a sliver) takes the nearest cell's route
        _, (ii, jj) = ndimage.distance_transform_edt(~grid.active, return_indices=True)
        self.waypoint = waypoint[ii, jj]
        self.remaining = rest[ii, jj]

    def _cells(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = self.grid
        x0, _, y0, _ = g.domain.bounds
        i = np.clip(((points[:, 0] - x0) / g.dx).astype(np.intp), 0, g.cells[0] - 1)
        j = np.clip(((points[:, 1] - y0) / g.dy).astype(np.intp), 0, g.cells[1] - 1)
        return i, j

    def heading(self, points: np.ndarray) -> np.ndarray:
        """Unit vectors ``(N, 2)`` from each point towards its cell's waypoint (0 on the waypoint)."""
        i, j = self._cells(points)
        d = self.waypoint[i, j] - points
        norm = np.hypot(d[:, 0], d[:, 1])
        return np.divide(d, norm[:, None], out=np.zeros_like(d), where=norm[:, None] > 0)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """The length of each point's route to the exit: straight to its cell's waypoint, then along the route."""
        i, j = self._cells(points)
        return np.hypot(*(self.waypoint[i, j] - points).T) + self.remaining[i, j]


def routes_for(region: Any, grid: Grid, sight: SightLines | None = None) -> ExitRoutes:
    """:class:`ExitRoutes` to the exits of ``region`` on ``grid`` (refused, naming ``domain.exits``, without)."""
    from meanfield.geometry.exits import exit_segments

    return ExitRoutes(grid, exit_segments(region), sight)
