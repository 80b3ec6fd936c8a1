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
``fastest-route`` (the informed crowd on the routes the crowd shapes)
    Everyone keeps the exit nearest where it started (or its group's) and walks the route of least
    travel time to it through the crowd, Hughes' eikonal restricted to that exit's basin
    (:mod:`meanfield.crowds.crowd_routes`; :class:`RouteGuidance`).
``hughes`` (Hughes' model)
    Everyone walks the route of least travel time to any exit given the crowd (R. L. Hughes, "A
    continuum theory for the flow of pedestrians", Transp. Res. B 36 (2002) 507–535), changing
    exits as the queues grow (:mod:`meanfield.crowds.crowd_routes`).

A factory receives the :class:`~meanfield.interfaces.CrowdContext` and the agents' initial
positions and returns a :class:`Guidance`, or None for the robots' signs.

**The density.**  The crowd's density (crowd kind ``fokker-planck``,
:class:`~meanfield.crowds.density_crowd.DensityCrowd`) asks each guidance what it gives the
mean-field equation: a guidance's record (:class:`~meanfield.capabilities.GuidanceCapabilities`, read with
:func:`meanfield.plugins.capabilities`) holds ``for_density``, a function of the
:class:`~meanfield.interfaces.CrowdContext` returning a :class:`DensityGuidance`; a guidance whose
``for_density`` is None (a plug-in's for agents only) is refused by the density, naming ``crowd.guidance``.
The built-in ones (docs page *Congestion*,
"The PDE"):

``signs``
    The robots' field ``v_r`` on the faces (eq. (3)), as ever (:func:`signs_for_density`).
``geodesic``
    The drift ``v₀ (−∇φ/|∇φ|)`` on the faces, ``φ`` the distance to the nearest exit
    (:func:`~meanfield.geometry.geodesic.exit_distance`) and ``v₀ = crowd.free_speed``
    (:func:`route_velocity`); the robots' field does not act (:func:`geodesic_for_density`).
``random-walk``
    No drift: the persistent random walk's long-time diffusion ``D = s²/(2 D_r)`` added to σ
    (:func:`walk_diffusion`; :func:`random_walk_for_density`).
``fastest-route``, ``hughes``
    The same routes, planned from the density at every control period, its cells' basins following
    their exits (:class:`DensityRoutes`; :mod:`meanfield.crowds.crowd_routes`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from meanfield.capabilities import GuidanceCapabilities, declares
from meanfield.crowds.crowd_routes import route_velocity  # (where it lives: the routes' drift on the faces)
from meanfield.errors import ParameterError
from meanfield.geometry.grid import FaceField
from meanfield.interfaces import CrowdContext

__all__ = [
    "Guidance",
    "GeodesicGuidance",
    "RandomWalkGuidance",
    "DensityGuidance",
    "RouteGuidance",
    "DensityRoutes",
    "signs",
    "geodesic",
    "random_walk",
    "hughes",
    "fastest_route",
    "routes_of",
    "signs_for_density",
    "geodesic_for_density",
    "random_walk_for_density",
    "hughes_for_density",
    "fastest_route_for_density",
    "route_velocity",
    "walk_diffusion",
]


class Guidance(Protocol):
    """A velocity the humans choose without the robots (a baseline).

    A guidance that plans from where the crowd is also declares ``observe(positions, here, t)``: the agent
    crowd calls it before :meth:`velocity` every step with who is still in Ω (``here``, None: everyone), as
    the rows of those who left hold stand-in points (:class:`RouteGuidance`).
    """

    def velocity(self, positions: np.ndarray, t: float, dt: float) -> np.ndarray:
        """The chosen velocity ``(N, 2)`` at ``positions`` (rows of those who left are ignored)."""
        ...

    def advance(self, dt: float) -> None:
        """After the step (a walker's heading diffuses)."""
        ...


class GeodesicGuidance:
    """The informed crowd: each human walks its route to the nearest exit (or its assigned one) at ``speed``.

    Parameters
    ----------
    routes : ExitRoutes
        The routes from every cell (:mod:`meanfield.geometry.geodesic`).
    speed : float
        The free walking speed, > 0 (1.34 m/s, Weidmann).
    exit_of : ndarray of int, shape (N,), optional
        Each human's assigned exit, an index into ``routes.segs`` (-1: the nearest); people in groups
        (:mod:`meanfield.crowds.groups`).
    """

    def __init__(self, routes: Any, speed: float, exit_of: np.ndarray | None = None):
        from meanfield.geometry.geodesic import AssignedRoutes

        self.speed = float(speed)
        self.plan = AssignedRoutes(routes.grid, routes.segs, routes.sight, nearest=routes)
        self.exit_of = np.full(0, -1, dtype=np.intp) if exit_of is None else np.asarray(exit_of, np.intp).copy()

    @property
    def routes(self) -> Any:
        """The routes to the nearest open exit (:class:`~meanfield.geometry.geodesic.ExitRoutes`)."""
        return self.plan.nearest

    def velocity(self, positions: np.ndarray, t: float, dt: float) -> np.ndarray:
        if not len(self.exit_of):  # everyone to the nearest exit
            return self.speed * self.plan.nearest.heading(positions)
        return self.speed * self.plan.heading(positions, self.exit_of)  # people in groups with their own exit

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Plan again: the routes to the nearest of the exits still open (a scenario's ``[[events]]``); those
        assigned to an exit that closes take them too.

        With no exit left the routes stay as they were (nobody can leave; the run ends).
        """
        self.plan.exits_closed(open_exits, self.exit_of)

    def walls_changed(self, change: Any) -> None:
        """Plan again round the new walls (a ``block`` event;
        :meth:`~meanfield.geometry.geodesic.AssignedRoutes.walls_changed`)."""
        self.plan.walls_changed(change)

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

    def walls_changed(self, change: Any) -> None:
        """The walk turns at the new walls (a ``block`` event)."""
        self.view.walls_changed(change)

    def advance(self, dt: float) -> None:
        self.view.advance(dt)


class RouteGuidance:
    """The informed crowd on the routes the crowd shapes (:class:`~meanfield.crowds.crowd_routes.CrowdRoutes`).

    Each human walks ``speed`` along the route of least travel time through the crowd: to the exit it keeps
    (``fastest-route``: the nearest where it started, or its group's) or to the exit of least travel time
    (``hughes``).  The routes are planned every step from the humans still here (:meth:`observe`, which the
    agent crowd calls before :meth:`velocity`), their density counted within ``radius``.

    Parameters
    ----------
    routes : CrowdRoutes
    speed : float
        The free walking speed, > 0.
    radius : float
        ``r`` of the agents' density (``crowd.congestion_radius``; module :mod:`meanfield.crowds.crowd_routes`, (R2)).
    exit_of : ndarray of int, shape (N,), optional
        Each human's exit (-1: its cell's nearest open exit); ignored without ``routes.keep_exit``.
    """

    def __init__(self, routes: Any, speed: float, radius: float, exit_of: np.ndarray | None = None):
        if not (math.isfinite(radius) and radius > 0):
            raise ParameterError("crowd.congestion_radius", radius, "a radius > 0")
        self.routes, self.speed, self.radius = routes, float(speed), float(radius)
        self.exit_of = None if exit_of is None else np.asarray(exit_of, np.intp).copy()

    def observe(self, positions: np.ndarray, here: np.ndarray | None, t: float) -> None:
        """The humans ``here`` (None: everyone) at ``t``: the routes planned again round them."""
        self.routes.plan_for_agents(positions, here, self.radius)

    def velocity(self, positions: np.ndarray, t: float, dt: float) -> np.ndarray:
        return self.speed * self.routes.headings(positions, self.exit_of)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Plan to the exits still open; those who kept a closed one take their cell's nearest open exit."""
        self.routes.exits_closed(open_exits)

    def walls_changed(self, change: Any) -> None:
        """Plan round the new walls (a ``block`` event)."""
        self.routes.walls_changed(change)

    def advance(self, dt: float) -> None:
        """No memory beyond the routes."""


def signs(ctx: CrowdContext, positions: np.ndarray) -> None:
    """Registry factory (kind ``guidance``, name ``signs``): the robots' signs, the paper's eq. (3)."""
    return None


def geodesic(ctx: CrowdContext, positions: np.ndarray) -> GeodesicGuidance:
    """Registry factory (``geodesic``): the informed crowd, at ``crowd.free_speed``, to the exits."""
    from meanfield.crowds.groups import assigned_exits
    from meanfield.geometry.exits import exit_segments
    from meanfield.geometry.geodesic import ExitRoutes

    segs = exit_segments(ctx.scenario.domain)
    if not len(segs):
        raise ParameterError("crowd.guidance", "geodesic", "a plan with exits (domain.exits) for the informed crowd")
    c = ctx.scenario.crowd
    exit_of = assigned_exits(c.groups) if c.initial == "groups" else None
    return GeodesicGuidance(ExitRoutes(ctx.grid, segs, ctx.sight), c.free_speed, exit_of)


def random_walk(ctx: CrowdContext, positions: np.ndarray) -> RandomWalkGuidance:
    """Registry factory (``random-walk``): the uninformed crowd, walking as ``[view]`` says."""
    from meanfield.crowds.local_view import LocalView

    v = ctx.scenario.view
    return RandomWalkGuidance(
        LocalView.blind(len(positions), v.walk_speed, v.turning_rate, ctx.scenario.domain, ctx.rng)
    )


def routes_of(ctx: CrowdContext, keep_exit: bool) -> Any:
    """The scenario's :class:`~meanfield.crowds.crowd_routes.CrowdRoutes`: to its exits, at the speed of the diagram of
    ``crowd.congestion`` (with ``crowd.free_speed`` and ``crowd.rho_max``); refused, naming ``crowd.guidance``, on a
    plan without exits."""
    from meanfield import plugins
    from meanfield.crowds.crowd_routes import CrowdRoutes
    from meanfield.geometry.exits import exit_segments

    name = "fastest-route" if keep_exit else "hughes"
    segs = exit_segments(ctx.scenario.domain)
    if not len(segs):
        raise ParameterError("crowd.guidance", name, "a plan with exits (domain.exits) for the routes to them")
    c = ctx.scenario.crowd
    diagram = plugins.load("congestion", ctx.scenario.congestion_model)(free_speed=c.free_speed, rho_max=c.rho_max)
    return CrowdRoutes(ctx.grid, segs, diagram, keep_exit, ctx.sight)


def fastest_route(ctx: CrowdContext, positions: np.ndarray) -> RouteGuidance:
    """Registry factory (``fastest-route``): the informed crowd, each to the exit nearest where it started (or
    its group's), on the route of least travel time through the crowd (:mod:`meanfield.crowds.crowd_routes`)."""
    from meanfield.crowds.groups import assigned_exits

    routes = routes_of(ctx, keep_exit=True)
    c = ctx.scenario.crowd
    exit_of = routes.nearest_exit(positions)
    if c.initial == "groups":
        own = assigned_exits(c.groups)
        exit_of = np.where(own >= 0, own, exit_of)
    return RouteGuidance(routes, c.free_speed, c.congestion_radius, exit_of)


def hughes(ctx: CrowdContext, positions: np.ndarray) -> RouteGuidance:
    """Registry factory (``hughes``): Hughes' model, each to the exit of least travel time through the crowd."""
    c = ctx.scenario.crowd
    return RouteGuidance(routes_of(ctx, keep_exit=False), c.free_speed, c.congestion_radius)


# ---------------------------------------------------------------------------------------------- the density


@dataclass(frozen=True)
class DensityGuidance:
    """What a guidance gives the crowd's density, the mean-field equation (docs page *Congestion*, "The PDE").

    Parameters
    ----------
    velocity : FaceField, optional
        A drift on the grid's interior faces that the density follows instead of the robots' field
        (fixed in time); None: no drift of its own.
    diffusion : float, default 0
        A diffusion added to the crowd's σ (length²/time, ``>= 0``).
    follows_signs : bool, default False
        Whether the robots' field ``v_r`` (eq. (3)) drives the density (the paper); ``velocity`` is
        then None.
    velocity_of : callable, optional
        A drift that depends on the density: ``velocity_of(ρ)`` returns the drift on the interior
        faces for the current density ``ρ`` (unit mass, on the grid's cells), which the density
        follows over the next control period (:meth:`~meanfield.crowds.density_crowd.DensityCrowd.advance`
        asks it at the start of every period); the routes the crowd shapes (:class:`DensityRoutes`).  At most one of
        ``velocity``, ``velocity_of`` and ``follows_signs``.  One that declares ``exits_closed`` is told
        when exits close (a scenario's ``[[events]]``).
    replan : callable, optional
        ``replan(open_exits)``: the guidance planned again to the exits with ``open_exits[k]`` (a
        scenario's ``[[events]]``); None: nothing to plan (it does not walk to the exits).
    """

    velocity: FaceField | None = None
    diffusion: float = 0.0
    follows_signs: bool = False
    velocity_of: Callable[[np.ndarray], FaceField] | None = None
    replan: Callable[[np.ndarray], DensityGuidance] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.diffusion) and self.diffusion >= 0):
            raise ParameterError("diffusion", self.diffusion, "a diffusion >= 0")
        if self.follows_signs and self.velocity is not None:
            raise ParameterError("velocity", "a field beside the signs", "None when the density follows the signs")
        if self.velocity_of is not None and (self.follows_signs or self.velocity is not None):
            raise ParameterError(
                "velocity_of", "a drift beside another", "None when the density follows the signs or a fixed velocity"
            )
        if self.velocity_of is not None and not callable(self.velocity_of):
            raise ParameterError("velocity_of", self.velocity_of, "a function of the density returning a FaceField")

    @property
    def drifts(self) -> bool:
        """Whether the density follows a drift of the guidance's own (``velocity`` or ``velocity_of``)."""
        return self.velocity is not None or self.velocity_of is not None


def walk_diffusion(walk_speed: float, turning_rate: float) -> float:
    """The long-time diffusion ``D = s²/(2 D_r)`` of the persistent random walk of ``[view]`` (2-D).

    The walk of :mod:`meanfield.crowds.local_view`: speed ``s``, heading ``θ`` diffusing with
    ``dθ = sqrt(2 D_r) dW``, so ``E[e(t)·e(0)] = exp(−D_r t)`` and the mean squared displacement is
    ``(2 s²/D_r) t − (2 s²/D_r²)(1 − exp(−D_r t))``: ``4 D t`` at long times, ``D = s²/(2 D_r)``.
    The agents' walk in steps of ``dt`` (the heading held over each step) has
    ``D_dt = (s² dt/4) coth(D_r dt/2) = D (1 + (D_r dt)²/12 + …)``; the difference is left out.

    Parameters
    ----------
    walk_speed : float
        ``s >= 0`` (``view.walk_speed``).
    turning_rate : float
        ``D_r`` (rad²/s, ``view.turning_rate``); > 0 when ``s > 0``: a walker that never turns
        walks straight on, which no diffusion describes.
    """
    if not (math.isfinite(walk_speed) and walk_speed >= 0):
        raise ParameterError("view.walk_speed", walk_speed, "a speed >= 0")
    if walk_speed == 0:
        return 0.0
    if not (math.isfinite(turning_rate) and turning_rate > 0):
        raise ParameterError(
            "view.turning_rate",
            turning_rate,
            "a rate > 0 (rad²/s) for the density's random walk: its diffusion is walk_speed²/(2 turning_rate)",
        )
    return walk_speed**2 / (2.0 * turning_rate)


def signs_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``signs`` gives the density: the robots' field, eq. (3) on the faces (the paper)."""
    return DensityGuidance(follows_signs=True)


def geodesic_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``geodesic`` gives the density: the route to the nearest exit at ``crowd.free_speed``.

    The drift ``v₀ (−∇φ/|∇φ|)`` on the faces (:func:`route_velocity`), ``φ`` the distance to the
    exits of :func:`~meanfield.geometry.geodesic.exit_distance`; a plan without exits is refused,
    naming ``crowd.guidance``.
    """
    from meanfield.geometry.exits import exit_segments
    from meanfield.geometry.geodesic import exit_distance

    segs = exit_segments(ctx.scenario.domain)
    if not len(segs):
        raise ParameterError("crowd.guidance", "geodesic", "a plan with exits (domain.exits) for the informed crowd")
    grid, speed = ctx.grid, ctx.scenario.crowd.free_speed

    def to(open_exits: np.ndarray) -> DensityGuidance:  # the route to the nearest of the open exits
        velocity = route_velocity(grid, exit_distance(grid, segs[open_exits]), speed)
        return DensityGuidance(velocity=velocity, replan=to)

    return to(np.ones(len(segs), dtype=bool))


def random_walk_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``random-walk`` gives the density: no drift, the walk's diffusion :func:`walk_diffusion` added to σ."""
    v = ctx.scenario.view
    return DensityGuidance(diffusion=walk_diffusion(v.walk_speed, v.turning_rate))




class DensityRoutes:
    """The density's drift on the routes the crowd shapes: ``velocity_of`` of a :class:`DensityGuidance`.

    Parameters
    ----------
    routes : CrowdRoutes
    people : float
        ``N``: the density has unit mass, ``N ρ`` persons per unit area (``crowd.n``), > 0.
    """

    def __init__(self, routes: Any, people: float):
        if not (math.isfinite(people) and people > 0):
            raise ParameterError("crowd.n", people, "a number of people > 0")
        self.routes, self.people = routes, float(people)

    def __call__(self, rho: np.ndarray) -> FaceField:
        """The drift on the interior faces at the density ``rho`` (the routes planned again)."""
        self.routes.plan_for_density(rho, self.people)
        return self.routes.density_velocity()

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Plan to the exits still open (a scenario's ``[[events]]``)."""
        self.routes.exits_closed(open_exits)


def fastest_route_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``fastest-route`` gives the density: each cell's mass to the exit of its basin, on the route of least
    travel time through the crowd (:class:`DensityRoutes`)."""
    return DensityGuidance(velocity_of=DensityRoutes(routes_of(ctx, keep_exit=True), ctx.scenario.crowd.n))


def hughes_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``hughes`` gives the density: Hughes' route at the current density (:class:`DensityRoutes`)."""
    return DensityGuidance(velocity_of=DensityRoutes(routes_of(ctx, keep_exit=False), ctx.scenario.crowd.n))


# what each guidance can do: what it gives the density (meanfield.plugins.capabilities("guidance", name).for_density)
declares(GuidanceCapabilities(for_density=signs_for_density))(signs)
declares(GuidanceCapabilities(for_density=geodesic_for_density))(geodesic)
declares(GuidanceCapabilities(for_density=random_walk_for_density))(random_walk)
declares(GuidanceCapabilities(for_density=fastest_route_for_density))(fastest_route)
declares(GuidanceCapabilities(for_density=hughes_for_density))(hughes)
