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

The excluded volume is a velocity, never a displacement (:func:`~meanfield.crowds._headway_loops.contact_cone`):

* (H2) each human's walk is projected onto the velocities that do not approach anyone it touches (closer than
  ``d``): it slides past a neighbour instead of walking into it, and pushes nobody on;
* (H3) a soft core: two people closer than ``d`` step apart at up to the free speed ``v₀`` (at the same point),
  ``u (1 − r/d)`` each, so that the overlaps the noise makes are undone at a walker's pace.

Both are drifts of the SDE that do not depend on the step, so the model has a limit as ``dt → 0``.  A contact
that moves people by their overlap over the step (the twin's push, or a projection of the positions) reflects
the noise, and turns σ into a pressure that drives people through the doors, more the finer the step (docs
page *Congestion*, "The headway door model", where the three are measured against the step).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.crowds._headway_loops import cell_list, contact_cone, headways
from meanfield.crowds.congestion import FundamentalDiagram

__all__ = ["Headway", "HEADWAY_REACH"]

HEADWAY_REACH = 3.0
"""m: nobody farther ahead slows a human (the diagram's speed at the density of that spacing, 0.13 persons/m²
at 5.4 persons/m² jam, is within 2.5 % of ``v₀`` for the linear diagram)."""


class Headway:
    """The headway door model, (H1), (H2) and (H3).

    Parameters
    ----------
    diagram : FundamentalDiagram
        A diagram that slows (finite ``rho_max``).
    reach : float
        ``R``, m: the farthest person ahead that counts (:data:`HEADWAY_REACH`).
    separation : float, optional
        ``u`` of (H3), m/s (default: the diagram's free speed ``v₀``).
    """

    caps_exits = True
    """Each exit passes at most ``q_max`` per metre of its width, as the density's exit face does (docs page
    *Congestion*, "The exits' capacity"): without it, people converging on a door in a wall from a half circle
    find nobody ahead in their lanes and pass it at 3.4–4.2 persons/s per metre (``rimea-9``)."""

    def __init__(
        self, diagram: FundamentalDiagram, reach: float = HEADWAY_REACH, separation: float | None = None
    ) -> None:
        self.diagram = diagram
        self.separation = float(diagram.free_speed if separation is None else separation)
        self.rho_max = float(diagram.rho_max)
        self.jam_spacing = math.sqrt(2.0 / (math.sqrt(3.0) * self.rho_max))
        self.lane = self.jam_spacing
        self.reach = float(reach)
        self._headway = np.empty(0)

    def density(self, headway: np.ndarray) -> np.ndarray:
        """``ρ(s) = ρ_max (d/s)²``, persons/m², of a hexagonal crowd at spacing ``s`` (0 for ``s = inf``)."""
        s = np.asarray(headway, float)
        with np.errstate(divide="ignore"):
            return self.rho_max * (self.jam_spacing / s) ** 2

    def speed_factor(self, headway: np.ndarray) -> np.ndarray:
        """``f = g(ρ(s))`` of (H1), in [0, 1]."""
        return np.asarray(self.diagram.speed_factor(self.density(headway)), float)

    def slow_down(self, velocity: np.ndarray, positions: np.ndarray, active: np.ndarray | None, dt: float = 0.0,
                  density: Any = None) -> np.ndarray:  # fmt: skip
        """(H1), (H2) and (H3), in place on ``velocity`` (m/s, the walk before congestion); returns the local density to
        report: ``density``'s count (a :class:`~meanfield.crowds.local_density.LocalDensity`), or, without one,
        the density (H1) reads from each headway.  ``dt`` is not used: nothing here depends on the step.

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
        e = velocity.copy()
        norm = np.hypot(e[:, 0], e[:, 1])
        np.divide(e, norm[:, None], out=e, where=norm[:, None] > 0)
        e[norm == 0] = 0.0
        cells = cell_list(positions, active, self.jam_spacing)
        if len(self._headway) != n:
            self._headway = np.empty(n)
        s = headways(positions, e, active, self.lane, self.reach, cells, self._headway)
        velocity *= self.speed_factor(s)[:, None]
        contact_cone(velocity, positions, active, self.jam_spacing, self.separation, cells)
        return self.density(s) if density is None else density(positions, active)
