"""NMPC baseline: the robots plan their inputs over a short horizon on a coarse Fokker–Planck model.

What a control engineer would try instead of the paper's backstepping (Section IV): a
receding-horizon optimal-control problem on a coarse discretisation of the crowd's
mean-field density and of the robots' kinematics, re-solved every control period.

The prediction model
    The Fokker–Planck equation of the paper (eq. (4)) with the navigation field of eq. (3),
    without interaction (``W = 0``) or disturbance (``v_a`` is unknown to the controller)::

        ∂_t ρ = -∇·(v_r ρ) + σ Δρ,   (v_r ρ - σ∇ρ)·n = 0 on ∂Ω,   v_r(x) = Σ_i c e^{-|x - R_i|²/η} e(θ_i)

    on ``cells`` coarse cells over the box Ω (cell-centred finite volumes), ``v_r`` sampled
    at the coarse face centres, upwind (default) or central advective fluxes, two-point
    diffusive fluxes, no flux through the walls.  In time, backward (implicit) Euler with
    the field at the end of the step, ``ρ_{k+1} = ρ_k + Δt_p L(v_r(R_{k+1}, θ_{k+1})) ρ_{k+1}``:
    unconditionally stable, so the prediction step ``Δt_p`` is not tied to the CFL bound
    ``Δt (2|v|(1/Δx + 1/Δy) + 2σ(1/Δx² + 1/Δy²)) <= 1`` of explicit Euler (which, with the
    rigorous bound ``|v_r| <= n c``, would ask ``Δt <= 7.5e-3`` on a 10×10 grid of the paper
    scenario).  With upwind fluxes ``I - Δt_p L`` is an M-matrix whose columns sum to one in
    the cell-volume weights, so the step keeps ``ρ >= 0`` and conserves mass exactly.  The
    robots follow eq. (2) by forward Euler, ``R_{k+1} = R_k + Δt_p u_k``, ``θ_{k+1} = θ_k + Δt_p ω_k``.

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

from meanfield.control import BacksteppingController, ControlState
from meanfield.errors import ParameterError
from meanfield.grid import Grid
from meanfield.interfaces import Command, ControllerParts, Observation
from meanfield.kernels import GaussianKernel, NavigationKernel
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

FLUXES = ("upwind", "central")
"""Advective fluxes of the coarse model: upwind (positive, first order) or central (second order)."""

HESSIANS = ("exact", "limited-memory")
"""IPOPT's Hessian: exact (CasADi's automatic differentiation) or L-BFGS."""


# ---------------------------------------------------------------------- options
def _opt_name(key: str) -> str:
    return f"controller.options.{key}"


def _int_option(key: str, value: Any, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float)):
        raise ParameterError(_opt_name(key), value, f"an integer >= {lo}")
    if isinstance(value, float) and not value.is_integer():
        raise ParameterError(_opt_name(key), value, f"an integer >= {lo}")
    if value < lo:
        raise ParameterError(_opt_name(key), value, f"an integer >= {lo}")
    return int(value)


def _float_option(key: str, value: Any, *, positive: bool) -> float:
    allowed = "a finite number > 0" if positive else "a finite number >= 0"
    if isinstance(value, bool):
        raise ParameterError(_opt_name(key), value, allowed)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(_opt_name(key), value, allowed) from None
    if not math.isfinite(x) or x < 0 or (positive and x == 0):
        raise ParameterError(_opt_name(key), value, allowed)
    return x


@dataclass(frozen=True)
class NMPCOptions:
    """Options of :class:`NMPCController` (``[controller.options]`` of a scenario).

    Parameters
    ----------
    horizon : int
        ``H``, prediction steps (>= 1).
    cells : int or (int, int)
        Coarse cells ``(nx, ny)`` over Ω's bounding box (each >= 3).
    period : float
        ``Δt_c``: time between solves (> 0).  Inputs follow the plan in between.
    step : float or None
        ``Δt_p``: prediction step (> 0); None means ``period``.
    r_u, r_omega : float
        Input weights (>= 0) of ``r_u |u_i|²`` and ``r_ω ω_i²``.
    terminal : float
        ``q_T`` (>= 0, a time): weight of the terminal error ``‖ρ_H - ρ_*‖²``.
    flux : {"upwind", "central"}
        Advective fluxes of the coarse model.
    max_iter : int
        IPOPT iteration limit per solve (>= 1).
    tol : float
        IPOPT tolerance (> 0).
    hessian : {"exact", "limited-memory"}
        IPOPT's Hessian.
    warm_start : bool
        Start each solve from the previous solution shifted (otherwise from zero inputs).
    """

    horizon: int = 5
    cells: tuple[int, int] = (10, 10)
    period: float = 0.2
    step: float | None = None
    r_u: float = 0.1
    r_omega: float = 1e-3
    terminal: float = 1.0
    flux: str = "upwind"
    max_iter: int = 50
    tol: float = 1e-6
    hessian: str = "exact"
    warm_start: bool = True

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "horizon", _int_option("horizon", self.horizon, 1))
        cells = self.cells
        if isinstance(cells, (int, np.integer, float)) and not isinstance(cells, bool):
            cells = (cells, cells)
        try:
            cx, cy = cells
        except (TypeError, ValueError):
            raise ParameterError(_opt_name("cells"), self.cells, "an integer >= 3 or a pair [nx, ny]") from None
        set_(self, "cells", (_int_option("cells", cx, 3), _int_option("cells", cy, 3)))
        set_(self, "period", _float_option("period", self.period, positive=True))
        if self.step is not None:
            set_(self, "step", _float_option("step", self.step, positive=True))
        for key in ("r_u", "r_omega", "terminal"):
            set_(self, key, _float_option(key, getattr(self, key), positive=False))
        if self.flux not in FLUXES:
            raise ParameterError(_opt_name("flux"), self.flux, " or ".join(map(repr, FLUXES)))
        set_(self, "max_iter", _int_option("max_iter", self.max_iter, 1))
        set_(self, "tol", _float_option("tol", self.tol, positive=True))
        if self.hessian not in HESSIANS:
            raise ParameterError(_opt_name("hessian"), self.hessian, " or ".join(map(repr, HESSIANS)))
        if not isinstance(self.warm_start, (bool, np.bool_)):
            raise ParameterError(_opt_name("warm_start"), self.warm_start, "true or false")
        set_(self, "warm_start", bool(self.warm_start))

    @property
    def prediction_step(self) -> float:
        """``Δt_p`` (``step``, or ``period`` when ``step`` is None)."""
        return self.period if self.step is None else self.step

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | None) -> NMPCOptions:
        """Options from a scenario's ``controller.options`` table.

        Raises
        ------
        ParameterError
            Naming ``controller.options.<key>`` for an unknown key or a bad value.
        """
        if options is None:
            return cls()
        if not isinstance(options, Mapping):
            raise ParameterError("controller.options", options, "a table of NMPC options")
        known = [f.name for f in dataclasses.fields(cls)]
        for key in options:
            if key not in known:
                raise ParameterError(_opt_name(key), options[key], f"a known NMPC option: one of {known}")
        return cls(**dict(options))


# ---------------------------------------------------------------------- the coarse model
class CoarseFokkerPlanck:
    """Coarse finite-volume Fokker–Planck model of eq. (4) driven by the robots' Gaussian kernels.

    Cells ``(nx, ny)`` tile the box ``bounds``; fields are arrays of shape ``(nx, ny)``
    (``x`` along the first axis, as :class:`~meanfield.grid.Grid`) or their C-order
    flattening of length ``nx·ny``.  The x-velocity lives on the ``(nx-1, ny)`` interior
    x-faces, the y-velocity on the ``(nx, ny-1)`` interior y-faces; wall faces carry no flux.

    The rate is ``L(v) ρ = -div F``, ``F = v ρ_face - σ ∇ρ`` with ``ρ_face`` the upwind
    (``v⁺ρ_left + v⁻ρ_right``) or central (mean) face value and ``∇ρ`` the two-point
    difference; one step is backward Euler, ``(I - Δt L(v)) ρ_{k+1} = ρ_k``.

    The same expressions are compiled to CasADi functions (:attr:`velocity_function`,
    :attr:`rate_function`, :attr:`residual_function`) for the optimiser and evaluated
    numerically here, so the tests check the model the controller predicts with.

    Parameters
    ----------
    bounds : (x0, x1, y0, y1)
        The box.
    cells : (int, int)
        ``(nx, ny)``, each >= 2.
    sigma : float
        Diffusion ``σ >= 0``.
    kernel : GaussianKernel
        The robots' kernel ``K̄(ξ) = c exp(-|ξ|²/η)`` (paper, Section III).
    n_robots : int
        Number of robots ``n``.
    step : float
        Prediction step ``Δt_p > 0``.
    flux : {"upwind", "central"}
    """

    def __init__(
        self,
        bounds: tuple[float, float, float, float],
        cells: tuple[int, int],
        sigma: float,
        kernel: GaussianKernel,
        n_robots: int,
        step: float,
        flux: str = "upwind",
    ):
        if not isinstance(kernel, GaussianKernel):
            raise ParameterError("kernel", type(kernel).__name__, "a GaussianKernel (the NMPC model is built on it)")
        if flux not in FLUXES:
            raise ParameterError(_opt_name("flux"), flux, " or ".join(map(repr, FLUXES)))
        sigma = float(sigma)
        if not math.isfinite(sigma) or sigma < 0:
            raise ParameterError("sigma", sigma, "a constant finite number >= 0")
        x0, x1, y0, y1 = (float(b) for b in bounds)
        nx, ny = (int(c) for c in cells)
        if nx < 2 or ny < 2:
            raise ParameterError(_opt_name("cells"), cells, "a pair of integers, each >= 2")
        self.bounds = (x0, x1, y0, y1)
        self.shape = (nx, ny)
        self.size = nx * ny
        self.sigma = sigma
        self.kernel = kernel
        self.n_robots = int(n_robots)
        self.step = float(step)
        self.flux = flux
        self.dx = (x1 - x0) / nx
        self.dy = (y1 - y0) / ny
        self.cell_volume = self.dx * self.dy
        self.x = x0 + (np.arange(nx) + 0.5) * self.dx
        self.y = y0 + (np.arange(ny) + 0.5) * self.dy
        self.x_faces = x0 + np.arange(1, nx) * self.dx
        self.y_faces = y0 + np.arange(1, ny) * self.dy
        self._build_functions()

    # ------------------------------------------------------------------ CasADi expressions
    def _velocity_expr(self, rx, ry, th):
        """``v_r`` at the faces (paper, eq. (3)), separable: ``c e^{-(x-R_x)²/η} e^{-(y-R_y)²/η} e(θ)``."""
        n, eta, c = self.n_robots, self.kernel.eta, self.kernel.c

        def factor(coords: np.ndarray, r):
            d = ca.repmat(ca.DM(coords).T, n, 1) - ca.repmat(r, 1, len(coords))
            return ca.exp(-(d * d) / eta)  # (n, len(coords))

        exf, exc = factor(self.x_faces, rx), factor(self.x, rx)
        eyf, eyc = factor(self.y_faces, ry), factor(self.y, ry)
        vx = ca.mtimes((ca.repmat(c * ca.cos(th), 1, len(self.x_faces)) * exf).T, eyc)  # (nx-1, ny)
        vy = ca.mtimes((ca.repmat(c * ca.sin(th), 1, len(self.x)) * exc).T, eyf)  # (nx, ny-1)
        # C-order flattening: casadi reshapes column-major, so flatten the transpose
        return ca.reshape(vx.T, -1, 1), ca.reshape(vy.T, -1, 1)

    def _rate_expr(self, rho, vx, vy):
        """``L(v) ρ = -div(v ρ_face - σ∇ρ)`` with zero flux through the walls (eq. (4))."""
        nx, ny = self.shape
        idx = np.arange(self.size).reshape(nx, ny)
        left, right = idx[:-1, :].ravel().tolist(), idx[1:, :].ravel().tolist()
        bottom, top = idx[:, :-1].ravel().tolist(), idx[:, 1:].ravel().tolist()
        fluxes = []
        for v, a, b, h in ((vx, left, right, self.dx), (vy, bottom, top, self.dy)):
            ra, rb = rho[a], rho[b]
            if self.flux == "upwind":
                adv = ca.fmax(v, 0) * ra + ca.fmin(v, 0) * rb
            else:
                adv = v * (0.5 * (ra + rb))
            fluxes.append((adv - self.sigma * (rb - ra) / h, a, b, h))
        out = 0
        for F, a, b, h in fluxes:
            m = len(a)
            # divergence: +F/h into the cell on the low side (its high face), -F/h on the high side
            D = ca.DM.triplet(a + b, list(range(m)) * 2, [1.0 / h] * m + [-1.0 / h] * m, self.size, m)
            out = out - ca.mtimes(D, F)
        return out

    def _build_functions(self) -> None:
        n, C = self.n_robots, self.size
        rx, ry, th = ca.SX.sym("rx", n), ca.SX.sym("ry", n), ca.SX.sym("th", n)
        vx_s = ca.SX.sym("vx", (self.shape[0] - 1) * self.shape[1])
        vy_s = ca.SX.sym("vy", self.shape[0] * (self.shape[1] - 1))
        rho, rho_prev = ca.SX.sym("rho", C), ca.SX.sym("rho_prev", C)
        vx, vy = self._velocity_expr(rx, ry, th)
        rate = self._rate_expr(rho, vx_s, vy_s)
        self.velocity_function = ca.Function("velocity", [rx, ry, th], [vx, vy], ["rx", "ry", "th"], ["vx", "vy"])
        self.rate_function = ca.Function("rate", [rho, vx_s, vy_s], [rate], ["rho", "vx", "vy"], ["rate"])
        self.operator_function = ca.Function("operator", [vx_s, vy_s], [ca.jacobian(rate, rho)])
        res = rho - rho_prev - self.step * self._rate_expr(rho, vx, vy)
        self.residual_function = ca.Function(
            "residual", [rho, rho_prev, rx, ry, th], [res], ["rho", "rho_prev", "rx", "ry", "th"], ["residual"]
        )

    # ------------------------------------------------------------------ numerical evaluation
    def face_velocity(self, positions: np.ndarray, headings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``v_r`` of the robots at the coarse faces: ``(vx (nx-1, ny), vy (nx, ny-1))``."""
        positions = np.asarray(positions, float).reshape(-1, 2)
        vx, vy = self.velocity_function(positions[:, 0], positions[:, 1], np.asarray(headings, float))
        nx, ny = self.shape
        return np.asarray(vx).reshape(nx - 1, ny), np.asarray(vy).reshape(nx, ny - 1)

    def rate(self, rho: np.ndarray, velocity: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """``L(v) ρ``: the coarse Fokker–Planck right-hand side, shape ``(nx, ny)``."""
        out = self.rate_function(np.ravel(rho), np.ravel(velocity[0]), np.ravel(velocity[1]))
        return np.asarray(out).reshape(self.shape)

    def operator(self, velocity: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """The matrix ``L(v)`` acting on C-order flattened densities, shape ``(nx·ny, nx·ny)``."""
        return np.asarray(ca.densify(self.operator_function(np.ravel(velocity[0]), np.ravel(velocity[1]))))

    def step_density(self, rho: np.ndarray, velocity: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """One backward-Euler step ``(I - Δt_p L(v)) ρ_{k+1} = ρ_k`` with face velocity ``velocity``."""
        A = np.eye(self.size) - self.step * self.operator(velocity)
        return np.linalg.solve(A, np.ravel(rho)).reshape(self.shape)

    def mass(self, rho: np.ndarray) -> float:
        """``∫ ρ dx`` on the coarse cells."""
        return float(self.cell_volume * np.sum(rho))

    def norm(self, f: np.ndarray) -> float:
        """Coarse ``‖f‖_{L²}``."""
        return float(np.sqrt(self.cell_volume * np.sum(np.square(f))))

    def restriction(self, grid: Grid) -> tuple[np.ndarray, np.ndarray]:
        """Overlap matrices ``(Px (nx, grid.nx), Py (ny, grid.ny))`` with ``ρ_c = Px ρ Pyᵀ``.

        ``Px[I, i]`` is the length of coarse column ``I`` ∩ fine column ``i`` divided by the
        coarse width, so ``ρ_c`` is the exact cell average of the piecewise-constant fine field.
        """
        gx0, gx1, gy0, gy1 = grid.domain.bounds
        cx0, cx1, cy0, cy1 = self.bounds

        def overlap(c0, c1, nc, f0, f1, nf):
            ce = np.linspace(c0, c1, nc + 1)
            fe = np.linspace(f0, f1, nf + 1)
            lo = np.maximum(ce[:-1, None], fe[None, :-1])
            hi = np.minimum(ce[1:, None], fe[None, 1:])
            return np.clip(hi - lo, 0.0, None) / ((c1 - c0) / nc)

        return (
            overlap(cx0, cx1, self.shape[0], gx0, gx1, grid.shape[0]),
            overlap(cy0, cy1, self.shape[1], gy0, gy1, grid.shape[1]),
        )

    def restrict(self, rho: np.ndarray, grid: Grid) -> np.ndarray:
        """A fine-grid density averaged onto the coarse cells and renormalised to unit mass."""
        Px, Py = self.restriction(grid)
        rc = Px @ np.asarray(rho, float) @ Py.T
        m = self.mass(rc)
        if not np.isfinite(m) or m <= 0:
            raise ParameterError("density", f"mass {m}", "a non-negative field of positive mass")
        return rc / m

    def predict(
        self,
        rho: np.ndarray,
        positions: np.ndarray,
        headings: np.ndarray,
        u: np.ndarray,
        omega: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Roll the model out under inputs ``u (H, n, 2)``, ``omega (H, n)``.

        Returns the densities ``(H+1, nx, ny)``, positions ``(H+1, n, 2)`` and headings
        ``(H+1, n)``, the initial state first (robots by eq. (2), forward Euler; density by
        backward Euler with the field at the end of each step).
        """
        u = np.asarray(u, float)
        omega = np.asarray(omega, float)
        R = [np.asarray(positions, float).reshape(-1, 2)]
        T = [np.asarray(headings, float).ravel()]
        P = [np.asarray(rho, float).reshape(self.shape)]
        for k in range(len(u)):
            R.append(R[-1] + self.step * u[k])
            T.append(T[-1] + self.step * omega[k])
            P.append(self.step_density(P[-1], self.face_velocity(R[-1], T[-1])))
        return np.array(P), np.array(R), np.array(T)


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
