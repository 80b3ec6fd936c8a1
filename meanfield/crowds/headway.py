"""The headway door model: each human walks at the diagram's speed for the spacing to the person ahead in its lane.

A human ``j`` walking along ``e_j`` whose nearest person ahead in its lane is ``s_j`` away (its headway,
:func:`~meanfield.crowds._headway_loops.headways`) walks at the fraction of ``v₀`` that the fundamental diagram
gives a crowd packed hexagonally at that spacing (docs page *Congestion*, "The headway door model")::

    f_j = g(ρ(s_j)),   ρ(s) = 2 / (√3 s²) = ρ_max (d/s)²,   d = sqrt(2 / (√3 ρ_max))                 (H1)

so that in an even crowd at density ρ each human walks at ``v₀ g(ρ)``, the diagram the density obeys, and
nobody walks on when the person ahead is at the jam spacing ``d`` (0.46 m at 5.4 persons/m²).  The lane is
``d`` wide on either side of the line of walk: two bodies of diameter ``d`` collide if their centres are less
than ``d`` apart across it.  This is the follow-the-leader law of Lighthill–Whitham–Richards traffic (speed
from the gap ahead), whose many-vehicle limit is the conservation law with the diagram's flux
(M. Di Francesco, M. D. Rosini, "Rigorous derivation of nonlinear scalar conservation laws from
follow-the-leader type models via many particle limit", Arch. Ration. Mech. Anal. 217 (2015) 831–871), and
the speed rule of the collision-free speed model (A. Tordeux, M. Chraibi, A. Seyfried, "Collision-free speed
model for pedestrian dynamics", Traffic and Granular Flow '15, Springer 2016, 225–232), there with the
diagram's speed instead of a time gap.  The head of a queue, with nobody ahead, walks at ``v₀``, and a queue
discharges by the speeds of the gaps that open in it, as in the conservation law: nobody waits for a count of
those behind it to fall.

(H1) alone reads a disordered crowd as denser than a hexagonal one at the same density: the nearest person in a
lane of random neighbours is nearer than the hexagonal spacing, and an even crowd placed at random walks well
under the diagram (docs page *Congestion*, "The walk's direction", measures it).  So each human also chooses its
line of walk:

* (H4) among the directions :data:`TURNS` off its route's (every 15° up to 45° on either side), each walks the
  one along which it makes most progress on its route, ``g(ρ(s_θ)) cos θ``, ``s_θ`` its headway along ``θ``; a
  wall less than :data:`HEADWAY_REACH` ahead along a turned direction counts as a person ``d/2`` beyond it (a
  body's centre stops ``d/2`` short of a wall, ``d`` short of another's centre).  Ties go to the smallest turn,
  the route's own direction first.  The route's own direction is the route's: it is never turned off a wall.

In a hexagonal crowd with spacing at most ``2d`` every lane holds a neighbour at the spacing (each direction lies
within 30° of one of the six), so no turn makes more progress and (H1)'s diagram stands; in a disordered crowd
people step into the gaps, as the heuristic walkers of M. Moussaïd, D. Helbing and G. Theraulaz ("How simple
rules determine pedestrian behavior and crowd disasters", PNAS 108 (2011) 6884–6888) choose the direction of
least obstruction within their field of view.

The excluded volume is a velocity, never a displacement (:func:`~meanfield.crowds._contact_loops.contact_cone`):

* (H2) each human's walk is projected onto the velocities that do not approach anyone it touches (closer than
  ``d``): it slides past a neighbour instead of walking into it, and pushes nobody on;
* (H3) a soft core: two people closer than ``d`` step apart at up to the free speed ``v₀`` (at the same point),
  ``u (1 − r/d)`` each, so that the overlaps the noise makes are undone at a walker's pace.

* (H5) the noise among contacts: a human's diffusion is ``σ φ_j``, each contact at ``r < d`` scaling it by
  ``(r/d)^m``, and its drift gains ``σ ∇_j φ_j`` (:func:`~meanfield.crowds._contact_loops.contact_noise`), so that
  the noise is ``∇·(σ φ ∇p)`` and not Itô's ``Δ(σ φ p)``, which would pile people into their contacts.  A touching
  pair's overlap is no longer the Ornstein–Uhlenbeck pair's ``√(σ d/u)``, which packed the queues beyond
  ``1.25 ρ_max`` at σ = 0.1 m²/s; at the jam spacing and beyond nobody's noise changes, so no queue is frozen.

(H2), (H3) and (H5) do not depend on the step, so the model has a limit as ``dt → 0``.  A contact
that moves people by their overlap over the step (the twin's push, or a projection of the positions) reflects
the noise, and turns σ into a pressure that drives people through the doors, more the finer the step (docs
page *Congestion*, "The headway door model", where the three are measured against the step).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.crowds._cell_list import cell_list
from meanfield.crowds._contact_loops import CONTACT_NOISE_POWER, contact_cone, contact_noise
from meanfield.crowds._headway_loops import (
    NO_COUNT,
    NO_WALLS,
    HeadwayWork,
    LaneWalls,
    choose_lanes,
    headway_step,
    lane_headways,
)
from meanfield.crowds.congestion import FundamentalDiagram, Linear
from meanfield.crowds.local_density import SHARE_FLOOR, LocalDensity

__all__ = ["Headway", "HEADWAY_REACH", "TURNS", "boundary_walls"]

HEADWAY_REACH = 3.0
"""m: nobody farther ahead slows a human (the diagram's speed at the density of that spacing, 0.13 persons/m²
at 5.4 persons/m² jam, is within 2.5 % of ``v₀`` for the linear diagram), and no wall farther along a turned
direction (H4)."""

TURNS: tuple[float, ...] = tuple(math.radians(a) for a in (0.0, -15.0, 15.0, -30.0, 30.0, -45.0, 45.0))
"""rad: the directions (H4) weighs, off the route's, in the order ties are settled (the route's own first)."""


def boundary_walls(region: Any) -> Any:
    """A :class:`~meanfield.geometry.walls.WallIndex` over every edge of ``region``'s outline and holes (None for a
    region without :meth:`~meanfield.geometry.region.Region.to_shapely`)."""
    to_shapely = getattr(region, "to_shapely", None)
    if to_shapely is None:
        return None
    from meanfield.geometry.plan import polygon_rings
    from meanfield.geometry.walls import WallIndex

    polygon = to_shapely()
    rings = [np.asarray(ring.coords, float) for ring in polygon_rings(polygon)]
    x0, y0, x1, y1 = polygon.bounds
    return WallIndex(np.vstack([c[:-1] for c in rings]), np.vstack([np.diff(c, axis=0) for c in rings]),
                     (x0, x1, y0, y1))  # fmt: skip


class Headway:
    """The headway door model, (H1) to (H4).

    Parameters
    ----------
    diagram : FundamentalDiagram
        A diagram that slows (finite ``rho_max``).
    reach : float
        ``R``, m: the farthest person ahead that counts (:data:`HEADWAY_REACH`).
    separation : float, optional
        ``u`` of (H3), m/s (default: the diagram's free speed ``v₀``).
    region : Region, optional
        Ω, whose walls (H4) keeps the turned directions off (None: no walls).
    turns : tuple of float, optional
        (H4)'s directions off the route's, rad (default :data:`TURNS`; ``(0.0,)``: (H1) to (H3) alone).
    contact_power : float, optional
        ``m`` of (H5), each contact at ``r < d`` scaling one's noise by ``(r/d)^m``
        (:func:`~meanfield.crowds._contact_loops.contact_noise`; default
        :data:`~meanfield.crowds._contact_loops.CONTACT_NOISE_POWER`; 0: the noise unchanged).

    Attributes
    ----------
    noise_factor, noise_gradient : ndarray, shape (N,) and (N, 2), or None
        (H5) at the last :meth:`slow_down`'s positions: ``φ_j`` and ``∇_j φ_j`` (None with ``contact_power = 0``).
        The crowd scales its noise by ``φ`` and adds ``σ ∇φ`` to the drift (docs page *Congestion*, "The headway
        door model").
    """

    caps_doors = True
    """Each exit and each inner door of the plan passes at most ``q_max`` per metre of its width, as the density's
    faces do (docs page *Congestion*, "The exits' capacity" and "The doors' capacity"): without it, people
    converging on a door in a wall from a half circle find nobody ahead in their lanes and pass it at 3.4–4.2
    persons/s per metre (``rimea-9``)."""

    def __init__(
        self, diagram: FundamentalDiagram, reach: float = HEADWAY_REACH, separation: float | None = None,
        region: Any = None, turns: tuple[float, ...] = TURNS, contact_power: float = CONTACT_NOISE_POWER,
    ) -> None:  # fmt: skip
        self.diagram = diagram
        self.separation = float(diagram.free_speed if separation is None else separation)
        self.rho_max = float(diagram.rho_max)
        self.jam_spacing = math.sqrt(2.0 / (math.sqrt(3.0) * self.rho_max))
        self.lane = self.jam_spacing
        self.reach = float(reach)
        self.turns = tuple(float(t) for t in turns)
        if not self.turns or self.turns[0] != 0.0:
            raise ValueError(f"turns must start with the route's own direction 0.0, got {turns!r}")
        self._cos = np.array([math.cos(a) for a in self.turns])
        self._sin = np.array([math.sin(a) for a in self.turns])
        self._set_walls(region)
        self._headway = np.empty(0)
        self._density = np.empty(0)
        self._fused = type(diagram) is Linear  # (H1) to (H4) in one compiled pass (headway_step)
        self._work: HeadwayWork | None = None
        self._count: tuple | None = None  # (the count, what headway_step takes of it)
        self.contact_power = float(contact_power)
        self.noise_factor: np.ndarray | None = None
        self.noise_gradient: np.ndarray | None = None

    def density(self, headway: np.ndarray) -> np.ndarray:
        """``ρ(s) = ρ_max (d/s)²``, persons/m², of a hexagonal crowd at spacing ``s`` (0 for ``s = inf``)."""
        s = np.asarray(headway, float)
        with np.errstate(divide="ignore"):
            return self.rho_max * (self.jam_spacing / s) ** 2

    def speed_factor(self, headway: np.ndarray) -> np.ndarray:
        """``f = g(ρ(s))`` of (H1), in [0, 1]."""
        return np.asarray(self.diagram.speed_factor(self.density(headway)), float)

    def choose_direction(
        self, positions: np.ndarray, e: np.ndarray, active: np.ndarray, cells: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(H4) with (H1): each human's headway, speed factor and unit line of walk, the turn of :attr:`turns` off
        its route's direction ``e`` (unit, or 0 for one standing) along which ``f cos θ`` is largest.

        A wall along a turned direction ``θ`` less than :attr:`reach` away, at ``w``, makes the headway there
        ``min(s_θ, w + d/2)``; every edge of Ω's outline is a wall here, its exits too (the route's own direction,
        which is never turned off a wall, is the one that leads through them).

        One compiled pass finds every human's headway along all the turns at once and casts the turned lanes' rays
        at the walls (:func:`~meanfield.crowds._headway_loops.lane_headways`, each human's neighbours walked once),
        and a second picks the turn (:func:`~meanfield.crowds._headway_loops.choose_lanes`); between them the
        diagram's ``g`` of every lane, in numpy.  The numbers are those of one
        :func:`~meanfield.crowds._headway_loops.headways` per turn and one
        :meth:`~meanfield.geometry.walls.WallIndex.first_hit` for all the turned rays, to the last bit, on any
        number of threads (docs page *Congestion*, "The headway door model").

        Parameters
        ----------
        positions, e : ndarray, shape (N, 2)
        active : ndarray of bool, shape (N,)
        cells : CellList
            The active humans in cells (:func:`~meanfield.crowds._cell_list.cell_list`).

        Returns
        -------
        s, f : ndarray, shape (N,)
            The chosen turn's headway (m) and speed factor.
        walk : ndarray, shape (N, 2)
            The chosen turn's unit direction (0 for one standing).
        """
        n, k = len(positions), len(self.turns)
        if self._headway.shape != (n, k):
            self._headway = np.empty((n, k))
        s = lane_headways(positions, e, active, self._cos, self._sin, self.lane, self.reach, cells, self._headway,
                          self._lane_walls, 0.5 * self.jam_spacing)  # fmt: skip
        rho = self._density
        if rho.shape != s.shape:
            rho = self._density = np.empty_like(s)
        with np.errstate(divide="ignore"):  # (H1)'s density of every lane, in place: density()'s numbers
            np.divide(self.jam_spacing, s, out=rho)
        np.square(rho, out=rho)
        rho *= self.rho_max
        f = np.asarray(self.diagram.speed_factor(rho), float)
        best_s, best_f, walk = np.empty(n), np.empty(n), np.empty((n, 2))
        choose_lanes(f, s, e, self._cos, self._sin, best_s, best_f, walk)
        return best_s, best_f, walk

    def slow_down(self, velocity: np.ndarray, positions: np.ndarray, active: np.ndarray | None, dt: float = 0.0,
                  density: Any = None) -> np.ndarray:  # fmt: skip
        """(H4), (H1), (H2) and (H3), in place on ``velocity`` (m/s, the walk before congestion), and (H5)'s
        :attr:`noise_factor` and :attr:`noise_gradient`; returns the local density to report: ``density``'s count (a
        :class:`~meanfield.crowds.local_density.LocalDensity`), or, without one, the density (H1) reads from each
        headway.  ``dt`` is not used: nothing here depends on the step.

        Parameters
        ----------
        velocity : ndarray, shape (N, 2)
            Each human's walk; its direction is the line of walk (0: standing).
        positions : ndarray, shape (N, 2)
        active : ndarray of bool, shape (N,), or None
            Who is still here (None: everyone).
        """
        n = len(positions)
        if active is None:
            active = np.ones(n, dtype=bool)
        if self._fused and (density is None or (type(density) is LocalDensity and density.n == n)):
            return self._one_pass(velocity, positions, active, density)
        e = velocity.copy()
        norm = np.hypot(e[:, 0], e[:, 1])
        np.divide(e, norm[:, None], out=e, where=norm[:, None] > 0)
        e[norm == 0] = 0.0
        cells = cell_list(positions, active, self.jam_spacing)
        s, f, e = self.choose_direction(positions, e, active, cells)
        velocity[:] = (norm * f)[:, None] * e
        contact_cone(velocity, positions, active, self.jam_spacing, self.separation, cells)
        self._contact_noise(positions, active, cells)
        return self.density(s) if density is None else density(positions, active)

    def _set_walls(self, region: Any) -> None:
        """The walls (H4) keeps the turned lanes off: ``region``'s (None: none)."""
        self.walls = boundary_walls(region) if len(self.turns) > 1 else None
        w = self.walls
        self._lane_walls = NO_WALLS if w is None else LaneWalls(
            w.a, w.e, (w.origin[0], w.origin[0] + w.shape[0] * w.size, w.origin[1], w.origin[1] + w.shape[1] * w.size),
            self.reach)  # fmt: skip

    def walls_changed(self, change: Any) -> None:
        """Ω is ``change.region`` from now on (a ``block`` event): (H4)'s lanes stop at its walls, the new ones
        too (:class:`~meanfield.geometry.blocking.WallsChange`)."""
        self._set_walls(change.region)

    def _contact_noise(self, positions: np.ndarray, active: np.ndarray, cells: Any) -> None:
        """(H5): each one's share of the noise among its contacts, :attr:`noise_factor`, and its gradient,
        :attr:`noise_gradient` (nothing with ``contact_power = 0``); ``cells`` the active humans in cells."""
        noise = self._noise_arrays(len(positions))
        if noise is not None:
            contact_noise(positions, active, self.jam_spacing, cells, *noise, self.contact_power)

    def _noise_arrays(self, n: int) -> tuple[np.ndarray, np.ndarray] | None:
        """:attr:`noise_factor` and :attr:`noise_gradient` for ``n`` humans, allocated once (None without (H5))."""
        if not self.contact_power:
            return None
        if self.noise_factor is None or len(self.noise_factor) != n:
            self.noise_factor, self.noise_gradient = np.empty(n), np.empty((n, 2))
        return self.noise_factor, self.noise_gradient

    def _one_pass(self, velocity: np.ndarray, positions: np.ndarray, active: np.ndarray,
                  density: LocalDensity | None) -> np.ndarray:  # fmt: skip
        """:meth:`slow_down` with the linear diagram, in one compiled pass
        (:func:`~meanfield.crowds._headway_loops.headway_step`, the same numbers), its work arrays kept between
        steps."""
        n = len(positions)
        if self._work is None or self._work.n != n:
            self._work = HeadwayWork(n)
        x = np.ascontiguousarray(positions, dtype=float)
        here = np.ascontiguousarray(active, dtype=bool)
        v = velocity if velocity.dtype == np.float64 and velocity.flags.c_contiguous else np.array(velocity, float)
        rho = None if density is None else np.empty(n)
        s = headway_step(v, x, here, self._cos, self._sin, self.lane, self.reach, 0.5 * self.jam_spacing,
                         self._lane_walls, self.jam_spacing, self.separation, self.rho_max, self._work,
                         NO_COUNT if density is None else self._count_of(density), rho, self._noise_arrays(n),
                         self.contact_power)  # fmt: skip
        if v is not velocity:
            velocity[:] = v
        return self.density(s) if rho is None else rho

    def _count_of(self, density: LocalDensity) -> tuple:
        """What :func:`~meanfield.crowds._headway_loops.headway_step` takes of the count ``density`` (kept)."""
        if self._count is None or self._count[0] is not density:
            share = density.share
            table, (x0, y0), spacing = (NO_COUNT[2], (0.0, 0.0), 1.0) if share is None else (
                share.table, share.origin, share.spacing)  # fmt: skip
            clipped = share is not None
            args = (density.radius, density.inv_area, table, float(x0), float(y0), float(spacing), SHARE_FLOOR, clipped)
            self._count = (density, args)
        return self._count[1]
