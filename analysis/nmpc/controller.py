"""NMPC baseline: the robots plan their inputs over a short horizon on a coarse Fokker–Planck model.

What a control engineer would try instead of the paper's backstepping (Section IV): a
receding-horizon optimal-control problem on a coarse discretisation of the crowd's
mean-field density and of the robots' kinematics, re-solved every control period.

The prediction model
    The Fokker–Planck equation of the paper (eq. (4)) without interaction or disturbance,
    on ``cells`` coarse cells (finite volumes, upwind or central advective fluxes), backward
    Euler in time with the prediction step ``Δt_p``; the robots follow eq. (2) by forward
    Euler.  It is :class:`~analysis.nmpc.prediction_model.CoarseFokkerPlanck` (docs/nmpc.md, "The
    prediction model"); the options are :class:`~analysis.nmpc.options.NMPCOptions`.  Both
    are exported by the package, :mod:`analysis.nmpc`.

The optimal-control problem (every ``Δt_c = period``)::

    minimise   Δt_p Σ_{k=0}^{H-1} [ ‖ρ_{k+1} - ρ_*‖² + r_u Σ_i |u_{ik}|² + r_ω Σ_i ω_{ik}² ]  +  q_T ‖ρ_H - ρ_*‖²
    subject to the model above,  |u_{ik}|² <= u_max²,  |ω_{ik}| <= ω_max,  R_{ik} in the robots' region

with ``‖·‖`` the coarse L² norm, ``ρ_0`` the fine-grid KDE estimate averaged onto the coarse
cells (renormalised to unit mass) and ``ρ_*`` the target averaged likewise.  Two solvers of
this one problem (``solver``):

* ``"sqp"`` (default): the states eliminated, SQP on the robots' inputs with the exact
  Hessian and the exact constraints, a few QPs per control period (real-time iterations),
  optionally with move blocking (:mod:`analysis.nmpc.condensed`, :mod:`analysis.nmpc.sqp`,
  :mod:`analysis.nmpc.qp`);
* ``"ipopt"``: every state lifted as a decision variable, compiled once with CasADi's Opti
  stack and solved by IPOPT to convergence (:mod:`analysis.nmpc.ipopt`).

Each solve is warm-started from the previous solution shifted by the elapsed prediction
steps.  Between solves the robots apply the plan open loop (with ``period == step``, the
default, the first input is held).  With ``spread`` an SQP solve runs in slices, one per
control step, and its plan is applied from the time the solve started once it is done.

The inputs returned are the plan's; the other fields of the returned
:class:`~meanfield.controllers.backstepping.ControlState` (``v_d``, ``ṽ``, ``b``, ``g``, ``A``, dissipation)
are those of the loop's :class:`~meanfield.controllers.backstepping.BacksteppingController` at the same
state, so that ``V₂ = ∫½ρ̃² + ½|ṽ|²`` is comparable between the two controllers
(``shortfall`` is NaN: NMPC does not cancel ``A``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Generator, Mapping
from typing import Any

import numpy as np

from analysis.nmpc.condensed import CondensedProblem
from analysis.nmpc.ipopt import ipopt_arrays, ipopt_function
from analysis.nmpc.options import NMPCOptions
from analysis.nmpc.plan import NMPCSolution, robot_state
from analysis.nmpc.prediction_model import CoarseFokkerPlanck
from analysis.nmpc.sqp import SQPSolver
from meanfield.capabilities import ControllerCapabilities, declares
from meanfield.controllers.backstepping import BacksteppingController, ControlState
from meanfield.errors import ParameterError
from meanfield.geometry.grid import Grid
from meanfield.interfaces import Command, ControllerParts, Observation
from meanfield.signs.kernels import NavigationKernel
from meanfield.signs.robots import NavigationField, RobotTeam

__all__ = ["NMPCController", "nmpc_controller_for"]


# ---------------------------------------------------------------------- the controller
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
        One entry per solve: ``t`` (when it started), ``seconds`` (its compute, all slices),
        ``slices`` and ``slowest_slice`` (control steps it ran in, and the longest of them),
        ``status`` (the solver's), ``success``, ``iterations``, ``cost``, ``max_speed_solver`` and
        ``max_turn_rate_solver`` (the largest ``‖u_ik‖``, ``|ω_ik|`` of the solver's solution, before projection) and
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
        self.solver = self._build()  # a casadi.Function (IPOPT) or an SQPSolver
        self.stats: list[dict[str, Any]] = []
        self.backstepping_seconds: list[float] = []
        self.plan: NMPCSolution | None = None
        self._t_plan = 0.0
        self._t_start: float | None = None  # when the last solve started
        self._pending: Generator[None, None, NMPCSolution] | None = None  # a solve under way (spread)
        self._slices: list[float] = []

    # ------------------------------------------------------------------ the solver
    def _build(self) -> Any:
        """The compiled IPOPT function, or the SQP solver on the condensed problem."""
        o, m = self.options, self.model
        if o.solver == "ipopt":
            return ipopt_function(m, o, self.n, self.u_max, self.omega_max, self.region)
        problem = CondensedProblem(m, o.input_blocks, o.r_u, o.r_omega, o.terminal)
        return SQPSolver(problem, self.u_max, self.omega_max, self.region, o.hessian)

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
        previous: NMPCSolution | None = None,
        shift: int = 0,
    ) -> dict[str, Any]:
        """Initial guess of a solve: ``previous`` shifted by ``shift`` prediction steps (the last
        input repeated), or zero inputs; robot states rolled out from ``(positions, headings)``;
        the previous multipliers (IPOPT) and damping (SQP)."""
        H, n = self.options.horizon, self.n
        positions = np.asarray(positions, float).reshape(-1, 2)
        headings = np.asarray(headings, float).ravel()
        rho_c = np.asarray(rho_coarse, float)
        if previous is None:
            u = np.zeros((H, n, 2))
            w = np.zeros((H, n))
            lam, damping = 0.0, 0.0
            rho_guess = np.repeat(rho_c.reshape(1, -1), H, axis=0)
        else:
            s = min(max(shift, 0), H)
            idx = np.minimum(np.arange(H) + s, H - 1)
            u, w = previous.u[idx], previous.omega[idx]
            lam, damping = previous.lam_g, previous.damping
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
            "damping": damping,
        }

    def solve(
        self,
        rho_coarse: np.ndarray,
        positions: np.ndarray,
        headings: np.ndarray,
        guess: Mapping[str, Any] | None = None,
    ) -> NMPCSolution:
        """Solve the optimal-control problem once (the SQP's QPs, or a call of the compiled IPOPT function).

        Parameters
        ----------
        rho_coarse : ndarray (nx, ny)
            ``ρ_0`` on the coarse cells (see :meth:`restrict`).
        positions, headings : ndarray (n, 2), (n,)
            Robot states ``R_i``, ``θ_i`` now.
        guess : mapping, optional
            Initial guess (the keys of :meth:`initial_guess`); default zero inputs.

        Returns
        -------
        NMPCSolution
            The solver's inputs (:meth:`robot_inputs` projects them onto the limits).
        """
        positions = np.asarray(positions, float).reshape(-1, 2)
        headings = np.asarray(headings, float).ravel()
        rho_c = np.asarray(rho_coarse, float).reshape(self.model.shape)
        g = dict(guess) if guess is not None else self.initial_guess(rho_c, positions, headings)
        if self.options.solver == "sqp":
            t0, steps = time.perf_counter(), self._sqp_plan(rho_c, positions, headings, g)
            while True:
                try:
                    next(steps)
                except StopIteration as done:
                    done.value.seconds = time.perf_counter() - t0
                    return done.value
        damping = g.pop("damping", 0.0)
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
        a = ipopt_arrays(out, self.n, self.options.horizon, self.model.shape)
        return NMPCSolution(
            u=a["u"],
            omega=a["omega"],
            positions=np.concatenate([positions[None], a["R"]]),
            headings=np.concatenate([headings[None], a["T"]]),
            rho=np.concatenate([rho_c[None], a["P"]]),
            cost=a["cost"],
            lam_g=a["lam_g"],
            status=str(st.get("return_status", "unknown")),
            success=bool(st.get("success", False)),
            iterations=int(st.get("iter_count", -1)),
            seconds=seconds,
            damping=damping,
        )

    def _sqp_plan(
        self, rho_c: np.ndarray, positions: np.ndarray, headings: np.ndarray, g: Mapping[str, Any]
    ) -> Generator[None, None, NMPCSolution]:
        """:meth:`solve` with the SQP solver, in slices: the guess's inputs at the first step of each block."""
        p = self.solver.problem
        starts = np.concatenate([[0], np.cumsum(p.blocks)[:-1]])
        z0 = np.stack([np.asarray(g["ux"]), np.asarray(g["uy"]), np.asarray(g["omega"])], axis=-1)  # (n, H, 3)
        z0 = z0.reshape(self.n, self.options.horizon, 3)[:, starts].transpose(1, 0, 2)
        o = self.options
        res = yield from self.solver.iterate(
            rho_c, positions, headings, z0, self.target_coarse, o.iteration_limit, o.tol, float(g.get("damping", 0.0))
        )
        z = res.z[p.beta]  # (H, n, 3)
        R, T = p.states(positions, headings, res.z)
        _, P = p.rollout(rho_c, positions, headings, res.z, self.target_coarse)
        return NMPCSolution(
            u=z[..., :2],
            omega=z[..., 2],
            positions=np.concatenate([positions[None], R]),
            headings=np.concatenate([headings[None], T]),
            rho=np.concatenate([rho_c[None], P]),
            cost=res.cost,
            lam_g=np.empty(0),
            status=res.status,
            success=res.converged,
            iterations=res.iterations,
            seconds=math.nan,  # set by the caller (the solve may be spread over control steps)
            damping=res.damping,
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
        o, h = self.options, self.model.step
        since = t - self._t_start if self._t_start is not None else math.inf
        if self._pending is None and (since < -1e-9 or since >= o.period - 1e-9):
            positions, headings = robot_state(field, self.robots)
            rho_c = self.restrict(np.asarray(rho, float))
            previous = self.plan if o.warm_start else None
            elapsed = t - self._t_plan
            shift = int(round(elapsed / h)) if previous is not None and elapsed >= 0 else 0
            guess = self.initial_guess(rho_c, positions, headings, previous, shift)
            self._pending, self._t_start, self._slices = self._plan_steps(rho_c, positions, headings, guess), t, []
        if self._pending is not None:
            t1 = time.perf_counter()
            plan = None
            while plan is None:  # one slice when spreading the solve, else all of them
                try:
                    next(self._pending)
                except StopIteration as done:
                    plan = done.value
                if o.spread:
                    break
            self._slices.append(time.perf_counter() - t1)
            if plan is not None:
                self._adopt(plan, self._t_start)
        if self.plan is None:  # spreading the first solve: stand still until its plan is ready
            return dataclasses.replace(state, u=np.zeros((self.n, 2)), omega=np.zeros(self.n), shortfall=math.nan)
        k = min(int(math.floor((t - self._t_plan) / h + 1e-9)), o.horizon - 1)
        return dataclasses.replace(state, u=self.plan.u[k].copy(), omega=self.plan.omega[k].copy(), shortfall=math.nan)

    def _plan_steps(
        self, rho_c: np.ndarray, positions: np.ndarray, headings: np.ndarray, guess: Mapping[str, Any]
    ) -> Generator[None, None, NMPCSolution]:
        """A solve as a generator: the SQP's slices (:meth:`SQPSolver.iterate`), or IPOPT's one call."""
        if self.options.solver == "sqp":
            plan = yield from self._sqp_plan(rho_c, positions, headings, guess)
            return plan
        return self.solve(rho_c, positions, headings, guess)

    def _adopt(self, plan: NMPCSolution, t_start: float) -> None:
        """Make ``plan`` (solved from the state at ``t_start``) the current one, projected onto the limits."""
        u, w = self.project(plan.u, plan.omega)
        raw_speed = float(np.hypot(plan.u[..., 0], plan.u[..., 1]).max())
        raw_turn = float(np.abs(plan.omega).max())
        projected = bool(np.any(np.abs(u - plan.u) > 0) or np.any(np.abs(w - plan.omega) > 0))
        plan.u, plan.omega, plan.seconds = u, w, float(sum(self._slices))
        self.plan, self._t_plan, self._pending = plan, t_start, None
        self.stats.append(
            {
                "t": float(t_start),
                "seconds": plan.seconds,
                "slices": len(self._slices),
                "slowest_slice": max(self._slices),
                "status": plan.status,
                "success": plan.success,
                "iterations": plan.iterations,
                "cost": plan.cost,
                "max_speed_solver": raw_speed,
                "max_turn_rate_solver": raw_turn,
                "projected": projected,
            }
        )

    def act(self, observation: Observation) -> Command:
        """The :class:`~meanfield.interfaces.Controller` interface: :meth:`robot_inputs` at the observation.

        The command carries the backstepping quantities at the same state (for the records).
        """
        import time

        o = observation
        start = time.perf_counter()
        state = self.robot_inputs(o.density, o.field, o.t, o.dt)
        # each control step's compute against its period, for the summary's real-time factor
        self._act_factors = [*getattr(self, "_act_factors", []), (time.perf_counter() - start) / float(o.dt)]
        return Command(state.u, state.omega, state)

    def reset(self) -> None:
        """Forget the plan (next call re-solves from zero inputs), the statistics and the
        backstepping diagnostics' memory."""
        self.plan, self._pending, self._t_start = None, None, None
        self._t_plan = 0.0
        self.stats = []
        self.backstepping_seconds = []
        self._act_factors = []
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
        factors = np.array(getattr(self, "_act_factors", []), float)
        return {
            "solves": int(secs.size),
            # each control step's compute (act: the solve, when there is one, and the law) against the
            # control period dt; < 1 is faster than real time (the scenario's time unit read as a second)
            "realtime_factor_mean": float(factors.mean()) if factors.size else math.nan,
            "realtime_factor_worst": float(factors.max()) if factors.size else math.nan,
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


@declares(ControllerCapabilities(options=NMPCOptions))  # [controller.options.nmpc], checked when the scenario is read
def nmpc_controller_for(parts: ControllerParts) -> NMPCController:
    """Plugin factory (entry point ``nmpc`` of ``meanfield.controllers``): an NMPC from the loop's parts.

    The options come from ``parts.options`` (``controller.options.nmpc`` of the scenario; see
    :class:`NMPCOptions`); the backstepping law it reports beside its plan is built from the
    same parts (:meth:`~meanfield.controllers.backstepping.BacksteppingController.from_parts`).

    Raises
    ------
    ParameterError
        For a bad option (naming ``controller.options.nmpc.<key>``), a non-box domain, a
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


nmpc_controller_for.options = NMPCOptions  # type: ignore[attr-defined]  # what the core reads (plugins.declared)
