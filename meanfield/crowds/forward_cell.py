"""The forward-cell door model: each human walks at the diagram's speed for the density of the room ahead of it.

The headway model (:mod:`meanfield.crowds.headway`) reads the density from the spacing to the person ahead as a
hexagonal crowd would have it, ``ρ_max (d/s)²``; a crowd whose lanes keep their lateral spacing while their
headways grow (a jam opening in a corridor) is not hexagonal, and its capacity then depends on the corridor's
width and the noise (docs page *Congestion*, "The model's own capacity: a jam let go": 1.54–2.21 persons/(m·s)
against the diagram's 1.81).  This model reads the density from the room each human has ahead of it instead::

    f_jq = g(ρ_jq),   ρ_jq = (1/2 + n_jq) / (A_jq + Σ_{k ∈ N_jq} |V_k|),   A_jq = |V_j ∩ H_jq|           (C1)

``V_j`` is the part of the human's Voronoi cell (the points nearer it than anyone else, within the square of
half-side :data:`CELL_REACH`) that it sees past the walls, ``H_jq`` the half-plane ahead of it along the turn
``q`` of its route's direction, ``N_jq`` its Voronoi neighbours ahead along that turn that it sees, ``n_jq`` their
number (:func:`~meanfield.crowds._forward_cell_loops.forward_densities`).  The cells tile the plane, so (C1) is
a count of people over an area, the density the crowd has there whatever its structure:

* in a lattice (hexagonal, square, or stretched) every cell has the same area ``1/ρ``, and one's own is
  centrally symmetric, so any line through its centre halves it: ``ρ``, along every direction;
* in lanes with headway ``s`` and lateral spacing ``ℓ``: ``ρ = 1/(s ℓ)``, the follow-the-leader rule of
  Lighthill–Whitham–Richards traffic in each lane (M. Di Francesco, M. D. Rosini, Arch. Ration. Mech. Anal. 217
  (2015) 831–871), whose many-vehicle limit is the conservation law with the diagram's flux;
* the head of a queue, with nobody ahead, has the whole square's half ahead of it and walks at the free speed
  (``ρ = 1/(4 R²)``, 0.028 persons/m² at ``R`` = 3 m); the exits do not cut the cells, so the people at a door
  are not slowed by it, and the exits and inner doors pass at most ``q_max`` per metre (:attr:`caps_doors`), as the
  density's faces do.

One's own cell ahead alone, ``1/(2 A_jq)``, is as right in a lattice, but in a disordered crowd ``1/A`` is biased
(a crowd placed at random at 2.5 persons/m² reads 4.3 on average, and walks at 0.41 of ``v₀`` where the diagram
says 0.54); pooled with the neighbours' cells ahead it reads 2.8 (docs page *Congestion*, "The forward-cell door
model", where both are measured).

The Voronoi cell is the density estimate of pedestrian science (B. Steffen, A. Seyfried, "Methods for measuring
pedestrian density, flow, speed and direction with minimal scatter", Physica A 389 (2010) 1902–1910), which
PedPy measures with; taking its half ahead makes it the downwind density that a Lagrangian (follow-the-leader)
discretisation of the conservation law needs.  Every human then chooses its turn as the headway model's (H4)
does, by ``f_jq cos θ_q``, and the contacts are (H2'), (H3) (the soft core) and (H5) (the noise among contacts).
(H2') is the headway model's cone (H2) made relative: a human's walk is the nearest that approaches nobody it
touches faster than that one walks away (:func:`~meanfield.crowds._contact_loops.following_cone`).  (H2) itself
stopped a human whose leader, touching, walked away, and so took 15 % of the walk in a jam let go at σ = 0.1
m²/s; without any cone a single file in the open, whose cells reach sideways to the square's edge, would walk
into a person standing at its head (docs page *Congestion*, "The forward-cell door model", where the choices
are measured).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.crowds._cell_list import cell_list
from meanfield.crowds._contact_loops import following_cone
from meanfield.crowds._forward_cell_loops import CellWork, forward_densities
from meanfield.crowds._headway_loops import choose_lanes
from meanfield.crowds.congestion import FundamentalDiagram
from meanfield.crowds.headway import HEADWAY_REACH, TURNS, Headway

__all__ = ["ForwardCell", "CELL_REACH", "wall_segments"]

CELL_REACH = HEADWAY_REACH
"""m: the half-side of the square that bounds each human's cell (a human alone reads ``1/(4 R²)``, 0.028
persons/m² at 3 m, and walks within 0.6 % of ``v₀`` on the linear diagram)."""


def wall_segments(region: Any) -> tuple[np.ndarray, np.ndarray]:
    """The walls of ``region``'s boundary, its exits left out, each oriented with Ω on its left: their starts and
    vectors, shape (W, 2) each (none for a region without
    :meth:`~meanfield.geometry.region.Region.boundary_parts`).

    A wall's side is read once, by whether Ω holds the point a ten-thousandth of the wall's length to the left of
    its midpoint."""
    parts = getattr(region, "boundary_parts", None)
    lines = [np.asarray(p.points, float) for p in (parts() if parts else ()) if p.kind == "wall"]
    lines = [pts for pts in lines if len(pts) > 1]
    if not lines:
        return np.empty((0, 2)), np.empty((0, 2))
    a = np.vstack([pts[:-1] for pts in lines])
    v = np.vstack([np.diff(pts, axis=0) for pts in lines])
    keep = np.hypot(v[:, 0], v[:, 1]) > 0.0
    a, v = a[keep], v[keep]
    probe = a + 0.5 * v + 1e-4 * np.column_stack([-v[:, 1], v[:, 0]])
    flip = ~np.asarray(region.contains(probe[:, 0], probe[:, 1]), bool)
    a[flip] += v[flip]
    v[flip] *= -1.0
    return np.ascontiguousarray(a), np.ascontiguousarray(v)


class ForwardCell(Headway):
    """The forward-cell door model: (C1), (H4)'s choice of turn, (H2'), (H3) and (H5) (module docstring).

    Parameters
    ----------
    diagram : FundamentalDiagram
        A diagram that slows (finite ``rho_max``).
    region : Region, optional
        Ω, whose walls cut the cells (None: no walls).
    reach : float, optional
        ``R``, m: the half-side of the square that bounds each cell (:data:`CELL_REACH`).
    separation : float, optional
        ``u`` of (H3), m/s (default: the diagram's free speed ``v₀``).
    turns : tuple of float, optional
        (H4)'s directions off the route's, rad (default :data:`~meanfield.crowds.headway.TURNS`).
    contact_power : float, optional
        ``m`` of (H5) (default :data:`~meanfield.crowds._contact_loops.CONTACT_NOISE_POWER`).
    """

    def __init__(
        self, diagram: FundamentalDiagram, region: Any = None, reach: float = CELL_REACH,
        separation: float | None = None, turns: tuple[float, ...] = TURNS, contact_power: float | None = None,
    ) -> None:  # fmt: skip
        if not (np.isfinite(reach) and reach > 0.0):
            raise ValueError(f"ForwardCell's reach must be a finite length > 0 m, got {reach!r}")
        extra = {} if contact_power is None else {"contact_power": contact_power}
        super().__init__(diagram, reach=reach, separation=separation, region=region, turns=turns, **extra)
        self._fused = False
        self._rho = np.empty((0, 0))
        self._work: CellWork | None = None  # the cell pass's arrays, kept between steps

    def _set_walls(self, region: Any) -> None:
        """``region``'s walls cut the cells (at the start, and after a ``block`` event: the headway's
        ``walls_changed``); the headway's lanes, which the cells replace, keep none."""
        super()._set_walls(None)
        self.wall_starts, self.wall_vectors = wall_segments(region)

    def choose_direction(
        self, positions: np.ndarray, e: np.ndarray, active: np.ndarray, cells: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(C1) and (H4): each human's forward cell along every turn, and the turn of most progress ``f cos θ``.

        Parameters
        ----------
        positions, e : ndarray, shape (N, 2)
            Positions (m) and the routes' unit directions (0 for one standing).
        active : ndarray of bool, shape (N,)
        cells : CellList
            The active humans in cells (:func:`~meanfield.crowds._cell_list.cell_list`).

        Returns
        -------
        rho, f : ndarray, shape (N,)
            The chosen turn's density (persons/m²) and speed factor.
        walk : ndarray, shape (N, 2)
            The chosen turn's unit direction (0 for one standing).
        """
        n, k = len(positions), len(self.turns)
        if self._rho.shape != (n, k):
            self._rho = np.empty((n, k))
            self._work = CellWork(n, k)
        x = np.ascontiguousarray(positions, dtype=float)
        rho = forward_densities(x, np.ascontiguousarray(e, dtype=float), np.ascontiguousarray(active, dtype=bool),
                                self._cos, self._sin, self.reach, self.wall_starts, self.wall_vectors, cells,
                                self._rho, self._work)  # fmt: skip
        f = np.asarray(self.diagram.speed_factor(rho), float)
        best_rho, best_f, walk = np.empty(n), np.empty(n), np.empty((n, 2))
        choose_lanes(f, rho, e, self._cos, self._sin, best_rho, best_f, walk)
        return best_rho, best_f, walk

    def slow_down(self, velocity: np.ndarray, positions: np.ndarray, active: np.ndarray | None, dt: float = 0.0,
                  density: Any = None) -> np.ndarray:  # fmt: skip
        """(C1), (H4), (H2'), (H3) and (H5)'s :attr:`noise_factor` and :attr:`noise_gradient`, in place on ``velocity``
        (m/s, the walk before congestion); returns the local density to report: ``density``'s count (a
        :class:`~meanfield.crowds.local_density.LocalDensity`), or, without one, the density of each human's
        chosen forward cell.  ``dt`` is not used: nothing here depends on the step.
        """
        n = len(positions)
        if active is None:
            active = np.ones(n, dtype=bool)
        e = velocity.copy()
        norm = np.hypot(e[:, 0], e[:, 1])
        np.divide(e, norm[:, None], out=e, where=norm[:, None] > 0)
        e[norm == 0] = 0.0
        x = np.ascontiguousarray(positions, dtype=float)
        cells = cell_list(x, active, self.jam_spacing)
        rho, f, walk = self.choose_direction(x, e, active, cells)
        walk = np.ascontiguousarray((norm * f)[:, None] * walk)
        v = np.empty_like(walk)
        following_cone(v, walk, x, active, self.jam_spacing, self.separation, cells, self._noise_arrays(n),
                       self.contact_power)  # fmt: skip
        velocity[:] = v
        return np.where(active, rho, 0.0) if density is None else density(positions, active)
