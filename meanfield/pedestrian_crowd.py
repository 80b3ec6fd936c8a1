"""The crowd as pedestrians with bodies: the JuPedSim backend of the closed loop.

Where :class:`~meanfield.crowd.Crowd` moves point masses by the SDE of eq. (1), this crowd
hands each human's velocity to a JuPedSim operational model (the collision-free speed
model by default) as a *desired* velocity: every control period ``dt`` each human gets a
target point ahead of it in the direction of that velocity and a desired speed equal to
its magnitude, capped at ``max_speed``; JuPedSim then walks the bodies ``dt / time_step``
steps, avoiding each other and the walls.  The Brownian term of eq. (1) is not applied:
bodies, collision avoidance and the random walk of the humans who see no robot
(:mod:`meanfield.local_view`) replace it.

:func:`place_bodies` draws the initial crowd from the scenario's initial law without
overlapping bodies and at least one radius from the walls, or refuses the body radius.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from meanfield.agent_crowd import AgentCrowd, initial_positions
from meanfield.errors import ParameterError
from meanfield.interfaces import CrowdContext
from meanfield.jupedsim_api import JuPedSimAdapter
from meanfield.metrics import max_body_overlap
from meanfield.region import Region as Domain

__all__ = ["PedestrianCrowd", "place_bodies", "jupedsim_crowd"]


def place_bodies(
    draw: Callable[[int], np.ndarray],
    n: int,
    radius: float,
    domain: Domain,
    *,
    gap: float = 0.0,
    max_draws: int | None = None,
) -> np.ndarray:
    """``n`` non-overlapping bodies from a law, by random sequential adsorption.

    Candidates are drawn from ``draw(k) -> (k, 2)`` (the scenario's initial law) and kept
    when their disk of ``radius`` lies in Ω and keeps ``gap`` from every kept body.

    Parameters
    ----------
    draw : callable
        ``draw(k)`` returns ``k`` candidate positions (uses the caller's generator).
    n : int
        Number of bodies.
    radius : float
        Body radius ``> 0``.
    domain : Domain
        Ω (convex): bodies must stay ``radius`` inside its walls.
    gap : float
        Extra clearance between bodies.
    max_draws : int, optional
        Give up after this many candidates (default ``200 n + 1000``).

    Raises
    ------
    ParameterError
        ``pedestrians.radius`` when fewer than ``n`` bodies could be placed: the bodies do
        not fit in the room (or in the initial law's support) without overlapping.
    """
    if not radius > 0:
        raise ParameterError("pedestrians.radius", radius, "a body radius > 0")
    limit = 200 * n + 1000 if max_draws is None else max_draws
    d_min = 2.0 * radius + gap
    cell = d_min
    buckets: dict[tuple[int, int], list[int]] = {}
    kept = np.empty((n, 2))
    count = drawn = 0
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
            "pedestrians.radius",
            radius,
            f"a body radius at which {n} humans fit without overlapping in the initial crowd "
            f"(only {count} could be placed from {drawn} draws; use smaller bodies, fewer humans "
            "or a wider initial law)",
        )
    return kept


class PedestrianCrowd:
    """Humans as JuPedSim bodies under direct steering (same interface as :class:`~meanfield.crowd.Crowd`).

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Initial positions: inside Ω, a radius from the walls, bodies not overlapping
        (see :func:`place_bodies`).
    domain : Domain
        Ω, the walkable area.
    radius : float
        Body radius (m).
    max_speed : float
        Cap on the desired speed (m/s).
    time_step : float
        JuPedSim's step; the control period must be a whole number of them.
    model : str
        JuPedSim operational model (``pedestrians.model``).
    seed : int
        Seed for models with randomness.
    """

    def __init__(
        self,
        positions: np.ndarray,
        domain: Domain,
        radius: float,
        max_speed: float,
        time_step: float,
        model: str = "collision-free-speed",
        seed: int = 0,
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
        self.adapter = JuPedSimAdapter(domain.to_shapely(resolution=256), model, time_step, seed)
        self.adapter.add_agents(positions, radius, max_speed)
        self.positions = self.adapter.positions()
        self.model = model
        # deepest overlap of two bodies so far, over every control step (from the start)
        self.max_body_overlap, self.max_body_overlap_time = 0.0, None
        self.track_body_overlap(0.0)

    @property
    def body_radius(self) -> float:
        """The bodies' radius (the walkers keep it from the walls)."""
        return self.radius

    def track_body_overlap(self, t: float) -> None:
        """Record the deepest overlap of the bodies at time ``t``."""
        pos = self.positions
        depth, _ = max_body_overlap(pos[:, 0], pos[:, 1], self.radius)
        if depth > self.max_body_overlap:
            self.max_body_overlap, self.max_body_overlap_time = depth, t

    def summary(self) -> dict[str, Any]:
        """The bodies' radius, model and deepest overlap over every control step.

        The recorded frames of ``timeseries.nc`` are a subset of those steps; anyone can
        re-check them with :func:`~meanfield.metrics.max_body_overlap`.
        """
        return {
            "pedestrian_model": self.model,
            "jupedsim_version": self.adapter.version,
            "body_radius": self.radius,
            "body_overlap_max": self.max_body_overlap,
            "body_overlap_max_relative": self.max_body_overlap / (2.0 * self.radius),
            "body_overlap_time": self.max_body_overlap_time,
        }

    @property
    def n(self) -> int:
        """Number of humans N."""
        return len(self.positions)

    def steering_targets(self, velocity: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Target points and desired speeds for desired velocities (N, 2) over a period ``dt``.

        The target lies ``2 max_speed dt + 2 radius`` ahead (farther than a period's walk,
        so a human does not stop at it), moved inside the walkable area: a target beyond a
        wall is projected onto it and pulled back a radius towards the human.
        """
        speed = np.hypot(velocity[:, 0], velocity[:, 1])
        moving = speed > 0
        direction = np.zeros_like(velocity)
        direction[moving] = velocity[moving] / speed[moving, None]
        x = self.positions
        targets = x + (2.0 * self.max_speed * dt + 2.0 * self.radius) * direction
        out = ~self.domain.contains(targets[:, 0], targets[:, 1], tol=-self.radius)
        if out.any():
            q = self.domain.project(targets[out].copy())
            back = x[out] - q
            dist = np.hypot(back[:, 0], back[:, 1])
            pull = np.minimum(self.radius, dist)
            ok = dist > 0
            q[ok] += back[ok] * (pull[ok] / dist[ok])[:, None]
            q[~ok] = x[out][~ok]
            targets[out] = q
        return targets, np.minimum(speed, self.max_speed)

    def step(self, drift: np.ndarray, t: float, dt: float) -> None:
        """Walk the bodies for one control period ``dt`` towards the desired velocities ``drift``."""
        targets, speeds = self.steering_targets(drift, dt)
        self.adapter.steer(targets, speeds)
        self.adapter.iterate(int(round(dt / self.time_step)))
        self.adapter.positions(out=self.positions)
        self.track_body_overlap(t + dt)


def jupedsim_crowd(ctx: CrowdContext) -> AgentCrowd:
    """Registry factory (kind ``crowd``, name ``jupedsim``): the scenario's humans as JuPedSim bodies.

    The initial bodies come from the scenario's initial law without overlap
    (:func:`place_bodies`); without JuPedSim, its adapter refuses here with the install command.
    """
    sc = ctx.scenario
    ped = sc.pedestrians
    humans = place_bodies(lambda k: initial_positions(sc, k, ctx.rng), sc.crowd.n, ped.radius, sc.domain)
    engine = PedestrianCrowd(humans, sc.domain, ped.radius, ped.max_speed, ped.time_step, ped.model, sc.seed)
    return AgentCrowd.from_context(engine, ctx)
