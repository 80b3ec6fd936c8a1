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
``hughes`` (the informed crowd that routes round the crowd; the density only)
    Everyone walks the route of least travel time given the crowd (R. L. Hughes, "A continuum
    theory for the flow of pedestrians", Transp. Res. B 36 (2002) 507–535): the density's
    guidance (below); the agents refuse it, naming ``crowd.guidance`` (:func:`hughes`).

A factory receives the :class:`~meanfield.interfaces.CrowdContext` and the agents' initial
positions and returns a :class:`Guidance`, or None for the robots' signs.

**The density.**  The crowd's density (crowd kind ``fokker-planck``,
:class:`~meanfield.crowds.density_crowd.DensityCrowd`) asks each guidance what it gives the
mean-field equation: a factory declares ``for_density``, a function of the
:class:`~meanfield.interfaces.CrowdContext` returning a :class:`DensityGuidance` (read with
:func:`meanfield.plugins.declared`); a guidance that declares nothing (a plug-in's) is refused
by the density, naming ``crowd.guidance``.  The built-in ones (docs page *Congestion*,
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
``hughes``
    Hughes' route, recomputed from the density at every control period: ``φ`` the travel time
    to the exits, ``|∇φ| = 1/f̂``, ``f̂ = max(v₀ g(Nρ), f_min)`` (the diagram of
    ``crowd.congestion``, ``f_min`` = :data:`HUGHES_SPEED_FLOOR` ``· v₀``), by fast marching
    (:class:`~meanfield.geometry.geodesic.ExitEikonal`), and the drift ``v₀ (−∇φ/|∇φ|)`` on the
    faces (:func:`route_velocity`), which the congested flux slows by ``g``
    (:class:`HughesRoute`; :func:`hughes_for_density`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry.grid import FaceField, Grid
from meanfield.interfaces import CrowdContext

__all__ = [
    "Guidance",
    "GeodesicGuidance",
    "RandomWalkGuidance",
    "DensityGuidance",
    "HughesRoute",
    "HUGHES_SPEED_FLOOR",
    "signs",
    "geodesic",
    "random_walk",
    "hughes",
    "signs_for_density",
    "geodesic_for_density",
    "random_walk_for_density",
    "hughes_for_density",
    "route_velocity",
    "walk_diffusion",
]


class Guidance(Protocol):
    """A velocity the humans choose without the robots (a baseline)."""

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


def hughes(ctx: CrowdContext, positions: np.ndarray) -> Guidance:
    """Registry factory (``hughes``): Hughes' route round the crowd, for the density only.

    The agents refuse it, naming ``crowd.guidance``: an agent's guidance sees the positions, not
    the density Hughes' potential is solved for, and the point masses, which nothing keeps below the
    jam density (docs page *Congestion*, "What does not match"), would put the speed of every
    queue on the floor of :data:`HUGHES_SPEED_FLOOR`.  The density (``crowd.kind =
    "fokker-planck"``) takes it (:func:`hughes_for_density`).
    """
    raise ParameterError(
        "crowd.guidance",
        "hughes",
        "'geodesic', 'random-walk' or 'signs' for the agents: Hughes' route is the density's "
        "(crowd.kind = 'fokker-planck')",
    )


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
        asks it at the start of every period); Hughes' route (:class:`HughesRoute`).  At most one of
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


HUGHES_SPEED_FLOOR = 0.05
"""``f_min / v₀``: the floor of the walking speed in Hughes' eikonal equation, as the evacuation
controller's (``meanfield.controllers.evacuation.SPEED_FLOOR``): crossing a jammed cell costs as long as
crossing 20 free ones, so that ``φ`` stays finite behind a jam and a route prefers a detour of up to
20 cells to a jam."""


class HughesRoute:
    """Hughes' route on the faces at the density ``ρ`` (R. L. Hughes, Transp. Res. B 36 (2002) 507–535).

    The potential ``φ`` is the remaining travel time to the exits at the walking speed the crowd
    allows, the eikonal equation::

        |∇φ| = 1/f̂(ρ)  in Ω,   φ = 0  on the exits,   f̂ = max(v₀ g(Nρ), f_min)

    (Hughes' eq. with his discomfort factor 1; ``g`` the diagram of ``crowd.congestion``, ``Nρ`` in
    persons/m², ``f_min`` = ``floor · v₀``), solved by fast marching with the speed ``f̂`` on the
    cells (:meth:`~meanfield.geometry.geodesic.ExitEikonal.travel_time`).  The density walks
    ``v₀ e``, ``e = −∇φ/|∇φ|`` (:func:`route_velocity`), and the congested flux multiplies it by
    ``g`` (:mod:`meanfield.fokker_planck.congested`): the crowd walks at ``f = v₀ g`` along the
    route of least travel time, Hughes' model (docs page *Congestion*, "The PDE").  Where nobody
    is (``ρ = 0``) ``f̂ = v₀`` and ``φ`` is the distance over ``v₀``: the ``geodesic`` route.

    Parameters
    ----------
    grid : Grid
    eikonal : ExitEikonal
        The exits' fast-marching solver on ``grid`` (:class:`~meanfield.geometry.geodesic.ExitEikonal`).
    diagram : FundamentalDiagram
        ``g`` and ``v₀`` (``free_speed``) (:mod:`meanfield.crowds.congestion`); one that does not slow
        (``"none"``) gives the geodesic route at every density, computed once.
    people : float
        ``N``: the density has unit mass, ``N ρ`` persons/m² (``crowd.n``), > 0.
    floor : float, default HUGHES_SPEED_FLOOR
        ``f_min / v₀`` in ``(0, 1]``.
    """

    def __init__(self, grid: Grid, eikonal: Any, diagram: Any, people: float, floor: float = HUGHES_SPEED_FLOOR):
        if not (math.isfinite(people) and people > 0):
            raise ParameterError("crowd.n", people, "a number of people > 0")
        if not (math.isfinite(floor) and 0 < floor <= 1):
            raise ParameterError("floor", floor, "a share of the free speed in (0, 1]")
        self.grid, self.eikonal, self.diagram = grid, eikonal, diagram
        self.people, self.floor = float(people), float(floor)
        self.free_speed = float(diagram.free_speed)
        self._still: FaceField | None = None  # a diagram that does not slow: the geodesic route, once
        self._all_exits = eikonal.segs  # (exits_closed plans to a subset of these)

    def speed(self, rho: np.ndarray) -> np.ndarray:
        """``f̂ = max(v₀ g(Nρ), f_min)`` on the cells (``v₀`` on the inactive ones)."""
        rho = np.asarray(rho, float)
        if rho.shape != self.grid.shape:
            raise ParameterError("rho", rho.shape, f"an array of grid.shape {self.grid.shape}")
        persons = self.people * np.where(self.grid.active, np.maximum(rho, 0.0), 0.0)
        f = self.free_speed * np.asarray(self.diagram.speed_factor(persons), float)
        return np.where(self.grid.active, np.maximum(f, self.floor * self.free_speed), self.free_speed)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Plan to the exits with ``open_exits[k]`` from now on (a scenario's ``[[events]]``; none left: unchanged)."""
        from meanfield.geometry.geodesic import ExitEikonal

        open_exits = np.asarray(open_exits, dtype=bool)
        if open_exits.any():
            e = self.eikonal
            self.eikonal = ExitEikonal(e.grid, self._all_exits[open_exits], e.sight)
            self._still = None

    def potential(self, rho: np.ndarray) -> np.ndarray:
        """Hughes' ``φ`` (s): the travel time to the exits at the speed :meth:`speed` (``inf`` off Ω)."""
        return self.eikonal.travel_time(self.speed(rho))

    def __call__(self, rho: np.ndarray) -> FaceField:
        """The drift ``v₀ (−∇φ/|∇φ|)`` on the interior faces for the density ``rho`` (:func:`route_velocity`)."""
        if not self.diagram.slows:
            if self._still is None:
                self._still = route_velocity(self.grid, self.eikonal.distance, self.free_speed)
            return self._still
        return route_velocity(self.grid, self.potential(rho), self.free_speed)


def random_walk_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``random-walk`` gives the density: no drift, the walk's diffusion :func:`walk_diffusion` added to σ."""
    v = ctx.scenario.view
    return DensityGuidance(diffusion=walk_diffusion(v.walk_speed, v.turning_rate))


# what each guidance gives the density (the core asks: meanfield.plugins.declared("guidance", name, "for_density"))
signs.for_density = signs_for_density  # type: ignore[attr-defined]
geodesic.for_density = geodesic_for_density  # type: ignore[attr-defined]
random_walk.for_density = random_walk_for_density  # type: ignore[attr-defined]


def hughes_for_density(ctx: CrowdContext) -> DensityGuidance:
    """What ``hughes`` gives the density: Hughes' route at the current density (:class:`HughesRoute`).

    The diagram is the scenario's (:attr:`~meanfield.scenarios.scenario.Scenario.congestion_model`, with
    ``crowd.free_speed`` and ``crowd.rho_max``), ``N = crowd.n``; with ``"none"`` the route is the
    ``geodesic`` one.  A plan without exits is refused, naming ``crowd.guidance``.
    """
    from meanfield import plugins
    from meanfield.geometry.exits import exit_segments
    from meanfield.geometry.geodesic import ExitEikonal

    segs = exit_segments(ctx.scenario.domain)
    if not len(segs):
        raise ParameterError("crowd.guidance", "hughes", "a plan with exits (domain.exits) for Hughes' route")
    c = ctx.scenario.crowd
    diagram = plugins.load("congestion", ctx.scenario.congestion_model)(free_speed=c.free_speed, rho_max=c.rho_max)
    route = HughesRoute(ctx.grid, ExitEikonal(ctx.grid, segs, ctx.sight), diagram, c.n)
    return DensityGuidance(velocity_of=route)


hughes.for_density = hughes_for_density  # type: ignore[attr-defined]
