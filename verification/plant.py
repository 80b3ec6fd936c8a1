"""The density plants the theorem checks run: the crowd's PDE closed under Step I (and Step II).

Two discretisations of eq. (4) with ``v_r = v_d + w`` (``w = ṽ + v_a``, zero for Theorem 1):

* :func:`model_trajectory` — the controller's own semi-discrete model (central face
  fluxes, :meth:`~meanfield.controllers.backstepping.BacksteppingController.density_rate`), on which
  ``v_r = v_d`` turns eq. (4) into ``ρ̃̇ = ∇_h·(α ∇_h ρ̃) − ∇_h·(w ρ_f)`` *exactly*.
  It is integrated by an implicit stiff solver (SciPy's BDF) to a tight tolerance, so
  what it shows is the theorem's argument on the grid, free of time-stepping error.  It
  never divides by ρ, so it also shows when ρ would have to become negative — where
  ``v_d`` is undefined and no crowd can follow.
* :func:`fokker_planck_trajectory` — the toolkit's Fokker–Planck solver
  (Scharfetter–Gummel fluxes, positive) driven by ``v_d(ρⁿ) + w`` re-evaluated every
  step: the closed loop as a sampled-data feedback realises it.

Both record ``V₁ = ∫ρ̃²`` and the Step-I dissipation ``∫α|∇ρ̃|²`` along the way.  On a
region with exits the Fokker–Planck plant loses the exits' outflow after every step, as
the toolkit's density crowd does (:class:`~meanfield.geometry.exits.ExitSink`; ``docs/verification.md``,
*Floor plans and exits*), and records the mass left in Ω.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import sparse
from scipy.integrate import solve_ivp

from meanfield.controllers.backstepping import BacksteppingController
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.exits import ExitSink, exit_segments
from meanfield.geometry.grid import FaceField, Grid

__all__ = [
    "Trajectory",
    "RobotLoopTrajectory",
    "alpha_on_faces",
    "exit_sink",
    "face_points",
    "model_trajectory",
    "fokker_planck_trajectory",
    "robot_loop_trajectory",
]

FaceDisturbance = Callable[[float], FaceField]
"""``w(t)`` on the grid's interior faces (x-faces, y-faces)."""


@dataclass
class Trajectory:
    """A recorded density trajectory of a Step-I plant.

    Attributes
    ----------
    t : ndarray
        Times.
    V1 : ndarray
        ``∫ρ̃²`` (no ½).
    dissipation : ndarray
        ``∫α|∇ρ̃|²`` on the faces.
    dV1_dt : ndarray
        ``2⟨ρ̃, ρ̇⟩`` along the plant's own right-hand side.
    rho_min, rho_max : ndarray
        Extremes of ρ over the cells.
    alpha_min : ndarray
        ``min α`` over the open faces (the theorem's ``α_inf`` is its minimum over t).
    w_norm : ndarray
        ``‖w(t)‖`` on the faces (0 for Theorem 1).
    rho_final : ndarray
        The last density.
    mass : ndarray or None
        ``∫ρ`` at the records (the initial mass throughout without exits).
    """

    t: np.ndarray
    V1: np.ndarray
    dissipation: np.ndarray
    dV1_dt: np.ndarray
    rho_min: np.ndarray
    rho_max: np.ndarray
    alpha_min: np.ndarray
    w_norm: np.ndarray
    rho_final: np.ndarray
    info: dict = field(default_factory=dict)
    mass: np.ndarray | None = None

    @property
    def rho_error(self) -> np.ndarray:
        """``‖ρ̃(t)‖``."""
        return np.sqrt(np.maximum(self.V1, 0.0))


