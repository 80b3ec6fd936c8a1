"""The three interfaces of the closed loop: :class:`Region`, :class:`Crowd`, :class:`Controller`.

:class:`Region` lives in :mod:`meanfield.geometry.region` (the geometry at the bottom of the layers
names it) and is re-exported here; the controller's contracts come with it: the Step-I gain
(:class:`AlphaSchedule`), the β/γ rule (:class:`BetaGammaStrategy`, :class:`ExtraInputs`)
and the law's quantities a command may carry (:class:`ControlState`).

One step of :class:`meanfield.simulation.loop.ClosedLoop` (docs page *Architecture*)::

    observation = Observation(crowd.density(), robots' field, t, dt)   # what the robots know
    command     = controller.act(observation)                          # (u_i, ω_i), eq. (8)
    crowd.advance(robots, t, dt)                                       # eq. (1) or eq. (4)
    robots.advance(saturated command, dt)                              # eq. (2)
    observers see the new state

Each interface is a :class:`typing.Protocol`: an implementation need not inherit from it,
only have the methods.  Implementations are chosen by name from :mod:`meanfield.plugins`
and built by :func:`meanfield.simulation.assembly.assemble` from parts, never from the loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from meanfield.errors import SigmaLike
from meanfield.geometry.blocking import ReactsToWalls
from meanfield.geometry.exits import ReactsToClosedExits
from meanfield.geometry.grid import FaceField, Grid
from meanfield.geometry.region import BoundaryPart, Region
from meanfield.geometry.sight import SightLines
from meanfield.signs.interaction import InteractionField
from meanfield.signs.kernels import NavigationKernel
from meanfield.signs.robots import NavigationField, RobotTeam

__all__ = [
    "BoundaryPart",
    "Region",
    "Crowd",
    "CrowdOfAgents",
    "EvacuatingCrowd",
    "Reports",
    "ReactsToClosedExits",
    "ReactsToWalls",
    "Controller",
    "Observation",
    "Command",
    "ControlState",
    "AlphaSchedule",
    "BetaGammaStrategy",
    "ExtraInputs",
    "CrowdContext",
    "ControllerParts",
    "StabilityStep",
    "SigmaLike",
    "Disturbance",
]

Disturbance = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]
"""An external velocity ``v_a(x, y, t) -> (vx, vy)`` (eq. (1))."""


# ---------------------------------------------------------------------- Crowd
@runtime_checkable
class Crowd(Protocol):
    """The humans: agents (positions) or a density on the grid (the mean-field limit).

    A crowd owns its own dynamics (eq. (1) for agents, eq. (4) for the density): given the
    robots, it builds the navigation velocity it feels (plus interaction and disturbance)
    and advances one step.
    """

    @property
    def n(self) -> int | None:
        """Number of humans (None for a density)."""
        ...

    @property
    def positions(self) -> np.ndarray | None:
        """Positions ``(N, 2)`` (None for a density)."""
        ...

    def advance(self, robots: RobotTeam, t: float, dt: float) -> None:
        """One step of the crowd under the robots' signs at their current states.

        Raises :class:`~meanfield.errors.SimulationDiverged`, leaving the crowd unchanged,
        if the velocity it would follow is not finite.
        """
        ...

    def density(self) -> np.ndarray:
        """The density on the loop's grid that the robots observe (a KDE of agents; the PDE's state)."""
        ...

    def fraction_in_disk(self, center: tuple[float, float], radius: float) -> float:
        """Fraction of the crowd within ``radius`` of ``center``."""
        ...

    def summary(self) -> dict[str, Any]:
        """Crowd-specific figures for the run's summary (may be empty)."""
        ...


@runtime_checkable
class EvacuatingCrowd(Crowd, Protocol):
    """A crowd whose people leave through the region's exits (docs page *Buildings*): the point masses, JuPedSim's
    bodies and the density.  The loop records the fraction out, and the evacuation's measures the persons out
    through each exit, of a crowd that is one (:mod:`meanfield.simulation.evacuation_measures`)."""

    @property
    def models_exits(self) -> bool:
        """Whether people leave through the exits (a region with exits is refused with a crowd that says no)."""
        ...

    def remaining_fraction(self) -> float:
        """The share of the crowd still in Ω (1 without exits)."""
        ...

    def persons_out(self, n_exits: int) -> np.ndarray:
        """How many persons have left through each of the region's ``n_exits`` exits, shape ``(n_exits,)`` (the
        density: its mass out times ``crowd.n``)."""
        ...


@runtime_checkable
class CrowdOfAgents(Crowd, Protocol):
    """A crowd of agents, each a person with a position, a body and a view of the signs (the point masses and
    JuPedSim's bodies, :class:`~meanfield.crowds.agent_crowd.AgentCrowd`): what the observers record of them."""

    @property
    def body_radius(self) -> float:
        """The agents' body radius (0 for point masses)."""
        ...

    @property
    def reached(self) -> np.ndarray | None:
        """Whom a sign reached at the last step (None: nobody follows signs, or before the first step)."""
        ...

    def seen_fraction(self) -> float:
        """Fraction of the agents with a robot in view at the last step (1 without a view radius)."""
        ...

    def field_error_bound(self, robots: RobotTeam) -> float | None:
        """Interpolation error bound of a sampled ``v_r`` at the robots' states (None: evaluated exactly)."""
        ...


