"""One assembly step: a :class:`~meanfield.scenarios.scenario.Scenario` becomes the parts of the closed loop.

Each part is chosen by name from the registry (:mod:`meanfield.plugins`) and built from
the parts before it, never from the loop that will hold it:

1. Ω (the scenario's region), the grid, the navigation kernel, the target density ``ρ_*``;
2. the crowd (``crowd.kind``): it draws its initial state from the run's generator;
3. the robots (``robots.layout``, random headings from the same generator);
4. the controller (``controller.kind``) from :class:`~meanfield.interfaces.ControllerParts`.

The generator's draws keep this order (humans, robots, then the walkers' headings and the
steps' noise), so a seed gives the same run whatever the parts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from meanfield import plugins
from meanfield.controllers.alpha_schedules import ConstantAlpha, SaturatingAlpha
from meanfield.errors import ParameterError
from meanfield.geometry.grid import Grid
from meanfield.geometry.sight import SightLines
from meanfield.geometry.target import gaussian_target, target_region_radius
from meanfield.interfaces import (
    BetaGammaStrategy,
    Controller,
    ControllerParts,
    Crowd,
    CrowdContext,
    Disturbance,
    EvacuatingCrowd,
    Region,
    SigmaLike,
)
from meanfield.scenarios.scenario import Scenario
from meanfield.signs.interaction import GaussianPotential, InteractionField
from meanfield.signs.kernels import GaussianKernel, NavigationKernel
from meanfield.signs.robots import RobotTeam
from meanfield.simulation.preflight import check_fits

__all__ = [
    "Parts",
    "assemble",
    "alpha_schedule_for",
    "disturbance_for",
    "initial_robots",
    "plant_congestion",
    "sensing_controllers",
]


@dataclass
class Parts:
    """The closed loop's parts, built once from a scenario by :func:`assemble`.

    Attributes
    ----------
    scenario : Scenario
    region : Region
        Ω.
    grid : Grid
    kernel : NavigationKernel
    target : ndarray
        ``ρ_*`` on the grid.
    target_center : (float, float)
    target_radius : float
        Radius of the target region (the disk holding 90 % of ``ρ_*``).
    sigma : SigmaLike
    disturbance : Disturbance or None
    interaction : InteractionField or None
    crowd : Crowd
    robots : RobotTeam
    robot_region : Region
    controller : Controller
    sight : SightLines
        Which walls hide the robots' signs (:mod:`meanfield.geometry.sight`; none in a convex room).
    overrides : list of str
        The Python-only overrides used (``sigma``, ``disturbance``, ``beta_gamma``, ``kernel``, ...).
    """

    scenario: Scenario
    region: Region
    grid: Grid
    kernel: NavigationKernel
    target: np.ndarray
    target_center: tuple[float, float]
    target_radius: float
    sigma: SigmaLike
    disturbance: Disturbance | None
    interaction: InteractionField | None
    crowd: Crowd
    robots: RobotTeam
    robot_region: Region
    controller: Controller
    sight: SightLines
    overrides: list[str] = field(default_factory=list)

    @property
    def dt(self) -> float:
        """The control period."""
        return self.scenario.dt


def alpha_schedule_for(scenario: Scenario) -> ConstantAlpha | SaturatingAlpha:
    """The Step-I gain α(ρ) of ``scenario.controller`` (``"constant"`` or ``"saturating"``)."""
    c = scenario.controller
    return ConstantAlpha(c.alpha) if c.alpha_schedule == "constant" else SaturatingAlpha(c.alpha, c.rho_floor)


def disturbance_for(scenario: Scenario) -> Disturbance | None:
    """The scenario's disturbance ``v_a(x, y, t) -> (vx, vy)`` (eq. (1)), or None without one."""
    d = scenario.disturbance
    if d.kind == "none":
        return None
    if d.kind == "constant":
        vx, vy = d.velocity
        return lambda x, y, t: (np.full_like(x, vx), np.full_like(y, vy))
    cx, cy = scenario.domain.center
    s = d.strength
    return lambda x, y, t: (-s * (y - cy), s * (x - cx))


