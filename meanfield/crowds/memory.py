"""People who remember the way: once a sign has reached a person, the person knows the route out.

The paper's humans follow the navigation field ``v_r`` (eq. (3)) only at the instant they feel
it: a person the robot has just passed stops where the field fades (and, with a view radius,
walks randomly once no robot is in view; :mod:`meanfield.crowds.local_view`).  People who have
read a "THIS WAY" sign remember it: in robot-guided evacuation experiments the subjects who had
met the robot went on to the exit (Nayyar et al., SSRR 2023: 95.28 % of 112 subjects followed
the robot out).  ``view.memory = "route"`` models that:

* a person whom a sign has *reached* (``|v_r| >= REACH_FRACTION`` of one kernel's peak while it
  sees a robot: :attr:`meanfield.crowds.agent_crowd.AgentCrowd.reached`) knows the way from then on;
* who knows the way walks the informed crowd's route to the nearest open exit at the free speed
  (:class:`meanfield.geometry.geodesic.ExitRoutes`, as ``crowd.guidance = "geodesic"``), slowed by
  congestion like everyone, and no longer follows the signs;
* nobody forgets, and the routes are planned again when an exit closes (``[[events]]``).

So the robots' task becomes reaching everyone once, not carrying everyone out.  The default,
``"none"``, is the paper's model, every number unchanged.
"""

from __future__ import annotations

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["MEMORIES", "RouteMemory"]

MEMORIES = ("none", "route")
"""``view.memory``: the paper's humans, who follow a sign only while they feel it, or people who remember the way."""


class RouteMemory:
    """Who knows the way (a sign reached them once) and the route they walk (module docstring).

    Parameters
    ----------
    n : int
        Number of humans.
    routes : ExitRoutes
        The routes to the nearest exit from every cell (:class:`meanfield.geometry.geodesic.ExitRoutes`).
    speed : float
        The free walking speed, > 0 (``crowd.free_speed``).
    """

    def __init__(self, n: int, routes: object, speed: float):
        if not speed > 0:
            raise ParameterError("crowd.free_speed", speed, "a walking speed > 0")
        self.routes = routes
        self._all_routes = routes
        self.speed = float(speed)
        self.knows = np.zeros(int(n), dtype=bool)

    def walk(self, velocity: np.ndarray, positions: np.ndarray, reached: np.ndarray) -> None:
        """In place: who was ``reached`` now knows the way; everyone who knows it walks the route at the free speed."""
        self.knows |= reached
        rows = np.flatnonzero(self.knows)
        if len(rows):
            velocity[rows] = self.speed * self.routes.heading(positions[rows])

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Plan the routes again to the exits with ``open_exits[k]`` (none left: unchanged)."""
        from meanfield.geometry.geodesic import ExitRoutes

        open_exits = np.asarray(open_exits, dtype=bool)
        if open_exits.any():
            r = self._all_routes
            self.routes = ExitRoutes(r.grid, r.segs[open_exits], r.sight)

    def summary(self) -> dict[str, float]:
        """``knew_the_way_fraction``: the share of the crowd a sign had reached by the end."""
        return {"knew_the_way_fraction": float(self.knows.mean()) if len(self.knows) else 0.0}
