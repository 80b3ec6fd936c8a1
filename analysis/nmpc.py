"""NMPC baseline: the robots plan their inputs over a short horizon on a coarse Fokker–Planck model.

What a control engineer would try instead of the paper's backstepping (Section IV): a
receding-horizon optimal-control problem on a coarse discretisation of the crowd's
mean-field density and of the robots' kinematics, re-solved every control period.

The prediction model
    The Fokker–Planck equation of the paper (eq. (4)) without interaction or disturbance,
    on ``cells`` coarse cells (finite volumes, upwind or central advective fluxes), backward
    Euler in time with the prediction step ``Δt_p``; the robots follow eq. (2) by forward
    Euler.  It is :class:`~analysis.nmpc_model.CoarseFokkerPlanck` (docs/nmpc.md, "The
    prediction model"); the options are :class:`~analysis.nmpc_options.NMPCOptions`.  Both
    are re-exported here.

The optimal-control problem (every ``Δt_c = period``)::

    minimise   Δt_p Σ_{k=0}^{H-1} [ ‖ρ_{k+1} - ρ_*‖² + r_u Σ_i |u_{ik}|² + r_ω Σ_i ω_{ik}² ]  +  q_T ‖ρ_H - ρ_*‖²
    subject to the model above,  |u_{ik}|² <= u_max²,  |ω_{ik}| <= ω_max,  R_{ik} in the robots' region

with ``‖·‖`` the coarse L² norm, ``ρ_0`` the fine-grid KDE estimate averaged onto the coarse
cells (renormalised to unit mass) and ``ρ_*`` the target averaged likewise.  The problem is
built once with CasADi's Opti stack (every state lifted as a decision variable: sparse
Jacobians and Hessians), compiled to one function with ``Opti.to_function`` and solved by
IPOPT (exact Hessian by default), warm-started from the previous solution shifted by the
elapsed prediction steps.  Between solves the robots apply the plan open loop (with
``period == step``, the default, the first input is held).

The inputs returned are the plan's; the other fields of the returned
:class:`~meanfield.control.ControlState` (``v_d``, ``ṽ``, ``b``, ``g``, ``A``, dissipation)
are those of the loop's :class:`~meanfield.control.BacksteppingController` at the same
state, so that ``V₂ = ∫½ρ̃² + ½|ṽ|²`` is comparable between the two controllers
(``shortfall`` is NaN: NMPC does not cancel ``A``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from analysis.nmpc_model import CoarseFokkerPlanck
from analysis.nmpc_options import FLUXES, HESSIANS, NMPCOptions
from meanfield.control import BacksteppingController, ControlState
from meanfield.errors import ParameterError
from meanfield.grid import Grid
from meanfield.interfaces import Command, ControllerParts, Observation
from meanfield.kernels import NavigationKernel
from meanfield.robots import NavigationField, RobotTeam

__all__ = [
    "FLUXES",
    "HESSIANS",
    "NMPCOptions",
    "CoarseFokkerPlanck",
    "NMPCPlan",
    "NMPCController",
    "nmpc_controller_for",
]


# ---------------------------------------------------------------------- the controller
@dataclass
class NMPCPlan:
    """One solution of the optimal-control problem.

    Attributes
    ----------
    u : ndarray (H, n, 2)
        Planned velocities ``u_{ik}`` (within the speed limit).
    omega : ndarray (H, n)
        Planned turn rates.
    positions, headings : ndarray (H+1, n, 2), (H+1, n)
        Predicted robot states, the initial state first.
    rho : ndarray (H+1, nx, ny)
        Predicted coarse densities, ``ρ_0`` first.
    cost : float
        The optimal cost.
    lam_g : ndarray
        Constraint multipliers (for the next warm start).
    status : str
        IPOPT's return status.
    success : bool
    iterations : int
    seconds : float
        Wall time of the compiled function call (the solve).
    """

    u: np.ndarray
    omega: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    rho: np.ndarray
    cost: float
    lam_g: np.ndarray
    status: str
    success: bool
    iterations: int
    seconds: float


class NMPCController:
    """Receding-horizon controller of the robots on a coarse Fokker–Planck model (see the module).

    Parameters
    ----------
    grid : Grid
        The loop's (fine) grid of the density estimate; its domain must be a box.
    target : ndarray
        ``ρ_*`` on ``grid.shape``.
    kernel : GaussianKernel
        The robots' kernel.
    sigma : float
        Diffusion ``σ`` (a constant).
    robots : RobotTeam
        The robots: their number and speed limits (``u_max``, ``omega_max``; infinite
        means no constraint), and their states when the navigation field does not carry them.
    backstepping : BacksteppingController
        Computes the diagnostic fields of the returned :class:`ControlState`.
    options : NMPCOptions or mapping, optional
    region : (x0, x1, y0, y1), optional
        Box the planned robot positions must stay in (default: the grid's box).

    Attributes
    ----------
    stats : list of dict
        One entry per solve: ``t``, ``seconds`` (wall time of the solve), ``status`` (IPOPT),
        ``success``, ``iterations``, ``cost``, ``max_speed_solver`` and ``max_turn_rate_solver``
        (the largest ``‖u_ik‖``, ``|ω_ik|`` of IPOPT's solution, before projection) and
        ``projected`` (whether the returned inputs had to be projected back onto the limits,
        which IPOPT meets only to its tolerance).
    backstepping_seconds : list of float
        Wall time of the backstepping law (``robot_inputs``) at every call, measured in the
        same run: the reference of the compute comparison.
    """

    def __init__(
        self,
        grid: Grid,
        target: np.ndarray,
        kernel: NavigationKernel,
        sigma: float,
        robots: RobotTeam,
        backstepping: BacksteppingController,
        options: NMPCOptions | Mapping[str, Any] | None = None,
        region: tuple[float, float, float, float] | None = None,
    ):
        self.options = options if isinstance(options, NMPCOptions) else NMPCOptions.from_mapping(options)
        if not grid.is_box:
            raise ParameterError("domain", grid.domain.kind, "a box (the NMPC coarse model is a box grid)")
        if callable(sigma):
            raise ParameterError("sigma", "a callable", "a constant σ for the NMPC model")
        self.grid = grid
        self.robots = robots
        self.backstepping = backstepping
        self.n = robots.n
        self.u_max = float(robots.u_max)
        self.omega_max = float(robots.omega_max)
        o = self.options
        self.model = CoarseFokkerPlanck(grid.domain.bounds, o.cells, sigma, kernel, self.n, o.prediction_step, o.flux)
        self.region = tuple(float(b) for b in (region if region is not None else grid.domain.bounds))
        self._restriction = self.model.restriction(grid)
        self.target_coarse = self.restrict(np.asarray(target, float))
        self.solver = self._build()
        self.stats: list[dict[str, Any]] = []
        self.backstepping_seconds: list[float] = []
        self.plan: NMPCPlan | None = None
        self._t_plan = 0.0

    # ------------------------------------------------------------------ the compiled problem
    def _build(self) -> ca.Function:
        o, m, n = self.options, self.model, self.n
        H, C, h = o.horizon, m.size, m.step
        opti = ca.Opti()
        rho0, target = opti.parameter(C), opti.parameter(C)
        rx0, ry0, th0 = opti.parameter(n), opti.parameter(n), opti.parameter(n)
        Ux, Uy, W = opti.variable(n, H), opti.variable(n, H), opti.variable(n, H)
        Rx, Ry, Th = opti.variable(n, H), opti.variable(n, H), opti.variable(n, H)
        P = opti.variable(C, H)
        J = 0
        px, py, pt, pr = rx0, ry0, th0, rho0
        for k in range(H):
            opti.subject_to(Rx[:, k] == px + h * Ux[:, k])  # eq. (2), forward Euler
            opti.subject_to(Ry[:, k] == py + h * Uy[:, k])
            opti.subject_to(Th[:, k] == pt + h * W[:, k])
            opti.subject_to(m.residual_function(P[:, k], pr, Rx[:, k], Ry[:, k], Th[:, k]) == 0)  # eq. (4)
            e = P[:, k] - target
            J += h * (
                m.cell_volume * ca.sumsqr(e)
                + o.r_u * (ca.sumsqr(Ux[:, k]) + ca.sumsqr(Uy[:, k]))
                + o.r_omega * ca.sumsqr(W[:, k])
            )
            px, py, pt, pr = Rx[:, k], Ry[:, k], Th[:, k], P[:, k]
        J += o.terminal * m.cell_volume * ca.sumsqr(P[:, H - 1] - target)
        opti.minimize(J)
        if math.isfinite(self.u_max):
            opti.subject_to(ca.vec(Ux * Ux + Uy * Uy) <= self.u_max**2)
        if math.isfinite(self.omega_max):
            opti.subject_to(opti.bounded(-self.omega_max, ca.vec(W), self.omega_max))
        x0, x1, y0, y1 = self.region
        opti.subject_to(opti.bounded(x0, ca.vec(Rx), x1))
        opti.subject_to(opti.bounded(y0, ca.vec(Ry), y1))
        ipopt = {
            "print_level": 0,
            "sb": "yes",
            "max_iter": o.max_iter,
            "tol": o.tol,
            "hessian_approximation": o.hessian,
        }
        opti.solver("ipopt", {"print_time": False, "error_on_fail": False, "expand": True}, ipopt)
        self._shapes = {"H": H, "C": C}
        return opti.to_function(
            "nmpc",
            [rho0, rx0, ry0, th0, target, Ux, Uy, W, Rx, Ry, Th, P, opti.lam_g],
            [Ux, Uy, W, Rx, Ry, Th, P, opti.lam_g, opti.f],
            ["rho0", "rx0", "ry0", "th0", "target", "ux", "uy", "omega", "rx", "ry", "th", "rho", "lam_g"],
            ["ux_opt", "uy_opt", "omega_opt", "rx_opt", "ry_opt", "th_opt", "rho_opt", "lam_g_opt", "cost"],
        )

    # ------------------------------------------------------------------ pieces
    def restrict(self, rho: np.ndarray) -> np.ndarray:
        """The fine-grid density ``rho`` averaged onto the coarse cells, unit mass."""
        Px, Py = self._restriction
        rc = Px @ rho @ Py.T
        return rc / self.model.mass(rc)

    def initial_guess(
        self,
        rho_coarse: np.ndarray,
        positions: np.ndarray,
        headings: np.ndarray,
        previous: NMPCPlan | None = None,
        shift: int = 0,
    ) -> dict[str, Any]:
        """Initial guess of a solve: ``previous`` shifted by ``shift`` prediction steps (the last
        input repeated), or zero inputs; robot states rolled out from ``(positions, headings)``."""
        H, n = self.options.horizon, self.n
        positions = np.asarray(positions, float).reshape(-1, 2)
        headings = np.asarray(headings, float).ravel()
        rho_c = np.asarray(rho_coarse, float)
        if previous is None:
            u = np.zeros((H, n, 2))
            w = np.zeros((H, n))
            lam = 0.0
            rho_guess = np.repeat(rho_c.reshape(1, -1), H, axis=0)
        else:
            s = min(max(shift, 0), H)
            idx = np.minimum(np.arange(H) + s, H - 1)
            u, w = previous.u[idx], previous.omega[idx]
            lam = previous.lam_g
            rho_guess = previous.rho[1:][idx].reshape(H, -1)
        x0, x1, y0, y1 = self.region
        h = self.model.step
        R = np.clip(positions[None] + h * np.cumsum(u, axis=0), [x0, y0], [x1, y1])
        T = headings[None] + h * np.cumsum(w, axis=0)
        return {
            "ux": u[..., 0].T,
            "uy": u[..., 1].T,
            "omega": w.T,
            "rx": R[..., 0].T,
            "ry": R[..., 1].T,
            "th": T.T,
            "rho": rho_guess.T,
            "lam_g": lam,
        }

    def solve(
        self,
        rho_coarse: np.ndarray,
        positions: np.ndarray,
        headings: np.ndarray,
        guess: Mapping[str, Any] | None = None,
    ) -> NMPCPlan:
        """Solve the optimal-control problem once (a call of the compiled function).

        Parameters
        ----------
        rho_coarse : ndarray (nx, ny)
            ``ρ_0`` on the coarse cells (see :meth:`restrict`).
        positions, headings : ndarray (n, 2), (n,)
            Robot states ``R_i``, ``θ_i`` now.
        guess : mapping, optional
            Initial guess (keys of the compiled function's inputs); default zero inputs.

        Returns
        -------
        NMPCPlan
            With the inputs projected onto the limits (IPOPT meets them only to its tolerance).
        """
        positions = np.asarray(positions, float).reshape(-1, 2)
        headings = np.asarray(headings, float).ravel()
        rho_c = np.asarray(rho_coarse, float).reshape(self.model.shape)
        g = dict(guess) if guess is not None else self.initial_guess(rho_c, positions, headings)
        t0 = time.perf_counter()
        out = self.solver(
            rho0=rho_c.ravel(),
            rx0=positions[:, 0],
            ry0=positions[:, 1],
            th0=headings,
            target=self.target_coarse.ravel(),
            **g,
        )
        seconds = time.perf_counter() - t0
        st = self.solver.stats()
        H, n = self.options.horizon, self.n
        u = np.stack([np.asarray(out["ux_opt"]).reshape(n, H).T, np.asarray(out["uy_opt"]).reshape(n, H).T], axis=-1)
        w = np.asarray(out["omega_opt"]).reshape(n, H).T
        R = np.stack([np.asarray(out["rx_opt"]).reshape(n, H).T, np.asarray(out["ry_opt"]).reshape(n, H).T], axis=-1)
        T = np.asarray(out["th_opt"]).reshape(n, H).T
        P = np.asarray(out["rho_opt"]).reshape(-1, H).T.reshape(H, *self.model.shape)
        return NMPCPlan(
            u=u,
            omega=w,
            positions=np.concatenate([positions[None], R]),
            headings=np.concatenate([headings[None], T]),
            rho=np.concatenate([rho_c[None], P]),
            cost=float(out["cost"]),
            lam_g=np.asarray(out["lam_g_opt"]).ravel(),
            status=str(st.get("return_status", "unknown")),
            success=bool(st.get("success", False)),
            iterations=int(st.get("iter_count", -1)),
            seconds=seconds,
        )

    def project(self, u: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inputs projected onto ``‖u_i‖ <= u_max``, ``|ω_i| <= ω_max`` (non-finite values become 0)."""
        u = np.where(np.isfinite(u), u, 0.0)
        omega = np.where(np.isfinite(omega), omega, 0.0)
        if math.isfinite(self.u_max):
            speed = np.hypot(u[..., 0], u[..., 1])
            scale = np.where(speed > self.u_max, self.u_max / np.where(speed > 0, speed, 1.0), 1.0)
            u = u * scale[..., None]
        if math.isfinite(self.omega_max):
            omega = np.clip(omega, -self.omega_max, self.omega_max)
        return u, omega

    def predicted_cost(
        self, rho_coarse: np.ndarray, positions: np.ndarray, headings: np.ndarray, u: np.ndarray, omega: np.ndarray
    ) -> float:
        """The optimal-control cost of inputs ``u (H, n, 2)``, ``omega (H, n)`` along the model."""
        o, m = self.options, self.model
        P, _, _ = m.predict(rho_coarse, positions, headings, u, omega)
        e = P[1:] - self.target_coarse
        stage = m.cell_volume * np.sum(e * e, axis=(1, 2)) + o.r_u * np.sum(u * u, axis=(1, 2))
        stage += o.r_omega * np.sum(np.square(omega), axis=1)
        return float(m.step * stage.sum() + o.terminal * m.cell_volume * np.sum(e[-1] ** 2))

    @staticmethod
    def _robot_state(field: NavigationField, robots: RobotTeam) -> tuple[np.ndarray, np.ndarray]:
        """``(R, θ)`` from the navigation field, else from the robot team (same instant in the loop)."""
        pos = getattr(field, "positions", None)
        if pos is None:
            pos = robots.positions
        heads = getattr(field, "headings", None)
        if heads is None:
            heads = np.arctan2(field.sin, field.cos)
        return np.array(pos, float).reshape(-1, 2), np.array(heads, float).ravel()

    # ------------------------------------------------------------------ the law
    def robot_inputs(
        self, rho: np.ndarray, field: NavigationField, t: float = 0.0, dt: float | None = None
    ) -> ControlState:
        """Robot inputs from the current plan, re-solving every ``period``.

        Parameters
        ----------
        rho : ndarray
            Density estimate on the loop's grid.
        field : NavigationField
            The robots' kernels now (their states ``R_i``, ``θ_i``).
        t : float
            Time.
        dt : float, optional
            Step since the previous call (passed to the backstepping diagnostics).

        Returns
        -------
        ControlState
            ``u``, ``omega``: the plan's inputs at ``t`` (within the limits); ``shortfall``
            NaN; every other field from the backstepping law at the same state.
        """
        t0 = time.perf_counter()
        state = self.backstepping.robot_inputs(rho, field, t, dt)
        self.backstepping_seconds.append(time.perf_counter() - t0)
        o = self.options
        h = self.model.step
        elapsed = t - self._t_plan
        if self.plan is None or elapsed < -1e-9 or elapsed >= o.period - 1e-9:
            positions, headings = self._robot_state(field, self.robots)
            rho_c = self.restrict(np.asarray(rho, float))
            shift = int(round(elapsed / h)) if self.plan is not None and elapsed >= 0 else 0
            previous = self.plan if o.warm_start else None
            plan = self.solve(
                rho_c, positions, headings, self.initial_guess(rho_c, positions, headings, previous, shift)
            )
            u, w = self.project(plan.u, plan.omega)
            raw_speed = float(np.hypot(plan.u[..., 0], plan.u[..., 1]).max())
            raw_turn = float(np.abs(plan.omega).max())
            projected = bool(np.any(np.abs(u - plan.u) > 0) or np.any(np.abs(w - plan.omega) > 0))
            plan.u, plan.omega = u, w
            self.plan, self._t_plan, elapsed = plan, t, 0.0
            self.stats.append(
                {
                    "t": float(t),
                    "seconds": plan.seconds,
                    "status": plan.status,
                    "success": plan.success,
                    "iterations": plan.iterations,
                    "cost": plan.cost,
                    "max_speed_solver": raw_speed,
                    "max_turn_rate_solver": raw_turn,
                    "projected": projected,
                }
            )
        k = min(int(math.floor(elapsed / h + 1e-9)), o.horizon - 1)
        return dataclasses.replace(state, u=self.plan.u[k].copy(), omega=self.plan.omega[k].copy(), shortfall=math.nan)

    def act(self, observation: Observation) -> Command:
        """The :class:`~meanfield.interfaces.Controller` interface: :meth:`robot_inputs` at the observation.

        The command carries the backstepping quantities at the same state (for the records).
        """
        o = observation
        state = self.robot_inputs(o.density, o.field, o.t, o.dt)
        return Command(state.u, state.omega, state)

    def reset(self) -> None:
        """Forget the plan (next call re-solves from zero inputs), the statistics and the
        backstepping diagnostics' memory."""
        self.plan = None
        self._t_plan = 0.0
        self.stats = []
        self.backstepping_seconds = []
        self.backstepping.reset()

    def summary(self) -> dict[str, Any]:
        """Compute statistics: solves, median/p90 solve seconds, backstepping seconds per call, statuses."""
        secs = np.array([s["seconds"] for s in self.stats], float)
        bs = np.array(self.backstepping_seconds, float)
        statuses: dict[str, int] = {}
        for s in self.stats:
            statuses[s["status"]] = statuses.get(s["status"], 0) + 1
        med = float(np.median(secs)) if secs.size else math.nan
        bmed = float(np.median(bs)) if bs.size else math.nan
        return {
            "solves": int(secs.size),
            "solve_seconds_median": med,
            "solve_seconds_p90": float(np.percentile(secs, 90)) if secs.size else math.nan,
            "solve_seconds_max": float(secs.max()) if secs.size else math.nan,
            "iterations_median": float(np.median([s["iterations"] for s in self.stats])) if self.stats else math.nan,
            "statuses": statuses,
            "backstepping_calls": int(bs.size),
            "backstepping_seconds_median": bmed,
            "backstepping_seconds_p90": float(np.percentile(bs, 90)) if bs.size else math.nan,
            "ratio_solve_over_backstepping": med / bmed if bs.size and secs.size and bmed > 0 else math.nan,
        }


def nmpc_controller_for(parts: ControllerParts) -> NMPCController:
    """Plugin factory (entry point ``nmpc`` of ``meanfield.controllers``): an NMPC from the loop's parts.

    The options come from ``parts.options`` (``controller.options`` of the scenario; see
    :class:`NMPCOptions`); the backstepping law it reports beside its plan is built from the
    same parts (:meth:`~meanfield.control.BacksteppingController.from_parts`).

    Raises
    ------
    ParameterError
        For a bad option (naming ``controller.options.<key>``), a non-box domain, a
        non-Gaussian kernel, a non-constant σ or an interaction potential (not in the model).
    """
    options = NMPCOptions.from_mapping(parts.options)
    if not parts.grid.is_box:
        raise ParameterError("domain", parts.region.kind, "a box (the NMPC coarse model is a box grid)")
    if parts.interaction is not None:
        raise ParameterError("interaction.kind", "gaussian", "'none' (not in the NMPC model)")
    backstepping = BacksteppingController.from_parts(dataclasses.replace(parts, options={}))
    return NMPCController(
        parts.grid,
        parts.target,
        parts.kernel,
        parts.sigma,
        parts.robots,
        backstepping,
        options,
        region=parts.robot_region.bounds,
    )