def sensing_controllers() -> list[str]:
    """The registered controllers that run on a group's knowledge (their records' ``accepts_sensing``)."""
    names = plugins.available("controller")
    return [name for name in names if plugins.capabilities("controller", name).accepts_sensing]


def law_scales(scenario: Scenario, region: Region, kernel: NavigationKernel) -> tuple[float, float] | None:
    """``(ℓ, c)`` of ``controller.scaling = "kernel"`` (``√|Ω|`` and the kernel's strength), else None."""
    if scenario.controller.scaling != "kernel":
        return None
    c = kernel.c if isinstance(kernel, GaussianKernel) else None  # the paper's kernel: its strength
    if not (isinstance(c, (int, float)) and c > 0):
        raise ParameterError("controller.scaling", "kernel", "a kernel with a strength c > 0 (the unit of speed)")
    strategy = scenario.controller.beta_gamma
    if not plugins.capabilities("beta_gamma", strategy).accepts_kernel_scaling:
        rules = plugins.available("beta_gamma")
        fits = [s for s in rules if plugins.capabilities("beta_gamma", s).accepts_kernel_scaling]
        raise ParameterError(
            "controller.scaling",
            "kernel",
            f"beta_gamma among {fits} (the other strategies' limits are in the scenario's units)",
        )
    return (float(np.sqrt(region.area)), float(c))


def plant_congestion(scenario: Scenario) -> Any:
    """The fundamental diagram the crowd walks by (``crowd.congestion`` resolved, as the crowds build it),
    for the controller's parts with ``controller.congestion = "compensate"``; None with ``"ignore"`` (the
    default: the law ignores it)."""
    if scenario.controller.congestion != "compensate":
        return None
    c = scenario.crowd
    return plugins.load("congestion", scenario.congestion_model)(free_speed=c.free_speed, rho_max=c.rho_max)


def initial_robots(scenario: Scenario, rng: np.random.Generator) -> tuple[RobotTeam, Region]:
    """The robots' initial states (``robots.layout``, headings) and the region they may stand in."""
    r = scenario.robots
    region = scenario.domain.robot_region(r.margin)
    if r.layout == "grid":
        positions = region.lattice(r.n)
    elif r.layout == "random":
        positions = region.sample_uniform(r.n, rng)
    else:
        positions = np.asarray(r.positions, float)
    headings = rng.uniform(0.0, 2 * np.pi, r.n) if isinstance(r.headings, str) else np.asarray(r.headings, float)
    robots = RobotTeam(positions, headings, r.u_max, r.omega_max)
    robots.check_inside(scenario.domain)
    return robots, region


