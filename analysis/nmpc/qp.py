"""The quadratic subproblem of the NMPC's SQP solver: a dense primal–dual interior-point method.

Each SQP iteration of :mod:`analysis.nmpc.sqp` solves, in the inputs ``x = z (B, n, 3) =
(u_x, u_y, ω)`` of every robot on every input block::

    minimise   ½ xᵀ P x + qᵀ x                       (P positive definite)
    subject to |u_bi| <= u_max                       (the speed limit, eq. (2); a disk per robot and block)
               |ω_bi| <= ω_max                       (the turn-rate limit)
               lo <= R_i + Δt_p Σ_b N[k, b] u_bi <= hi   (planned positions in the robots' region, every step k)

— the constraints of the NMPC problem (docs/nmpc.md), exactly: the disks are kept as convex
quadratic constraints, not polygons.  With a few hundred variables and a dense ``P`` a sparse
conic solver spends its time on the dense block; this solver forms the normal equations
``(P + Σ_j λ_j ∇²f_j + Jᵀ diag(λ/s) J) Δx = r`` densely and factors them by Cholesky, with
Mehrotra's predictor–corrector (an infeasible start is allowed: slacks ``s > 0`` for
``f(x) + s = 0``).  The sparse Gram terms ``Gᵀ diag(d) G`` of the linear rows are assembled
by one precomputed sparse map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

__all__ = ["InputQP", "QPResult"]


@dataclass
class QPResult:
    """A solution of :class:`InputQP`.

    Attributes
    ----------
    x : ndarray (B·n·3,)
    disk_multipliers : ndarray (B, n)
        Multipliers of the speed-limit disks (zero without a speed limit).
    iterations : int
    converged : bool
    """

    x: np.ndarray
    disk_multipliers: np.ndarray
    iterations: int
    converged: bool


class InputQP:
    """The structured QP above for ``n`` robots on input blocks with step counts ``N (H, B)``.

    Parameters
    ----------
    N : ndarray (H, B)
        ``N[k, b]``: prediction steps ``0..k`` on block ``b`` (:func:`analysis.nmpc.condensed.block_counts`).
    n : int
        Robots.
    step : float
        ``Δt_p``.
    u_max, omega_max : float
        Limits (``inf``: no constraint).
    region : (x0, x1, y0, y1)
        Box of the planned positions.
    """

    def __init__(self, N: np.ndarray, n: int, step: float, u_max: float, omega_max: float, region: tuple[float, ...]):
        self.N = np.asarray(N, float)
        H, B = self.N.shape
        self.B, self.n, self.h = B, n, float(step)
        self.u_max, self.omega_max = float(u_max), float(omega_max)
        self.lo = np.array([region[0], region[2]], float)
        self.hi = np.array([region[1], region[3]], float)
        nz = B * n * 3
        idx = np.arange(nz).reshape(B, n, 3)
        self.iu = idx[..., :2].reshape(-1, 2)  # (B n, 2): the u entries of each disk
        rows: list[np.ndarray] = []  # the linear rows G x <= h0 + shift(R)
        if math.isfinite(self.omega_max):
            e = sp.csr_matrix((np.ones(B * n), (np.arange(B * n), idx[..., 2].ravel())), shape=(B * n, nz))
            rows += [e / self.omega_max, -e / self.omega_max]
        # positions after step k: P[(k, i, c), (b, i, c)] = Δt_p N[k, b]
        r, c, v = [], [], []
        for k in range(H):
            for b in range(B):
                if self.N[k, b]:
                    r.append(((k * n + np.arange(n)) * 2)[:, None] + np.arange(2)[None])
                    c.append(idx[b, :, :2])
                    v.append(np.full((n, 2), self.h * self.N[k, b]))
        Pm = sp.csr_matrix(
            (np.concatenate(v).ravel(), (np.concatenate(r).ravel(), np.concatenate(c).ravel())), shape=(H * n * 2, nz)
        )
        self._positions = Pm
        rows += [Pm, -Pm]
        self.G = sp.vstack(rows).tocsr()
        self._GT = self.G.T.tocsr()
        self.m_lin = self.G.shape[0]
        self.m_disk = B * n if math.isfinite(self.u_max) else 0
        self.size = nz
        # the map d -> entries of Gᵀ diag(d) G (precomputed: each row's outer product)
        G = self.G.tocoo()
        order = np.argsort(G.row, kind="stable")
        gr, gc, gv = G.row[order], G.col[order], G.data[order]
        starts = np.searchsorted(gr, np.arange(self.m_lin + 1))
        ent_r, ent_c, ent_w, ent_row = [], [], [], []
        for row in range(self.m_lin):
            cols, vals = gc[starts[row] : starts[row + 1]], gv[starts[row] : starts[row + 1]]
            ent_r.append(np.repeat(cols, len(cols)))
            ent_c.append(np.tile(cols, len(cols)))
            ent_w.append(np.outer(vals, vals).ravel())
            ent_row.append(np.full(len(cols) ** 2, row))
        flat = np.concatenate(ent_r) * nz + np.concatenate(ent_c)
        self._gram_index, inverse = np.unique(flat, return_inverse=True)
        self._gram_map = sp.csr_matrix(
            (np.concatenate(ent_w), (inverse.ravel(), np.concatenate(ent_row))),
            shape=(len(self._gram_index), self.m_lin),
        )

    def _bounds(self, R0: np.ndarray) -> np.ndarray:
        """Right-hand side ``h0`` of ``G x <= h0`` for robot positions ``R0`` now."""
        R0 = np.asarray(R0, float).reshape(self.n, 2)
        H = self.N.shape[0]
        upper = np.broadcast_to(self.hi - R0, (H, self.n, 2)).ravel()
        lower = np.broadcast_to(R0 - self.lo, (H, self.n, 2)).ravel()
        w = np.ones(2 * self.B * self.n) if math.isfinite(self.omega_max) else np.empty(0)
        return np.concatenate([w, upper, lower])

    def constraints(self, x: np.ndarray, R0: np.ndarray) -> np.ndarray:
        """``f(x) <= 0`` (linear rows, then one ``½(|u|²/u_max² - 1)`` per disk)."""
        f = self.G @ x - self._bounds(R0)
        if self.m_disk:
            u = x[self.iu]
            f = np.concatenate([f, 0.5 * (np.sum(u * u, axis=1) / self.u_max**2 - 1.0)])
        return f

    def _jt(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``Jᵀ y`` at the disk values ``u (B n, 2)``."""
        out = self._GT @ y[: self.m_lin]
        if self.m_disk:
            out[self.iu] += (y[self.m_lin :] / self.u_max**2)[:, None] * u  # disjoint entries
        return out

    def _jv(self, dx: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``J dx`` at the disk values ``u``."""
        out = self.G @ dx
        if not self.m_disk:
            return out
        return np.concatenate([out, np.sum(u * dx[self.iu], axis=1) / self.u_max**2])

    def _normal_matrix(self, P: np.ndarray, d: np.ndarray, lam_disk: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``P + Σ_j λ_j ∇²f_j + Jᵀ diag(d) J`` (dense)."""
        M = P.copy()
        M.ravel()[self._gram_index] += self._gram_map @ d[: self.m_lin]
        if self.m_disk:
            iu, inv = self.iu, 1.0 / self.u_max**2
            dd = d[self.m_lin :] * inv * inv
            M[iu[:, 0], iu[:, 0]] += lam_disk * inv + dd * u[:, 0] ** 2
            M[iu[:, 1], iu[:, 1]] += lam_disk * inv + dd * u[:, 1] ** 2
            M[iu[:, 0], iu[:, 1]] += dd * u[:, 0] * u[:, 1]
            M[iu[:, 1], iu[:, 0]] += dd * u[:, 0] * u[:, 1]
        return M

    def solve(
        self, P: np.ndarray, q: np.ndarray, x0: np.ndarray, R0: np.ndarray, tol: float = 1e-9, max_iter: int = 60
    ) -> QPResult:
        """Solve from ``x0`` (Mehrotra predictor–corrector; ``P`` must be positive definite).

        Parameters
        ----------
        P, q : ndarray (B·n·3, B·n·3), (B·n·3,)
            The quadratic and linear terms.
        x0 : ndarray (B·n·3,)
            Starting point (need not be feasible: the slacks start positive).
        R0 : ndarray (n, 2)
            Robot positions now (the region constraints, eq. (2)).
        tol : float
            Converged when the dual residual is below ``tol (1 + |q|∞)`` and the primal residual
            and the mean complementarity below ``tol``.
        max_iter : int
            Interior-point iterations at most.

        Returns
        -------
        QPResult
        """
        x = np.array(x0, float)
        hv = self._bounds(R0)
        m = self.m_lin + self.m_disk
        s = np.maximum(-self.constraints(x, R0), 1e-2)
        lam = np.ones(m)
        qn = 1.0 + float(np.abs(q).max())
        it = 0
        for it in range(max_iter + 1):  # noqa: B007 (the count is returned)
            u = x[self.iu]
            f = self.G @ x - hv
            if self.m_disk:
                f = np.concatenate([f, 0.5 * (np.sum(u * u, axis=1) / self.u_max**2 - 1.0)])
            rp = f + s
            rd = P @ x + q + self._jt(lam, u)
            mu = float(lam @ s) / m
            if it == max_iter or (np.abs(rd).max() <= tol * qn and np.abs(rp).max() <= tol and mu <= tol):
                break
            M = self._normal_matrix(P, lam / s, lam[self.m_lin :], u)
            try:
                L = sla.cho_factor(M, check_finite=False)
            except np.linalg.LinAlgError:
                M[np.diag_indices(self.size)] += 1e-10 * (1.0 + np.abs(np.diag(M)))
                L = sla.cho_factor(M, check_finite=False)
            # the affine (predictor) direction, then the centred corrector
            dx, ds, dl = self._direction(L, rd, rp, lam * s, lam, s, u)
            ap, ad = min(1.0, _step(s, ds)), min(1.0, _step(lam, dl))
            sigma = (float((lam + ad * dl) @ (s + ap * ds)) / m / mu) ** 3
            dx, ds, dl = self._direction(L, rd, rp, lam * s + dl * ds - sigma * mu, lam, s, u)
            ap, ad = min(1.0, 0.99 * _step(s, ds)), min(1.0, 0.99 * _step(lam, dl))
            x += ap * dx
            s += ap * ds
            lam += ad * dl
        disk = lam[self.m_lin :].reshape(self.B, self.n) if self.m_disk else np.zeros((self.B, self.n))
        return QPResult(x, disk, it, it < max_iter)

    def _direction(
        self, L: tuple, rd: np.ndarray, rp: np.ndarray, rc: np.ndarray, lam: np.ndarray, s: np.ndarray, u: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Newton direction ``(Δx, Δs, Δλ)`` of the perturbed KKT system with complementarity residual ``rc``."""
        dx = sla.cho_solve(L, -rd - self._jt((lam * rp - rc) / s, u), check_finite=False)
        ds = -rp - self._jv(dx, u)
        return dx, ds, (-rc - lam * ds) / s


def _step(v: np.ndarray, dv: np.ndarray) -> float:
    """Largest ``α`` with ``v + α dv >= 0`` (``inf`` if ``dv >= 0``)."""
    neg = dv < 0
    return float(np.min(-v[neg] / dv[neg])) if np.any(neg) else math.inf
