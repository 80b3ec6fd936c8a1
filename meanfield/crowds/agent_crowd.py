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
persons/m² (:mod:`meanfield.crowds.local_density`: its neighbours within 0.6 m, over the part of
the disk inside Ω; docs page *Congestion*)::

    u_W(X_j) + g(ρ_j) v_r(X_j, t) + v_a(X_j, t)

``v_r`` standing for whatever the human follows: the signs, the random walk out of a robot's
view, or a baseline's guidance.  The interaction, the disturbance and the Brownian noise are
not slowed (the mean-field equation keeps ``σΔρ`` as it is: ``∂ₜρ + ∇·(ρ g(ρ) v) = σΔρ``).

People are not all alike (:class:`Individuals`; docs pages *Buildings*, "People are not all
alike", and *Scenarios*): with ``crowd.premovement`` each human waits its own pre-movement time
``τ_j`` (RiMEA's test 5) and stands until then: its whole velocity is 0, and no noise moves it
(an engine that has ``standing`` keeps it still); only other bodies may push it.  With
``crowd.compliance = c < 1`` a share ``1 − c`` of the humans, drawn once, ignores the robots'
signs and walks the persistent random walk of ``[view]`` (:mod:`meanfield.crowds.local_view`), as a
human who sees no robot does.  Both draws come from the run's generator after every draw the
model made before (at the first step, after the walkers' headings and before the step's noise),
so with the defaults (``"none"``, ``1.0``) nothing is drawn and every number is as before.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from meanfield import plugins
from meanfield.capabilities import CrowdCapabilities, declares
from meanfield.crowds._field_loops import bilinear_at, gaussian_field_at
from meanfield.crowds.congestion import FundamentalDiagram, GodunovTwin
from meanfield.crowds.forward_cell import ForwardCell
from meanfield.crowds.groups import group_positions
from meanfield.crowds.guidance import Guidance
from meanfield.crowds.headway import Headway
from meanfield.crowds.kde import KernelDensityEstimator
from meanfield.crowds.local_density import DENSITY_RADIUS, LocalDensity
from meanfield.crowds.local_view import LocalView
from meanfield.crowds.memory import RouteMemory
from meanfield.crowds.point_mass import PointMassEngine
from meanfield.errors import ParameterError, num
from meanfield.geometry.region import Region
from meanfield.geometry.sight import SightLines
from meanfield.geometry.target import fraction_in_disk
from meanfield.interfaces import CrowdContext, Disturbance
from meanfield.signs.interaction import InteractionField
from meanfield.signs.kernels import REACH_FRACTION, GaussianKernel, NavigationKernel
from meanfield.signs.robots import RobotTeam, navigation_velocity
from meanfield.signs.sampled_field import SampledNavigationField

__all__ = [
    "AgentEngine",
    "AgentCrowd",
    "Individuals",
    "PREMOVEMENT_LAWS",
    "premovement_law",
    "draw_premovement",
    "initial_positions",
    "point_mass_crowd",
    "SAMPLED_FIELD_ABOVE",
]

SAMPLED_FIELD_ABOVE = 2_000_000
"""``crowd.field_evaluation = "auto"`` samples ``v_r`` on a lattice above this many human-robot pairs."""
_EVERYONE = np.ones((0, 0), dtype=bool)  # no sight mask: every robot seen


def _twin(diagram: FundamentalDiagram, region: Region | None) -> GodunovTwin:
    return GodunovTwin(diagram)


def _headway(diagram: FundamentalDiagram, region: Region | None) -> Headway:
    return Headway(diagram, region=region)


def _forward_cell(diagram: FundamentalDiagram, region: Region | None) -> ForwardCell:
    return ForwardCell(diagram, region=region)


DOOR_MODELS: dict[str, Callable[[FundamentalDiagram, Region | None], Any] | None] = {
    "count": None,  # g of the count in the whole disk (AgentCrowd._slow_down)
    "godunov-twin": _twin,
    "headway": _headway,
    "forward-cell": _forward_cell,
}
"""The agents' door models (``crowd.door_model``; docs page *Congestion*, "The agents' door model"): each makes,
from the diagram and Ω, an object whose ``slow_down(velocity, positions, active, dt, density)`` changes the walk
in place and returns the local density to report (``density``: the crowd's :class:`LocalDensity`).  One that
declares ``caps_doors`` has each exit and each inner door of the plan pass at most the diagram's capacity ``q_max``
per metre of its width (:meth:`~meanfield.crowds.point_mass.PointMassEngine.cap_exits` and
:meth:`~meanfield.crowds.point_mass.PointMassEngine.cap_doors`, on an engine that can)."""


class AgentEngine(Protocol):
    """Moves agents given each one's velocity (the SDE step, or JuPedSim's bodies)."""

    positions: np.ndarray
    body_radius: float

    def step(self, drift: np.ndarray, t: float, dt: float) -> None: ...

    def summary(self) -> dict[str, Any]: ...


@runtime_checkable
class SharesNoise(Protocol):
    """A door model with (H5), the noise shared among contacts (the headway and the forward cell; docs page
    *Congestion*, "The headway door model"): after its ``slow_down``, each human's share ``φ_j`` of σ and its
    gradient (None without (H5))."""

    noise_factor: np.ndarray | None
    noise_gradient: np.ndarray | None


@runtime_checkable
class TakesNoiseShare(Protocol):
    """An engine whose noise each human's share scales: ``σ`` (m²/s, a number or ``σ(x, y, t)``) and the share
    ``φ_j`` it steps with, ``σ φ_j`` (None: σ for all; :class:`~meanfield.crowds.point_mass.PointMassEngine`)."""

    sigma: Any
    noise_factor: np.ndarray | None


def initial_positions(scenario: Any, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` initial positions from the scenario's crowd law (uniform on Ω, a normal law
    restricted to Ω by rejection, or groups in their regions: :mod:`meanfield.crowds.groups`),
    drawn from ``rng``."""
    c = scenario.crowd
    if c.initial == "uniform":
        return scenario.domain.sample_uniform(n, rng)
    if c.initial == "groups":  # (n is the groups' sum, checked with the scenario)
        return group_positions(c.groups, scenario.domain, rng)
    out = np.empty((0, 2))
    while len(out) < n:
        p = rng.normal(loc=c.initial_center, scale=c.initial_std, size=(2 * (n - len(out)) + 8, 2))
        out = np.vstack([out, p[scenario.domain.contains(p[:, 0], p[:, 1])]])
    return out[:n].copy()


# ---------------------------------------------------------------------- people are not all alike
PREMOVEMENT_LAWS: dict[str, tuple[str, ...]] = {"uniform": ("low", "high"), "lognormal": ("median", "sigma")}
"""The laws of ``crowd.premovement`` and their parameters, in the scenario's time unit (s in SI).

``uniform``: ``τ ~ U[low, high]``, ``0 <= low <= high`` (RiMEA: uniform or normal between a
minimum and a maximum; its test 5 takes 10 to 100 s).  ``lognormal``: ``τ = median · exp(sigma Z)``,
``Z ~ N(0, 1)``, ``median > 0``, ``sigma >= 0``, the law measured pre-movement times fit best
(Forssberg et al. 2019).  Docs page *Scenarios*, "People who wait, people who do not follow"."""

_PREMOVEMENT_ALLOWED = (
    '"none", or a table {law = "uniform", low = L, high = H} with 0 <= L <= H, or '
    '{law = "lognormal", median = M, sigma = S} with M > 0 and S >= 0 (times in the scenario\'s unit, s in SI)'
)


LOGNORMAL_SIGMA_MAX = 5.0
"""The largest ``sigma`` of a lognormal pre-movement law (larger spreads draw times of 0 and of infinity)."""


def premovement_law(value: Any, field: str = "crowd.premovement") -> dict[str, Any] | None:
    """``crowd.premovement`` checked: None for ``"none"``, else the law's table with float parameters.

    Parameters
    ----------
    value : str or dict
        ``"none"``, or ``{"law": "uniform", "low": L, "high": H}`` or
        ``{"law": "lognormal", "median": M, "sigma": S}`` (:data:`PREMOVEMENT_LAWS`).
    field : str
        The field's name in the errors.

    Returns
    -------
    dict or None
        ``{"law": ..., <parameters as floats>}``.

    Raises
    ------
    ParameterError
        Naming ``field`` (not a table, not ``"none"``), ``field.law`` (an unknown law), or the
        parameter (``field.low`` below 0, ``field.high`` below ``low``, ``field.median <= 0``,
        ``field.sigma < 0``, a missing or unknown key): no pre-movement time is below 0.
    """
    if isinstance(value, str) and value == "none":
        return None
    if not isinstance(value, dict):
        raise ParameterError(field, value, _PREMOVEMENT_ALLOWED)
    law = value.get("law")
    if not isinstance(law, str) or law not in PREMOVEMENT_LAWS:
        raise ParameterError(f"{field}.law", law, f"one of {sorted(PREMOVEMENT_LAWS)}")
    keys = PREMOVEMENT_LAWS[law]
    for key in value:
        if key != "law" and key not in keys:
            raise ParameterError(f"{field}.{key}", value[key], f"a key of the {law} law: law, {', '.join(keys)}")
    for key in keys:
        if key not in value:
            raise ParameterError(f"{field}.{key}", "missing", f"a number: the {law} law takes {', '.join(keys)}")
    out: dict[str, Any] = {"law": law}
    if law == "uniform":
        out["low"] = num(f"{field}.low", value["low"], lo=0.0, allowed="a time >= 0 (no pre-movement time below 0)")
        out["high"] = num(
            f"{field}.high", value["high"], lo=out["low"], allowed=f"a finite time >= low = {out['low']:g}"
        )
    else:
        out["median"] = num(f"{field}.median", value["median"], lo=0.0, lo_open=True, allowed="a time > 0")
        out["sigma"] = num(
            f"{field}.sigma", value["sigma"], lo=0.0, hi=LOGNORMAL_SIGMA_MAX,
            allowed=f"a number in [0, {LOGNORMAL_SIGMA_MAX:g}] (the log's spread: {LOGNORMAL_SIGMA_MAX:g} already puts "
            "one person in a thousand beyond e^15 times the median)",
        )  # fmt: skip
    return out


def draw_premovement(law: dict[str, Any], n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` pre-movement times from a law of :func:`premovement_law`, drawn from ``rng`` (one call)."""
    if law["law"] == "uniform":
        return rng.uniform(law["low"], law["high"], n)
    return law["median"] * np.exp(law["sigma"] * rng.standard_normal(n))


class Individuals:
    """Who waits and who ignores the signs: each human's pre-movement time and compliance.

    Docs page *Buildings*, "People are not all alike".  Nothing is drawn until :meth:`start`
    (the crowd's first step), so that the draws come after every draw the model made before:
    first the ``N`` pre-movement times (with a law), then ``N`` uniforms ``U_j`` (with
    ``compliance < 1``; human ``j`` ignores the signs when ``U_j >= compliance``), then the
    non-followers' initial headings; each step after the crowd's own view, their headings'
    increments.

    Parameters
    ----------
    n : int
        Number of humans.
    premovement : dict, str or None
        A law of :func:`premovement_law` (None or ``"none"``: everyone walks from the start).
    compliance : float
        The share of the humans who follow the signs, in [0, 1].
    rng : numpy.random.Generator
        The run's generator.
    walk_speed, turning_rate : float
        The non-followers' random walk (``[view]``: :class:`~meanfield.crowds.local_view.LocalView`).
    domain : Region
        Ω, whose walls turn the walkers.
    clearance : float
        A body's radius (the walkers keep it from the walls).

    Attributes
    ----------
    times : ndarray, shape (N,), or None
        The pre-movement times (None without a law, or before :meth:`start`).
    ignores : ndarray of bool, shape (N,), or None
        Who ignores the signs (None with ``compliance = 1``, or before :meth:`start`).
    walk : LocalView or None
        The non-followers' walk (a view that sees no robot, one row per non-follower).
    """

    def __init__(
        self,
        n: int,
        premovement: Any,
        compliance: float,
        rng: np.random.Generator,
        walk_speed: float = 0.0,
        turning_rate: float = 0.0,
        domain: Region | None = None,
        clearance: float = 0.0,
    ):
        self.n = int(n)
        self.law = premovement_law("none" if premovement is None else premovement)
        self.compliance = num("crowd.compliance", compliance, lo=0.0, hi=1.0)
        self.rng = rng
        self.walk_speed, self.turning_rate = float(walk_speed), float(turning_rate)
        self.domain, self.clearance = domain, float(clearance)
        self.times: np.ndarray | None = None
        self.ignores: np.ndarray | None = None
        self.walkers = np.zeros(0, dtype=np.intp)  # the rows of the non-followers
        self.walk: LocalView | None = None
        self._started = False
        self._last_start = math.inf  # the latest pre-movement time (then nobody waits any more)

    @property
    def default(self) -> bool:
        """Whether everyone walks from the start and follows the signs (nothing to draw)."""
        return self.law is None and self.compliance == 1.0

    def start(self) -> None:
        """Draw the times, who ignores the signs and their headings (once; later calls do nothing)."""
        if self._started:
            return
        self._started = True
        if self.law is not None:
            self.times = draw_premovement(self.law, self.n, self.rng)
            self._last_start = float(self.times.max()) if self.n else 0.0
        if self.compliance < 1.0:
            self.ignores = self.rng.random(self.n) >= self.compliance
            self.walkers = np.flatnonzero(self.ignores)
            self.walk = LocalView.blind(
                len(self.walkers), self.walk_speed, self.turning_rate, self.domain, self.rng, self.clearance
            )
            self.walk.headings  # noqa: B018 -- drawn now, after who ignores the signs

    def waiting(self, t: float) -> np.ndarray | None:
        """Who has not started at time ``t`` (``t < τ_j``); None when nobody waits any more."""
        if self.times is None or t >= self._last_start:
            return None
        return t < self.times

    def ignore_signs(self, velocity: np.ndarray, positions: np.ndarray, dt: float) -> None:
        """Replace, in place, the rows of the non-followers of ``velocity`` (N, 2) by their walk."""
        if len(self.walkers):
            w = self.walkers
            velocity[w] = self.walk.walk_velocity(positions[w], dt)

    def walls_changed(self, change: Any) -> None:
        """The non-followers' walk turns at the new walls (a ``block`` event)."""
        self.domain = change.region
        if self.walk is not None:
            self.walk.walls_changed(change)

    def advance(self, dt: float) -> None:
        """After the step: the non-followers' headings diffuse."""
        if self.walk is not None:
            self.walk.advance(dt)

    def summary(self) -> dict[str, Any]:
        """The drawn pre-movement times (smallest, median, largest) and the number of non-followers."""
        out: dict[str, Any] = {}
        if self.law is not None:
            out["premovement_law"] = self.law["law"]
            if self.times is not None and self.n:
                out["premovement_min"] = float(self.times.min())
                out["premovement_median"] = float(np.median(self.times))
                out["premovement_max"] = float(self.times.max())
        if self.compliance < 1.0:
            out["compliance"] = self.compliance
            if self.ignores is not None:
                out["non_followers"] = int(self.ignores.sum())
        return out


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
        The radius of each human's local density with congestion, m
        (:data:`meanfield.crowds.local_density.DENSITY_RADIUS`); the disk is cut by ``domain``'s walls.
    individuals : Individuals, optional
        Pre-movement times and compliance (:class:`Individuals`); None, or one with the defaults:
        everyone walks from the start and follows the signs, every number as without it.  A
        compliance below 1 needs the robots' signs (``guidance`` None): a baseline has no sign
        to ignore.
    memory : RouteMemory, optional
        People who remember the way once a sign has reached them (``view.memory = "route"`` or ``"sign"``,
        :mod:`meanfield.crowds.memory`); None: the paper's humans.
    door_model : {"forward-cell", "headway", "count", "godunov-twin"}
        How a congested human's speed follows the crowd round it (``crowd.door_model``, :data:`DOOR_MODELS`):
        the density of its Voronoi cell ahead (:class:`~meanfield.crowds.forward_cell.ForwardCell`, the default),
        the spacing to the person ahead (:class:`~meanfield.crowds.headway.Headway`), ``g(ρ_j)`` of the count in its
        disk, or the Godunov twin (:class:`~meanfield.crowds.congestion.GodunovTwin`).
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
        individuals: Individuals | None = None,
        memory: RouteMemory | None = None,
        door_model: str = "forward-cell",
    ):
        self.engine = engine
        self.memory = memory
        self.kernel = kernel
        self.kde = kde
        self.view = view
        self.interaction = interaction
        self.disturbance = disturbance
        self.field_evaluation = field_evaluation
        self.sight = sight
        self.guidance = guidance
        self._guidance_observes = callable(getattr(guidance, "observe", None))  # (declared by the guidance)
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
        self._density = None if self.congestion is None else LocalDensity(len(engine.positions), density_radius, domain)
        if door_model not in DOOR_MODELS:
            raise ParameterError("crowd.door_model", door_model, " or ".join(map(repr, DOOR_MODELS)))
        self.door_model = door_model
        model = DOOR_MODELS[door_model]
        self._door = None if self.congestion is None or model is None else model(self.congestion, domain)
        # (H5) reaches the engine where both declare it (decided once: a protocol's isinstance costs ~16 µs a step)
        self._shares_noise = isinstance(self._door, SharesNoise) and isinstance(engine, TakesNoiseShare)
        if getattr(self._door, "caps_doors", False):  # each exit and door passes at most q_max per metre of width
            q_max = self.congestion.capacity()[0]
            for kind, cap in (("exits", "cap_exits"), ("doors", "cap_doors")):
                ends = np.asarray(getattr(engine, kind, ()), float).reshape(-1, 2, 2)
                if len(ends):
                    getattr(engine, cap)(q_max * np.hypot(*(ends[:, 1] - ends[:, 0]).T))
        self.local_density: np.ndarray | None = None  # persons/m² around each human at the last step (congestion)
        self.congestion_name = "none" if self.congestion is None else type(self.congestion).__name__.lower()
        self.peak_local_density = 0.0  # its largest value over the run so far
        self.peak_local_density_time = 0.0
        self.individuals = individuals if individuals is not None and not individuals.default else None
        if self.individuals is not None and self.individuals.compliance < 1.0 and guidance is not None:
            raise ParameterError(
                "crowd.compliance",
                self.individuals.compliance,
                "1 with a baseline crowd.guidance (compliance is the share who follow the robots' signs: "
                'a crowd that follows no sign has none to ignore; use crowd.guidance = "signs")',
            )
        self.standing: np.ndarray | None = None  # who stood still at the last step (pre-movement; None: nobody)

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

        With :class:`Individuals` (the first call draws them), the humans who ignore the signs
        walk their random walk instead of ``v_r`` (no sign reaches them), and the whole
        velocity of those whose pre-movement time has not come (``t < τ_j``) is 0
        (:attr:`standing`).
        """
        positions = self.positions
        visible = None  # which robot each human sees (the exact field's; None: all, or not computed)
        if self.guidance is not None:  # a baseline: the humans ignore the robots
            if self._guidance_observes:  # a guidance that plans from where the crowd is (routes round it)
                self.guidance.observe(positions, self._here(), t)
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
        people = self.individuals
        if people is not None:  # (with the defaults not one operation more)
            people.start()  # the first step: the draws, after every draw made before
            if len(people.walkers):
                people.ignore_signs(drift, positions, dt)
                if self.reached is not None:
                    self.reached[people.walkers] = False
        if self.memory is not None and self.reached is not None:  # who a sign reached knows the way from then on
            named = None
            if robots.shows is not None and self.memory.shown:  # signs that name an exit: each is read on its own
                named, read = self._named_exits(robots, positions, visible)
                if self.view.gated:
                    read &= self.view.seen
                if people is not None and len(people.walkers):
                    read[people.walkers] = False
                self.reached[:] = read
            self.memory.walk(drift, positions, self.reached, named)
        if self.congestion is not None:  # (without congestion not one operation more: every number as before)
            self._slow_down(drift, positions, t, dt)
        if self.interaction is not None:
            drift += self.interaction.at_points(positions)
        if self.disturbance is not None:
            ax, ay = self.disturbance(positions[:, 0], positions[:, 1], t)
            drift[:, 0] += ax
            drift[:, 1] += ay
        if people is not None:
            self.standing = people.waiting(t)
            if self.standing is not None:
                drift[self.standing] = 0.0
        return drift

    def _slow_down(self, velocity: np.ndarray, positions: np.ndarray, t: float, dt: float) -> None:
        """The door model in place.  ``"count"``: ``velocity *= g(ρ_j)``, ``ρ_j`` the local density of those still
        here (:class:`LocalDensity`); the others (:data:`DOOR_MODELS`) change the velocity by their own
        ``slow_down``, and the count is kept as the local density all of them report."""
        active = getattr(self.engine, "active", None)
        if self._door is None:
            rho = self._density(positions, active)
            velocity *= self.congestion.speed_factor(rho)[:, None]
        else:
            rho = self._door.slow_down(velocity, positions, active, dt, self._density)
            door, engine = self._door, self.engine
            if self._shares_noise and door.noise_factor is not None:
                sigma = engine.sigma  # (H5): the noise among contacts (docs page Congestion, "The headway door model")
                s = np.asarray(sigma(positions[:, 0], positions[:, 1], t), float)[:, None] if callable(sigma) else sigma
                velocity += s * door.noise_gradient  # σ ∇φ: the noise ∇·(σφ∇p), not Itô's Δ(σφp)
                engine.noise_factor = door.noise_factor
        self._peak(rho, t)

    def _peak(self, rho: np.ndarray, t: float) -> None:
        """Keep the local densities of this step and their largest value over the run."""
        self.local_density = rho
        peak = float(rho.max()) if len(rho) else 0.0
        if peak > self.peak_local_density:
            self.peak_local_density, self.peak_local_density_time = peak, t

    def _named_exits(self, robots: RobotTeam, positions: np.ndarray,
                     visible: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Signs that name an exit (:attr:`~meanfield.signs.robots.RobotTeam.shows`): who reads one, and the exit the
        one each reads names (``-1``: an arrow alone, or nobody's sign).

        A human reads the sign whose kernel is strongest among the robots it sees, where that kernel is at least
        :data:`~meanfield.signs.kernels.REACH_FRACTION` of its peak: a sign is read on its own, so two arrows that
        point apart do not hide each other as they do in the field ``v_r`` they sum to.  ``visible``: the sight mask
        the field was computed with, if any (computed here otherwise).
        """
        r = np.real(np.asarray(robots.positions, float)).reshape(-1, 2)
        strength = np.abs(self.kernel.magnitude(positions[None, :, 0] - r[:, None, 0],
                                                positions[None, :, 1] - r[:, None, 1]))  # fmt: skip
        if visible is None and self.sight is not None:
            visible = self.sight.mask(r, positions, self.kde.grid)
        if visible is not None:
            strength = np.where(visible, strength, 0.0)
        strongest = np.argmax(strength, axis=0)
        read = strength[strongest, np.arange(len(positions))] >= self._reach_speed
        named = np.where(read, np.asarray(robots.shows, dtype=np.intp)[strongest], -1)
        return named, read

    def _work(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The drift (n, 2) and reached (n,) arrays, kept between steps of the same crowd size."""
        if self._drift is None or len(self._drift) != n:
            self._drift, self._reached = np.empty((n, 2)), np.empty(n, dtype=bool)
        return self._drift, self._reached

    def _here(self) -> np.ndarray | None:
        """Who is still in Ω (None: everyone)."""
        gone = self._gone()
        return None if gone is None else ~gone

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
        if self.individuals is not None and hasattr(self.engine, "standing"):
            self.engine.standing = self.standing  # those waiting: no noise, no exit (the point masses)
        self.engine.step(drift, t, dt)  # (raises SimulationDiverged, nobody moved, on a non-finite drift)
        self.view.advance(dt)
        if self.guidance is not None:
            self.guidance.advance(dt)
        if self.individuals is not None:
            self.individuals.advance(dt)

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

    def persons_out(self, n_exits: int) -> np.ndarray:
        """How many agents have left through each of the region's ``n_exits`` exits (floats, for the measures)."""
        index = self.engine.exit_index
        return np.bincount(index[index >= 0], minlength=n_exits).astype(float)

    @property
    def models_exits(self) -> bool:
        """Whether the engine lets agents leave through exits (the point-mass SDE does)."""
        return hasattr(self.engine, "exit_time")

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """From now on only the exits with ``open_exits[k]`` take people (a scenario's ``[[events]]``).

        The engine stops taking people through the others and a guidance that walks to the exits
        plans again (each part that has ``exits_closed`` is told).
        """
        from meanfield.geometry.exits import tell_exits_closed

        tell_exits_closed((self.engine, self.guidance, self.memory), open_exits)

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event, :class:`~meanfield.geometry.blocking.WallsChange`).

        The engine's walls are the new ones (those standing in the block step out of it), the KDE estimates
        on the new grid, the signs are hidden by the new walls (a sampled field, which cannot tell which
        side of a wall, gives way to the exact one), the local density's disks are cut by them, and the
        guidance, the remembered routes and the non-followers' walk are planned round them; the door model reads
        the density by the new walls (its lanes or cells stop at them).
        """
        from meanfield.geometry.blocking import tell_walls_changed

        k = self.kde
        self.kde = KernelDensityEstimator(
            change.grid, k.bandwidth, k.boundary, k.method, k.normalize, k.oversample, k.convolution
        )
        self.sight = None if change.sight.trivial else change.sight
        if self.sight is not None and self.sampled_field is not None:
            self.sampled_field, self.field_evaluation = None, "exact"
        if self._density is not None:
            self._density = LocalDensity(len(self.engine.positions), self.density_radius, change.region)
        tell_walls_changed((self.engine, self._door, self.view, self.guidance, self.memory, self.individuals), change)

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
        if self.individuals is not None:  # pre-movement times and non-followers (nothing with the defaults)
            out.update(self.individuals.summary())
        if self.memory is not None:
            out.update(self.memory.summary())
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
        c = sc.crowd  # pre-movement and compliance: the non-followers walk as [view] says
        people = Individuals(
            n, c.premovement, c.compliance, ctx.rng, v.walk_speed, v.turning_rate, sc.domain, engine.body_radius
        )
        memory = None
        if sc.memory != "none" and guidance is None:  # (a baseline follows no sign, and learns nothing from one)
            from meanfield.geometry.exits import exit_segments

            segs = exit_segments(sc.domain)
            if not len(segs):
                raise ParameterError("view.memory", v.memory, '"none" on a plan without exits: the way is to an exit')
            memory = RouteMemory(n, ctx.grid, segs, c.free_speed, ctx.sight, shown=sc.memory == "sign")
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
            sc.crowd.congestion_radius,
            people,
            memory,
            sc.door_model,
        )
        crowd.congestion_name = sc.congestion_model
        return crowd


@declares(
    CrowdCapabilities(
        # each human is an agent: it may wait its own pre-movement time and ignore the signs
        # (crowd.premovement, crowd.compliance; Individuals)
        models_individuals=True,
        # people may be placed in groups, each in its region with its own exit (crowd.initial = "groups",
        # meanfield.crowds.groups); each person keeps its group's exit
        places_groups=True,
        group_exits=True,
        # a congested human's speed from the density of one's Voronoi cell ahead ("forward-cell", the first: the
        # default), the spacing to the person ahead, the count round it or the Godunov twin (crowd.door_model,
        # DOOR_MODELS)
        door_models=("forward-cell", "headway", "count", "godunov-twin"),
        # a region can become wall during a run ([[events]] block, AgentCrowd.walls_changed): the people in it step
        # out, and the signs, routes and walks go round it
        changes_walls=True,
        # an exit can close during a run ([[events]], AgentCrowd.exits_closed): the engine stops taking people
        # through it and the informed crowd's routes lead to the exits still open
        closes_exits=True,
        # crowd.congestion = "auto": the linear diagram in metres and seconds (it reproduces the measured
        # bottleneck flows, docs page Congestion), none in the paper's dimensionless units
        default_congestion={"SI": "linear"},
    )
)
def point_mass_crowd(ctx: CrowdContext) -> AgentCrowd:
    """Registry factory (kind ``crowd``, name ``point-mass``): the SDE of eq. (1) with reflecting walls."""
    sc = ctx.scenario
    humans = initial_positions(sc, sc.crowd.n, ctx.rng)
    return AgentCrowd.from_context(PointMassEngine(humans, sc.domain, ctx.sigma, ctx.rng), ctx)