def face_points(grid: Grid) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Midpoints of the interior x-faces and y-faces, where face fields live."""
    return grid.face_points_x, grid.face_points_y


def alpha_on_faces(ctrl: BacksteppingController, rho: np.ndarray) -> FaceField:
    """``α(ρ_f)`` on the faces, as the controller uses it (``α = (α/ρ)·ρ``).

    A density-dependent schedule is evaluated at ``max(ρ_f, 0)``: the semi-discrete model
    may carry ρ slightly below zero, where a saturating ``α ∝ ρ`` would turn negative
    (backward diffusion).  Constant α is unaffected."""
    rf = ctrl.grid.face_average(rho)
    return ctrl.alpha.alpha(np.maximum(rf[0], 0.0)), ctrl.alpha.alpha(np.maximum(rf[1], 0.0))


def _open_min(grid: Grid, a: FaceField) -> float:
    if grid.is_box:
        return float(min(a[0].min(), a[1].min()))
    vals = [a[0][grid.aperture_x > 0], a[1][grid.aperture_y > 0]]
    return float(min(v.min() for v in vals if v.size))


def _measure(ctrl: BacksteppingController, rho: np.ndarray, rho_dot: np.ndarray, w: FaceField | None) -> tuple:
    g = ctrl.grid
    rt = rho - ctrl.target
    a = alpha_on_faces(ctrl, rho)
    grt = g.gradient(rt)
    diss = g.face_inner((a[0] * grt[0], a[1] * grt[1]), grt)
    inside = rho[g.active]
    wn = g.face_norm(w) if w is not None else 0.0
    return g.inner(rt, rt), diss, 2.0 * g.inner(rt, rho_dot), inside.min(), inside.max(), _open_min(g, a), wn


def _model_rate(ctrl: BacksteppingController, rho: np.ndarray, w: FaceField | None) -> np.ndarray:
    """``∇_h·(α∇_hρ̃) − ∇_h·(w ρ_f)``: eq. (4) with ``v_r = v_d + w`` on the controller's faces."""
    g = ctrl.grid
    a = alpha_on_faces(ctrl, rho)
    grt = g.gradient(rho - ctrl.target)
    flux = [-a[k] * grt[k] for k in range(2)]
    if w is not None:
        rf = g.face_average(rho)
        flux = [flux[k] + w[k] * rf[k] for k in range(2)]
    return -g.divergence((flux[0], flux[1]))


def _sparsity(grid: Grid) -> sparse.csr_matrix:
    """The 5-point stencil of the active cells (Jacobian pattern for the stiff solver)."""
    nx, ny = grid.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows = [idx.ravel()]
    cols = [idx.ravel()]
    for a, b in ((idx[:-1, :], idx[1:, :]), (idx[:, :-1], idx[:, 1:])):
        rows += [a.ravel(), b.ravel()]
        cols += [b.ravel(), a.ravel()]
    r, c = np.concatenate(rows), np.concatenate(cols)
    return sparse.csr_matrix((np.ones(r.size), (r, c)), shape=(nx * ny, nx * ny))


def model_trajectory(
    ctrl: BacksteppingController,
    rho0: np.ndarray,
    t_eval: np.ndarray,
    w: FaceDisturbance | None = None,
    rtol: float = 1e-8,
) -> Trajectory:
    """Integrate the controller's semi-discrete closed loop ``v_r = v_d + w`` (Theorems 1 and 2).

    ``ρ̇ = ∇_h·(α(ρ_f)∇_h(ρ − ρ_*)) − ∇_h·(w ρ_f)``, the exact substitution of eq. (6)
    into eq. (4) on the controller's faces, by BDF with relative tolerance ``rtol``.
    Cells outside Ω (cut-cell grids) stay at zero.

    Parameters
    ----------
    ctrl : BacksteppingController
        Supplies the grid, ``ρ_*`` and the α schedule.
    rho0 : ndarray
        Initial density on the grid.
    t_eval : ndarray
        Recording times (increasing, starting at the initial time).
    w : callable, optional
        ``w(t)`` on the faces (Theorem 2's ``ṽ + v_a``).
    rtol : float
        Relative tolerance of the integrator.
    """
    g = ctrl.grid
    shape = g.shape
    t_eval = np.asarray(t_eval, float)

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        rho = y.reshape(shape)
        out = _model_rate(ctrl, rho, None if w is None else w(t))
        return np.where(g.active, out, 0.0).ravel()

    sol = solve_ivp(
        rate,
        (t_eval[0], t_eval[-1]),
        np.asarray(rho0, float).ravel(),
        method="BDF",
        t_eval=t_eval,
        rtol=rtol,
        atol=rtol * 1e-4 * float(np.abs(rho0).max()),
        jac_sparsity=_sparsity(g),
    )
    if not sol.success:
        raise RuntimeError(f"the stiff integrator failed: {sol.message}")
    rows = []
    for k, t in enumerate(sol.t):
        rho = sol.y[:, k].reshape(shape)
        wf = None if w is None else w(t)
        rows.append(_measure(ctrl, rho, _model_rate(ctrl, rho, wf), wf))
    cols = [np.array(c, float) for c in zip(*rows, strict=True)]
    return Trajectory(sol.t, *cols, rho_final=sol.y[:, -1].reshape(shape), info={"nfev": int(sol.nfev)})


def exit_sink(grid: Grid, sigma: Any) -> ExitSink | None:
    """The outflow of the region's exits on ``grid`` (``None`` without exits), as the density
    crowd builds it: a diffusion σ given as a function gives no outflow, there as in
    :class:`~meanfield.crowds.density_crowd.DensityCrowd`."""
    segs = exit_segments(grid.domain)
    if not len(segs):
        return None
    return ExitSink(grid, segs, 0.0 if callable(sigma) else float(sigma))


