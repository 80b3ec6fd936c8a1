"""The crowd as agents under the robots' signs: the drift of eq. (1) and the density the robots see.

An :class:`AgentCrowd` implements :class:`~meanfield.interfaces.Crowd` for any *engine* that
moves agents given their velocities: the point-mass SDE (:class:`~meanfield.crowds.point_mass.PointMassEngine`,
registered as ``point-mass``) or JuPedSim's bodies
(:class:`~meanfield.crowds.jupedsim_engine.JuPedSimEngine`, ``jupedsim``).  What the humans feel
is the same for both (paper, eq. (1))::

    u_W(X_j) + v_r(X_j, t) + v_a(X_j, t)

with ``v_r`` (eq. (3)) evaluated exactly or sampled on a lattice (large crowds,
:mod:`meanfield.signs.sampled_field`), replaced by a random walk for the humans who see no robot
(:mod:`meanfield.crowds.local_view`).  The robots observe the crowd through a Gaussian KDE on the
grid (paper, Section IV-A; :mod:`meanfield.crowds.kde`).

With congestion (``crowd.congestion`` other than ``"none"``, :mod:`meanfield.crowds.congestion`)
each human walks at ``g(ρ_j)`` times the velocity it chooses, ``ρ_j`` the density around it in
persons/m² (:func:`local_density`: its neighbours within :data:`DENSITY_RADIUS`; docs page
*Congestion*)::

    u_W(X_j) + g(ρ_j) v_r(X_j, t) + v_a(X_j, t)

``v_r`` standing for whatever the human follows: the signs, the random walk out of a robot's
view, or a baseline's guidance.  The interaction, the disturbance and the Brownian noise are
not slowed (the mean-field equation keeps ``σΔρ`` as it is: ``∂ₜρ + ∇·(ρ g(ρ) v) = σΔρ``).
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from meanfield import plugins
from meanfield.crowds._congestion_loops import count_neighbours
from meanfield.crowds._field_loops import bilinear_at, gaussian_field_at
from meanfield.crowds.congestion import FundamentalDiagram
from meanfield.crowds.guidance import Guidance
from meanfield.crowds.kde import KernelDensityEstimator
from meanfield.crowds.local_view import LocalView
from meanfield.crowds.point_mass import PointMassEngine
from meanfield.errors import ParameterError
from meanfield.geometry.region import Region
from meanfield.geometry.sight import SightLines
from meanfield.geometry.target import fraction_in_disk
from meanfield.interfaces import CrowdContext, Disturbance
from meanfield.signs.interaction import InteractionField
from meanfield.signs.kernels import GaussianKernel, NavigationKernel
from meanfield.signs.robots import RobotTeam, navigation_velocity
from meanfield.signs.sampled_field import SampledNavigationField

__all__ = [
    "AgentEngine",
    "AgentCrowd",
    "initial_positions",
    "local_density",
    "point_mass_crowd",
    "SAMPLED_FIELD_ABOVE",
    "DENSITY_RADIUS",
]

SAMPLED_FIELD_ABOVE = 2_000_000
"""``crowd.field_evaluation = "auto"`` samples ``v_r`` on a lattice above this many human-robot pairs."""
_EVERYONE = np.ones((0, 0), dtype=bool)  # no sight mask: every robot seen
REACH_FRACTION = 0.05
"""A sign *reaches* a human whose ``|v_r|`` is at least this share of one kernel's peak (and who
sees a robot): :attr:`AgentCrowd.reached`, the stragglers of ``summary.json``."""
DENSITY_RADIUS = 0.6
"""m: the local density of a congested human counts its neighbours within this radius (docs page
*Congestion*: small enough to resolve a 0.8 m door, large enough to hold a few people at the
densities where walking slows, 1.1 persons in the disk at 1 person/m²)."""


def local_density(
    positions: np.ndarray, active: np.ndarray | None = None, radius: float = DENSITY_RADIUS
) -> np.ndarray:
    """Each human's local density, persons/m²: the other humans within ``radius``, over ``π radius²``.

    One compiled pass over a cell list (:func:`meanfield.crowds._congestion_loops.count_neighbours`),
    O(N).  The disk is not clipped by walls: a human against a wall sees about half the
    density there is (docs page *Congestion*).

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        The humans (rows of those not active are ignored).
    active : ndarray of bool, shape (N,), optional
        Who is still here (None: everyone).
    radius : float
        ``r > 0``, metres.

    Returns
    -------
    ndarray, shape (N,)
        ``#{k ≠ j active: |X_k − X_j| < r} / (π r²)``; 0 for those not active.
    """
    if not radius > 0:
        raise ParameterError("radius", radius, "a radius > 0 (m)")
    x = np.ascontiguousarray(positions, dtype=float)
    here = np.ones(len(x), dtype=bool) if active is None else np.ascontiguousarray(active, dtype=bool)
    counts = np.empty(len(x), dtype=np.int64)
    count_neighbours(x, here, float(radius), counts)
    return counts / (math.pi * radius * radius)


class AgentEngine(Protocol):
    """Moves agents given each one's velocity (the SDE step, or JuPedSim's bodies)."""

    positions: np.ndarray
    body_radius: float

    def step(self, drift: np.ndarray, t: float, dt: float) -> None: ...

    def summary(self) -> dict[str, Any]: ...


def initial_positions(scenario: Any, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` initial positions from the scenario's crowd law (uniform on Ω, or a normal law
    restricted to Ω by rejection), drawn from ``rng``."""
    c = scenario.crowd
    if c.initial == "uniform":
        return scenario.domain.sample_uniform(n, rng)
    out = np.empty((0, 2))
    while len(out) < n:
        p = rng.normal(loc=c.initial_center, scale=c.initial_std, size=(2 * (n - len(out)) + 8, 2))
        out = np.vstack([out, p[scenario.domain.contains(p[:, 0], p[:, 1])]])
    return out[:n].copy()


