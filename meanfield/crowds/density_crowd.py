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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield import plugins
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.grid import Grid
from meanfield.geometry.sight import SightLines
from meanfield.geometry.target import gaussian_target
from meanfield.interfaces import CrowdContext
from meanfield.signs.kernels import NavigationKernel
from meanfield.signs.robots import NavigationField, RobotTeam

__all__ = ["DensityCrowd", "initial_density"]


def initial_density(scenario: Any, grid: Grid) -> np.ndarray:
    """The density of the scenario's initial crowd law on ``grid`` (unit mass): uniform on Ω,
    or the normal law restricted to Ω — the mean-field initial condition of eq. (4)."""
    c = scenario.crowd
    if c.initial == "uniform":
        return grid.normalize(np.ones(grid.shape))
    return gaussian_target(grid, c.initial_center, c.initial_std)


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
    """

    n = None
    positions = None

    models_exits = True

    default_congestion = {"SI": "linear"}
    """``crowd.congestion = "auto"``: as the point masses, the linear diagram in SI units, none in the
    paper's dimensionless units (:attr:`~meanfield.scenarios.scenario.Scenario.congestion_model`)."""

    def __init__(
        self,
        fp: FokkerPlanck,
        rho0: np.ndarray,
        kernel: NavigationKernel,
        substeps: bool = True,
        sight: SightLines | None = None,
    ):
        self.fp = fp
        self.sight = sight
        self.grid = fp.grid
        self.rho = np.array(rho0, dtype=float)
        if self.rho.shape != self.grid.shape:
            from meanfield.errors import ParameterError

            raise ParameterError("rho0", self.rho.shape, f"an array of grid.shape {self.grid.shape}")
        self.kernel = kernel
        self.substeps = bool(substeps)
        self.last_field: NavigationField | None = None
        # the exits: the solver's sink (Dirichlet ρ = 0 on them, the same rates as ever).  A solver
        # built with exits=False leaves them to the crowd, applied once per control period (Lie
        # splitting over the period, the toolkit's results number for number); a solver that
        # absorbs (the default, and always with congestion) applies them after each of its steps.
        self.sink = fp.sink
        self._period_sink = fp.sink is not None and not fp.absorbing
        self._out_before = fp.mass_out.copy()
        self.initial_mass = float(self.grid.integrate(self.rho))
        self.out_per_exit = np.zeros(0 if fp.sink is None else fp.sink.n_exits)

    def robot_velocity(self, robots: RobotTeam) -> tuple[np.ndarray, np.ndarray]:
        """``v_r`` (eq. (3)) on the grid faces at the robots' current states."""
        self.last_field = NavigationField(self.kernel, self.grid, robots.positions, robots.headings, self.sight)
        return self.last_field.velocity()

    def advance(self, robots: RobotTeam, t: float, dt: float) -> None:
        """One control period of eq. (4) under the robots' field frozen at their current states."""
        v_r = self.robot_velocity(robots)
        if self.substeps:
            self.rho = self.fp.solve(self.rho, t + dt, t0=t, face_velocity=v_r)
        else:
            self.rho = self.fp.step(self.rho, t, dt, face_velocity=v_r)
        if self._period_sink:  # the exits' outflow over the period (Lie splitting, exact for the sink)
            self.rho, out = self.sink.apply(self.rho, dt)
            self.out_per_exit += out
        elif self.sink is not None:  # the solver's own count over its steps
            self.out_per_exit = self.fp.mass_out - self._out_before

    def remaining_fraction(self) -> float:
        """The mass still in Ω over the initial mass."""
        return float(self.grid.integrate(self.rho)) / self.initial_mass

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
        out = {"fokker_planck_method": self.fp.method, "mass_final": float(self.grid.integrate(self.rho))}
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

        The run's generator advances exactly as the agents' initial draw would
        (:func:`~meanfield.crowds.agent_crowd.initial_positions`), so that a seed gives the same
        robots, initial headings included, whether the crowd is agents or their density:
        the two can be compared under the same robots.
        """
        from meanfield.crowds.agent_crowd import initial_positions
        from meanfield.errors import ParameterError

        if ctx.scenario.crowd.guidance != "signs":
            raise ParameterError(
                "crowd.guidance", ctx.scenario.crowd.guidance, "'signs' for the density (the baselines are agents')"
            )
        initial_positions(ctx.scenario, ctx.scenario.crowd.n, ctx.rng)  # the agents' draw, discarded
        c = ctx.scenario.crowd
        diagram = plugins.load("congestion", ctx.scenario.congestion_model)(free_speed=c.free_speed, rho_max=c.rho_max)
        congested = bool(diagram.slows)  # "none": the paper's crowd, unchanged
        fp = FokkerPlanck(
            ctx.grid,
            ctx.sigma,
            interaction=ctx.interaction,
            disturbance=ctx.disturbance,
            method=method,
            exits=congested,  # uncongested: the exits once per control period, as ever (see __init__)
            congestion=diagram if congested else None,
            people=c.n if congested else None,
        )
        return cls(fp, initial_density(ctx.scenario, ctx.grid), ctx.kernel, substeps=substeps, sight=ctx.sight)
