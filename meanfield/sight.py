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
they are dropped once, and a convex room (every :class:`~meanfield.domain.Domain`) has no
sight-blocking wall at all: :class:`SightLines` then answers "visible" without a test.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.plan_loops import segments_clear

__all__ = ["SightLines", "blocking_walls"]


def blocking_walls(region: Any) -> np.ndarray:
    """The wall segments ``(W, 2, 2)`` of ``region`` that can hide one point of it from another.

    Every edge of the outline and of the holes, except the outline's edges on its convex hull.
    A region without :meth:`~meanfield.region.Region.to_shapely` (a stand-in) has none.
    """
    import shapely

    to_shapely = getattr(region, "to_shapely", None)
    if to_shapely is None or getattr(region, "kind", None) != "plan":  # the toolkit's other regions are convex
        return np.zeros((0, 2, 2))
    polygon = to_shapely()
    hull = polygon.convex_hull.boundary
    tol = 1e-9 * max(polygon.length, 1.0)
    segs = []
    for k, ring in enumerate([polygon.exterior, *polygon.interiors]):
        c = np.asarray(ring.coords)
        for a, b in zip(c[:-1], c[1:], strict=True):
            if k == 0 and hull.distance(shapely.Point(a)) < tol and hull.distance(shapely.Point(b)) < tol:
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
        # a point in a cell without volume looks from the nearest cell that has some
        _, (self._ii, self._jj) = ndimage.distance_transform_edt(~grid.active, return_indices=True)
        self._rows: dict[tuple[int, int], np.ndarray] = {}
        x0, _, y0, _ = grid.domain.bounds
        self._origin = np.array([x0, y0])
        self._size = np.array([grid.dx, grid.dy])
        self._last = np.zeros((0, 2), dtype=np.intp), np.zeros((0, *grid.shape), dtype=bool)

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cell (with volume) of each point; a point outside the grid takes the nearest edge cell."""
        ij = ((points - self._origin) / self._size).astype(np.intp)  # NaN rows: some cell, never read
        i = np.clip(ij[:, 0], 0, self.grid.cells[0] - 1)
        j = np.clip(ij[:, 1], 0, self.grid.cells[1] - 1)
        return self._ii[i, j], self._jj[i, j]

    def rows(self, robots: np.ndarray) -> np.ndarray:
        """The cells seen from the cell of each robot: bool, ``(n, nx, ny)`` (the last answer reused)."""
        i, j = self.index(robots)
        keys = np.column_stack([i, j])
        last_keys, last_rows = self._last
        if np.array_equal(keys, last_keys):
            return last_rows
        out = np.stack([self._row((int(a), int(b))) for a, b in keys])
        self._last = keys, out
        return out

    def _row(self, key: tuple[int, int]) -> np.ndarray:
        row = self._rows.get(key)
        if row is None:
            row = self.sight.visible(self.points[key], self.points) & self.active
            row[key] = True
            self._rows[key] = row
        return row