def fokker_planck_trajectory(
    ctrl: BacksteppingController,
    fp: FokkerPlanck,
    rho0: np.ndarray,
    t_final: float,
    dt: float,
    w: FaceDisturbance | None = None,
    record_every: int = 1,
    sink: ExitSink | None = None,
) -> Trajectory:
    """Run the Fokker–Planck plant under the sampled Step-I feedback ``v_r = v_d(ρⁿ) + w(tⁿ)``.

    Every step re-evaluates eq. (6) at the current density and hands it to
    :meth:`~meanfield.fokker_planck.solver.FokkerPlanck.step` as the face velocity; with exits,
    the step is followed by their outflow (``sink``, Lie splitting as in the density crowd),
    and the recorded ``dV₁/dt`` includes the outflow's rate ``−kρ``.

    Parameters
    ----------
    ctrl : BacksteppingController
    fp : FokkerPlanck
        The plant (same grid and σ as ``ctrl``; no prescribed robot field).
    rho0 : ndarray
    t_final, dt : float
        Horizon and step.
    w : callable, optional
        ``w(t)`` on the faces.
    record_every : int
        Record every so many steps (and the last).
    sink : ExitSink, optional
        The exits' outflow (:func:`exit_sink`); ``None``: zero flux through all of ∂Ω.

    Notes
    -----
    The run stops early, saying so in ``info["stopped"]``, if ρ reaches 0 on a face, where
    ``v_d`` is undefined (the theorems assume ρ > 0).  The last record then holds the state
    but no rate (``dV₁/dt`` and the dissipation's pairing are set from ``ρ̇ = 0``).
    """
    steps = int(round(t_final / dt))
    rho = np.asarray(rho0, float).copy()
    times, rows, mass = [], [], []
    t = 0.0
    g = ctrl.grid
    info: dict[str, Any] = {"dt": dt, "steps": steps}
    for k in range(steps + 1):
        wf = None if w is None else w(t)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v = ctrl.virtual_velocity(rho, t)
        if not (np.isfinite(v[0]).all() and np.isfinite(v[1]).all()):  # ρ = 0 on a face: v_d undefined
            info["stopped"] = f"ρ reached 0 on a face at t = {t:.4g}: v_d = −(α∇ρ̃ − ∇(σρ))/ρ is undefined there"
            if not times or times[-1] != t:
                times.append(t)
                rows.append(_measure(ctrl, rho, np.zeros_like(rho), wf))  # ρ̇ unknown: the record keeps V₁ only
                mass.append(g.integrate(rho))
            break
        if wf is not None:
            v = (v[0] + wf[0], v[1] + wf[1])
        if k % record_every == 0 or k == steps:
            times.append(t)
            rate = fp.rhs(rho, t, face_velocity=v)
            if sink is not None:
                rate = rate - sink.total_rate * rho
            rows.append(_measure(ctrl, rho, rate, wf))
            mass.append(g.integrate(rho))
        if k == steps:
            break
        rho = fp.step(rho, t, dt, face_velocity=v)
        if sink is not None:
            rho, _ = sink.apply(rho, dt)
        t = (k + 1) * dt
    cols = [np.array(c, float) for c in zip(*rows, strict=True)]
    return Trajectory(np.array(times), *cols, rho_final=rho, info=info, mass=np.array(mass, float))


@dataclass
class RobotLoopTrajectory:
    """A recorded run of the PDE plant closed by the robot law (Theorem 3).

    Every array is per recorded step.  ``dV2_dt`` is the semi-discrete rate
    ``⟨ρ̃, ρ̇⟩ + ⟨ṽ, ∂_t v_r − ∂_t v_d⟩`` along the plant's own ``ρ̇`` and the applied
    inputs; ``claim`` is ``−∫α|∇ρ̃|² − Σk_u|b_i|² − Σk_ω g_i² + shortfall`` (eq. (8) with
    the part of ``A`` the applied inputs did not cancel).  With exits, ``ρ̇`` includes their
    outflow ``E = −kρ`` and ``exit_term`` is its share of the rate,
    ``⟨ρ̃, E⟩ − ⟨ṽ, ∂_ρv_d[E]⟩``: the law's model has no exits, so the law does not cancel it
    and ``dV₂/dt = claim + exit_term`` is what Step II gives (``None`` without exits).
    """

    t: np.ndarray
    V2: np.ndarray
    rho_error: np.ndarray
    v_error: np.ndarray
    dV2_dt: np.ndarray
    claim: np.ndarray
    action: np.ndarray  # Σ k_u|b_i|² + Σ k_ω g_i²
    dissipation: np.ndarray
    shortfall: np.ndarray
    speed: np.ndarray  # largest commanded robot speed
    at_limit: np.ndarray  # robots whose command reached a limit
    info: dict = field(default_factory=dict)
    exit_term: np.ndarray | None = None  # with exits: their share of dV₂/dt, which the law does not cancel
    mass: np.ndarray | None = None  # ∫ρ at the records


