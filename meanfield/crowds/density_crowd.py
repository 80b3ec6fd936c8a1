"""The crowd as a density: the Fokker–Planck equation (paper, eq. (4)) as a :class:`~meanfield.interfaces.Crowd`.

The mean-field limit of the agents::

    ∂_t ρ = −∇·((u_W[ρ] + v_r + v_a) ρ) + Δ(σρ),   zero flux through the walls

solved by :class:`~meanfield.fokker_planck.solver.FokkerPlanck` (docs page *The Fokker–Planck
solver*) with ``v_r`` (eq. (3)) on the grid faces from the robots' states.  The robots
observe the density itself (no estimate), so the closed loop of
:class:`~meanfield.simulation.loop.ClosedLoop` run on this crowd is the PDE plant of Theorems 1–3.
Registered as crowd ``fokker-planck``.

Exits absorb (``ρ = 0`` on them, the solver's :class:`~meanfield.geometry.exits.ExitSink`); without
congestion the crowd applies them once per control period, as it always has, and with
``crowd.congestion`` the solver solves ``∂_t ρ + ∇·(ρ g(Nρ) v) = Δ(σρ)`` and its exits pass at
most their capacity (:mod:`meanfield.fokker_planck.congested`; docs page *The Fokker–Planck
solver*, "Exits and congestion").

What the density follows is ``crowd.guidance``, as for the agents: each guidance declares what it
gives the density (``for_density``, a :class:`~meanfield.crowds.guidance.DensityGuidance`: the
robots' field, a drift of its own on the faces, a diffusion added to σ), and a guidance that
declares nothing is refused (docs page *Congestion*, "The PDE").  The informed crowd
(``geodesic``) walks ``v₀ (−∇φ/|∇φ|)``, the route to the nearest exit; without congestion its
exits pass what the drift brings them, ``a_n⁺ ρ`` per metre of door (upwind, as the congested
exits without their capacity), beside the diffusive outflow.  A guidance's drift may depend on
the density (``velocity_of``: the routes the crowd shapes, ``fastest-route`` and ``hughes``,
:mod:`meanfield.crowds.crowd_routes`): it is asked afresh at the start of every control period,
from the density then.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from meanfield import plugins
from meanfield.capabilities import CrowdCapabilities
from meanfield.crowds.guidance import DensityGuidance
from meanfield.errors import ParameterError
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.grid import FaceField, Grid
from meanfield.geometry.sight import SightLines
from meanfield.geometry.target import gaussian_target
from meanfield.interfaces import CrowdContext
from meanfield.signs.kernels import NavigationKernel
from meanfield.signs.robots import NavigationField, RobotTeam

__all__ = ["DensityCrowd", "initial_density"]


def initial_density(scenario: Any, grid: Grid) -> np.ndarray:
    """The density of the scenario's initial crowd law on ``grid`` (unit mass): uniform on Ω,
    the normal law restricted to Ω, or the groups' — the mean-field initial condition of eq. (4).

    With ``crowd.initial = "groups"`` (:mod:`meanfield.crowds.groups`) group ``g`` of ``n_g`` people is uniform on
    its region ``R_g`` ∩ Ω, as the point masses are drawn: ``ρ = Σ_g (n_g / N) 1_{R_g} / |R_g ∩ Ω|``, each cell
    taking the share of its area in ``R_g`` (:func:`region_shares`).
    """
    c = scenario.crowd
    if c.initial == "uniform":
        return grid.normalize(np.ones(grid.shape))
    if c.initial == "groups":
        from meanfield.crowds.groups import group_region

        rho = np.zeros(grid.shape)
        for i, g in enumerate(c.groups):
            inside = region_shares(grid, group_region(g["region"], f"crowd.groups[{i}].region"))
            mass = float((inside * grid.volume).sum())
            if not mass > 0:
                raise ParameterError(f"crowd.groups[{i}].region", g["region"], "a region with room inside the plan")
            rho += (g["n"] / c.n) * inside / mass
        return rho
    return gaussian_target(grid, c.initial_center, c.initial_std)


def region_shares(grid: Grid, region: Any) -> np.ndarray:
    """The share of each cell's part in Ω (its volume) that lies in ``region`` (a shapely polygon), in [0, 1]."""
    import shapely

    boxes = grid.cell_boxes()
    to_shapely = getattr(grid.domain, "to_shapely", None)
    if to_shapely is not None:
        region = shapely.intersection(region, to_shapely())
    area = shapely.area(shapely.intersection(boxes, region))
    return np.divide(area, grid.volume, out=np.zeros(grid.shape), where=grid.volume > 0).clip(0.0, 1.0)