def assemble(
    scenario: Scenario,
    *,
    sigma: SigmaLike | None = None,
    disturbance: Disturbance | None = None,
    beta_gamma: BetaGammaStrategy | None = None,
    kernel: NavigationKernel | None = None,
    crowd: str | None = None,
    controller: str | None = None,
) -> Parts:
    """Build the parts of ``scenario``'s closed loop.

    Parameters
    ----------
    scenario : Scenario
    sigma : float or callable, optional
        Overrides ``crowd.sigma``; a callable ``σ(x, y, t)`` is allowed here.
    disturbance : callable, optional
        ``v_a(x, y, t) -> (vx, vy)``, overriding ``scenario.disturbance``.
    beta_gamma : BetaGammaStrategy, optional
        Overrides ``controller.beta_gamma`` (e.g. a :class:`~meanfield.controllers.backstepping.UserBetaGamma`).
    kernel : NavigationKernel, optional
        Overrides the scenario's Gaussian kernel.
    crowd : str, optional
        A registered crowd name, overriding ``crowd.kind`` (e.g. ``"fokker-planck"``
        for the PDE plant).
    controller : str, optional
        A registered controller name, overriding ``controller.kind``.
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError("scenario", type(scenario).__name__, "a Scenario")
    sc = scenario
    check_fits(sc)  # refuse what cannot fit in memory before anything is allocated
    region = sc.domain
    rng = np.random.default_rng(sc.seed)
    grid = Grid(region, sc.grid.cells)
    kern = kernel if kernel is not None else GaussianKernel(sc.kernel.c, sc.kernel.eta)
    target = gaussian_target(grid, sc.target.center, sc.target.std)
    sig = sc.crowd.sigma if sigma is None else sigma
    dist = disturbance if disturbance is not None else disturbance_for(sc)
    interaction = None
    if sc.interaction.kind == "gaussian":
        interaction = InteractionField(grid, GaussianPotential(sc.interaction.strength, sc.interaction.length))
    crowd_name = sc.crowd.kind if crowd is None else crowd
    sight = SightLines(region)
    context = CrowdContext(sc, grid, kern, sig, dist, interaction, rng, None if sight.trivial else sight)
    the_crowd = plugins.load("crowd", crowd_name)(context)
    evacuates = isinstance(the_crowd, EvacuatingCrowd) and the_crowd.models_exits
    if any(part.kind == "exit" for part in region.boundary_parts()) and not evacuates:
        raise ParameterError(
            "domain.exits",
            f"exits with the {crowd_name!r} crowd",
            "a crowd that lets people leave: 'point-mass', 'fokker-planck' or 'jupedsim'",
        )
    robots, robot_region = initial_robots(sc, rng)
    c = sc.controller
    strategy = beta_gamma if beta_gamma is not None else plugins.load("beta_gamma", c.beta_gamma)(sc)
    parts = ControllerParts(
        grid=grid,
        region=region,
        robot_region=robot_region,
        kernel=kern,
        target=target,
        target_center=sc.target.center,
        sigma=sig,
        interaction=interaction,
        robots=robots,
        alpha=alpha_schedule_for(sc),
        k_u=c.k_u,
        k_omega=c.k_omega,
        beta_gamma=strategy,
        dvd_dt=c.dvd_dt,
        options=dict(c.options.get(c.kind if controller is None else controller, {})),
        dt=sc.dt,
        scales=law_scales(sc, region, kern),
        sight=sight,
        congestion=plant_congestion(sc),
        people=sc.crowd.n,
        free_speed=sc.crowd.free_speed,
    )
    kind = c.kind if controller is None else controller
    factory = plugins.load("controller", kind)
    the_controller = factory(parts)
    if sc.sensing.local:  # one controller per robot, on what its group knows
        from meanfield.controllers.local_sensing import LocalSensing

        if not plugins.capabilities("controller", kind).accepts_sensing:
            raise ParameterError(
                "sensing", kind, f"controller.kind among {sensing_controllers()} with a sensing or comm radius"
            )
        own = [the_controller] + [factory(parts) for _ in range(robots.n - 1)]
        the_controller = LocalSensing(own, grid, kern, sc.sensing.radius, sc.sensing.comm_radius, sight)
    overrides: dict[str, Any] = {
        "sigma": sigma,
        "disturbance": disturbance,
        "beta_gamma": beta_gamma,
        "kernel": kernel,
        "crowd": crowd,
        "controller": controller,
    }
    return Parts(
        scenario=sc,
        region=region,
        grid=grid,
        kernel=kern,
        target=target,
        target_center=sc.target.center,
        target_radius=target_region_radius(region, sc.target.center, sc.target.std),
        sigma=sig,
        disturbance=dist,
        interaction=interaction,
        crowd=the_crowd,
        robots=robots,
        robot_region=robot_region,
        controller=the_controller,
        sight=sight,
        overrides=sorted(k for k, v in overrides.items() if v is not None),
    )