class _LyapunovRates:
    """Observer of the closed loop on the density: ``V₂`` and its rate against eq. (8)'s claim at each step."""

    def __init__(self, record_every: int):
        self.record_every = record_every
        self.rows: list[tuple] = []
        self.exit_term: list[float] = []
        self.mass: list[float] = []

    def start(self, loop: Any) -> None:
        pass

    def step(self, loop: Any, record: Any) -> None:
        if record.index % self.record_every:
            return
        g, ctrl, fp = loop.grid, loop.controller, loop.crowd.fp
        obs, st, u, w = record.observation, record.command.state, record.u, record.omega
        rho, t = obs.density, obs.t
        rho_dot = fp.rhs(rho, t, face_velocity=obs.field.velocity())
        sink = getattr(loop.crowd, "sink", None)
        if sink is not None:  # the exits' outflow: part of the plant's ρ̇, unknown to the law
            out = -sink.total_rate * rho
            rho_dot = rho_dot + out
            dvd_out = ctrl.virtual_velocity_rate(rho, out, t)
            self.exit_term.append(g.inner(st.rho_tilde, out) - g.face_inner(st.v_tilde, dvd_out))
        self.mass.append(g.integrate(rho))
        dvr = obs.field.velocity_rate(u, w)
        dvd = ctrl.virtual_velocity_rate(rho, rho_dot, t)
        dV2 = g.inner(st.rho_tilde, rho_dot) + g.face_inner(st.v_tilde, (dvr[0] - dvd[0], dvr[1] - dvd[1]))
        k_u = np.broadcast_to(ctrl.k_u, (loop.robots.n,))
        k_w = np.broadcast_to(ctrl.k_omega, (loop.robots.n,))
        action = float((k_u * (st.b**2).sum(1)).sum() + (k_w * st.g**2).sum())
        short = record.shortfall_applied
        re, ve = g.norm(st.rho_tilde), g.face_norm(st.v_tilde)
        self.rows.append(
            (
                t,
                0.5 * re * re + 0.5 * ve * ve,
                re,
                ve,
                dV2,
                -st.dissipation - action + short,
                action,
                st.dissipation,
                short,
                float(np.hypot(st.u[:, 0], st.u[:, 1]).max()),
                record.at_limit,
            )
        )


def robot_loop_trajectory(scenario: Any, t_final: float, dt: float, record_every: int = 1) -> RobotLoopTrajectory:
    """The closed loop of the robot law on the Fokker–Planck plant (eqs. (4), (6), (8)), measured.

    :class:`~meanfield.simulation.loop.ClosedLoop` runs the scenario's robots and backstepping law on
    the crowd's density (:class:`~meanfield.crowds.density_crowd.DensityCrowd`, the split stepper,
    one step of ``dt`` per control period); the controller sees the exact density and the
    robots integrate eq. (2) within their limits.  An observer records ``V₂`` and the
    semi-discrete ``dV₂/dt`` against the claim of eq. (8) at every ``record_every``-th step.

    Parameters
    ----------
    scenario : Scenario
        Its robots, controller gains and limits, σ, interaction, kernel, target and
        initial law (its ``controller.kind`` is ignored: the paper's law is checked; so is
        its disturbance: Theorem 3 assumes none).
    t_final, dt : float
        Horizon and control period.
    record_every : int
    """
    import dataclasses

    from meanfield.crowds.density_crowd import DensityCrowd
    from meanfield.errors import SimulationDiverged
    from meanfield.simulation.assembly import assemble
    from meanfield.simulation.loop import ClosedLoop

    sc = scenario.replace(dt=dt, t_final=t_final)
    parts = assemble(sc, crowd="fokker-planck", controller="backstepping")
    # Theorem 3's plant: no v_a, split stepping, one step per period
    fp = FokkerPlanck(parts.grid, parts.sigma, method="split", interaction=parts.interaction)
    crowd = DensityCrowd(fp, parts.crowd.density(), parts.kernel, substeps=False)
    rates = _LyapunovRates(record_every)
    loop = ClosedLoop(dataclasses.replace(parts, crowd=crowd), observers=[rates])
    steps = int(round(t_final / dt))
    try:
        for _ in range(steps):
            loop.step()
    except SimulationDiverged:
        pass
    cols = [np.array(c, float) for c in zip(*rates.rows, strict=True)]
    exit_term = np.array(rates.exit_term, float) if crowd.sink is not None else None
    return RobotLoopTrajectory(
        *cols, info={"dt": dt, "steps": steps}, exit_term=exit_term, mass=np.array(rates.mass, float)
    )