class DensityCrowd:
    """The crowd's density on the grid, advanced by the Fokker–Planck solver.

    Parameters
    ----------
    fp : FokkerPlanck
        The solver (its grid, σ, interaction and disturbance); no prescribed ``velocity``:
        the robots' field is handed to it every step.
    rho0 : ndarray
        Initial density on ``fp.grid`` (unit mass).
    kernel : NavigationKernel
        The robots' navigation kernel.
    substeps : bool, default True
        ``True``: each control period is solved with the solver's own stable sub-steps
        (:meth:`FokkerPlanck.solve`); ``False``: one step of ``dt`` (:meth:`FokkerPlanck.step`),
        the sampled-data plant of the theorem checks.
    sight : SightLines, optional
        A plan's walls that hide the signs (:mod:`meanfield.geometry.sight`).
    guidance : DensityGuidance, optional
        What the density follows (:mod:`meanfield.crowds.guidance`): the robots' field (None, the
        default: the paper), or a drift of its own on the faces, fixed or a function of the density
        (the robots' field then does not act); its added diffusion is already in ``fp``'s σ.
    people : int, optional
        ``N`` = ``crowd.n``: the persons the unit mass stands for, to count the persons out
        (:meth:`persons_out`); None: a crowd of mass only.
    """

    n = None
    positions = None

    models_exits = True

    capabilities: ClassVar[CrowdCapabilities] = CrowdCapabilities(
        # an exit can close during a run ([[events]], exits_closed): it becomes a wall for the density's flux and its
        # sink, and a guidance that walks to the exits plans again
        closes_exits=True,
        # crowd.congestion = "auto": as the point masses, the linear diagram in SI units, none in the paper's
        # dimensionless units (Scenario.congestion_model)
        default_congestion={"SI": "linear"},
        # people may start in groups, each uniform in its region (crowd.initial = "groups", initial_density): the
        # same starting law as the point masses'; a group's own exit is refused (one density cannot hold people
        # bound for different exits: no group_exits)
        places_groups=True,
    )
    """What it can do (:class:`~meanfield.capabilities.CrowdCapabilities`)."""

    def __init__(
        self,
        fp: FokkerPlanck,
        rho0: np.ndarray,
        kernel: NavigationKernel,
        substeps: bool = True,
        sight: SightLines | None = None,
        guidance: DensityGuidance | None = None,
        people: int | None = None,
    ):
        self.fp = fp
        self.people = people
        self.guidance = DensityGuidance(follows_signs=True) if guidance is None else guidance
        self.sight = sight
        self.grid = fp.grid
        self.rho = np.array(rho0, dtype=float)
        if self.rho.shape != self.grid.shape:
            raise ParameterError("rho0", self.rho.shape, f"an array of grid.shape {self.grid.shape}")
        self.kernel = kernel
        self.substeps = bool(substeps)
        self.last_field: NavigationField | None = None
        # the exits: the solver's sink (Dirichlet ρ = 0 on them, the same rates as ever).  A solver
        # built with exits=False leaves them to the crowd, applied once per control period (Lie
        # splitting over the period, the toolkit's results number for number); a solver that
        # absorbs (the default, and always with congestion) applies them after each of its steps.
        self.sink = fp.sink
        self._all_exits = getattr(fp.sink, "plain", fp.sink)  # the exits without a drift's outflow (exits_closed)
        self._period_sink = fp.sink is not None and not fp.absorbing
        self._out_before = fp.mass_out.copy()
        self.initial_mass = float(self.grid.integrate(self.rho))
        self.out_per_exit = np.zeros(0 if fp.sink is None else fp.sink.n_exits)
        # a drift that depends on the density, without congestion: the exits pass what it brings them, so
        # their rates follow it (_advective_exits from the solver's own sink, every period)
        follows = self.guidance.velocity_of is not None
        self._plain_exits = fp.sink if follows and fp.congestion is None and fp.absorbing else None

    def robot_velocity(self, robots: RobotTeam) -> tuple[np.ndarray, np.ndarray]:
        """``v_r`` (eq. (3)) on the grid faces at the robots' current states."""
        self.last_field = NavigationField(self.kernel, self.grid, robots.positions, robots.headings, self.sight)
        return self.last_field.velocity()

    def velocity(self, robots: RobotTeam) -> FaceField | None:
        """The drift the density follows over the next period: the robots' field (frozen at their
        current states) when it follows the signs, else its guidance's own (None: none), for a
        guidance whose drift depends on the density that at the current density (``velocity_of``)."""
        if self.guidance.follows_signs:
            return self.robot_velocity(robots)
        if self.guidance.velocity_of is not None:
            return self.guidance.velocity_of(self.rho)
        return self.guidance.velocity

    def advance(self, robots: RobotTeam, t: float, dt: float) -> None:
        """One control period of eq. (4) under the robots' field frozen at their current states
        (or the guidance's drift, a drift that depends on the density taken at the period's start)."""
        v = self.velocity(robots)
        if self._plain_exits is not None and v is not None:
            self.fp.sink = _advective_exits(self.fp.grid, self._plain_exits, v)
        if self.substeps:
            self.rho = self.fp.solve(self.rho, t + dt, t0=t, face_velocity=v)
        else:
            self.rho = self.fp.step(self.rho, t, dt, face_velocity=v)
        if self._period_sink:  # the exits' outflow over the period (Lie splitting, exact for the sink)
            self.rho, out = self.sink.apply(self.rho, dt)
            self.out_per_exit += out
        elif self.sink is not None:  # the solver's own count over its steps
            self.out_per_exit = self.fp.mass_out - self._out_before

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """From now on only the exits with ``open_exits[k]`` take mass (a scenario's ``[[events]]``).

        The others become walls wherever the exits act: the solver's sink and congested doors
        (:meth:`~meanfield.fokker_planck.solver.FokkerPlanck.exits_closed`), the sink applied once per control
        period, and the drift's outflow of a guidance of its own (``_advective_exits``), built again on the open
        exits; a guidance that walks to the exits plans again (:attr:`DensityGuidance.replan`, and Hughes' route
        through its own ``exits_closed``).
        """
        from meanfield.geometry.exits import tell_exits_closed

        if self._all_exits is None:
            return
        open_exits = np.asarray(open_exits, dtype=bool)
        if self.guidance.replan is not None and open_exits.any():
            self.guidance = self.guidance.replan(open_exits)
        tell_exits_closed((self.guidance.velocity_of,), open_exits)
        plain = self._all_exits.closed(open_exits)
        self.fp.exits_closed(open_exits)
        if self._period_sink:
            self.sink = plain
        if self._plain_exits is not None:
            self._plain_exits = plain
        elif self.guidance.velocity is not None and self.fp.congestion is None and self.fp.sink is not None:
            self.fp.sink = _advective_exits(self.grid, plain, self.guidance.velocity)

    def remaining_fraction(self) -> float:
        """The mass still in Ω over the initial mass."""
        return float(self.grid.integrate(self.rho)) / self.initial_mass

    def persons_out(self, n_exits: int) -> np.ndarray:
        """The persons out through each of its exits: the mass out over the initial mass, times ``people``
        (``crowd.n``; the solver's exits are the region's ``n_exits``).

        Raises
        ------
        ParameterError
            Naming ``people`` for a crowd built without it (by hand: it has mass, not persons).
        """
        if self.people is None:
            raise ParameterError("people", None, "the crowd's number of people (crowd.n), to count the persons out")
        return self.people * np.asarray(self.out_per_exit, float) / self.initial_mass

    def density(self) -> np.ndarray:
        """The density itself (the robots see it exactly)."""
        return self.rho

    def fraction_in_disk(self, center: tuple[float, float], radius: float) -> float:
        """Mass of the cells whose centre lies within ``radius`` of ``center``."""
        X, Y = self.grid.centers
        inside = (X - center[0]) ** 2 + (Y - center[1]) ** 2 <= radius**2
        return float(self.grid.integrate(np.where(inside, self.rho, 0.0)))

    def summary(self) -> dict[str, Any]:
        """The solver's method and the mass (1 up to round-off with zero-flux walls); with exits, the mass out."""
        out: dict[str, Any] = {
            "fokker_planck_method": self.fp.method,
            "mass_final": float(self.grid.integrate(self.rho)),
        }
        if self.guidance.diffusion > 0:
            out["guidance_diffusion"] = self.guidance.diffusion
        if self.sink is not None:
            out["evacuated_per_exit"] = (self.out_per_exit / self.initial_mass).tolist()
        return out

    @classmethod
    def from_context(cls, ctx: CrowdContext, method: str | None = None, substeps: bool = True) -> DensityCrowd:
        """Registry factory (kind ``crowd``, name ``fokker-planck``): eq. (4) from the scenario's
        initial law, σ, interaction and disturbance, on the loop's grid; with ``crowd.congestion``
        (not ``"none"``) the congested equation ``∂_t ρ + ∇·(ρ g(Nρ) v) = Δ(σρ)`` with
        ``N = crowd.n`` and the diagram of ``crowd.congestion``/``crowd.rho_max``
        (:mod:`meanfield.fokker_planck.congested`; ``method`` ``"split"`` or ``"explicit"``).

        ``crowd.guidance`` says what drives the density: that guidance's record holds
        ``for_density`` (:func:`meanfield.plugins.capabilities`), which returns a
        :class:`~meanfield.crowds.guidance.DensityGuidance` (docs page *Congestion*, "The PDE");
        a guidance without one is refused, naming ``crowd.guidance`` and those the
        density takes.

        The run's generator advances exactly as the agents' initial draw would
        (:func:`~meanfield.crowds.agent_crowd.initial_positions`), so that a seed gives the same
        robots, initial headings included, whether the crowd is agents or their density:
        the two can be compared under the same robots.
        """
        from meanfield.crowds.agent_crowd import initial_positions

        c = ctx.scenario.crowd
        for_density = plugins.capabilities("guidance", c.guidance).for_density
        if for_density is None:
            takes = [n for n in plugins.available("guidance") if plugins.capabilities("guidance", n).for_density]
            raise ParameterError(
                "crowd.guidance",
                c.guidance,
                f"a guidance that declares what it gives the density (for_density): {', '.join(map(repr, takes))}",
            )
        guidance = for_density(ctx)
        if not isinstance(guidance, DensityGuidance):
            raise ParameterError(
                "crowd.guidance", c.guidance, "a for_density returning a meanfield.crowds.guidance.DensityGuidance"
            )
        initial_positions(ctx.scenario, c.n, ctx.rng)  # the agents' draw, discarded
        diagram = plugins.load("congestion", ctx.scenario.congestion_model)(free_speed=c.free_speed, rho_max=c.rho_max)
        congested = bool(diagram.slows)  # "none": the paper's crowd, unchanged
        own_drift = guidance.drifts
        fp = FokkerPlanck(
            ctx.grid,
            _added(ctx.sigma, guidance.diffusion),
            interaction=ctx.interaction,
            disturbance=ctx.disturbance,
            method=method,
            # uncongested: the exits once per control period, as ever (see __init__); a drift of the
            # guidance's own: after every step of the solver, with the drift's outflow (_advective_exits;
            # a drift that depends on the density: refreshed every period, in advance)
            exits=congested or own_drift,
            congestion=diagram if congested else None,
            people=c.n if congested else None,
        )
        if guidance.velocity is not None and not congested and fp.sink is not None:
            fp.sink = _advective_exits(fp.grid, fp.sink, guidance.velocity)
        return cls(
            fp,
            initial_density(ctx.scenario, ctx.grid),
            ctx.kernel,
            substeps=substeps,
            sight=ctx.sight,
            guidance=guidance,
            people=c.n,
        )


