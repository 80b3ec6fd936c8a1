"""Line of sight in a floor plan: a wall between a robot and a human hides the robot's sign.

Design notes, section *Signs need line of sight* (docs page *Buildings*): robot ``i``'s
navigation field is zero at ``x`` when the segment from ``R_i`` to ``x`` crosses a wall,
so eq. (3) becomes ``v_r(x) = Σ_i s_i(x) K̄(x − R_i) e(θ_i)`` with ``s_i(x) ∈ {0, 1}``.

Sight is decided at the grid's resolution, the same way for the agents and for the grid's
field (what the robots' law and the density see): a human sees robot ``i`` when the point
of the robot's cell sees the point of the human's cell, and a face is seen when the
robot's cell sees the points of both cells beside it (a cell's point is its centre, or the
nearest point of Ω when the centre is in a wall).  Each cell's row of that table is
computed the first time a robot stands in the cell and kept, so a robot costs one test of
every cell against the walls per new cell, and a step costs a table look-up per pair.
:meth:`SightLines.visible` is the exact test of segments (used to build the rows).

Only walls that can stand between two points of Ω can hide anything: the walls of the
outline that lie on its convex hull never do (both points are on the same side of them), so
they are dropped once, and a convex room (every :class:`~meanfield.geometry.domain.Domain`) has no
sight-blocking wall at all: :class:`SightLines` then answers "visible" without a test.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.geometry._sight_loops import cell_index, segments_clear, sight_row

__all__ = ["SightLines", "blocking_walls"]


def blocking_walls(region: Any) -> np.ndarray:
    """The wall segments ``(W, 2, 2)`` of ``region`` that can hide one point of it from another.

    Every edge of the outline and of the holes, except the outline's edges on its convex hull.
    A region without :meth:`~meanfield.geometry.region.Region.to_shapely` (a stand-in) has none.
    """
    import shapely

    to_shapely = getattr(region, "to_shapely", None)
    if to_shapely is None or getattr(region, "kind", None) != "plan":  # the toolkit's other regions are convex
        return np.zeros((0, 2, 2))
    from meanfield.geometry.plan import polygon_rings

    polygon = to_shapely()
    hull = polygon.convex_hull.boundary
    tol = 1e-9 * max(polygon.length, 1.0)
    segs = []
    for ring in polygon_rings(polygon):  # (a hole's edges are never on the hull: tested as any)
        c = np.asarray(ring.coords)
        for a, b in zip(c[:-1], c[1:], strict=True):
            if hull.distance(shapely.Point(a)) < tol and hull.distance(shapely.Point(b)) < tol:
                mid = shapely.Point(0.5 * (a + b))
                if hull.distance(mid) < tol:
                    continue  # on the hull: hides nothing
            segs.append((a, b))
    return np.array(segs, float).reshape(-1, 2, 2)


class SightLines:
    """Who sees whom in a region: the segment between two points crosses no wall.

    Parameters
    ----------
    region : Region
        Ω; its sight-blocking walls are found once (:func:`blocking_walls`).
    """

    def __init__(self, region: Any):
        self.region = region
        self._grids: dict[int, _CellSight] = {}
        self.walls = blocking_walls(region)
        a = self.walls[:, 0]
        self._a = np.ascontiguousarray(a)
        self._e = np.ascontiguousarray(self.walls[:, 1] - a)

    @property
    def trivial(self) -> bool:
        """True when no wall can hide anything (a convex room): everything is visible."""
        return not len(self.walls)

    def visible(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Whether each segment ``start[k] → end[k]`` (arrays ``(..., 2)`` broadcast together) crosses no wall.

        A segment that only touches a wall at one of its ends (a human standing against it)
        is visible; one that passes through a wall's interior or one of its corners is not.
        """
        start, end = np.broadcast_arrays(np.asarray(start, float), np.asarray(end, float))
        shape = start.shape[:-1]
        if self.trivial:
            return np.ones(shape, dtype=bool)
        p = np.ascontiguousarray(start.reshape(-1, 2))
        q = np.ascontiguousarray(end.reshape(-1, 2))
        out = segments_clear(p, q, self._a, self._e, np.empty(len(p), dtype=bool))
        return out.reshape(shape)

    def visible_from(self, point: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Whether each segment ``point → ends[k]`` (``ends`` (M, 2)) crosses no wall: :meth:`visible` from one point.

        One compiled pass (:func:`meanfield.geometry._sight_loops.sight_row`: the nearest walls first).
        """
        ends = np.ascontiguousarray(ends, float).reshape(-1, 2)
        if self.trivial:
            return np.ones(len(ends), dtype=bool)
        point = np.ascontiguousarray(point, float).reshape(2)
        work = np.empty(len(self._a), np.intp), np.empty((len(self._a), 7))
        return sight_row(point, ends, self._a, self._e, *work, np.empty(len(ends), dtype=bool))

    def mask(self, robots: np.ndarray, points: np.ndarray, grid: Any = None) -> np.ndarray | None:
        """``s_i(x)``: shape ``(n, M)``, True where robot ``i`` sees point ``x`` (None: all visible).

        Exact segment tests without ``grid``; with it, decided between the grid's cells
        (the cell of the robot sees the cell of the point), as the grid's field is, at the
        cost of a table look-up per pair.
        """
        if self.trivial:
            return None
        robots = np.real(np.asarray(robots)).reshape(-1, 2)
        points = np.asarray(points, float).reshape(-1, 2)
        if grid is None:
            return self.visible(robots[:, None, :], points[None, :, :])
        cells = self._cells_of(grid)
        i, j = cells.index(points)
        return cells.rows(robots)[:, i, j]

    def face_masks(self, grid: Any, robots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which faces of ``grid`` each robot sees: shapes ``(n, nx-1, ny)`` and ``(n, nx, ny-1)``.

        Decided between the points of cells (module docstring); every face is seen in a
        room without sight-blocking walls.
        """
        robots = np.real(np.asarray(robots)).reshape(-1, 2)
        nx, ny = grid.shape
        if self.trivial:
            return np.ones((len(robots), nx - 1, ny), bool), np.ones((len(robots), nx, ny - 1), bool)
        cells = self._cells_of(grid)
        rows = cells.rows(robots)
        return rows[:, 1:, :] & rows[:, :-1, :], rows[:, :, 1:] & rows[:, :, :-1]

    def cell_rows(self, grid: Any, robots: np.ndarray) -> np.ndarray:
        """Which cells of ``grid`` each robot sees: bool, ``(n, nx, ny)`` (all, without sight-blocking walls)."""
        robots = np.real(np.asarray(robots)).reshape(-1, 2)
        if self.trivial:
            return np.ones((len(robots), *grid.shape), bool)
        return self._cells_of(grid).rows(robots)

    def _cells_of(self, grid: Any) -> _CellSight:
        cells = self._grids.get(id(grid))
        if cells is None or cells.grid is not grid:
            cells = self._grids[id(grid)] = _CellSight(grid, self)
        return cells


class _CellSight:
    """Which cells of a grid see each other (rows computed on demand and kept)."""

    def __init__(self, grid: Any, sight: SightLines):
        from scipy import ndimage

        self.grid = grid
        self.sight = sight
        X, Y = grid.centers
        points = np.stack([X, Y], axis=-1)
        inside = grid.domain.contains(X, Y)
        if not inside.all():  # a cut cell whose centre is in a wall: the nearest point of Ω
            points[~inside] = grid.domain.project(points[~inside].copy())
        self.points = points
        self.active = grid.active
        self._active_points = np.ascontiguousarray(points[grid.active])
        # a point in a cell without volume looks from the nearest cell that has some
        _, (ii, jj) = ndimage.distance_transform_edt(~grid.active, return_indices=True)
        self._ii, self._jj = np.ascontiguousarray(ii, np.intp), np.ascontiguousarray(jj, np.intp)
        self._table = np.zeros((8, *grid.shape), dtype=bool)  # the rows computed so far, in the order computed
        self._row_of = np.full(grid.shape, -1, dtype=np.intp)  # each cell's row in the table (-1: not yet)
        self._count = 0
        x0, _, y0, _ = grid.domain.bounds
        self._frame = (float(x0), float(y0), float(grid.dx), float(grid.dy))
        self._last = np.zeros((0, 2), dtype=np.intp), np.zeros((0, *grid.shape), dtype=bool)
        self._last_robots = b""  # the robots' positions (bytes) of the last answer of rows()

    def cells(self, points: np.ndarray) -> np.ndarray:
        """The cell (with volume) of each point, ``(M, 2)`` ints; a point outside the grid takes the nearest edge cell.

        One compiled pass (:func:`meanfield.geometry._sight_loops.cell_index`); a NaN point gets some cell, never read.
        """
        points = np.ascontiguousarray(points, float)
        return cell_index(points, *self._frame, self._ii, self._jj, np.empty((len(points), 2), np.intp))

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cell (with volume) of each point as ``(i, j)``: :meth:`cells`."""
        ij = self.cells(points)
        return ij[:, 0], ij[:, 1]

    def rows(self, robots: np.ndarray) -> np.ndarray:
        """The cells seen from the cell of each robot: bool, ``(n, nx, ny)`` (the last answer reused).

        Robots at the positions of the last call (the law, the coverage and the crowd ask within a
        step) get the last answer without a look-up; robots in the cells of the last call, too.
        """
        robots = np.ascontiguousarray(robots, float)
        key = robots.tobytes()
        if key == self._last_robots:
            return self._last[1]
        keys = self.cells(robots)
        last_keys, last_rows = self._last
        if not np.array_equal(keys, last_keys):
            ids = self._row_of[keys[:, 0], keys[:, 1]]
            for k in np.flatnonzero(ids < 0):  # cells no robot stood in before
                ids[k] = self._add((int(keys[k, 0]), int(keys[k, 1])))
            last_rows = self._table[ids]
            self._last = keys, last_rows
        self._last_robots = key
        return last_rows

    def _row(self, key: tuple[int, int]) -> np.ndarray:
        """The cells seen from the cell ``key`` (which has volume): bool, ``grid.shape``."""
        k = self._add(key)  # (which may grow the table)
        return self._table[k]

    def _add(self, key: tuple[int, int]) -> int:
        """The row of ``key`` in the table, computed and appended the first time."""
        k = int(self._row_of[key])
        if k >= 0:
            return k
        if self._count == len(self._table):  # grown by half (the rows of a large grid are large)
            more = np.zeros((max(8, len(self._table) // 2), *self._table.shape[1:]), dtype=bool)
            self._table = np.concatenate([self._table, more])
        k = self._count
        row = self._table[k]  # only the cells with volume can be seen
        row[self.active] = self.sight.visible_from(self.points[key], self._active_points)
        row[key] = True
        self._row_of[key] = k
        self._count += 1
        return k
