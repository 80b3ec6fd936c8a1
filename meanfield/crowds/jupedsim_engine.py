"""The crowd as pedestrians with bodies: the JuPedSim backend of the closed loop.

Where :class:`~meanfield.crowds.point_mass.PointMassEngine` moves point masses by the SDE of eq. (1), this crowd
hands each human's velocity to a JuPedSim operational model (the collision-free speed
model by default) as a *desired* velocity: every control period ``dt`` each human gets a
target point ahead of it in the direction of that velocity and a desired speed equal to
its magnitude, capped at ``max_speed``; JuPedSim then walks the bodies ``dt / time_step``
steps, avoiding each other and the walls.  The Brownian term of eq. (1) is not applied:
bodies, collision avoidance and the random walk of the humans who see no robot
(:mod:`meanfield.crowds.local_view`) replace it.

:func:`place_bodies` draws the initial crowd from the scenario's initial law without
overlapping bodies and at least one radius from the walls, or refuses the body radius.

**Exits.**  Bodies leave through the region's exits by JuPedSim's exit stages.  Each door
is opened in JuPedSim's walkable area: a *vestibule*, the door segment pushed
``2 radius`` outwards, is added to Ω, and is the exit stage's area (:func:`door_areas`;
where there is no room behind a door, a strip ``2 radius`` deep just inside it is the
area instead).  A human whose desired velocity leads through a door within its look-ahead
(the steering distance of :meth:`JuPedSimEngine.steering_targets`) is put on that exit's
journey: JuPedSim routes it through the opening, past the door posts and the other
bodies, at its desired speed, and removes it when its centre is in the area, i.e. once it
has crossed the door.  A human whose velocity turns away is steered directly again.
Direct steering alone could not do this: its targets are kept a radius inside the walls,
doors included, so a body never crosses one.  The door then has a capacity: bodies
queue at it, where point masses pass in any number.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from meanfield.capabilities import CrowdCapabilities, declares
from meanfield.crowds._jupedsim_api import MODEL_PARAMETERS, PEDESTRIAN_MODELS, REPULSION, JuPedSimAdapter
from meanfield.crowds.agent_crowd import AgentCrowd, initial_positions
from meanfield.crowds.point_mass import PointMassEngine
from meanfield.errors import ParameterError, choice, num
from meanfield.geometry.exits import exit_segments, leaving
from meanfield.geometry.region import Region
from meanfield.interfaces import CrowdContext

__all__ = [
    "JuPedSimEngine",
    "place_bodies",
    "place_groups",
    "door_areas",
    "jupedsim_crowd",
    "JuPedSimOptions",
    "check_scenario",
    "PEDESTRIAN_MODELS",
    "max_body_overlap",
]


def place_bodies(
    draw: Callable[[int], np.ndarray],
    n: int,
    radius: float,
    domain: Region,
    *,
    gap: float = 0.0,
    max_draws: int | None = None,
    occupied: np.ndarray | None = None,
) -> np.ndarray:
    """``n`` non-overlapping bodies from a law, by random sequential adsorption.

    Candidates are drawn from ``draw(k) -> (k, 2)`` (the scenario's initial law) and kept
    when their disk of ``radius`` lies in Ω and keeps ``gap`` from every kept body (and from
    the bodies already ``occupied``, placed before: an earlier group's).

    Parameters
    ----------
    draw : callable
        ``draw(k)`` returns ``k`` candidate positions (uses the caller's generator).
    n : int
        Number of bodies.
    radius : float
        Body radius ``> 0``.
    domain : Region
        Ω (convex): bodies must stay ``radius`` inside its walls.
    gap : float
        Extra clearance between bodies.
    max_draws : int, optional
        Give up after this many candidates (default ``200 n + 1000``).
    occupied : ndarray, shape (M, 2), optional
        Bodies of the same radius already placed, which the new ones keep clear of (not returned).

    Raises
    ------
    ParameterError
        ``crowd.options.jupedsim.radius`` when fewer than ``n`` bodies could be placed: the bodies do
        not fit in the room (or in the initial law's support) without overlapping.
    """
    if not radius > 0:
        raise ParameterError("crowd.options.jupedsim.radius", radius, "a body radius > 0")
    limit = 200 * n + 1000 if max_draws is None else max_draws
    d_min = 2.0 * radius + gap
    cell = d_min
    buckets: dict[tuple[int, int], list[int]] = {}
    before = np.empty((0, 2)) if occupied is None else np.asarray(occupied, float).reshape(-1, 2)
    m = len(before)
    kept = np.empty((m + n, 2))
    kept[:m] = before
    for k, (x, y) in enumerate(before):
        buckets.setdefault((math.floor(x / cell), math.floor(y / cell)), []).append(k)
    n += m
    count, drawn = m, 0
    while count < n and drawn < limit:
        batch = np.asarray(draw(min(max(2 * (n - count), 64), limit - drawn)), float)
        drawn += len(batch)
        inside = domain.contains(batch[:, 0], batch[:, 1], tol=-radius)
        for x, y in batch[inside]:
            i, j = math.floor(x / cell), math.floor(y / cell)
            clash = False
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    for k in buckets.get((i + di, j + dj), ()):
                        if (kept[k, 0] - x) ** 2 + (kept[k, 1] - y) ** 2 < d_min * d_min:
                            clash = True
                            break
                    if clash:
                        break
                if clash:
                    break
            if clash:
                continue
            kept[count] = (x, y)
            buckets.setdefault((i, j), []).append(count)
            count += 1
            if count == n:
                break
    if count < n:
        raise ParameterError(
            "crowd.options.jupedsim.radius",
            radius,
            f"a body radius at which {n - m} humans fit without overlapping in the initial crowd "
            f"(only {count - m} could be placed from {drawn} draws; use smaller bodies, fewer humans "
            "or a wider initial law)",
        )
    return kept[m:]


def place_groups(groups: list[dict[str, Any]], radius: float, domain: Region, rng: np.random.Generator) -> np.ndarray:
    """Each group's bodies in its region, group after group, none overlapping another (``crowd.initial =
    "groups"``, :mod:`meanfield.crowds.groups`): :func:`place_bodies` from the uniform law on the region, each
    group keeping clear of the groups placed before it.

    Raises
    ------
    ParameterError
        ``crowd.groups[i].n`` when the group's bodies do not fit in its region without overlapping.
    """
    import shapely

    from meanfield.crowds.groups import group_region

    placed = np.empty((0, 2))
    for i, g in enumerate(groups):
        region = group_region(g["region"], f"crowd.groups[{i}].region")
        x0, y0, x1, y1 = region.bounds

        def draw(k: int, region: Any = region, box: tuple = ((x0, y0), (x1, y1))) -> np.ndarray:
            p = rng.uniform(*box, size=(4 * k + 8, 2))
            return p[shapely.contains_xy(region, p[:, 0], p[:, 1])][:k]

        try:
            bodies = place_bodies(draw, g["n"], radius, domain, occupied=placed)
        except ParameterError:
            raise ParameterError(
                f"crowd.groups[{i}].n", g["n"],
                f"a count whose bodies of radius {radius:g} m fit in the group's region without overlapping "
                "(use a larger region, fewer people or smaller bodies, crowd.options.jupedsim.radius)",
            ) from None  # fmt: skip
        placed = np.vstack([placed, bodies])
    return placed


def door_areas(area: Any, segs: np.ndarray, depth: float) -> tuple[Any, list[Any]]:
    """JuPedSim's walkable area and one exit area per door (:mod:`meanfield.geometry.exits` segments).

    Each door gets a *vestibule*: the rectangle on the door segment, ``depth`` deep on the
    side away from Ω (and ``depth / 1000`` into Ω, so that it overlaps Ω rather than
    touching it up to round-off).  It is added to the walkable area and is the door's exit
    area, so that a body walks through the door and leaves once its centre has crossed it.
    A vestibule that would reach into Ω away from its door (a wall thinner than ``depth``
    behind the door, a pillar cut in two) is not added; the exit area is then the strip
    ``depth`` deep just inside the door, where a body leaves when it reaches the door.

    Parameters
    ----------
    area : shapely.Polygon
        Ω (holes allowed).
    segs : ndarray, shape (E, 2, 2)
        The doors.
    depth : float
        Depth of the vestibules and strips, > 0 (twice the body radius).

    Returns
    -------
    walkable : shapely.Polygon
        Ω with the vestibules.
    exits : list of shapely.Polygon
        The exit areas, in the order of ``segs``.
    """
    import shapely

    walkable, exits = area, []
    for a, b in np.asarray(segs, float):
        e = b - a
        normal = np.array([e[1], -e[0]]) / math.hypot(*e)
        # the side away from Ω is the one whose rectangle covers less of Ω
        inward = [shapely.area(shapely.intersection(_rect(a, b, s * normal, 0.0, depth), area)) for s in (1.0, -1.0)]
        outward = normal if inward[0] <= inward[1] else -normal
        vestibule = _rect(a, b, outward, -1e-3 * depth, depth)
        overlap = shapely.intersection(vestibule, area)
        grown = shapely.union(walkable, vestibule)
        fits = (  # Ω meets the vestibule only next to the door (a disk's chord: the cap behind it)
            shapely.hausdorff_distance(overlap, shapely.LineString([a, b])) <= 0.25 * depth
            and isinstance(grown, shapely.Polygon)
            and len(grown.interiors) == len(walkable.interiors)
        )
        if fits:
            # one order of the walls, whatever the doors: the anticipation model slides along
            # the walls one after the other, and some orders stop its bodies at a door post
            walkable = shapely.normalize(grown)
            exits.append(vestibule)
        else:
            exits.append(shapely.intersection(_rect(a, b, -outward, 0.0, depth), area))
    return walkable, exits


def _rect(a: np.ndarray, b: np.ndarray, normal: np.ndarray, near: float, far: float) -> Any:
    """The rectangle on the segment ``a b`` between the offsets ``near`` and ``far`` along ``normal``."""
    import shapely

    return shapely.Polygon([a + near * normal, b + near * normal, b + far * normal, a + far * normal])


class JuPedSimEngine:
    """Humans as JuPedSim bodies under direct steering (the interface of
    :class:`~meanfield.crowds.point_mass.PointMassEngine`).

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Initial positions: inside Ω, a radius from the walls, bodies not overlapping
        (see :func:`place_bodies`).
    domain : Region
        Ω, the walkable area.
    radius : float
        Body radius (m).
    max_speed : float
        Cap on the desired speed (m/s).
    time_step : float
        JuPedSim's step; the control period must be a whole number of them.
    model : str
        JuPedSim operational model (``crowd.options.jupedsim.model``).
    seed : int
        Seed for models with randomness.
    parameters : mapping of str to float, optional
        The model's parameters that differ from JuPedSim's defaults
        (:data:`~meanfield.crowds._jupedsim_api.MODEL_PARAMETERS`; :meth:`JuPedSimOptions.parameters`).

    Attributes
    ----------
    exits : ndarray, shape (E, 2, 2)
        Ω's exits (:func:`~meanfield.geometry.exits.exit_segments`), as in
        :class:`~meanfield.crowds.point_mass.PointMassEngine`.
    active : ndarray of bool, shape (N,)
        The humans still in Ω.
    exit_time : ndarray, shape (N,)
        When each human left: the end of the JuPedSim step that brought its centre through
        the door (NaN while here).
    exit_index : ndarray of int, shape (N,)
        The exit it left through (-1 while here).
    """

    def __init__(
        self,
        positions: np.ndarray,
        domain: Region,
        radius: float,
        max_speed: float,
        time_step: float,
        model: str = "collision-free-speed",
        seed: int = 0,
        parameters: dict[str, float] | None = None,
    ):
        positions = np.array(positions, dtype=float)
        if positions.ndim != 2 or positions.shape[1] != 2 or len(positions) < 1:
            raise ParameterError("crowd.positions", positions.shape, "an array of shape (N, 2), N >= 1")
        inside = domain.contains(positions[:, 0], positions[:, 1], tol=-radius * (1 - 1e-9))
        if not inside.all():
            k = int(np.flatnonzero(~inside)[0])
            raise ParameterError(
                f"crowd.positions[{k}]", positions[k].tolist(), f"a body of radius {radius:g} inside the walkable area"
            )
        self.domain = domain
        self.radius = float(radius)
        self.max_speed = float(max_speed)
        self.time_step = float(time_step)
        # a plan's holes (pillars) are kept: JuPedSim's geometry takes the polygon's interiors
        self.exits = exit_segments(domain)
        self.open_exits = np.ones(len(self.exits), dtype=bool)  # (an exit may close during a run: [[events]])
        area = domain.to_shapely(resolution=256)
        walkable, exit_areas = door_areas(area, self.exits, 2.0 * self.radius)
        # a region that is not convex (a plan): steering targets go to Ω shrunk by a radius
        self._inner = area.buffer(-self.radius, join_style="mitre") if self._not_convex(domain) else None
        self.adapter = JuPedSimAdapter(walkable, model, time_step, seed, exit_areas, parameters)
        self.adapter.add_agents(positions, radius, max_speed)
        self.positions = self.adapter.positions()
        self.active = self.adapter.alive.copy()
        self.exit_time = self.adapter.left_at.copy()
        self.exit_index = self.adapter.left_by.copy()
        self.model = model
        # deepest overlap of two bodies so far, over every control step (from the start)
        self.max_body_overlap, self.max_body_overlap_time = 0.0, None
        self.track_body_overlap(0.0)

    @staticmethod
    def _not_convex(domain: Region) -> bool:
        """Whether Ω may be non-convex (a plan: its reflection follows paths)."""
        return bool(getattr(domain, "reflects_along_paths", False))

    @property
    def body_radius(self) -> float:
        """The bodies' radius (the walkers keep it from the walls)."""
        return self.radius

    def track_body_overlap(self, t: float) -> None:
        """Record the deepest overlap of the bodies at time ``t``."""
        pos = self.positions[self.active]
        depth, _ = max_body_overlap(pos[:, 0], pos[:, 1], self.radius)
        if depth > self.max_body_overlap:
            self.max_body_overlap, self.max_body_overlap_time = depth, t

    def summary(self) -> dict[str, Any]:
        """The bodies' radius, model and deepest overlap over every control step.

        The recorded frames of ``timeseries.nc`` are a subset of those steps; anyone can
        re-check them with :func:`~meanfield.crowds.jupedsim_engine.max_body_overlap`.
        """
        out: dict[str, Any] = {
            "pedestrian_model": self.model,
            "pedestrian_parameters": dict(self.adapter.parameters),
            "jupedsim_version": self.adapter.version,
            "body_radius": self.radius,
            "body_overlap_max": self.max_body_overlap,
            "body_overlap_max_relative": self.max_body_overlap / (2.0 * self.radius),
            "body_overlap_time": self.max_body_overlap_time,
        }
        out.update(PointMassEngine.summary(self))  # with exits, the point masses' figures (same attributes)
        return out

    def remaining(self) -> int:
        """How many humans have not left."""
        return int(np.count_nonzero(self.active))

    @property
    def n(self) -> int:
        """Number of humans N."""
        return len(self.positions)

    def look_ahead(self, dt: float) -> float:
        """How far ahead a human's target lies: ``2 max_speed dt + 2 radius``."""
        return 2.0 * self.max_speed * dt + 2.0 * self.radius

    def steering_targets(self, velocity: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Target points and desired speeds for desired velocities (N, 2) over a period ``dt``.

        The target lies :meth:`look_ahead` ahead (farther than a period's walk, so a human
        does not stop at it), moved inside the walkable area: a target beyond a wall is
        projected onto it and pulled back a radius towards the human.  On a plan (pillars,
        re-entrant corners) that pull could land in a pillar, where JuPedSim refuses a
        target: there the target is the nearest point a radius inside the walls.  The rows
        of those who left are NaN.
        """
        speed = np.hypot(velocity[:, 0], velocity[:, 1])
        moving = speed > 0
        direction = np.zeros_like(velocity)
        direction[moving] = velocity[moving] / speed[moving, None]
        here = np.flatnonzero(self.active)
        x = self.positions[here]
        targets = np.full_like(velocity, np.nan)
        ahead = x + self.look_ahead(dt) * direction[here]
        out = ~self.domain.contains(ahead[:, 0], ahead[:, 1], tol=-self.radius)
        if out.any() and self._inner is not None:  # the nearest point a radius inside the walls
            import shapely

            lines = shapely.shortest_line(self._inner, shapely.points(ahead[out]))
            ahead[out] = shapely.get_coordinates(lines).reshape(-1, 2, 2)[:, 0]
        elif out.any():  # convex Ω: onto the wall, then a radius back towards the human
            q = self.domain.project(ahead[out].copy())
            back = x[out] - q
            dist = np.hypot(back[:, 0], back[:, 1])
            pull = np.minimum(self.radius, dist)
            ok = dist > 0
            q[ok] += back[ok] * (pull[ok] / dist[ok])[:, None]
            q[~ok] = x[out][~ok]
            ahead[out] = q
        targets[here] = ahead
        return targets, np.minimum(speed, self.max_speed)

    def exit_routes(self, velocity: np.ndarray, dt: float) -> np.ndarray:
        """The exit each human walks through (-1: none): the first its look-ahead crosses.

        A human whose desired velocity (N, 2) leads through a door within
        :meth:`look_ahead` walks on that exit's journey (JuPedSim routes it through the door).
        """
        routes = np.full(len(velocity), -1, dtype=np.intp)
        speed = np.hypot(velocity[:, 0], velocity[:, 1])
        rows = np.flatnonzero(self.active & (speed > 0))
        if not len(self.exits) or not len(rows):
            return routes
        x = self.positions[rows]
        ahead = x + (self.look_ahead(dt) / speed[rows])[:, None] * velocity[rows]
        routes[rows] = leaving(x, ahead, self.exits, 0.0, dt, None)  # crossings only: no draw
        closed = routes >= 0
        closed[closed] = ~self.open_exits[routes[closed]]
        routes[closed] = -1  # a closed exit's journey takes nobody (those on it are steered back)
        return routes

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """From now on nobody leaves through the exits without ``open_exits[k]`` (a scenario's ``[[events]]``).

        No body is put on a closed exit's journey any more, and those on it are switched back to direct
        steering at the next step (:meth:`exit_routes`); its door area stays walkable, a recess in the wall.
        """
        self.open_exits = np.asarray(open_exits, dtype=bool).copy()

    def step(self, drift: np.ndarray, t: float, dt: float) -> None:
        """Walk the bodies for one control period ``dt`` towards the desired velocities ``drift``.

        With exits, a human whose velocity leads through a door walks through it
        (:meth:`exit_routes`) and leaves: its row of :attr:`positions` becomes NaN, and
        :attr:`active`, :attr:`exit_time`, :attr:`exit_index` record it.
        """
        targets, speeds = self.steering_targets(drift, dt)
        routes = self.exit_routes(drift, dt) if len(self.exits) else None
        self.adapter.steer(targets, speeds, routes)
        self.adapter.iterate(int(round(dt / self.time_step)))
        self.adapter.positions(out=self.positions)
        if len(self.exits):
            self.active[:] = self.adapter.alive
            self.exit_time[:] = self.adapter.left_at
            self.exit_index[:] = self.adapter.left_by
        self.track_body_overlap(t + dt)


@dataclass
class JuPedSimOptions:
    """The JuPedSim crowd's options, the table ``[crowd.options.jupedsim]`` of a scenario.

    Each control period ``dt`` every human gets a desired velocity (``v_r`` or its random
    walk) whose speed is capped at ``max_speed`` (m/s); JuPedSim advances in steps of
    ``time_step`` (s; ``dt`` must be a whole number of them) with the operational ``model``,
    one of :data:`~meanfield.crowds._jupedsim_api.PEDESTRIAN_MODELS`, moving bodies of
    ``radius`` metres.  The table is kept whatever ``crowd.kind`` is, so that
    ``--crowd jupedsim`` finds it.

    The model's own parameters, by JuPedSim's names, each unset (``None``, or the string
    ``"default"``, which ``--set`` can give: JuPedSim's default) unless given: ``time_gap`` (s,
    how fast a body closes a gap: its speed is the gap to the one ahead over ``time_gap``;
    JuPedSim accepts 0.1–10 s), the neighbours' and the walls' repulsion
    ``strength_neighbor_repulsion``, ``range_neighbor_repulsion`` (m),
    ``strength_geometry_repulsion``, ``range_geometry_repulsion`` (m).  The collision-free speed
    models (v1, v2, v3) have all five, the anticipation velocity model the first three, the
    others none (:data:`~meanfield.crowds._jupedsim_api.MODEL_PARAMETERS`): a parameter the
    model does not have is refused, naming it (unset it to change the model).

    The defaults are the body and the step of JuPedSim's own validation of the bottleneck
    (jpscore's ``systemtest/Validation/test_13``: the collision-free speed model, bodies of
    0.15 m, steps of 0.05 s, ``T`` = 1 s); with bodies of 0.2 m (JuPedSim's default) and steps
    of 0.01 s the bodies clog a 0.8 m bottleneck and stall at rimea-9's doors
    (``studies/jupedsim_bottleneck_alone.py``).  That validation's neighbour repulsion, 5 where
    JuPedSim's default is 8, is what the ``bottleneck`` and ``rimea-9`` scenarios set.
    """

    model: str = "collision-free-speed"
    radius: float = 0.15
    max_speed: float = 1.34
    time_step: float = 0.05
    time_gap: float | None = None
    strength_neighbor_repulsion: float | None = None
    range_neighbor_repulsion: float | None = None
    strength_geometry_repulsion: float | None = None
    range_geometry_repulsion: float | None = None

    def __post_init__(self) -> None:
        self.model = choice(f"{_OPTIONS}.model", self.model, PEDESTRIAN_MODELS)
        self.radius = num(f"{_OPTIONS}.radius", self.radius, lo=0.0, lo_open=True)
        self.max_speed = num(f"{_OPTIONS}.max_speed", self.max_speed, lo=0.0, lo_open=True)
        self.time_step = num(f"{_OPTIONS}.time_step", self.time_step, lo=0.0, lo_open=True)
        for name in ("time_gap", *REPULSION):
            if isinstance(getattr(self, name), str) and getattr(self, name) == "default":
                setattr(self, name, None)
        if self.time_gap is not None:  # JuPedSim's own bounds (CheckModelConstraint)
            self.time_gap = num(f"{_OPTIONS}.time_gap", self.time_gap, lo=0.1, hi=10.0)
        for name in REPULSION:
            if getattr(self, name) is not None:
                setattr(self, name, num(f"{_OPTIONS}.{name}", getattr(self, name), lo=0.0, lo_open=True))
        has = MODEL_PARAMETERS[self.model]
        for name, value in self.parameters().items():
            if name not in has:
                raise ParameterError(
                    f"{_OPTIONS}.{name}",
                    value,
                    f'"default" (the model {self.model} has no such parameter; it has: {", ".join(has) or "none"})',
                )

    def parameters(self) -> dict[str, float]:
        """The model's parameters that are set (the others keep JuPedSim's defaults), by JuPedSim's names."""
        return {name: getattr(self, name) for name in ("time_gap", *REPULSION) if getattr(self, name) is not None}

    @classmethod
    def of(cls, scenario: Any) -> JuPedSimOptions:
        """The options a scenario gives this crowd (defaults where its table is absent)."""
        return cls(**scenario.crowd.options.get(_KIND, {}))


_KIND = "jupedsim"
_OPTIONS = f"crowd.options.{_KIND}"


def check_scenario(scenario: Any) -> None:
    """The JuPedSim crowd's cross-field checks of a scenario that chooses it: SI units, whole
    sub-steps, bodies that fit (:class:`~meanfield.errors.ParameterError` naming the field)."""
    p = JuPedSimOptions.of(scenario)
    if scenario.units != "SI":
        raise ParameterError(
            "crowd.kind",
            _KIND,
            f"a scenario in metres and seconds (units = \"SI\") for JuPedSim's bodies, whose radius "
            f"({p.radius:g} m) and speed ({p.max_speed:g} m/s) are physical; this one is {scenario.units} "
            "(the paper's room widths): use paper-unity, the same study in metres",
        )
    if scenario.congestion_model != "none":
        raise ParameterError(
            "crowd.congestion",
            scenario.crowd.congestion,
            '"none" or "auto" for JuPedSim\'s bodies, which queue by their own model (a speed that falls '
            "with the distance to the one ahead); the diagrams slow point masses and the density",
        )
    k = scenario.dt / p.time_step
    if round(k) < 1 or abs(k - round(k)) > 1e-9 * k:
        raise ParameterError(
            f"{_OPTIONS}.time_step", p.time_step, f"a step that divides dt = {scenario.dt:g} a whole number of times"
        )
    cover = scenario.crowd.n * math.pi * p.radius**2 / scenario.domain.area
    if cover > 0.5:
        raise ParameterError(
            f"{_OPTIONS}.radius",
            p.radius,
            f"a body radius whose {scenario.crowd.n} bodies cover at most half of the room "
            f"(they would cover {cover:.0%} of its area {scenario.domain.area:g})",
        )


@declares(
    CrowdCapabilities(
        options=JuPedSimOptions,  # [crowd.options.jupedsim]
        check_scenario=check_scenario,
        # people may be placed in groups, each group's bodies in its region (crowd.initial = "groups",
        # place_groups); each body keeps its group's exit, in the order place_groups places them
        places_groups=True,
        group_exits=True,
        # an exit can close during a run ([[events]], JuPedSimEngine.exits_closed): no body is routed through it
        # any more, and the informed crowd's routes lead to the exits still open
        closes_exits=True,
        # each body may wait its pre-movement time (its desired speed is 0 until then: it stands, and only other
        # bodies may push it) and ignore the signs (it walks the random walk of [view]): Individuals
        models_individuals=True,
    )
)
def jupedsim_crowd(ctx: CrowdContext) -> AgentCrowd:
    """Registry factory (kind ``crowd``, name ``jupedsim``): the scenario's humans as JuPedSim bodies.

    The initial bodies come from the scenario's initial law without overlap
    (:func:`place_bodies`), or group by group in the groups' regions (:func:`place_groups`); without
    JuPedSim, its adapter refuses here with the install command.
    Its options are :class:`JuPedSimOptions` (``[crowd.options.jupedsim]``), checked with the
    scenario by :func:`check_scenario`.
    """
    sc = ctx.scenario
    ped = JuPedSimOptions.of(sc)
    if sc.crowd.initial == "groups":
        humans = place_groups(sc.crowd.groups, ped.radius, sc.domain, ctx.rng)
    else:
        humans = place_bodies(lambda k: initial_positions(sc, k, ctx.rng), sc.crowd.n, ped.radius, sc.domain)
    engine = JuPedSimEngine(
        humans, sc.domain, ped.radius, ped.max_speed, ped.time_step, ped.model, sc.seed, ped.parameters()
    )
    return AgentCrowd.from_context(engine, ctx)


def max_body_overlap(x: np.ndarray, y: np.ndarray, radius: float) -> tuple[float, int]:
    """Deepest interpenetration of disks of ``radius`` over recorded frames.

    Parameters
    ----------
    x, y : ndarray, shape (T, N) or (N,)
        Positions of the N humans at T frames (e.g. a run's ``human_x``, ``human_y``).
    radius : float
        Body radius.

    Returns
    -------
    overlap : float
        ``max(0, 2 radius − |x_i − x_j|)`` over all pairs and frames (same unit as x).
    frame : int
        The frame where it occurs (-1 when no two bodies touch).
    """
    from scipy.spatial import cKDTree

    x = np.atleast_2d(np.asarray(x, float))
    y = np.atleast_2d(np.asarray(y, float))
    worst, where = 0.0, -1
    for k in range(x.shape[0]):
        pts = np.column_stack([x[k], y[k]])
        pairs = cKDTree(pts).query_pairs(2.0 * radius, output_type="ndarray")
        if len(pairs):
            d = np.hypot(*(pts[pairs[:, 0]] - pts[pairs[:, 1]]).T)
            depth = float(2.0 * radius - d.min())
            if depth > worst:
                worst, where = depth, k
    return worst, where