def _added(sigma: Any, diffusion: float) -> Any:
    """``σ + D``: a guidance's diffusion added to the crowd's (a number, or a function of ``(x, y, t)``)."""
    if diffusion == 0:
        return sigma
    if callable(sigma):
        return lambda x, y, t: np.asarray(sigma(x, y, t), float) + diffusion
    return float(sigma) + diffusion


def _advective_exits(g: Grid, exits: Any, velocity: FaceField) -> Any:
    """The solver's exits ``exits`` with the drift's outflow added: ``k = σℓ/(dV) + a_n⁺ ℓ/V`` per exit and cell
    (a copy; ``exits`` is unchanged).

    An exit is a face to an empty outside: the upwind flux through it is ``a_n⁺ ρ ℓ``, ``a_n`` the
    drift's outward normal component at the cell (the mean over its open faces, as the congested
    exits take it) and ``ℓ`` the door's length in the cell (:func:`~meanfield.fokker_planck.congested.door_lengths`);
    beside the diffusive rate ``σℓ/(dV)`` of :class:`~meanfield.geometry.exits.ExitSink` it is a rate
    linear in ``ρ``, which the sink applies exactly after each step (``ρ e^{−k dt}``).  The congested
    exits pass ``min(a_n⁺ D(ρ) + σρ/d, q_max/N)`` per metre; this is their limit without congestion.
    """
    import copy

    from meanfield.fokker_planck.congested import _cell_velocity, door_lengths, exit_normals

    sink = copy.copy(exits)
    sink.plain = getattr(exits, "plain", exits)  # (to close exits on the exits without the drift's outflow)
    vx, vy = _cell_velocity(g, *velocity)
    normal = exit_normals(g, sink.segments)
    speed = np.maximum(normal[:, 0, None, None] * vx[None] + normal[:, 1, None, None] * vy[None], 0.0)
    volume = np.where(g.active, g.volume, np.inf)
    sink.rates = sink.rates + speed * door_lengths(sink) / volume[None]
    sink.total_rate = sink.rates.sum(axis=0)
    return sink
