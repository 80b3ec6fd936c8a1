"""Routes the crowd shapes: the travel time to the exits at the crowd's speed (docs page *Congestion*, "Routes").

An informed person walks the route of least travel time, not the shortest one: where the crowd
is dense the diagram slows it (:mod:`meanfield.crowds.congestion`), and a route round the queue
may be faster.  The potential is Hughes' (R. L. Hughes, "A continuum theory for the flow of
pedestrians", Transp. Res. B 36 (2002) 507–535, with his discomfort factor 1)::

    |∇T_k| = 1/f̂(x),   T_k = 0 on exit k,   f̂ = max(v₀ g(ρ̄), f_min),            (R1)

``g`` the diagram, ``v₀`` the free speed, ``f_min`` = :data:`SPEED_FLOOR` ``· v₀``, solved by fast
marching (:class:`~meanfield.geometry.geodesic.ExitEikonal`).  The person walks ``v₀ e``,
``e = −∇T/|∇T|`` (:func:`route_velocity` on the grid's faces), and its
congestion model slows it.  Two ways to choose ``T``:

``keep_exit`` (the informed crowd, guidance ``fastest-route``)
    Each person keeps the exit nearest to where it started (the geodesic distance), or the one its
    group was given, and walks the fastest route to *that* exit: ``T_k`` of (R1) with the speed
    outside exit ``k``'s basin (the cells whose nearest exit is ``k``) put on the floor, so the
    route stays in the basin.  A crowd then spreads across its door instead of piling at the
    corners of the shortest route, and does not change exits because a queue formed (nobody
    knows the other door's queue from afar).
otherwise (Hughes' model, guidance ``hughes``)
    ``T = min_k T_k``: one march from every exit, so a person goes to the exit of least travel
    time, changing exits as the queues grow.

**The crowd's density in (R1).**  The agents' density is their count over the disk of radius ``r``
(``crowd.congestion_radius``, the radius of their own local density) round each cell centre, cut by Ω::

    ρ̄(c) = Σ_{c' : |x_c' − x_c| ≤ r} P(c') / Σ_{c' : |x_c' − x_c| ≤ r} |c' ∩ Ω|           (R2)

``P`` the agents in each cell (:meth:`CrowdRoutes.plan_for_agents`).  The density takes its own
cells, ``ρ̄ = N ρ`` (:meth:`CrowdRoutes.plan_for_density`): (R2) as ``r`` shrinks to the cell, the
mean-field limit of the agents' rule, whose radius can shrink as ``N`` grows.  The agents need the
disk (a person counts itself, ``1/(π r²)``, and a small disk reads one person alone beyond the jam); the
density needs its cells (smoothed, its route no longer sees the lanes of a corridor and steers the mass into
them).  Both are measured in the bottleneck on the docs page *Congestion*, "Routes".

The agents take the route's face field interpolated at their positions (the ``x`` component
bilinearly from the ``x``-faces, ``y`` from the ``y``-faces; a wall's face carries nothing),
normalised to ``v₀``: the density's drift at their point.  The routes are planned again at every
control period, at both scales: planned every 0.1 s or 0.2 s instead of every 0.05 s, the density's
bottleneck flow fell to 1.64 and 1.27 persons/(m·s) (``b`` = 1 m), the same lanes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry.grid import FaceField, Grid

__all__ = ["CrowdRoutes", "route_velocity", "disk_mean_density", "face_velocity_at", "SPEED_FLOOR"]

SPEED_FLOOR = 0.05
"""``f_min / v₀`` in (R1): crossing a jammed cell costs as long as crossing 20 free ones, so that ``T`` stays
finite behind a jam and a route prefers a detour of up to 20 cells to a jam (the evacuation controller's
Hughes potential takes the same floor, ``meanfield.controllers.evacuation.SPEED_FLOOR``)."""


def route_velocity(grid: Grid, phi: np.ndarray, speed: float) -> FaceField:
    """``speed · (−∇φ/|∇φ|)`` on the interior faces: walking the route down ``φ`` at ``speed``.

    On each face the normal component of ``∇φ`` is the difference of its two cells over their
    distance; the tangential one is the mean of the differences across the open faces of the
    same two cells in the other direction; the face gets ``−speed`` times the normal component
    over the length of the two.  So ``|a| <= speed`` on every face, with equality where the route
    crosses the face straight; a face that is closed (no aperture) or next to a cell without a
    finite ``φ`` carries nothing, and neither does a face where ``∇φ = 0``.

    Parameters
    ----------
    grid : Grid
    phi : ndarray
        The distance to the exits on the cells (:func:`~meanfield.geometry.geodesic.exit_distance`;
        ``inf`` outside Ω).
    speed : float
        The walking speed, > 0 (``crowd.free_speed``).

    Returns
    -------
    FaceField
        The normal velocities ``(ax, ay)`` on the x- and y-faces.
    """
    if not (math.isfinite(speed) and speed > 0):
        raise ParameterError("crowd.free_speed", speed, "a walking speed > 0")
    phi = np.asarray(phi, float)
    if phi.shape != grid.shape:
        raise ParameterError("phi", phi.shape, f"an array of grid.shape {grid.shape}")
    known = grid.active & np.isfinite(phi)
    f = np.where(known, phi, 0.0)
    open_x = known[1:, :] & known[:-1, :] & (grid.aperture_x > 0)
    open_y = known[:, 1:] & known[:, :-1] & (grid.aperture_y > 0)
    gx = np.where(open_x, (f[1:, :] - f[:-1, :]) / grid.dx, 0.0)
    gy = np.where(open_y, (f[:, 1:] - f[:, :-1]) / grid.dy, 0.0)
    nx, ny = grid.shape
    # the other component on each face: the mean over the open faces of its two cells in the other direction
    py, cy = np.zeros((nx, ny + 1)), np.zeros((nx, ny + 1))
    py[:, 1:-1], cy[:, 1:-1] = gy, open_y
    ty_sum = py[:-1, :-1] + py[:-1, 1:] + py[1:, :-1] + py[1:, 1:]
    ty_n = cy[:-1, :-1] + cy[:-1, 1:] + cy[1:, :-1] + cy[1:, 1:]
    ty = np.divide(ty_sum, ty_n, out=np.zeros_like(ty_sum), where=ty_n > 0)
    px, cx = np.zeros((nx + 1, ny)), np.zeros((nx + 1, ny))
    px[1:-1, :], cx[1:-1, :] = gx, open_x
    tx_sum = px[:-1, :-1] + px[1:, :-1] + px[:-1, 1:] + px[1:, 1:]
    tx_n = cx[:-1, :-1] + cx[1:, :-1] + cx[:-1, 1:] + cx[1:, 1:]
    tx = np.divide(tx_sum, tx_n, out=np.zeros_like(tx_sum), where=tx_n > 0)
    out = []
    for g, t, is_open in ((gx, ty, open_x), (gy, tx, open_y)):
        norm = np.hypot(g, t)
        out.append(np.divide(-speed * g, norm, out=np.zeros_like(g), where=is_open & (norm > 0)))
    return out[0], out[1]


def disk_mean_density(grid: Grid, persons: np.ndarray, radius: float) -> np.ndarray:
    """``ρ̄`` of (R2): the persons in the disk of ``radius`` round each cell centre over the disk's area in Ω.

    Parameters
    ----------
    grid : Grid
    persons : ndarray, shape grid.shape
        The persons in each cell (any mass; inactive cells must hold none).
    radius : float
        ``r > 0``, the length unit of the grid; the disk holds at least the cell itself.

    Returns
    -------
    ndarray
        persons per unit area on the active cells, 0 on the others.
    """
    from scipy import ndimage

    if not (math.isfinite(radius) and radius > 0):
        raise ParameterError("crowd.congestion_radius", radius, "a radius > 0")
    persons = np.asarray(persons, float)
    if persons.shape != grid.shape:
        raise ParameterError("persons", persons.shape, f"an array of grid.shape {grid.shape}")
    foot = _disk(grid, radius)
    count = ndimage.correlate(persons, foot, mode="constant", cval=0.0)
    area = ndimage.correlate(grid.volume, foot, mode="constant", cval=0.0)
    return np.divide(count, area, out=np.zeros(grid.shape), where=grid.active & (area > 0))


def _disk(grid: Grid, radius: float) -> np.ndarray:
    """The cells whose centres lie within ``radius`` of a cell's centre, as a footprint (odd by odd)."""
    mx, my = int(radius // grid.dx), int(radius // grid.dy)
    i, j = np.meshgrid(np.arange(-mx, mx + 1) * grid.dx, np.arange(-my, my + 1) * grid.dy, indexing="ij")
    return (np.hypot(i, j) <= radius * (1 + 1e-12)).astype(float)


def face_velocity_at(grid: Grid, velocity: FaceField, points: np.ndarray) -> np.ndarray:
    """A face field at ``points`` ``(N, 2)``: ``x`` bilinearly from the ``x``-faces, ``y`` from the ``y``-faces.

    The faces on the grid's edge carry 0 (walls); points outside the grid take the nearest edge's values.
    """
    ax, ay = velocity
    nx, ny = grid.shape
    x0, _, y0, _ = grid.domain.bounds
    u = np.zeros((nx + 1, ny))  # the x-faces, at x0 + i dx, y0 + (j + 1/2) dy
    u[1:-1] = ax
    v = np.zeros((nx, ny + 1))
    v[:, 1:-1] = ay
    sx = (points[:, 0] - x0) / grid.dx
    sy = (points[:, 1] - y0) / grid.dy
    return np.column_stack([_bilinear(u, sx, sy - 0.5), _bilinear(v, sx - 0.5, sy)])


def _bilinear(f: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``f`` at the fractional indices ``(s, t)``, clamped to its edges."""
    n, m = f.shape
    s = np.clip(s, 0.0, n - 1.0)
    t = np.clip(t, 0.0, m - 1.0)
    i = np.minimum(s.astype(np.intp), max(n - 2, 0))
    j = np.minimum(t.astype(np.intp), max(m - 2, 0))
    i1, j1 = np.minimum(i + 1, n - 1), np.minimum(j + 1, m - 1)
    fs, ft = s - i, t - j
    return (f[i, j] * (1 - fs) * (1 - ft) + f[i1, j] * fs * (1 - ft)
            + f[i, j1] * (1 - fs) * ft + f[i1, j1] * fs * ft)  # fmt: skip


class CrowdRoutes:
    """The routes of least travel time through the crowd, (R1) (module docstring).

    Parameters
    ----------
    grid : Grid
    segs : ndarray, shape (E, 2, 2)
        The exits (:func:`meanfield.geometry.exits.exit_segments`).
    diagram : FundamentalDiagram
        ``g`` and ``v₀`` (``free_speed``); one that does not slow (``"none"``) gives the geodesic routes,
        planned once.
    keep_exit : bool
        True: each person to its own exit (``fastest-route``); False: to the exit of least travel time
        (``hughes``).
    sight : SightLines, optional
        The walls that block a straight line (the exits' front; built from ``grid.domain`` when omitted).
    floor : float, default SPEED_FLOOR
        ``f_min / v₀`` in (0, 1].

    Attributes
    ----------
    basin : ndarray of int, shape grid.shape
        Each cell's nearest open exit by the geodesic distance (-1 off Ω and where no exit is reached).
    faces : dict of int to FaceField
        The route's drift ``v₀ e`` to each open exit (``keep_exit``), or one (key 0) to all, as last planned.
    speed_field : ndarray
        ``f̂`` on the cells, as last planned.
    """

    def __init__(self, grid: Grid, segs: np.ndarray, diagram: Any, keep_exit: bool, sight: Any = None,
                 floor: float = SPEED_FLOOR):  # fmt: skip
        if not (math.isfinite(floor) and 0 < floor <= 1):
            raise ParameterError("floor", floor, "a share of the free speed in (0, 1]")
        self.segs = np.asarray(segs, float).reshape(-1, 2, 2)
        if not len(self.segs):
            raise ParameterError("domain.exits", "none", "at least one exit for the routes")
        self.diagram, self.keep_exit = diagram, bool(keep_exit)
        self.free_speed = float(diagram.free_speed)
        self.floor = float(floor)
        self.open = np.ones(len(self.segs), dtype=bool)
        self._build(grid, sight)

    # ------------------------------------------------------------------------------------------ set-up

    def _build(self, grid: Grid, sight: Any) -> None:
        """The eikonal solvers and basins on ``grid`` for the open exits."""
        from meanfield.geometry.geodesic import ExitEikonal
        from meanfield.geometry.sight import SightLines

        self.grid = grid
        self.sight = SightLines(grid.domain) if sight is None else sight
        live = np.flatnonzero(self.open)
        if self.keep_exit:
            self._solvers = {int(k): ExitEikonal(grid, self.segs[k : k + 1], self.sight) for k in live}
            dist = np.stack([self._solvers[int(k)].distance for k in live])
            near = np.isfinite(dist).any(axis=0)
            self.basin = np.where(near & grid.active, live[np.argmin(dist, axis=0)], -1)
        else:
            self._all = ExitEikonal(grid, self.segs[live], self.sight)
            self.basin = np.where(np.isfinite(self._all.distance), 0, -1)
        self.faces: dict[int, FaceField] = {}
        self.speed_field = np.full(grid.shape, self.free_speed)

    def nearest_exit(self, points: np.ndarray) -> np.ndarray:
        """The open exit nearest to each point by the geodesic distance (its cell's basin; -1 where none)."""
        i, j = self.grid.cell_of(np.asarray(points, float))
        return self.basin[i, j]

    # ------------------------------------------------------------------------------------------ (R1), (R2)

    def speed(self, rho: np.ndarray) -> np.ndarray:
        """``f̂ = max(v₀ g(ρ̄), f_min)`` on the cells for the crowd's density ``ρ̄`` (persons per unit area;
        ``v₀`` off Ω)."""
        g = self.grid
        f = self.free_speed * np.asarray(self.diagram.speed_factor(np.where(g.active, rho, 0.0)), float)
        return np.where(g.active, np.maximum(f, self.floor * self.free_speed), self.free_speed)

    def travel_time(self, rho: np.ndarray, exit: int | None = None) -> np.ndarray:
        """``T`` of (R1) on the cells for the crowd's density ``ρ̄`` (persons per unit area): to ``exit`` alone
        (``keep_exit``; its route kept in its basin), or to the nearest of the open exits in time (``None``,
        without ``keep_exit``); ``inf`` off Ω."""
        if exit is None and self.keep_exit:
            raise ParameterError("exit", exit, f"one of the open exits {sorted(self._solvers)} (keep_exit)")
        if exit is not None and (not self.keep_exit or int(exit) not in self._solvers):
            raise ParameterError("exit", exit, "None (to the nearest exit in time)" if not self.keep_exit
                                 else f"one of the open exits {sorted(self._solvers)}")  # fmt: skip
        return self._travel_time(self._speed_of(rho), exit)

    def _speed_of(self, rho: np.ndarray) -> np.ndarray:
        return self.speed(rho) if self.diagram.slows else np.full(self.grid.shape, self.free_speed)

    def _travel_time(self, f: np.ndarray, exit: int | None) -> np.ndarray:
        """``T`` for the speed ``f`` on the cells: to all exits (None) or to ``exit`` in its basin."""
        if exit is None:
            return self._all.travel_time(f)
        k = int(exit)
        return self._solvers[k].travel_time(np.where(self.basin == k, f, self.floor * self.free_speed))

    def plan(self, rho: np.ndarray) -> None:
        """Plan the routes, (R1), for the crowd's density ``ρ̄`` on the cells (persons per unit area)."""
        if self.faces and not self.diagram.slows:
            return  # the geodesic routes, planned once
        f = self.speed_field = self._speed_of(rho)
        if not self.keep_exit:
            self.faces = {0: route_velocity(self.grid, self._travel_time(f, None), self.free_speed)}
        else:  # each exit's route, kept in its basin
            self.faces = {k: route_velocity(self.grid, self._travel_time(f, k), self.free_speed) for k in self._solvers}

    def plan_for_agents(self, positions: np.ndarray, here: np.ndarray | None, radius: float) -> None:
        """:meth:`plan` for agents: ``ρ̄`` of (R2), their count (those ``here``; None: everyone) over the disk of
        ``radius`` round each cell centre."""
        x = np.asarray(positions, float)
        if here is not None:
            x = x[here]
        if not self.diagram.slows:
            self.plan(np.zeros(self.grid.shape))
            return
        i, j = self.grid.cell_of(x)
        nx, ny = self.grid.shape
        persons = np.bincount(i * ny + j, minlength=nx * ny).reshape(nx, ny).astype(float)
        self.plan(disk_mean_density(self.grid, np.where(self.grid.active, persons, 0.0), radius))

    def plan_for_density(self, rho: np.ndarray, people: float) -> None:
        """:meth:`plan` for the density: ``ρ̄ = N ρ`` on its cells (``ρ`` of unit mass, ``N = people``)."""
        self.plan(people * np.maximum(np.asarray(rho, float), 0.0))

    # ------------------------------------------------------------------------------------------ the drifts

    def density_velocity(self) -> FaceField:
        """The density's drift on the interior faces: the route of each face's basin.

        A face between two basins (a ridge between exits, where the routes part) takes the route of the cell the
        flow leaves: the first cell's if it points into the second, the second's if it points into the first.
        """
        if not self.keep_exit:
            return self.faces[0]
        b = self.basin
        out = []
        for axis, (lo, hi) in enumerate(((b[:-1, :], b[1:, :]), (b[:, :-1], b[:, 1:]))):
            v = np.zeros(lo.shape)
            for k, f in self.faces.items():
                fk = f[axis]
                v = np.where((lo == k) & (hi == k), fk, v)
                v = np.where((lo == k) & (hi != k) & (fk > 0), fk, v)
                v = np.where((hi == k) & (lo != k) & (fk < 0), fk, v)
            out.append(v)
        return out[0], out[1]

    def headings(self, points: np.ndarray, exit_of: np.ndarray | None = None) -> np.ndarray:
        """Unit vectors ``(N, 2)``: the route at each point (to its exit ``exit_of[j]`` with ``keep_exit``; -1 or
        an exit no longer open: its cell's basin), 0 where no route leads."""
        points = np.asarray(points, float)
        out = np.zeros((len(points), 2))
        if not self.keep_exit:
            w = face_velocity_at(self.grid, self.faces[0], points)
        else:
            k = self.nearest_exit(points)
            if exit_of is not None and len(exit_of):  # their own exit, where its route reaches them
                mine = np.asarray(exit_of, np.intp)
                mine = np.where((mine >= 0) & self.open[np.maximum(mine, 0)], mine, -1)
                i, j = self.grid.cell_of(points)
                for e in np.unique(mine[mine >= 0]):
                    rows = np.flatnonzero(mine == e)
                    k[rows[np.isfinite(self._solvers[int(e)].distance[i[rows], j[rows]])]] = e
            w = np.zeros((len(points), 2))
            for e in np.unique(k[k >= 0]):
                rows = np.flatnonzero(k == e)
                w[rows] = face_velocity_at(self.grid, self.faces[int(e)], points[rows])
        norm = np.hypot(w[:, 0], w[:, 1])
        np.divide(w, norm[:, None], out=out, where=norm[:, None] > 1e-12 * self.free_speed)
        return out

    # ------------------------------------------------------------------------------------------ events

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Plan to the exits with ``open_exits[k]`` from now on (a scenario's ``[[events]]``; none left: unchanged).
        Those who kept a closed exit walk to their cell's nearest open one (:meth:`headings`)."""
        open_exits = np.asarray(open_exits, dtype=bool)
        if open_exits.any() and not np.array_equal(open_exits, self.open):
            self.open = open_exits.copy()
            self._build(self.grid, self.sight)

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event): the solvers and basins again on the new grid."""
        self._build(change.grid, change.sight)
