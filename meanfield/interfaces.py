"""The three interfaces of the closed loop: :class:`Region`, :class:`Crowd`, :class:`Controller`.

One step of :class:`meanfield.loop.ClosedLoop` (docs page *Architecture*)::

    observation = Observation(crowd.density(), robots' field, t, dt)   # what the robots know
    command     = controller.act(observation)                          # (u_i, ω_i), eq. (8)
    crowd.advance(robots, t, dt)                                       # eq. (1) or eq. (4)
    robots.advance(saturated command, dt)                              # eq. (2)
    observers see the new state

Each interface is a :class:`typing.Protocol`: an implementation need not inherit from it,
only have the methods.  Implementations are chosen by name from :mod:`meanfield.plugins`
and built by :func:`meanfield.assembly.assemble` from parts, never from the loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:  # annotations only: these modules import nothing from here
    from meanfield.control import BetaGammaStrategy, ControlState
    from meanfield.grid import Grid
    from meanfield.interaction import InteractionField
    from meanfield.kernels import NavigationKernel
    from meanfield.robots import NavigationField, RobotTeam
    from meanfield.scenario import Scenario

__all__ = [
    "BoundaryPart",
    "Region",
    "Crowd",
    "Controller",
    "Observation",
    "Command",
    "CrowdContext",
    "ControllerParts",
    "SigmaLike",
    "Disturbance",
]

SigmaLike = float | Callable[[np.ndarray, np.ndarray, float], np.ndarray]
"""The crowd's diffusion: a constant ``σ >= 0`` or ``σ(x, y, t)`` (noise ``sqrt(2σ) dB``, eq. (1))."""

Disturbance = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]
"""An external velocity ``v_a(x, y, t) -> (vx, vy)`` (eq. (1))."""


# ---------------------------------------------------------------------- Region
@dataclass(frozen=True)
class BoundaryPart:
    """One piece of ∂Ω: a polyline tagged ``"wall"`` (zero flux, reflecting) or ``"exit"`` (a door).

    Attributes
    ----------
    kind : {"wall", "exit"}
    points : ndarray, shape (m, 2)
        The polyline's vertices in order (metres).
    """

    kind: Literal["wall", "exit"]
    points: np.ndarray

    @property
    def length(self) -> float:
        """Length of the polyline."""
        d = np.diff(self.points, axis=0)
        return float(np.hypot(d[:, 0], d[:, 1]).sum())


@runtime_checkable
class Region(Protocol):
    """The workspace Ω as geometry (:class:`meanfield.domain.Domain` implements it).

    Ω is a bounded polygon, possibly with holes (a disk is an exact curved special case),
    whose boundary is split into walls and exits.  Box and disk answer every question
    below in closed form; a general polygon through shapely.
    """

    @property
    def kind(self) -> str:
        """The registered name of the shape (``"box"``, ``"disk"``, ``"polygon"``, ...)."""
        ...

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)``."""
        ...

    @property
    def center(self) -> tuple[float, float]: ...

    @property
    def area(self) -> float: ...

    @property
    def diameter(self) -> float: ...

    def contains(self, x: Any, y: Any, tol: float | None = None) -> np.ndarray:
        """Membership of the closed region, elementwise."""
        ...

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Mirror, in place, the points that left Ω back inside (reflecting walls)."""
        ...

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest point of Ω, in place, for the points outside."""
        ...

    def sample_uniform(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points drawn uniformly from Ω."""
        ...

    def cut_cells(
        self, x_edges: np.ndarray, y_edges: np.ndarray, dx: float, dy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cut cells of the lattice ``x_edges × y_edges`` (spacings ``dx``, ``dy``): volume
        fractions ``(nx, ny)`` and the open fractions of the interior x-faces ``(nx-1, ny)``
        and y-faces ``(nx, ny-1)`` (docs page *Discretisation*)."""
        ...

    def cells_meeting(self, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
        """Mask of the lattice cells whose interior meets Ω."""
        ...

    def robot_region(self, margin: float) -> Region:
        """Where robots may stand: Ω inset by ``margin`` (Ω itself for 0)."""
        ...

    def lattice(self, n: int) -> np.ndarray:
        """``n`` evenly spread points of Ω (the robots' grid layout)."""
        ...

    def boundary_parts(self) -> tuple[BoundaryPart, ...]:
        """∂Ω as walls and exits (every hole's boundary is wall)."""
        ...

    def to_shapely(self) -> Any:
        """Ω as a shapely polygon (holes as interiors)."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """The scenario's ``[domain]`` table: ``{"kind": name, ...}``."""
        ...


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


# ---------------------------------------------------------------------- Controller
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
    """

    u: np.ndarray
    omega: np.ndarray
    state: ControlState | None = None


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
    """

    scenario: Scenario
    grid: Grid
    kernel: NavigationKernel
    sigma: SigmaLike
    disturbance: Disturbance | None
    interaction: InteractionField | None
    rng: np.random.Generator


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
        ``controller.options`` of the scenario, for the controller to validate.
    dt : float
        The control period.
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
    alpha: Any
    k_u: float
    k_omega: float
    beta_gamma: BetaGammaStrategy
    dvd_dt: str
    options: dict[str, Any]
    dt: float