@runtime_checkable
class Reports(Protocol):
    """A part with figures of its own for the run's summary (a controller's ``summary()``; every crowd has one)."""

    def summary(self) -> dict[str, Any]:
        """Its figures (may be empty)."""
        ...


# ---------------------------------------------------------------------- Controller
class AlphaSchedule(Protocol):
    """The gain α(x, t) > 0 of Step I, given as ``q = α/ρ`` on faces and its ρ-derivative."""

    def over_rho(self, rho_f: np.ndarray) -> np.ndarray:
        """``α/ρ`` at face densities ``rho_f``."""
        ...

    def over_rho_derivative(self, rho_f: np.ndarray) -> np.ndarray:
        """``d(α/ρ)/dρ`` at face densities ``rho_f`` (model-based ∂_t v_d)."""
        ...

    def alpha(self, rho_f: np.ndarray) -> np.ndarray:
        """``α`` at face densities ``rho_f``."""
        ...


@dataclass
class ExtraInputs:
    """The robots' extra inputs ``δu`` (n, 2), ``δω`` (n,) and the part of ``A`` left uncancelled.

    ``shortfall = A - (Σ b_i·δu_i - Σ g_i δω_i)``: zero when the strategy meets the
    paper's condition; otherwise ``dV₂/dt`` carries ``+shortfall`` (an ISS input).
    """

    du: np.ndarray
    domega: np.ndarray
    shortfall: float


class BetaGammaStrategy(Protocol):
    """Chooses ``(δu, δω)`` with ``Σ b_i·δu_i - Σ g_i δω_i = A`` (or reports the shortfall)."""

    def __call__(self, b: np.ndarray, g: np.ndarray, A: float) -> ExtraInputs:
        """Extra inputs for the integrals ``b`` (n, 2), ``g`` (n,) and ``A``."""
        ...


@dataclass
class ControlState:
    """Everything the controller computed at one instant (for logging and checks)."""

    v_d: FaceField
    v_tilde: FaceField
    rho_tilde: np.ndarray
    b: np.ndarray
    g: np.ndarray
    A: float
    u: np.ndarray
    omega: np.ndarray
    shortfall: float
    dissipation: float  # ∫ α |∇ρ̃|²
    k_u: Any = 0.0  # the gains the law was evaluated with (scalar or per robot)
    k_omega: Any = 0.0
    # the law in the kernel's units (controller.scaling = "kernel"): b, g, A and the dissipation
    # are in those units, inputs u = input_scale[0] û and ω = input_scale[1] ω̂, and
    # V₂ = ½ v2_weights[0] ∫ρ̃² + ½ v2_weights[1] ∫|ṽ|²; all ones for the paper's law
    input_scale: tuple[float, float] = (1.0, 1.0)
    v2_weights: tuple[float, float] = (1.0, 1.0)

    def applied_shortfall(self, u: np.ndarray, omega: np.ndarray) -> float:
        """``A − (Σ b_i·δu_i − Σ g_i δω_i)`` for the inputs actually applied (after saturation).

        With ``δu_i = u_i − k_u b_i`` and ``δω_i = ω_i + k_ω g_i``, so that
        ``dV₂/dt = −∫α|∇ρ̃|² − Σ k_u|b_i|² − Σ k_ω g_i² + applied shortfall`` (eq. (8)):
        the part of ``A`` the robots did not cancel, whatever the controller, strategy or clipping.
        """
        k_u = np.asarray(self.k_u, float)
        k_u = k_u[:, None] if k_u.ndim else k_u
        u, omega = u / self.input_scale[0], omega / self.input_scale[1]  # in the law's units
        du = u - k_u * self.b
        dw = omega + np.asarray(self.k_omega, float) * self.g
        return float(self.A - ((self.b * du).sum() - (self.g * dw).sum()))


@dataclass(frozen=True)
class Observation:
    """What the controller knows at one instant.

    Attributes
    ----------
    density : ndarray
        The crowd's density (estimate) on the grid.
    field : NavigationField
        The robots' kernels on the grid at their current states (``field.positions``,
        ``field.headings``).
    t : float
        Time.
    dt : float or None
        The control period (the time to the next observation); None where there is none.
    """

    density: np.ndarray
    field: NavigationField
    t: float
    dt: float | None = None


@dataclass
class Command:
    """A controller's output: robot inputs, and the law's quantities where it has them.

    Attributes
    ----------
    u : ndarray, shape (n, 2)
        Commanded velocities (before the speed limits are applied).
    omega : ndarray, shape (n,)
        Commanded turn rates.
    state : ControlState or None
        The backstepping quantities at this instant (``ṽ``, ``ρ̃``, ``b_i``, ``g_i``, ``A``,
        ...), which observers record; None for a controller that computes none.
    shows : ndarray of int, shape (n,), or None
        The exit each robot's sign names from now on (``-1``: its arrow alone; :attr:`RobotTeam.shows
        <meanfield.signs.robots.RobotTeam.shows>`); None: unchanged.
    """

    u: np.ndarray
    omega: np.ndarray
    state: ControlState | None = None
    shows: np.ndarray | None = None