class AgentCrowd:
    """Agents that follow the robots' signs (the :class:`~meanfield.interfaces.Crowd` of agents).

    With exits (and an engine that models them, the point-mass SDE), the agents who left are
    NaN rows of :attr:`positions`; the drift, the KDE and the fractions use those still here.

    Parameters
    ----------
    engine : AgentEngine
        Owns the positions and moves them.
    kernel : NavigationKernel
        The robots' navigation kernel (eq. (3)).
    kde : KernelDensityEstimator
        How the robots estimate the density on the grid.
    view : LocalView
        Who sees a robot (everyone without a view radius).
    interaction : InteractionField, optional
        ``u_W`` at the agents.
    disturbance : callable, optional
        ``v_a(x, y, t)``.
    field_evaluation : {"exact", "sampled"}
        ``v_r`` at the agents exactly (O(Nn)) or sampled on a lattice over Ω's bounding box.
    domain : Region
        Ω (its bounding box carries the sampled lattice).
    sample_cells : (int, int)
        The grid's cells; the sampled lattice has ``2 nx + 1 × 2 ny + 1`` nodes.
    sight : SightLines, optional
        A plan's walls: a human behind a wall does not see that robot's sign
        (:mod:`meanfield.geometry.sight`, decided between the grid's cells); exact field evaluation only.
    guidance : Guidance, optional
        A baseline the humans follow instead of the signs (:mod:`meanfield.crowds.guidance`); None:
        the robots' signs.
    congestion : FundamentalDiagram, optional
        The speed–density relation the humans walk by (:mod:`meanfield.crowds.congestion`);
        None, or a diagram that does not slow (``slows`` false, ``"none"``): no congestion, every number as
        without it.
    density_radius : float
        The radius of each human's local density with congestion, m (:data:`DENSITY_RADIUS`).
    """

    def __init__(
        self,
        engine: AgentEngine,
        kernel: NavigationKernel,
        kde: KernelDensityEstimator,
        view: LocalView,
        interaction: InteractionField | None = None,
        disturbance: Disturbance | None = None,
        field_evaluation: str = "exact",
        domain: Region | None = None,
        sample_cells: tuple[int, int] = (30, 30),
        sight: SightLines | None = None,
        guidance: Guidance | None = None,
        congestion: FundamentalDiagram | None = None,
        density_radius: float = DENSITY_RADIUS,
    ):
        self.engine = engine
        self.kernel = kernel
        self.kde = kde
        self.view = view
        self.interaction = interaction
        self.disturbance = disturbance
        self.field_evaluation = field_evaluation
        self.sight = sight
        self.guidance = guidance
        if sight is not None and field_evaluation == "sampled":
            raise ParameterError(
                "crowd.field_evaluation",
                field_evaluation,
                "'exact' or 'auto' on a plan whose walls hide signs (a sampled field cannot tell which side of a wall)",
            )
        self.reached: np.ndarray | None = None  # whom a sign reached at the last step (None: baselines)
        peak = kernel.magnitude(np.zeros(1), np.zeros(1))
        self._reach_speed = REACH_FRACTION * float(np.max(np.abs(peak)))
        self.sampled_field = None
        if field_evaluation == "sampled":
            nx, ny = sample_cells
            self.sampled_field = SampledNavigationField(kernel, domain.bounds, (2 * nx + 1, 2 * ny + 1))
        self._drift: np.ndarray | None = None
        self.congestion = congestion if congestion is not None and congestion.slows else None  # "none": nothing
        if self.congestion is not None and not density_radius > 0:
            raise ParameterError("density_radius", density_radius, "a radius > 0 (m)")
        self.density_radius = float(density_radius)
        self.local_density: np.ndarray | None = None  # persons/m² around each human at the last step (congestion)
        self.congestion_name = "none" if self.congestion is None else type(self.congestion).__name__.lower()
        self.peak_local_density = 0.0  # its largest value over the run so far
        self.peak_local_density_time = 0.0

    @property
    def positions(self) -> np.ndarray:
        return self.engine.positions

    @property
    def n(self) -> int:
        return len(self.engine.positions)

    @property
    def body_radius(self) -> float:
        """The agents' body radius (0 for point masses)."""
        return self.engine.body_radius

    def seen_fraction(self) -> float:
        """Fraction of the agents with a robot in view at the last step (1 without a view radius)."""
        return float(self.view.seen.mean()) if self.view.gated else 1.0  # (ungated: seen stays all True)

    def drift(self, robots: RobotTeam, t: float, dt: float) -> np.ndarray:
        """``u_W(X_j) + v_r(X_j, t) + v_a(X_j, t)`` at every agent (paper, eq. (1)).

        With a finite view radius, ``v_r`` is replaced by the random walk for the humans who
        see no robot (:meth:`LocalView.gate`).  With the Gaussian kernel or a sampled field
        the returned array is a work array, overwritten by the next call; both are one
        compiled pass over the humans (:mod:`meanfield.crowds._field_loops`).
        """
        positions = self.positions
        if self.guidance is not None:  # a baseline: the humans ignore the robots
            drift = self.guidance.velocity(positions, t, dt)
        elif self.sampled_field is not None:
            f = self.sampled_field
            f.update(robots.positions, robots.headings)
            drift, self.reached = self._work(len(positions))
            (x0, y0), (hx, hy) = f.origin, f.spacing
            bilinear_at(f.vx, f.vy, x0, y0, 1.0 / hx, 1.0 / hy, positions, self._reach_speed, drift, self.reached)
            self.view.gate(drift, positions, robots.positions, dt)
            if self.view.gated:  # (otherwise everyone sees a robot)
                self.reached &= self.view.seen
        else:
            visible = None if self.sight is None else self.sight.mask(robots.positions, positions, self.kde.grid)
            if isinstance(self.kernel, GaussianKernel):  # one compiled pass (meanfield.crowds._field_loops)
                drift, self.reached = self._work(len(positions))
                k, seen = self.kernel, _EVERYONE if visible is None else visible
                r, theta = np.asarray(robots.positions, float), np.asarray(robots.headings, float)
                gaussian_field_at(positions, r, theta, k.c, 1.0 / k.eta, seen, self._reach_speed, drift, self.reached)
            else:
                drift = navigation_velocity(self.kernel, robots.positions, robots.headings, positions, visible)
                self.reached = np.hypot(drift[:, 0], drift[:, 1]) >= self._reach_speed
            self.view.gate(drift, positions, robots.positions, dt, visible)
            if self.view.gated:  # (otherwise everyone sees a robot)
                self.reached &= self.view.seen
        if self.congestion is not None:  # (without congestion not one operation more: every number as before)
            self._slow_down(drift, positions, t)
        if self.interaction is not None:
            drift += self.interaction.at_points(positions)
        if self.disturbance is not None:
            ax, ay = self.disturbance(positions[:, 0], positions[:, 1], t)
            drift[:, 0] += ax
            drift[:, 1] += ay
        return drift

    def _slow_down(self, velocity: np.ndarray, positions: np.ndarray, t: float) -> None:
        """``velocity *= g(ρ_j)`` in place, ``ρ_j`` the local density of those still here (:func:`local_density`)."""
        active = getattr(self.engine, "active", None)
        rho = local_density(positions, active, self.density_radius)
        velocity *= self.congestion.speed_factor(rho)[:, None]
        self.local_density = rho
        peak = float(rho.max()) if len(rho) else 0.0
        if peak > self.peak_local_density:
            self.peak_local_density, self.peak_local_density_time = peak, t

    def _work(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The drift (n, 2) and reached (n,) arrays, kept between steps of the same crowd size."""
        if self._drift is None or len(self._drift) != n:
            self._drift, self._reached = np.empty((n, 2)), np.empty(n, dtype=bool)
        return self._drift, self._reached

    def _gone(self) -> np.ndarray | None:
        """The rows of the humans who left through an exit (None: everyone is here)."""
        if not len(getattr(self.engine, "exits", ())):  # no exits: nobody leaves, nothing to look at
            return None
        active = self.engine.active
        return None if active.all() else ~active

    def advance(self, robots: RobotTeam, t: float, dt: float) -> None:
        """One step of the agents under the robots' signs; the drift must be finite."""
        gone = self._gone()
        if gone is not None:  # the drift of those who left is 0, evaluated at a stand-in point
            if gone.all():
                return
            x = self.engine.positions
            x[gone] = x[np.flatnonzero(~gone)[0]]
            drift = self.drift(robots, t, dt)
            x[gone] = np.nan
            drift[gone] = 0.0
        else:
            drift = self.drift(robots, t, dt)
        self.engine.step(drift, t, dt)  # (raises SimulationDiverged, nobody moved, on a non-finite drift)
        self.view.advance(dt)
        if self.guidance is not None:
            self.guidance.advance(dt)

    def density(self) -> np.ndarray:
        """The robots' KDE of the agents on the grid (with exits: of those still here, mass = their share)."""
        gone = self._gone()
        if gone is None:
            return self.kde(self.positions)
        here = ~gone
        if not here.any():
            return np.zeros(self.kde.grid.shape)
        return self.kde(self.positions[here]) * (np.count_nonzero(here) / len(here))

    def remaining(self) -> int:
        """How many agents are still in Ω."""
        gone = self._gone()
        return self.n if gone is None else int(np.count_nonzero(~gone))

    def remaining_fraction(self) -> float:
        """The share of the crowd still in Ω (1 without exits)."""
        return self.remaining() / self.n

    @property
    def models_exits(self) -> bool:
        """Whether the engine lets agents leave through exits (the point-mass SDE does)."""
        return hasattr(self.engine, "exit_time")

    def fraction_in_disk(self, center: tuple[float, float], radius: float) -> float:
        return fraction_in_disk(self.positions, center, radius)

    def field_error_bound(self, robots: RobotTeam) -> float | None:
        """Interpolation error bound of the sampled ``v_r`` at the robots' states (None: exact)."""
        if self.sampled_field is None:
            return None
        self.sampled_field.update(robots.positions, robots.headings)
        return self.sampled_field.error_bound()

    def summary(self) -> dict[str, Any]:
        """``field_evaluation``, the view's ``seen_fraction_final`` and the engine's own figures; with
        congestion also the largest local density the humans walked in (persons/m², and when)."""
        out = {
            "field_evaluation": self.field_evaluation,
            "seen_fraction_final": self.seen_fraction(),
            **self.engine.summary(),
        }
        if self.congestion is not None:
            out["congestion"] = self.congestion_name
            out["congestion_radius"] = self.density_radius
            out["peak_local_density"] = self.peak_local_density
            out["peak_local_density_time"] = self.peak_local_density_time
        return out

    @classmethod
    def from_context(cls, engine: AgentEngine, ctx: CrowdContext) -> AgentCrowd:
        """Build the agent crowd of ``ctx.scenario`` around an engine (the registered factories use this)."""
        sc = ctx.scenario
        bw = None if sc.density.bandwidth == "silverman" else sc.density.bandwidth
        kde = KernelDensityEstimator(ctx.grid, bw, sc.density.boundary, sc.density.method)
        v = sc.view
        n = len(engine.positions)
        view = LocalView(n, v.radius, v.walk_speed, v.turning_rate, sc.domain, ctx.rng, engine.body_radius)
        mode = sc.crowd.field_evaluation
        if mode == "auto":
            mode = "sampled" if n * sc.robots.n > SAMPLED_FIELD_ABOVE and ctx.sight is None else "exact"
        guidance = plugins.load("guidance", sc.crowd.guidance)(ctx, engine.positions)
        congestion = plugins.load("congestion", sc.congestion_model)(sc.crowd.free_speed, sc.crowd.rho_max)
        crowd = cls(
            engine,
            ctx.kernel,
            kde,
            view,
            ctx.interaction,
            ctx.disturbance,
            mode,
            sc.domain,
            sc.grid.cells,
            ctx.sight,
            guidance,
            congestion,
            DENSITY_RADIUS,
        )
        crowd.congestion_name = sc.congestion_model
        return crowd


def point_mass_crowd(ctx: CrowdContext) -> AgentCrowd:
    """Registry factory (kind ``crowd``, name ``point-mass``): the SDE of eq. (1) with reflecting walls."""
    sc = ctx.scenario
    humans = initial_positions(sc, sc.crowd.n, ctx.rng)
    return AgentCrowd.from_context(PointMassEngine(humans, sc.domain, ctx.sigma, ctx.rng), ctx)


point_mass_crowd.default_congestion = {"SI": "linear"}  # type: ignore[attr-defined]
"""``crowd.congestion = "auto"``: the linear diagram in metres and seconds (it reproduces the measured
bottleneck flows, docs page *Congestion*), none in the paper's dimensionless units."""
