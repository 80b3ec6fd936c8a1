"""What the humans follow: the robots' signs (the paper), or a baseline without them.

The crowd's ``guidance`` (``[crowd] guidance = "..."``, registry kind ``guidance``) is the
velocity each agent chooses before walls, interaction and disturbance act (paper, eq. (1),
the ``v_r`` term).  Robot guidance is judged against the baselines of the issue on real
buildings (docs page *Buildings*), on the same plan and seeds:

``signs`` (the default)
    The paper: the robots' navigation field ``v_r`` (eq. (3)), hidden behind walls
    (:mod:`meanfield.geometry.sight`), and the random walk out of a robot's view
    (:mod:`meanfield.crowds.local_view`).
``geodesic`` (the *informed crowd*)
    Everyone knows the building and walks the shortest route to the nearest exit at the
    free walking speed ``crowd.free_speed`` (:class:`~meanfield.geometry.geodesic.ExitRoutes`):
    the best a crowd does without congestion management.
``random-walk`` (the *uninformed crowd*)
    Nobody sees a sign: everyone walks the persistent random walk of ``[view]``
    (``walk_speed``, ``turning_rate``), as the Unity study's humans do out of view.

A factory receives the :class:`~meanfield.interfaces.CrowdContext` and the agents' initial
positions and returns a :class:`Guidance`, or None for the robots' signs.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from meanfield.errors import ParameterError
from meanfield.interfaces import CrowdContext

__all__ = ["Guidance", "GeodesicGuidance", "RandomWalkGuidance", "signs", "geodesic", "random_walk"]


class Guidance(Protocol):
    """A velocity the humans choose without the robots (a baseline)."""

    def velocity(self, positions: np.ndarray, t: float, dt: float) -> np.ndarray:
        """The chosen velocity ``(N, 2)`` at ``positions`` (rows of those who left are ignored)."""
        ...

    def advance(self, dt: float) -> None:
        """After the step (a walker's heading diffuses)."""
        ...


class GeodesicGuidance:
    """The informed crowd: each human walks its route to the nearest exit at ``speed``.

    Parameters
    ----------
    routes : ExitRoutes
        The routes from every cell (:mod:`meanfield.geometry.geodesic`).
    speed : float
        The free walking speed, > 0 (1.34 m/s, Weidmann).
    """

    def __init__(self, routes: Any, speed: float):
        self.routes = routes
        self.speed = float(speed)

    def velocity(self, positions: np.ndarray, t: float, dt: float) -> np.ndarray:
        return self.speed * self.routes.heading(positions)

    def advance(self, dt: float) -> None:
        """No memory."""


class RandomWalkGuidance:
    """The uninformed crowd: everyone walks the persistent random walk of a blind view.

    Parameters
    ----------
    view : LocalView
        A view that sees no robot (:meth:`~meanfield.crowds.local_view.LocalView.blind`).
    """

    def __init__(self, view: Any):
        self.view = view

    def velocity(self, positions: np.ndarray, t: float, dt: float) -> np.ndarray:
        return self.view.walk_velocity(positions, dt)

    def advance(self, dt: float) -> None:
        self.view.advance(dt)


def signs(ctx: CrowdContext, positions: np.ndarray) -> None:
    """Registry factory (kind ``guidance``, name ``signs``): the robots' signs, the paper's eq. (3)."""
    return None


def geodesic(ctx: CrowdContext, positions: np.ndarray) -> GeodesicGuidance:
    """Registry factory (``geodesic``): the informed crowd, at ``crowd.free_speed``, to the exits."""
    from meanfield.geometry.exits import exit_segments
    from meanfield.geometry.geodesic import ExitRoutes

    segs = exit_segments(ctx.scenario.domain)
    if not len(segs):
        raise ParameterError("crowd.guidance", "geodesic", "a plan with exits (domain.exits) for the informed crowd")
    return GeodesicGuidance(ExitRoutes(ctx.grid, segs, ctx.sight), ctx.scenario.crowd.free_speed)


def random_walk(ctx: CrowdContext, positions: np.ndarray) -> RandomWalkGuidance:
    """Registry factory (``random-walk``): the uninformed crowd, walking as ``[view]`` says."""
    from meanfield.crowds.local_view import LocalView

    v = ctx.scenario.view
    return RandomWalkGuidance(
        LocalView.blind(len(positions), v.walk_speed, v.turning_rate, ctx.scenario.domain, ctx.rng)
    )
