"""The NMPC problem in the robots' inputs only, with its exact gradient and Hessian.

(docs/controllers.md, "NMPC in real time".)

The optimal-control problem of :mod:`analysis.nmpc.controller` lifts every state (densities and robot
states) to a decision variable.  Here the states are eliminated: they are functions of the
inputs through the same model, :class:`~analysis.nmpc.prediction_model.CoarseFokkerPlanck` (eq. (4) on
the coarse cells, backward Euler; eq. (2), forward Euler)::

    s_{k+1} = s_k + Δt_p z_{β(k)},            s = (R_x, R_y, θ) of every robot
    A(s_{k+1}) ρ_{k+1} = ρ_k,                 A(s) = I - Δt_p L(v_r(s))
    J(z) = Δt_p Σ_k [ |ρ_{k+1} - ρ_*|² + r_u Σ_i |u_ik|² + r_ω Σ_i ω_ik² ] + q_T |ρ_H - ρ_*|²

with the coarse L² norm, ``z_b = (u, ω)`` of every robot on input block ``b`` and ``β(k)`` the
block of prediction step ``k`` (move blocking: an input is held over its block; one step per
block is the original problem).  :class:`CondensedProblem` evaluates ``J`` (one LU of a
``C × C`` matrix per step), and its gradient and **exact** Hessian: forward sensitivities
``S_k = ∂ρ_k/∂z``, the adjoint ``λ_k = A_k^{-T}(λ_{k+1} - ∂J/∂ρ_{k+1})`` and the reduced
Hessian of the Lagrangian ``ℒ = J + Σ_k λ_kᵀ(A(s_{k+1})ρ_{k+1} - ρ_k)``::

    ∇²J = R + Σ_k w_k S_kᵀS_k + Σ_k ( M_kᵀ Q_k M_k + M_kᵀ X_k S_{k+1} + S_{k+1}ᵀ X_kᵀ M_k )

``M_k = ∂s_{k+1}/∂z`` (constant), ``Q_k = ∂²_s(λ_kᵀAρ_{k+1})`` (block diagonal per robot: the
field is a sum over robots) and ``X_k = ∂²_{sρ}(λ_kᵀAρ_{k+1})``.  The upwind flux is piecewise
linear in the field: its kink is measure zero, and the Hessian is that of the active branch.
The same ``J`` is the cost of the full-space problem, so both have the same minimisers.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from analysis.nmpc.prediction_model import CoarseFokkerPlanck
from meanfield.errors import ParameterError

__all__ = ["CondensedProblem", "block_counts"]


def block_counts(blocks: tuple[int, ...]) -> np.ndarray:
    """``N[k, b]``: how many of the prediction steps ``0..k`` use input block ``b``.

    ``s_{k+1} = s_0 + Δt_p Σ_b N[k, b] z_b`` (eq. (2) with inputs held over their block).
    """
    beta = np.repeat(np.arange(len(blocks)), blocks)
    N = np.zeros((len(beta), len(blocks)))
    for k in range(len(beta)):
        np.add.at(N[k], beta[: k + 1], 1.0)
    return N


class CondensedProblem:
    """``J(z)`` of the NMPC problem in the inputs ``z (B, n, 3) = (u_x, u_y, ω)``, with derivatives.

    Parameters
    ----------
    model : CoarseFokkerPlanck
        The prediction model (its step is ``Δt_p``).
    blocks : tuple of int
        Prediction steps per input block (move blocking), summing to the horizon ``H``.
    r_u, r_omega, terminal : float
        The weights ``r_u``, ``r_ω``, ``q_T`` of the cost (docs/nmpc.md).
    """

    def __init__(self, model: CoarseFokkerPlanck, blocks: tuple[int, ...], r_u: float, r_omega: float, terminal: float):
        blocks = tuple(int(b) for b in blocks)
        if not blocks or min(blocks) < 1:
            raise ParameterError("controller.options.nmpc.blocks", blocks, "positive integers")
        self.model, self.blocks = model, blocks
        self.B, self.H, self.n = len(blocks), sum(blocks), model.n_robots
        self.beta = np.repeat(np.arange(self.B), blocks)
        self.N = block_counts(blocks)
        m, h = model, model.step
        nx, ny = m.shape
        idx = np.arange(m.size).reshape(nx, ny)
        self._a = np.concatenate([idx[:-1, :].ravel(), idx[:, :-1].ravel()])  # low side of each face
        self._b = np.concatenate([idx[1:, :].ravel(), idx[:, 1:].ravel()])  # high side
        self._hf = np.concatenate([np.full((nx - 1) * ny, m.dx), np.full(nx * (ny - 1), m.dy)])
        F, C = len(self._a), m.size
        self._D = np.zeros((C, F))  # L ρ = -D F (the divergence of the face fluxes)
        self._D[self._a, np.arange(F)] = 1.0 / self._hf
        self._D[self._b, np.arange(F)] = -1.0 / self._hf
        E = np.zeros((F, C))
        E[np.arange(F), self._b] = 1.0
        E[np.arange(F), self._a] -= 1.0
        self._Ldiff = self._D @ (m.sigma * E / self._hf[:, None])  # -D(-σ∇ρ)
        self._nxf = (nx - 1) * ny
        # cost: J = ½ Σ_k w_k |ρ_k - ρ_*|² + ½ Σ r_z z²  (the ½-form of the cost above)
        self.w = np.full(self.H, 2.0 * h * m.cell_volume)
        self.w[-1] += 2.0 * terminal * m.cell_volume
        rz = 2.0 * h * np.array([r_u, r_u, r_omega])[None, None, :] * np.array(blocks, float)[:, None, None]
        self.rz = np.broadcast_to(rz, (self.B, self.n, 3)).ravel().copy()
        self.size = self.B * self.n * 3

    # ------------------------------------------------------------------ the field (eq. (3))
    def _kernels(self, R: np.ndarray, th: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per robot and face ``(n, F)``: the term ``T = c e^{-|x-R|²/η} (cos θ or sin θ)``, its
        θ-derivative and the position factors ``a = 2(x - R)/η`` (x then y components)."""
        m = self.model
        eta, c = m.kernel.eta, m.kernel.c
        nx, ny = m.shape
        dxf, dxc = m.x_faces[None, :] - R[:, :1], m.x[None, :] - R[:, :1]
        dyf, dyc = m.y_faces[None, :] - R[:, 1:], m.y[None, :] - R[:, 1:]
        exf, exc, eyf, eyc = (np.exp(-d * d / eta) for d in (dxf, dxc, dyf, dyc))
        n = len(th)
        gx = (exf[:, :, None] * eyc[:, None, :]).reshape(n, -1)  # x-faces
        gy = (exc[:, :, None] * eyf[:, None, :]).reshape(n, -1)  # y-faces
        cs, sn = (c * np.cos(th))[:, None], (c * np.sin(th))[:, None]
        T = np.concatenate([cs * gx, sn * gy], axis=1)
        Tth = np.concatenate([-sn * gx, cs * gy], axis=1)
        ax = np.concatenate([np.repeat(2 * dxf / eta, ny, axis=1), np.repeat(2 * dxc / eta, ny - 1, axis=1)], axis=1)
        ay = np.concatenate([np.tile(2 * dyc / eta, (1, nx - 1)), np.tile(2 * dyf / eta, (1, nx))], axis=1)
        return T, Tth, ax, ay

    def _system(self, v: np.ndarray) -> np.ndarray:
        """``A = I - Δt_p L(v)`` (dense ``C × C``), upwind or central advective fluxes."""
        m = self.model
        C = m.size
        if m.flux == "upwind":
            pa, pb = np.maximum(v, 0.0), np.minimum(v, 0.0)
        else:
            pa = pb = 0.5 * v
        a, b, hf = self._a, self._b, self._hf
        L = self._Ldiff.copy()
        # flux F = pa ρ_a + pb ρ_b from a to b:  (Lρ)_a -= F/h,  (Lρ)_b += F/h
        L[a, b] -= pb / hf
        L[b, a] += pa / hf
        L[np.arange(C), np.arange(C)] += np.bincount(b, pb / hf, C) - np.bincount(a, pa / hf, C)
        return np.eye(C) - m.step * L

    def _upwind(self, v: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``∂F_f/∂v_f`` and, per face, the cells it depends on with their weights."""
        if self.model.flux == "upwind":
            up = np.where(v >= 0, self._a, self._b)
            return rho[up], up
        return 0.5 * (rho[self._a] + rho[self._b]), np.empty(0, int)

    # ------------------------------------------------------------------ evaluation
    def states(self, R0: np.ndarray, th0: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Robot positions ``(H, n, 2)`` and headings ``(H, n)`` after each step (eq. (2))."""
        z = np.asarray(z, float).reshape(self.B, self.n, 3)
        h = self.model.step
        R = np.asarray(R0, float)[None] + h * np.einsum("kb,bic->kic", self.N, z[..., :2])
        T = np.asarray(th0, float)[None] + h * np.einsum("kb,bi->ki", self.N, z[..., 2])
        return R, T

    def rollout(
        self, rho0: np.ndarray, R0: np.ndarray, th0: np.ndarray, z: np.ndarray, target: np.ndarray
    ) -> tuple[float, np.ndarray]:
        """``J(z)`` and the predicted densities ``ρ_1..ρ_H`` ``(H, nx, ny)`` (eq. (4), backward Euler)."""
        R, T = self.states(R0, th0, z)
        rho = np.asarray(rho0, float).ravel()
        tgt = np.asarray(target, float).ravel()
        J = 0.5 * float(np.sum(self.rz * np.square(np.ravel(z))))
        out = np.empty((self.H, self.model.size))
        for k in range(self.H):
            K, _, _, _ = self._kernels(R[k], T[k])
            rho = out[k] = np.linalg.solve(self._system(K.sum(axis=0)), rho)
            e = rho - tgt
            J += 0.5 * self.w[k] * float(e @ e)
        return J, out.reshape(self.H, *self.model.shape)

    def cost(self, rho0: np.ndarray, R0: np.ndarray, th0: np.ndarray, z: np.ndarray, target: np.ndarray) -> float:
        """``J(z)`` (no derivatives): one backward-Euler step per prediction step."""
        return self.rollout(rho0, R0, th0, z, target)[0]

    def derivatives(
        self, rho0: np.ndarray, R0: np.ndarray, th0: np.ndarray, z: np.ndarray, target: np.ndarray, exact: bool = True
    ) -> tuple[float, np.ndarray, np.ndarray]:
        """``J``, ``∇J`` and ``∇²J`` (exact, or Gauss–Newton ``R + Σ w_k S_kᵀS_k`` if not ``exact``).

        Parameters
        ----------
        rho0 : ndarray (nx, ny)
            ``ρ_0`` on the coarse cells.
        R0, th0 : ndarray (n, 2), (n,)
            Robot states now.
        z : ndarray (B, n, 3) or flat
            Inputs per block.
        target : ndarray (nx, ny)
            ``ρ_*`` on the coarse cells.

        Returns
        -------
        (float, ndarray (B·n·3,), ndarray (B·n·3, B·n·3))
        """
        m, h, n, B = self.model, self.model.step, self.n, self.B
        C, nz, n3 = m.size, self.size, 3 * self.n
        z = np.asarray(z, float).reshape(B, n, 3)
        Rs, Ts = self.states(R0, th0, z)
        rho = np.asarray(rho0, float).ravel()
        tgt = np.asarray(target, float).ravel()
        S = np.zeros((C, nz))
        steps = []
        for k in range(self.H):
            K, Kth, ax, ay = self._kernels(Rs[k], Ts[k])
            V = np.concatenate([K * ax, K * ay, Kth], axis=0).reshape(3, n, -1).transpose(2, 1, 0).reshape(-1, n3)
            lu = sla.lu_factor(self._system(K.sum(axis=0)), check_finite=False)
            rho = sla.lu_solve(lu, rho, check_finite=False)
            dF, up = self._upwind(K.sum(axis=0), rho)
            Y = -self._D @ (dF[:, None] * V)  # ∂(L(v)ρ)/∂s, (C, 3n)
            nb = (self.beta[k] + 1) * n3
            rhs = S[:, :nb] + h * h * np.kron(self.N[k, : self.beta[k] + 1], Y)
            S = np.zeros((C, nz))
            S[:, :nb] = sla.lu_solve(lu, rhs, check_finite=False)
            steps.append((K, Kth, ax, ay, V, lu, rho, dF, up, S))
        e = [st[6] - tgt for st in steps]
        J = 0.5 * sum(float(w * (ek @ ek)) for w, ek in zip(self.w, e, strict=True)) + 0.5 * float(
            np.sum(self.rz * z.ravel() ** 2)
        )
        Sw = np.concatenate([np.sqrt(w) * st[9] for w, st in zip(self.w, steps, strict=True)])
        Hm = Sw.T @ Sw
        Hm[np.diag_indices(nz)] += self.rz
        g = Sw.T @ np.concatenate([np.sqrt(w) * ek for w, ek in zip(self.w, e, strict=True)]) + self.rz * z.ravel()
        if exact:
            self._second_order(Hm, steps, e)
        return J, g, Hm

    def _second_order(self, Hm: np.ndarray, steps: list, e: list) -> None:
        """Add ``Σ_k M_kᵀQ_kM_k + M_kᵀX_kS_{k+1} + (·)ᵀ`` to ``Hm`` (the adjoint sweep, module docstring)."""
        m, h, n, B = self.model, self.model.step, self.n, self.B
        C, n3 = m.size, 3 * self.n
        eta = m.kernel.eta
        H4 = Hm.reshape(B, n3, B, n3)
        H6 = Hm.reshape(B, n, 3, B, n, 3)
        lam = np.zeros(C)
        for k in range(self.H - 1, -1, -1):
            K, Kth, ax, ay, V, lu, rho, dF, up, S = steps[k]
            lam = sla.lu_solve(lu, lam - self.w[k] * e[k], trans=1, check_finite=False)
            nu = self._D.T @ (-h * lam)  # λᵀAρ = λᵀρ - Σ_f ν_f F_f
            c = -nu * dF  # ∂(λᵀAρ)/∂v_f
            Q = np.zeros((n, 3, 3))
            Q[:, 0, 0] = (K * (ax * ax - 2 / eta)) @ c
            Q[:, 1, 1] = (K * (ay * ay - 2 / eta)) @ c
            Q[:, 0, 1] = Q[:, 1, 0] = (K * ax * ay) @ c
            Q[:, 2, 2] = -(K @ c)
            Q[:, 0, 2] = Q[:, 2, 0] = (Kth * ax) @ c
            Q[:, 1, 2] = Q[:, 2, 1] = (Kth * ay) @ c
            U = np.zeros((len(nu), C))  # ∂(∂F_f/∂v_f)/∂ρ: the upwind cell, or half of each side
            if len(up):
                U[np.arange(len(nu)), up] = 1.0
            else:
                U[np.arange(len(nu)), self._a] = U[np.arange(len(nu)), self._b] = 0.5
            X = -(V * nu[:, None]).T @ U  # ∂²(λᵀAρ)/∂s∂ρ, (3n, C)
            XS = (X @ S).reshape(n3, B, n3)
            cnt = h * self.N[k]
            r = np.arange(n)  # Q_k is block diagonal: robot r's 3×3 block on every pair of blocks
            H6[:, r, :, :, r, :] += np.einsum("b,d,rij->rbidj", cnt, cnt, Q)
            MXS = cnt[:, None, None, None] * XS[None]  # M_kᵀ X_k S_{k+1}, (B, n3, B, n3)
            H4 += MXS
            H4 += MXS.transpose(2, 3, 0, 1)
