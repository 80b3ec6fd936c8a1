"""The prediction model of the NMPC baseline: a coarse Fokker–Planck model (docs/nmpc.md, "The prediction model").

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

:class:`CoarseFokkerPlanck` is that model, both as CasADi functions (for the optimiser of
:class:`~analysis.nmpc.controller.NMPCController`) and numerically; it is re-exported by
:mod:`analysis.nmpc`.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from analysis.nmpc.options import FLUXES, _opt_name
from meanfield.errors import ParameterError
from meanfield.geometry.grid import Grid
from meanfield.signs.kernels import GaussianKernel

__all__ = ["CoarseFokkerPlanck"]


class CoarseFokkerPlanck:
    """Coarse finite-volume Fokker–Planck model of eq. (4) driven by the robots' Gaussian kernels.

    Cells ``(nx, ny)`` tile the box ``bounds``; fields are arrays of shape ``(nx, ny)``
    (``x`` along the first axis, as :class:`~meanfield.geometry.grid.Grid`) or their C-order
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
