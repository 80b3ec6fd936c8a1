"""A sequential-quadratic-programming solver of the NMPC problem in the inputs.

(docs/controllers.md, "NMPC in real time".)

The NMPC problem of :mod:`analysis.nmpc.controller` (docs/nmpc.md, "The optimal-control problem": the
paper's eq. (4) on coarse cells as the prediction model, eq. (2) for the robots with their
speed limits), condensed onto the robots' inputs
(:class:`~analysis.nmpc.condensed.CondensedProblem`: the same cost ``J(z)`` and the same
constraints, the states eliminated through the same model), is solved by SQP:

1. at the iterate ``z`` (always feasible: within the speed limits and the region), ``J``, ``∇J``
   and the exact ``∇²J`` (forward sensitivities and one adjoint sweep);
2. ``∇²J`` is made positive definite by reflecting its negative eigenvalues (``|λ|``; it is
   indefinite far from a minimum: the headings enter through cos and sin), plus a
   Levenberg–Marquardt term ``ν·mean(diag)·I``;
3. the QP ``min ½dᵀH d + ∇Jᵀd`` under the exact constraints (speed disks, turn-rate bounds,
   positions in the region) by the interior-point method of :class:`~analysis.nmpc.qp.InputQP`;
4. the ratio ``ρ = ΔJ / predicted`` of the full step drives ``ν`` (a trust region); the step
   is backtracked (halved, at most four times) until ``J`` decreases enough (Armijo); the
   constraints are convex, so every accepted iterate stays feasible.

It stops when the QP predicts a decrease below ``tol·(1 + J)`` (a KKT point of the NLP: ``d = 0``
solves the QP exactly when ``-∇J`` lies in the normal cone of the constraints at ``z``) or after
``max_iter`` QPs; the iterate returned is feasible either way, so an early stop — real-time
iterations, one or a few QPs per control period, warm-started from the previous plan — returns
a usable plan.  With ``hessian = "gauss-newton"`` step 1 keeps only ``R + Σ_k w_k S_kᵀS_k``
(no eigenvalues needed, but here the second-order term is large and the steps poor).
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np

from analysis.nmpc.condensed import CondensedProblem
from analysis.nmpc.qp import InputQP

__all__ = ["SQPResult", "SQPSolver"]


@dataclass
class SQPResult:
    """One solve of :class:`SQPSolver`.

    Attributes
    ----------
    z : ndarray (B, n, 3)
        Inputs per block ``(u_x, u_y, ω)`` (feasible).
    cost : float
        ``J(z)``.
    iterations : int
        QPs solved.
    converged : bool
        The last QP predicted a decrease below the tolerance.
    qp_iterations : int
        Interior-point iterations, all QPs together.
    status : str
        ``"converged"`` or ``"iteration_limit"``.
    damping : float
        The Levenberg–Marquardt ``ν`` at the end (the next warm start's).
    """

    z: np.ndarray
    cost: float
    iterations: int
    converged: bool
    qp_iterations: int
    status: str
    damping: float


class SQPSolver:
    """SQP on :class:`CondensedProblem` with the exact constraints (see the module).

    Parameters
    ----------
    problem : CondensedProblem
    u_max, omega_max : float
        Limits (``inf``: none).
    region : (x0, x1, y0, y1)
        Box of the planned robot positions.
    hessian : {"exact", "gauss-newton"}
    """

    def __init__(
        self,
        problem: CondensedProblem,
        u_max: float,
        omega_max: float,
        region: tuple[float, float, float, float],
        hessian: str = "exact",
    ):
        self.problem = problem
        self.u_max, self.omega_max = float(u_max), float(omega_max)
        self.region = tuple(float(r) for r in region)
        self.exact = hessian == "exact"
        self.qp = InputQP(problem.N, problem.n, problem.model.step, self.u_max, self.omega_max, self.region)

    def feasible(self, z: np.ndarray, R0: np.ndarray) -> np.ndarray:
        """``z`` moved into the constraints: speeds scaled onto the disk, turn rates clipped and
        velocities scaled down (by one factor per robot) until the planned positions are in the region."""
        p = self.problem
        z = np.array(z, float).reshape(p.B, p.n, 3)
        z = np.where(np.isfinite(z), z, 0.0)
        if math.isfinite(self.u_max):
            speed = np.hypot(z[..., 0], z[..., 1])
            z[..., :2] *= np.minimum(1.0, self.u_max / np.where(speed > 0, speed, 1.0))[..., None]
        if math.isfinite(self.omega_max):
            z[..., 2] = np.clip(z[..., 2], -self.omega_max, self.omega_max)
        lo, hi = np.array(self.region[0::2]), np.array(self.region[1::2])
        move = p.model.step * np.einsum("kb,bic->kic", p.N, z[..., :2])  # (H, n, 2)
        room = np.where(move > 0, hi - R0, np.where(move < 0, lo - R0, np.inf))  # R0 is inside
        with np.errstate(divide="ignore", invalid="ignore"):
            frac = np.where(move != 0, room / move, np.inf)
        scale = np.clip(np.min(frac, axis=(0, 2)), 0.0, 1.0)
        z[..., :2] *= scale[None, :, None]
        return z

    def _convexified(self, Hm: np.ndarray) -> np.ndarray:
        """``Hm`` with its negative eigenvalues reflected (``|λ|``, at least ``1e-8·mean|diag|``)."""
        if not self.exact:
            return Hm
        ev, V = np.linalg.eigh(Hm)
        floor = 1e-8 * float(np.mean(np.abs(np.diag(Hm)))) + 1e-300
        if ev[0] >= floor:
            return Hm
        return (V * np.maximum(np.abs(ev), floor)) @ V.T

    def solve(
        self,
        rho0: np.ndarray,
        R0: np.ndarray,
        th0: np.ndarray,
        z0: np.ndarray,
        target: np.ndarray,
        max_iter: int,
        tol: float = 1e-6,
        damping: float = 0.0,
    ) -> SQPResult:
        """Solve from ``z0`` (made feasible first) with at most ``max_iter`` QPs (:meth:`iterate` to its end).

        Parameters
        ----------
        rho0, target : ndarray (nx, ny)
            ``ρ_0`` and ``ρ_*`` on the coarse cells.
        R0, th0 : ndarray (n, 2), (n,)
            Robot states now (``R0`` inside the region).
        z0 : ndarray (B, n, 3)
            Initial guess of the inputs per block.
        max_iter : int
            QP limit.
        tol : float
            Stop when the QP's predicted decrease is below ``tol (1 + J)``.
        damping : float
            Initial Levenberg–Marquardt ``ν`` (a warm start passes the previous solve's).

        Returns
        -------
        SQPResult
        """
        steps = self.iterate(rho0, R0, th0, z0, target, max_iter, tol, damping)
        while True:
            try:
                next(steps)
            except StopIteration as done:
                return done.value

    def iterate(
        self,
        rho0: np.ndarray,
        R0: np.ndarray,
        th0: np.ndarray,
        z0: np.ndarray,
        target: np.ndarray,
        max_iter: int,
        tol: float = 1e-6,
        damping: float = 0.0,
    ) -> Generator[None, None, SQPResult]:
        """:meth:`solve` in slices: a generator that pauses after each derivative evaluation and
        after each QP, and returns the result (slices: the derivatives; the convexification and
        the QP; the trial point's cost and the next derivatives; ...).

        A controller that spreads a solve over several control steps runs one slice per step.
        """
        p = self.problem
        lo, hi = np.array(self.region[0::2]), np.array(self.region[1::2])
        R0 = np.clip(np.asarray(R0, float).reshape(p.n, 2), lo, hi)
        z = self.feasible(z0, R0).ravel()
        new, converged, qp_its, its = True, False, 0, 0
        nu = float(damping)
        J = p.cost(rho0, R0, th0, z, target) if max_iter < 1 else math.nan
        g = Hc = scale = None
        for _ in range(max_iter):
            if new:
                J, g, Hm = p.derivatives(rho0, R0, th0, z, target, exact=self.exact)
                yield  # slices: [derivatives] [convexification, QP] [trial cost, derivatives] ...
                Hc = self._convexified(Hm)
                scale = float(np.mean(np.diag(Hc)))
            Hr = Hc.copy()
            Hr[np.diag_indices(len(z))] += nu * scale
            res = self.qp.solve(Hr, g - Hr @ z, z, R0)
            qp_its += res.iterations
            its += 1
            d = res.x - z
            pred = float(g @ d + 0.5 * d @ Hr @ d)
            if -pred <= tol * (1.0 + J):
                converged = True
                break
            yield
            J_new = p.cost(rho0, R0, th0, z + d, target)
            ratio = (J - J_new) / -pred
            if ratio > 0.75:
                nu = nu / 4 if nu > 1e-6 else 0.0
            elif ratio < 0.25:
                nu = max(4 * nu, 1e-3)
            alpha = 1.0
            while J_new >= J + 1e-4 * alpha * pred and alpha > 1.0 / 16:  # backtrack along d (feasible: convex set)
                alpha /= 2
                yield
                J_new = p.cost(rho0, R0, th0, z + alpha * d, target)
            new = J_new < J
            if new:
                z, J = z + alpha * d, J_new
        z = self.feasible(z, R0)  # the QP meets its constraints to its tolerance: back onto them
        status = "converged" if converged else "iteration_limit"
        return SQPResult(z, float(J), its, converged, qp_its, status, min(nu, 1.0))