@runtime_checkable
class Controller(Protocol):
    """From an observation to robot inputs."""

    def act(self, observation: Observation) -> Command:
        """Robot inputs for this observation."""
        ...

    def reset(self) -> None:
        """Forget any memory (previous observations, plans)."""
        ...


# ---------------------------------------------------------------------- parts
@dataclass
class CrowdContext:
    """What a crowd factory gets from the assembly (registry kind ``crowd``).

    Attributes
    ----------
    scenario : Scenario
    grid : Grid
        The loop's grid (the density lives here).
    kernel : NavigationKernel
    sigma : SigmaLike
    disturbance : Disturbance or None
    interaction : InteractionField or None
    rng : numpy.random.Generator
        The run's one generator: draw the initial crowd at construction, and nothing
        else until the first step (the robots' initial headings come next).
    sight : SightLines or None
        The plan's walls that hide signs (:mod:`meanfield.geometry.sight`); None: every sign is seen.
    """

    scenario: Any  # a meanfield.scenarios.scenario.Scenario (the scenario module sits above this one)
    grid: Grid
    kernel: NavigationKernel
    sigma: SigmaLike
    disturbance: Disturbance | None
    interaction: InteractionField | None
    rng: np.random.Generator
    sight: SightLines | None = None


@dataclass(frozen=True)
class StabilityStep:
    """The largest stable time step a controller declares (``stability_step(scenario, grid)``).

    The preflight warns after a run whose ``dt`` exceeds it: ``"dt = … exceeds {what} = {dt} {why}"``.

    Attributes
    ----------
    dt : float
        The largest stable step.
    what : str
        What bounds it (e.g. ``"the sampled Step-I feedback's stability step 0.9 h²/(4 α₀)"``).
    why : str
        The numbers and what goes wrong past it.
    """

    dt: float
    what: str
    why: str


@dataclass
class ControllerParts:
    """What a controller factory gets from the assembly (registry kind ``controller``).

    Attributes
    ----------
    grid : Grid
    region : Region
        Ω.
    robot_region : Region
        Where the robots may stand.
    kernel : NavigationKernel
    target : ndarray
        Target density ``ρ_*`` on the grid.
    target_center : (float, float)
    sigma : SigmaLike
    interaction : InteractionField or None
    robots : RobotTeam
        The robots' initial states and speed limits (read, never moved, by a controller).
    alpha : AlphaSchedule
        Step-I gain.
    k_u, k_omega : float
        Step-II gains.
    beta_gamma : BetaGammaStrategy
    dvd_dt : str
        How ``∂_t v_d`` is obtained.
    options : dict
        The scenario's table ``controller.options.<kind>`` for the controller's kind (checked by the kind's
        declared options when the scenario was read; the factory reads it with the same dataclass).
    dt : float
        The control period.
    scales : (float, float) or None
        ``(ℓ, c)``: the law's unit of length and of speed with ``controller.scaling = "kernel"``
        (``ℓ = √|Ω|``, ``c`` the kernel's strength); None: the paper's law, in the scenario's units.
    sight : SightLines or None
        The run's sight lines (:mod:`meanfield.geometry.sight`), shared with the crowd and the loop so
        that their table of which cell sees which is computed once; None: built from ``region``.
    congestion : FundamentalDiagram or None
        The plant's fundamental diagram (``crowd.congestion`` resolved, :mod:`meanfield.crowds.congestion`),
        for a law that models it (:class:`~meanfield.controllers.backstepping.CongestedPlant`), with
        ``controller.congestion = "compensate"``; None with ``"ignore"`` (the default) or parts built by
        hand.  A diagram that does not slow (``"none"``) is the paper's crowd.
    people : int or None
        ``N`` = ``crowd.n``: a unit-mass density ``ρ`` has ``Nρ`` persons/m², the diagram's argument.
    free_speed : float or None
        The crowd's free walking speed (``crowd.free_speed``), for a controller that plans the crowd's walk; None:
        parts built by hand.
    """

    grid: Grid
    region: Region
    robot_region: Region
    kernel: NavigationKernel
    target: np.ndarray
    target_center: tuple[float, float]
    sigma: SigmaLike
    interaction: InteractionField | None
    robots: RobotTeam
    alpha: AlphaSchedule
    k_u: float
    k_omega: float
    beta_gamma: BetaGammaStrategy
    dvd_dt: str
    options: dict[str, Any]
    dt: float
    scales: tuple[float, float] | None = None
    sight: SightLines | None = None
    congestion: Any = None  # a meanfield.crowds.congestion.FundamentalDiagram (the crowds sit above this module)
    people: int | None = None
    free_speed: float | None = None
