"""People who remember the way: once a sign has reached a person, the person knows the route out.

The paper's humans follow the navigation field ``v_r`` (eq. (3)) only at the instant they feel
it: a person the robot has just passed stops where the field fades (and, with a view radius,
walks randomly once no robot is in view; :mod:`meanfield.crowds.local_view`).  People who have
read a "THIS WAY" sign remember it: in robot-guided evacuation experiments the subjects who had
met the robot went on to the exit (Nayyar et al., SSRR 2023: 95.28 % of 112 subjects followed
the robot out).  ``view.memory = "route"`` or ``"sign"`` models that:

* a person whom a sign has *reached* (``|v_r|`` at least
  :data:`~meanfield.signs.kernels.REACH_FRACTION` of one kernel's peak while it sees a robot:
  :attr:`meanfield.crowds.agent_crowd.AgentCrowd.reached`) knows the way from then on;
* with ``"route"`` the way is the informed crowd's route to the nearest open exit
  (:class:`meanfield.geometry.geodesic.ExitRoutes`): a sign tells a person to leave and which way
  is out, as a crowd that knows the building;
* with ``"sign"`` it is the way the latest sign that reached the person showed.  A sign that names an exit
  (``EXIT 2, THIS WAY``: :attr:`meanfield.signs.robots.RobotTeam.shows`, set by the guide,
  :mod:`meanfield.controllers.guide`) sends its reader to that exit; a person then reads the strongest sign
  it sees on its own (:meth:`meanfield.crowds.agent_crowd.AgentCrowd.drift`).  An arrow alone shows, of the
  routes to each exit, the shortest among those whose first leg at the person lies within 45° of the field
  ``v_r`` it feels (:data:`SHOWN_COS`), or, if none does, the one whose first leg is most nearly along it; so a
  sign pointing roughly towards the nearest exit sends people there, signs that send part of a crowd
  to a farther exit (``controller.options.potential = "balanced"``) are followed as such, and a
  person a later sign reaches takes the exit that one shows (people follow the sign before them: the
  robots can correct a split they see going wrong);
* who knows the way walks that route at the free speed, slowed by congestion like everyone, and no
  longer follows the signs; nobody forgets.  When an exit closes, those who were walking to it take
  the route to the nearest exit still open (``[[events]]``).

So the robots' task becomes reaching everyone once, not carrying everyone out.  The default, ``"auto"``
(:attr:`meanfield.scenarios.scenario.Scenario.memory`), is ``"sign"`` for agents in a plan with exits in SI units
and ``"none"``, the paper's model with every number unchanged, otherwise.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["MEMORIES", "RouteMemory"]

SHOWN_COS = math.cos(math.radians(45.0))
"""A sign shows the way to the exits whose route's first leg is within 45° of its field at the person."""
MEMORIES = ("none", "route", "sign")
"""``view.memory``: the paper's humans, who follow a sign only while they feel it; people whom a sign has reached and
who then know the way to the nearest exit (``route``); or who walk to the exit the latest sign showed (``sign``)."""


class RouteMemory:
    """Who knows the way (a sign reached them once), to which exit, and the routes they walk (module docstring).

    Parameters
    ----------
    n : int
        Number of humans.
    grid : Grid
        The cells the routes are planned on.
    segs : ndarray, shape (E, 2, 2)
        The exits (:func:`meanfield.geometry.exits.exit_segments`).
    speed : float
        The free walking speed, > 0 (``crowd.free_speed``).
    sight : SightLines, optional
        The walls that block a straight line (built from the grid's region when omitted).
    shown : bool
        Whether a person walks to the exit the sign showed (``view.memory = "sign"``) or to the nearest (``"route"``).
    """

    def __init__(self, n: int, grid: Any, segs: np.ndarray, speed: float, sight: Any = None, shown: bool = False):
        from meanfield.geometry.geodesic import AssignedRoutes

        if not speed > 0:
            raise ParameterError("crowd.free_speed", speed, "a walking speed > 0")
        self.shown = bool(shown)
        self.plan = AssignedRoutes(grid, segs, sight)  # to the nearest open exit, or to each exit alone ("sign")
        self.speed = float(speed)
        self.knows = np.zeros(int(n), dtype=bool)
        self.exit = np.full(int(n), -1, dtype=np.intp)  # the exit each walks to; -1: the nearest open one

    def walk(self, velocity: np.ndarray, positions: np.ndarray, reached: np.ndarray,
             named: np.ndarray | None = None) -> None:  # fmt: skip
        """In place: who was ``reached`` now knows the way (with ``shown``, the one the sign showed, the latest sign
        deciding: ``velocity`` holds the field felt, ``named`` the exit the sign names, ``-1`` for an arrow alone);
        everyone who knows it walks the route to its exit at the free speed."""
        new = np.flatnonzero(reached if self.shown else reached & ~self.knows)
        self.knows[new] = True  # (without shown: all walk to the nearest open exit, self.exit = -1)
        if len(new) and self.shown and named is not None:  # a sign that names an open exit: that one
            k = named[new]
            said = (k >= 0) & self.plan.open[np.maximum(k, 0)]
            if said.any():  # (a plan in pieces: an exit of another piece is no way)
                said &= self.plan.reaches(positions[new], np.where(said, k, -1))
                self.exit[new[said]] = k[said]
                new = new[~said]
        if len(new) and self.shown:
            open_k = np.flatnonzero(self.plan.open)
            p, v = positions[new], velocity[new]
            along = v / np.hypot(v[:, 0], v[:, 1])[:, None]  # (reached: |v| > 0)
            cos = np.stack([(self.plan.to(k).heading(p) * along).sum(axis=1) for k in open_k])  # (K, m)
            far = np.stack([self.plan.to(k).distance(p) for k in open_k])
            cos = np.where(np.isfinite(far), cos, -np.inf)  # (a plan in pieces: an exit of another piece is no way)
            shown = np.where(cos >= SHOWN_COS, far, np.inf)  # the nearest of the exits the sign points towards
            pick = np.where(np.isfinite(shown).any(axis=0), np.argmin(shown, axis=0), np.argmax(cos, axis=0))
            self.exit[new] = open_k[pick]
        rows = np.flatnonzero(self.knows)
        if len(rows):
            velocity[rows] = self.speed * self.plan.heading(positions[rows], self.exit[rows])

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Those walking to a closed exit take the route to the nearest open one (none left: unchanged)."""
        self.plan.exits_closed(open_exits, self.exit)

    def walls_changed(self, change: Any) -> None:
        """The routes are planned again round the new walls (a ``block`` event); who knows the way still does."""
        self.plan.walls_changed(change)

    def summary(self) -> dict[str, Any]:
        """``knew_the_way_fraction``: the share of the crowd a sign had reached by the end."""
        return {"knew_the_way_fraction": float(self.knows.mean()) if len(self.knows) else 0.0}
