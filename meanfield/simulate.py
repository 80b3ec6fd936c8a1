"""The closed loop: crowd SDE, robots, KDE density feedback and the backstepping law.

One step (``dt``) of :class:`ClosedLoop`:

1. ρ̂ = KDE of the humans' positions on the grid (paper, Section IV-A);
2. the robots' kernels on the grid faces; ``v_r`` (eq. (3));
3. controller: ``v_d`` (eq. (6)), ``ṽ``, ``b_i``, ``g_i``, ``A``, inputs ``(u_i, ω_i)`` (eq. (8));
4. humans: one Euler–Maruyama step of eq. (1) with drift ``v_r + u_W + v_a`` at each human
   (with a finite view radius, ``v_r`` only where a robot is in view, a random walk
   elsewhere: :mod:`meanfield.local_view`); with the JuPedSim backend the drift is each
   body's desired velocity instead (:mod:`meanfield.pedestrian_crowd`);
5. robots: one Euler step of eq. (2), saturated at the speed limits, kept in Ω.

:func:`run` returns a :class:`SimulationResult` holding an xarray Dataset of the recorded
frames and the summary; :meth:`SimulationResult.save` writes them atomically.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meanfield import plugins
from meanfield.control import (
    BacksteppingController,
    BetaGammaStrategy,
    ConstantAlpha,
    ControlState,
    MinimumNormBetaGamma,
    SaturatingAlpha,
)
from meanfield.crowd import Crowd
from meanfield.density import KernelDensityEstimator
from meanfield.domain import Domain
from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.grid import Grid
from meanfield.interaction import InteractionField
from meanfield.kernels import GaussianKernel, GaussianPotential, NavigationKernel
from meanfield.local_view import LocalView
from meanfield.metrics import (
    fraction_in_disk,
    gaussian_target,
    max_body_overlap,
    target_region_radius,
    w2_block_size,
    wasserstein2_to_grid_density,
)
from meanfield.robots import NavigationField, RobotTeam, navigation_velocity, saturate_inputs
from meanfield.sampled_field import SampledNavigationField
from meanfield.scenario import Scenario

__all__ = [
    "ClosedLoop",
    "SimulationResult",
    "run",
    "robot_layout",
    "alpha_schedule_for",
    "disturbance_for",
    "initial_crowd",
    "initial_density",
    "initial_humans",
    "recorded_humans",
]

Disturbance = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]

# crowd.field_evaluation = "auto" samples v_r on a lattice above this many human-robot pairs
SAMPLED_FIELD_ABOVE = 2_000_000


def robot_layout(domain: Domain, n: int, margin: float = 0.0) -> np.ndarray:
    """``n`` robot positions on a regular lattice covering Ω (the paper's 4×4 for n = 16).

    A box gets a cell-centred ``cols × rows`` lattice (``cols = ceil(sqrt(n))``), the last
    row centred if it is partial; other shapes get the smallest square lattice over the
    bounding box with at least ``n`` points inside Ω, of which ``n`` evenly spaced ones.
    """
    region = _robot_region(domain, margin)
    x0, x1, y0, y1 = region.bounds
    if domain.kind == "box":
        cols = math.ceil(math.sqrt(n))
        rows = math.ceil(n / cols)
        pts = []
        for r in range(rows):
            k = min(cols, n - r * cols)
            y = y0 + (r + 0.5) * (y1 - y0) / rows
            for c in range(k):
                pts.append((x0 + (c + 0.5 + (cols - k) / 2) * (x1 - x0) / cols, y))
        return np.array(pts, float)
    m = math.ceil(math.sqrt(n))
    while True:
        xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
        ys = y0 + (np.arange(m) + 0.5) * (y1 - y0) / m
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        inside = region.contains(X, Y)
        if inside.sum() >= n:
            cand = np.column_stack([X[inside], Y[inside]])
            idx = np.round(np.linspace(0, len(cand) - 1, n)).astype(int)
            return cand[idx]
        m += 1


def alpha_schedule_for(scenario: Scenario) -> ConstantAlpha | SaturatingAlpha:
    """The Step-I gain α(ρ) of ``scenario.controller`` (``"constant"`` or ``"saturating"``)."""
    c = scenario.controller
    return ConstantAlpha(c.alpha) if c.alpha_schedule == "constant" else SaturatingAlpha(c.alpha, c.rho_floor)


def initial_crowd(scenario: Scenario, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` initial positions from the scenario's crowd law (uniform on Ω, or a normal
    law restricted to Ω by rejection), drawn from ``rng``."""
    c = scenario.crowd
    if c.initial == "uniform":
        return scenario.domain.sample_uniform(n, rng)
    out = np.empty((0, 2))
    while len(out) < n:
        p = rng.normal(loc=c.initial_center, scale=c.initial_std, size=(2 * (n - len(out)) + 8, 2))
        out = np.vstack([out, p[scenario.domain.contains(p[:, 0], p[:, 1])]])
    return out[:n].copy()


def initial_humans(scenario: Scenario, rng: np.random.Generator) -> np.ndarray:
    """The initial crowd of the scenario's backend: points from :func:`initial_crowd`, or for
    JuPedSim non-overlapping bodies from the same law (:func:`~meanfield.pedestrian_crowd.place_bodies`)."""
    if scenario.pedestrians.backend == "point-mass":
        return initial_crowd(scenario, scenario.crowd.n, rng)
    from meanfield.pedestrian_crowd import place_bodies

    return place_bodies(
        lambda k: initial_crowd(scenario, k, rng), scenario.crowd.n, scenario.pedestrians.radius, scenario.domain
    )


def initial_density(scenario: Scenario, grid: Grid) -> np.ndarray:
    """The density of the scenario's initial crowd law on ``grid`` (unit mass): uniform on Ω,
    or the normal law restricted to Ω — the mean-field initial condition of eq. (4)."""
    c = scenario.crowd
    if c.initial == "uniform":
        return grid.normalize(np.ones(grid.shape))
    return gaussian_target(grid, c.initial_center, c.initial_std)


def _robot_region(domain: Domain, margin: float) -> Domain:
    """Where robots may stand: Ω, inset by ``margin`` for a box or a disk."""
    if margin <= 0:
        return domain
    if domain.kind == "box":
        x0, x1, y0, y1 = domain.bounds
        return Domain.box(x1 - x0 - 2 * margin, y1 - y0 - 2 * margin, (x0 + margin, y0 + margin))
    if domain.kind == "disk":
        return Domain.disk(domain.radius - margin, domain.center)
    raise ParameterError("robots.margin", margin, "0 for a polygon domain (a margin needs a box or a disk)")


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


@dataclass
class SimulationResult:
    """Outcome of a closed-loop run.

    Attributes
    ----------
    scenario : Scenario
    dataset : xarray.Dataset
        Recorded frames (robot states, humans, density estimates, V₁, V₂, errors, speeds).
    summary : dict
        ``fraction_in_target``, ``l2_error_initial``, ``l2_error_final``,
        ``w2_to_target_final``, ``time_to_90``, ``max_robot_speed``, ``speed_limit``,
        ``steps``, ``wall_seconds``, ``seed``, ``status``, the scenario, and more.
    """

    scenario: Scenario
    dataset: Any
    summary: dict[str, Any]
    kernel: NavigationKernel | None = None

    def save(self, out_dir: str | Path, figures: bool = True, animate: bool = False) -> dict[str, Path]:
        """Write ``timeseries.nc``, ``scenario.toml``, figures and (last) ``summary.json``.

        Every file is written atomically, and ``summary.json`` only once everything else
        is in place, so a directory with a ``summary.json`` is complete.
        """
        from meanfield.io import atomic_write_json, atomic_write_text, atomic_write_with

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths: dict[str, Path] = {}
        paths["timeseries"] = atomic_write_with(
            out / "timeseries.nc", lambda p: self.dataset.to_netcdf(p, engine="h5netcdf")
        )
        paths["scenario"] = atomic_write_text(out / "scenario.toml", self.scenario.to_toml())
        if figures or animate:
            from meanfield import plotting

            if figures:
                paths.update(plotting.save_run_figures(self, out))
            if animate:
                paths["animation"] = plotting.save_animation(self, out / "animation.gif")
        paths["summary"] = atomic_write_json(out / "summary.json", self.summary)
        return paths


class ClosedLoop:
    """The paper's closed loop, built from a :class:`Scenario`.

    Parameters
    ----------
    scenario : Scenario
    sigma : float or callable, optional
        Overrides ``scenario.crowd.sigma``; a callable ``σ(x, y, t)`` is allowed here.
    disturbance : callable, optional
        ``v_a(x, y, t) -> (vx, vy)``, overriding ``scenario.disturbance``.
    beta_gamma : BetaGammaStrategy, optional
        Overrides ``scenario.controller.beta_gamma`` (e.g. a :class:`~meanfield.control.UserBetaGamma`).
    kernel : NavigationKernel, optional
        Overrides the scenario's Gaussian kernel.

    Examples
    --------
    >>> from meanfield import ClosedLoop, paper_scenario
    >>> loop = ClosedLoop(paper_scenario(seed=1).replace(t_final=0.1))
    >>> result = loop.run(progress=False)
    >>> sorted(result.summary)[:3]
    ['A_final', 'fraction_in_target', 'l2_error_final']
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        sigma: float | Callable | None = None,
        disturbance: Disturbance | None = None,
        beta_gamma: BetaGammaStrategy | None = None,
        kernel: NavigationKernel | None = None,
    ):
        if not isinstance(scenario, Scenario):
            raise ParameterError("scenario", type(scenario).__name__, "a Scenario")
        self.scenario = sc = scenario
        self.rng = np.random.default_rng(sc.seed)
        self.domain = sc.domain
        self.grid = Grid(sc.domain, sc.grid.cells)
        self.kernel = kernel if kernel is not None else GaussianKernel(sc.kernel.c, sc.kernel.eta)
        self.target = gaussian_target(self.grid, sc.target.center, sc.target.std)
        self.target_center = sc.target.center
        self.target_radius = target_region_radius(sc.domain, sc.target.center, sc.target.std)
        bw = None if sc.density.bandwidth == "silverman" else sc.density.bandwidth
        self.kde = KernelDensityEstimator(self.grid, bw, sc.density.boundary, sc.density.method)
        sigma = sc.crowd.sigma if sigma is None else sigma
        self.disturbance = disturbance if disturbance is not None else disturbance_for(sc)
        # initial states: humans first, then robot headings, then the walkers' headings,
        # all from the one seeded generator
        humans = initial_humans(sc, self.rng)
        ped = sc.pedestrians
        if ped.backend == "jupedsim":
            from meanfield.pedestrian_crowd import PedestrianCrowd

            # without JuPedSim, its adapter refuses here with the install command
            self.crowd: Crowd | PedestrianCrowd = PedestrianCrowd(
                humans, sc.domain, ped.radius, ped.max_speed, ped.time_step, ped.model, sc.seed
            )
        else:
            self.crowd = Crowd(humans, sc.domain, sigma, self.rng)
        self.robot_region = _robot_region(sc.domain, sc.robots.margin)
        if sc.robots.layout == "grid":
            rpos = robot_layout(sc.domain, sc.robots.n, sc.robots.margin)
        elif sc.robots.layout == "random":
            rpos = self.robot_region.sample_uniform(sc.robots.n, self.rng)
        else:
            rpos = np.asarray(sc.robots.positions, float)
        if isinstance(sc.robots.headings, str):
            heads = self.rng.uniform(0.0, 2 * np.pi, sc.robots.n)
        else:
            heads = np.asarray(sc.robots.headings, float)
        self.robots = RobotTeam(rpos, heads, sc.robots.u_max, sc.robots.omega_max)
        self.robots.check_inside(sc.domain)
        self.body_radius = ped.radius if ped.backend == "jupedsim" else 0.0  # 0: point masses
        # deepest overlap of two bodies so far, over every control step (from the start)
        self.max_body_overlap, self.max_body_overlap_time = 0.0, None
        self._track_body_overlap(0.0)
        v = sc.view
        self.view = LocalView(
            self.crowd.n, v.radius, v.walk_speed, v.turning_rate, sc.domain, self.rng, self.body_radius
        )
        # v_r at the humans: exactly (O(N n)), or sampled on a lattice and interpolated
        mode = sc.crowd.field_evaluation
        if mode == "auto":
            mode = "sampled" if self.crowd.n * self.robots.n > SAMPLED_FIELD_ABOVE else "exact"
        self.field_evaluation = mode
        self.sampled_field = None
        if mode == "sampled":
            nx, ny = sc.grid.cells
            self.sampled_field = SampledNavigationField(self.kernel, sc.domain.bounds, (2 * nx + 1, 2 * ny + 1))
        self._drift: np.ndarray | None = None
        self.overrides = sorted(
            name
            for name, value in (
                ("sigma", sigma if sigma is not sc.crowd.sigma else None),
                ("disturbance", disturbance),
                ("beta_gamma", beta_gamma),
                ("kernel", kernel),
            )
            if value is not None
        )
        self.interaction = None
        if sc.interaction.kind == "gaussian":
            pot = GaussianPotential(sc.interaction.strength, sc.interaction.length)
            self.interaction = InteractionField(self.grid, pot)
        c = sc.controller
        alpha = alpha_schedule_for(sc)
        if beta_gamma is not None:
            strategy = beta_gamma
        elif c.beta_gamma == "min-norm":
            strategy = MinimumNormBetaGamma()
        else:
            strategy = plugins.load("beta_gamma", c.beta_gamma)(sc)
        self.sigma = sigma
        self.backstepping = BacksteppingController(
            self.grid, self.target, sigma, alpha, c.k_u, c.k_omega, strategy, self.interaction, c.dvd_dt
        )
        # the controller plugin (e.g. NMPC) sees the whole loop; backstepping is the paper's law
        self.controller = (
            self.backstepping if c.kind == "backstepping" else plugins.load("controller", c.kind)(self)
        )
        self.t = 0.0
        self.step_index = 0
        self.last_state: ControlState | None = None
        self.last_inputs: tuple[np.ndarray, np.ndarray] | None = None
        self.max_robot_speed = 0.0
        self.max_robot_turn_rate = 0.0
        self.saturated_steps = 0
        self.last_saturated = False
        self.binding_steps = 0
        self.last_at_limit = 0
        self.last_shortfall_applied = float("nan")
        self.density: np.ndarray = self.kde(self.crowd.positions)

    # ------------------------------------------------------------------ one step
    def human_drift(self, positions: np.ndarray) -> np.ndarray:
        """``u_W(X_j) + v_r(X_j, t) + v_a(X_j, t)`` at every human (paper, eq. (1)).

        With a finite view radius, ``v_r`` is replaced by the random walk for the humans who
        see no robot (:meth:`LocalView.gate`).  With a sampled field (large crowds) the
        returned array is reused, and overwritten, by the next call.
        """
        if self.sampled_field is not None:
            self.sampled_field.update(self.robots.positions, self.robots.headings)
            if self._drift is None or len(self._drift) != len(positions):
                self._drift = np.empty((len(positions), 2))
            drift = self.sampled_field.at_points(positions, out=self._drift)
        else:
            drift = navigation_velocity(self.kernel, self.robots.positions, self.robots.headings, positions)
        self.view.gate(drift, positions, self.robots.positions, self.scenario.dt)
        if self.interaction is not None:
            drift += self.interaction.at_points(positions)
        if self.disturbance is not None:
            ax, ay = self.disturbance(positions[:, 0], positions[:, 1], self.t)
            drift[:, 0] += ax
            drift[:, 1] += ay
        return drift

    def control(self) -> ControlState:
        """Controller output for the current state (density estimate already computed)."""
        field = NavigationField(self.kernel, self.grid, self.robots.positions, self.robots.headings)
        return self.controller.robot_inputs(self.density, field, self.t, self.scenario.dt)

    def step(self) -> ControlState:
        """Advance the closed loop by one ``dt``; raise :class:`SimulationDiverged` on NaN/inf.

        The state is only changed when every quantity entering the update is finite, so
        after the exception the loop still holds the last good state.
        """
        dt = self.scenario.dt
        state = self.control()
        drift = self.human_drift(self.crowd.positions)
        if not (np.isfinite(state.u).all() and np.isfinite(state.omega).all() and np.isfinite(drift).all()):
            raise SimulationDiverged(
                f"non-finite robot inputs or human drift at t = {self.t:.4g} (step {self.step_index}); "
                "the state is kept at the last good step",
                self.step_index,
            )
        u, w = saturate_inputs(state.u, state.omega, self.robots.u_max, self.robots.omega_max)
        self.crowd.step(drift, self.t, dt)
        self.view.advance(dt)
        self._track_body_overlap((self.step_index + 1) * dt)
        self.robots.advance(u, w, dt, self.robot_region)
        self.t = (self.step_index + 1) * dt
        self.step_index += 1
        self.last_state = state
        self.last_inputs = (u, w)
        speed = np.hypot(u[:, 0], u[:, 1])
        self.max_robot_speed = max(self.max_robot_speed, float(speed.max()))
        self.max_robot_turn_rate = max(self.max_robot_turn_rate, float(np.abs(w).max()))
        self.last_saturated = bool(
            (np.hypot(state.u[:, 0], state.u[:, 1]) > speed).any() or (np.abs(state.omega) > np.abs(w)).any()
        )
        self.saturated_steps += self.last_saturated
        self.last_at_limit = int(self.robots.at_limit(state.u, state.omega).sum())
        self.last_shortfall_applied = self.applied_shortfall(state, u, w)
        self.binding_steps += self.last_at_limit > 0
        self.density = self.kde(self.crowd.positions)
        if not np.isfinite(self.density).all():
            raise SimulationDiverged(f"non-finite density estimate at t = {self.t:.4g}", self.step_index)
        return state

    def applied_shortfall(self, state: ControlState, u: np.ndarray, omega: np.ndarray) -> float:
        """``A − (Σ b_i·δu_i − Σ g_i δω_i)`` for the inputs actually applied (after saturation).

        With ``δu_i = u_i − k_u b_i`` and ``δω_i = ω_i + k_ω g_i``, so that
        ``dV₂/dt = −∫α|∇ρ̃|² − Σ k_u|b_i|² − Σ k_ω g_i² + applied shortfall`` (eq. (8)):
        the part of ``A`` the robots did not cancel, whatever the strategy or the clipping.
        """
        c = self.backstepping
        k_u = c.k_u[:, None] if c.k_u.ndim else c.k_u
        du = u - k_u * state.b
        dw = omega + c.k_omega * state.g
        return float(state.A - ((state.b * du).sum() - (state.g * dw).sum()))

    # ------------------------------------------------------------------ the run
    def run(self, progress: bool = True, callback: Callable[[ClosedLoop], None] | None = None) -> SimulationResult:
        """Run to ``t_final``, recording every ``record_every`` steps.

        Parameters
        ----------
        progress : bool
            Show a tqdm progress bar.
        callback : callable, optional
            Called as ``callback(loop)`` after every step.

        Returns
        -------
        SimulationResult
            With ``summary["status"]`` ``"completed"``, ``"diverged"`` (the message in
            ``summary["message"]``; frames up to the last good state) or ``"interrupted"``
            (KeyboardInterrupt; frames so far).
        """
        from tqdm.auto import tqdm

        sc = self.scenario
        rec = _Recorder(self)
        rho_err0 = self.grid.norm(self.density - self.target)
        t90 = None
        frac = fraction_in_disk(self.crowd.positions, self.target_center, self.target_radius)
        if frac >= 0.9:
            t90 = 0.0
        status, message = "completed", ""
        n_steps = sc.steps - self.step_index
        start = time.perf_counter()
        bar = tqdm(total=n_steps, disable=not progress, desc=f"meanfield run {sc.name}", unit="step", mininterval=0.5)
        try:
            for _ in range(n_steps):
                k = self.step_index
                state = self.step()
                if k % sc.record_every == 0:
                    rec.record_control(state)
                frac = fraction_in_disk(self.crowd.positions, self.target_center, self.target_radius)
                if t90 is None and frac >= 0.9:
                    t90 = self.t
                if self.step_index % sc.record_every == 0 or self.step_index == sc.steps:
                    rec.record_state(frac)
                    bar.update(self.step_index - bar.n)
                if callback is not None:
                    callback(self)
        except SimulationDiverged as exc:
            status, message = "diverged", str(exc)
        except KeyboardInterrupt:
            status, message = "interrupted", f"interrupted at t = {self.t:.4g}"
        finally:
            bar.close()
        wall = time.perf_counter() - start
        if rec.last_recorded_step != self.step_index:
            rec.record_state(frac)
        dataset = rec.dataset()
        final_err = self.grid.norm(self.density - self.target)
        summary: dict[str, Any] = {
            "status": status,
            "message": message,
            "fraction_in_target": frac,
            "target_radius": self.target_radius,
            "l2_error_initial": rho_err0,
            "l2_error_final": final_err,
            "l2_error_ratio": final_err / rho_err0 if rho_err0 > 0 else None,
            "w2_to_target_final": wasserstein2_to_grid_density(
                self.crowd.positions, self.grid, self.target, seed=sc.seed
            ),
            "w2_coarsening_bound": self._w2_coarsening_bound(),
            "time_to_90": t90,
            "max_robot_speed": self.max_robot_speed,
            "speed_limit": None if math.isinf(self.robots.u_max) else self.robots.u_max,
            "max_robot_turn_rate": self.max_robot_turn_rate,
            "turn_rate_limit": None if math.isinf(self.robots.omega_max) else self.robots.omega_max,
            "saturated_fraction": self.saturated_steps / max(self.step_index, 1),
            "limits_binding_fraction": self.binding_steps / max(self.step_index, 1),
            "shortfall_mean": _finite_mean(dataset["shortfall"].values),
            "shortfall_max": _finite_max(dataset["shortfall"].values),
            "shortfall_applied_mean": _finite_mean(dataset["shortfall_applied"].values),
            "python_overrides": self.overrides,
            "backend": sc.pedestrians.backend,
            "field_evaluation": self.field_evaluation,
            "field_error_bound_final": self._field_error_bound(),
            "view_radius": sc.view.radius,
            "seen_fraction_final": float(self.view.seen.mean()),
            **self._body_summary(),
            "V2_initial": rec.first_V2,
            "V2_final": float(dataset["V2"].values[-1]) if dataset.sizes["time"] else None,
            "A_final": float(self.last_state.A) if self.last_state is not None else None,
            "steps": self.step_index,
            "time_final": self.t,
            "wall_seconds": wall,
            "steps_per_second": (self.step_index - (sc.steps - n_steps)) / wall if wall > 0 else None,
            "seed": sc.seed,
            "scenario": sc.to_dict(),
        }
        return SimulationResult(sc, dataset, summary, self.kernel)

    def _w2_coarsening_bound(self) -> float:
        """How far merging cells for the W₂ solve can move it (0: every cell kept)."""
        b = w2_block_size(self.grid)
        return 0.0 if b == 1 else b * math.hypot(self.grid.dx, self.grid.dy)

    def _field_error_bound(self) -> float | None:
        """Interpolation error bound of the sampled ``v_r`` at the final robots (None: exact)."""
        if self.sampled_field is None:
            return None
        self.sampled_field.update(self.robots.positions, self.robots.headings)
        return self.sampled_field.error_bound()

    def _track_body_overlap(self, t: float) -> None:
        """Record the deepest overlap of the bodies at time ``t`` (JuPedSim backend only)."""
        if self.body_radius:
            pos = self.crowd.positions
            depth, _ = max_body_overlap(pos[:, 0], pos[:, 1], self.body_radius)
            if depth > self.max_body_overlap:
                self.max_body_overlap, self.max_body_overlap_time = depth, t

    def _body_summary(self) -> dict[str, Any]:
        """JuPedSim runs: the bodies' radius, model and deepest overlap over every control step.

        The recorded frames of ``timeseries.nc`` are a subset of those steps; anyone can
        re-check them with :func:`~meanfield.metrics.max_body_overlap`.
        """
        ped = self.scenario.pedestrians
        if ped.backend != "jupedsim":
            return {}
        return {
            "pedestrian_model": ped.model,
            "jupedsim_version": self.crowd.adapter.version,
            "body_radius": ped.radius,
            "body_overlap_max": self.max_body_overlap,
            "body_overlap_max_relative": self.max_body_overlap / (2.0 * ped.radius),
            "body_overlap_time": self.max_body_overlap_time,
        }


def _finite_mean(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def _finite_max(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else None


def recorded_humans(n: int, record_humans: int | str) -> np.ndarray:
    """Indices of the humans whose positions a run records: all, or ``record_humans`` spaced ones.

    The humans are exchangeable (drawn i.i.d. from the initial law), so evenly spaced
    indices are a sample of the crowd; the density, the fraction in the target and every
    summary figure still use all ``n``.
    """
    if record_humans == "all" or record_humans >= n:
        return np.arange(n)
    # spacing (n - 1)/(k - 1) > 1 for k < n: the rounded indices are distinct and increasing
    return np.linspace(0, n - 1, int(record_humans)).round().astype(np.intp)


@dataclass
class _Recorder:
    """Collects frames; control quantities are those computed at the frame's state."""

    loop: ClosedLoop
    frames: dict[str, list] = field(default_factory=lambda: {k: [] for k in _Recorder.KEYS})
    last_recorded_step: int = -1
    first_V2: float | None = None
    humans: np.ndarray = field(init=False, repr=False)

    KEYS = (
        "time",
        "robot_x",
        "robot_y",
        "robot_heading",
        "robot_speed",
        "robot_turn_rate",
        "human_x",
        "human_y",
        "density",
        "V1",
        "V2",
        "rho_error_l2",
        "v_error_l2",
        "fraction_in_target",
        "A",
        "shortfall",
        "dissipation",
        "saturated",
        "robots_at_limit",
        "shortfall_applied",
        "seen_fraction",
    )

    def __post_init__(self) -> None:
        self.humans = recorded_humans(self.loop.crowd.n, self.loop.scenario.record_humans)
        self.record_state(fraction_in_disk(self.loop.crowd.positions, self.loop.target_center, self.loop.target_radius))

    def _lyapunov_values(self, state: ControlState) -> dict[str, float]:
        """‖ρ̃‖, ‖ṽ‖, V₁ = ∫ρ̃², V₂ = ∫½ρ̃² + ½|ṽ|² and the law's scalars at one state."""
        g = self.loop.grid
        rt = g.norm(state.rho_tilde)
        vt = g.face_norm(state.v_tilde)
        return {
            "V1": rt * rt,
            "V2": 0.5 * rt * rt + 0.5 * vt * vt,
            "rho_error_l2": rt,
            "v_error_l2": vt,
            "A": state.A,
            "shortfall": state.shortfall,
            "dissipation": state.dissipation,
        }

    def record_control(self, state: ControlState) -> None:
        """Fill the latest frame with the control computed at its state (before the step)."""
        u, w = self.loop.last_inputs
        vals = self._lyapunov_values(state)
        if self.first_V2 is None:
            self.first_V2 = vals["V2"]
        vals.update(
            robot_speed=np.hypot(u[:, 0], u[:, 1]),
            robot_turn_rate=w,
            saturated=self.loop.last_saturated,
            robots_at_limit=self.loop.last_at_limit,
            shortfall_applied=self.loop.last_shortfall_applied,
        )
        idx = len(self.frames["time"]) - 1
        for key, v in vals.items():
            self.frames[key][idx] = v

    def record_state(self, frac: float) -> None:
        loop = self.loop
        n = loop.robots.n
        f = self.frames
        f["time"].append(loop.t)
        f["robot_x"].append(loop.robots.positions[:, 0].copy())
        f["robot_y"].append(loop.robots.positions[:, 1].copy())
        f["robot_heading"].append(loop.robots.headings.copy())
        f["human_x"].append(loop.crowd.positions[self.humans, 0])
        f["human_y"].append(loop.crowd.positions[self.humans, 1])
        f["density"].append(loop.density.copy())
        f["fraction_in_target"].append(frac)
        f["seen_fraction"].append(float(loop.view.seen.mean()))
        for key in ("robot_speed", "robot_turn_rate"):
            f[key].append(np.full(n, np.nan))
        for key in ("V1", "V2", "rho_error_l2", "v_error_l2", "A", "shortfall", "dissipation"):
            f[key].append(np.nan)
        f["saturated"].append(False)
        f["robots_at_limit"].append(-1)
        f["shortfall_applied"].append(np.nan)
        self.last_recorded_step = loop.step_index

    def dataset(self):
        import xarray as xr

        loop = self.loop
        f = self.frames
        g = loop.grid
        # the last frame's control quantities: evaluate the controller at the final state
        if np.isnan(f["V2"][-1]):
            try:
                for key, v in self._lyapunov_values(loop.control()).items():
                    f[key][-1] = v
            except (FloatingPointError, ValueError):
                pass
        stack = np.asarray
        ped = loop.scenario.pedestrians
        ds = xr.Dataset(
            data_vars={
                "robot_x": (("time", "robot"), stack(f["robot_x"])),
                "robot_y": (("time", "robot"), stack(f["robot_y"])),
                "robot_heading": (("time", "robot"), stack(f["robot_heading"])),
                "robot_speed": (("time", "robot"), stack(f["robot_speed"])),
                "robot_turn_rate": (("time", "robot"), stack(f["robot_turn_rate"])),
                "human_x": (("time", "human"), stack(f["human_x"])),
                "human_y": (("time", "human"), stack(f["human_y"])),
                "density": (("time", "x", "y"), stack(f["density"])),
                "target_density": (("x", "y"), loop.target),
                "V1": ("time", stack(f["V1"], float)),
                "V2": ("time", stack(f["V2"], float)),
                "rho_error_l2": ("time", stack(f["rho_error_l2"], float)),
                "v_error_l2": ("time", stack(f["v_error_l2"], float)),
                "fraction_in_target": ("time", stack(f["fraction_in_target"], float)),
                "A": ("time", stack(f["A"], float)),
                "shortfall": ("time", stack(f["shortfall"], float)),
                "dissipation": ("time", stack(f["dissipation"], float)),
                "saturated": ("time", stack(f["saturated"], np.int8)),
                "robots_at_limit": ("time", stack(f["robots_at_limit"], np.int16)),
                "shortfall_applied": ("time", stack(f["shortfall_applied"], float)),
                "seen_fraction": ("time", stack(f["seen_fraction"], float)),
            },
            coords={
                "time": stack(f["time"], float),
                "x": g.x,
                "y": g.y,
                "robot": np.arange(loop.robots.n),
                "human": self.humans,
            },
            attrs={
                "title": "meanfield closed-loop run (Zheng et al., robot-assisted crowd evacuation)",
                "scenario_toml": loop.scenario.to_toml(),
                "seed": loop.scenario.seed,
                "target_center_x": loop.target_center[0],
                "target_center_y": loop.target_center[1],
                "target_radius": loop.target_radius,
                "V1_definition": "V1 = integral of rho_tilde^2 (no factor 1/2)",
                "V2_definition": "V2 = integral of rho_tilde^2/2 + |v_tilde|^2/2",
                "backend": loop.scenario.pedestrians.backend,
                "body_radius": ped.radius if ped.backend == "jupedsim" else 0.0,
                "humans_total": loop.crowd.n,
                "humans_recorded": len(self.humans),
            },
        )
        ds["human"].attrs["description"] = (
            "index of the human in the crowd (a spaced subset when record_humans < humans_total)"
        )
        ds["robot_speed"].attrs["description"] = "applied (saturated) speed |u_i| during the step from this frame"
        ds["shortfall"].attrs["description"] = "A minus what the strategy's (unclipped) extra inputs cancel"
        ds["shortfall_applied"].attrs["description"] = (
            "A minus what the applied (saturated) inputs cancel: dV2/dt = -diss - sum k_u|b|^2 - sum k_w g^2 + this"
        )
        ds["seen_fraction"].attrs["description"] = (
            "fraction of humans with a robot within the view radius (1 without gating); recorded at the frame's step"
        )
        ds["robots_at_limit"].attrs["description"] = (
            "robots whose commanded input reached a speed or turn-rate limit in the step from this frame"
            " (-1: none recorded)"
        )
        return ds


def run(
    scenario: Scenario | str, *, seed: int | None = None, progress: bool = True, **overrides: Any
) -> SimulationResult:
    """Build a :class:`ClosedLoop` and run it.

    Parameters
    ----------
    scenario : Scenario or str
        A scenario, a built-in name (``"paper"``) or a TOML path.
    seed : int, optional
        Override the scenario's seed.
    progress : bool
        Show a progress bar.
    **overrides
        Passed to :class:`ClosedLoop` (``sigma``, ``disturbance``, ``beta_gamma``, ``kernel``).
    """
    from meanfield.scenario import load_scenario

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if seed is not None:
        scenario = scenario.replace(seed=seed)
    return ClosedLoop(scenario, **overrides).run(progress=progress)
