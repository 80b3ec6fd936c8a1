"""The bounded β/γ program as a cone program: Clarabel's native API, and cvxpy (the reference).

Both solve the program of :mod:`analysis.bounded` (``docs/analysis.md``, *Bounded design*)
for the extra inputs ``δu_i``, ``δω_i`` of the Step-II law, eq. (8)::

    minimise    Σ‖δu_i‖² + Σ δω_i²
    subject to  Σ b_i·δu_i − Σ g_i δω_i ≥ A     (or = A)
                ‖k_u b_i + δu_i‖ ≤ u_max
                |−k_ω g_i + δω_i| ≤ ω_max

for ``A`` within the robots' reach (the caller answers the rest in closed form), and return
the raw ``(δu, δω)`` of the solver, or None when it did not report a solution.

- :class:`ClarabelProgram` writes the program in Clarabel's standard form
  ``min ½xᵀPx + qᵀx  s.t.  Ax + s = b, s ∈ K`` with scipy sparse ``P`` and ``A``, builds the
  solver once and, each call, only overwrites the values of ``A`` and ``b`` (the sparsity
  is fixed: the zeros of the integrals are kept as explicit entries); where this Clarabel
  does not allow data updates it builds the solver each call.
- :class:`CvxpyProgram` is the same program built once with cvxpy Parameters (disciplined
  parametrised programming) and re-solved by Clarabel through cvxpy.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["SOLVER_OPTIONS", "ClarabelProgram", "CvxpyProgram"]

SOLVER_OPTIONS: dict[str, float] = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10, "tol_ktratio": 1e-8}
"""Clarabel's tolerances for both cone programs (its defaults are 1e-8): the inputs agree
with the exact dual to about 1e-7 at the paper's scale, at one or two more iterations."""


def _check_condition(condition: str) -> None:
    if condition not in ("inequality", "equality"):
        raise ParameterError("condition", condition, "'inequality' or 'equality'")


class ClarabelProgram:
    """The bounded program in Clarabel's native API, its data updated in place each call.

    Variables ``x = (δu_1x, δu_1y, …, δu_nx, δu_ny, δω_1, …, δω_n)/τ`` in units of the
    inputs' size ``τ`` (:meth:`input_scale`), ``P = 2I`` (the objective ``Σ‖δu_i‖² + Σδω_i²``
    over ``τ²``, as cvxpy writes it), ``q = 0``, and the rows of ``Ax + s = b``, each
    divided by ``τ``:

    - the condition, ``s = Σ b_i·δu_i − Σ g_i δω_i − A`` in the nonnegative cone (the zero
      cone for ``"equality"``), also divided by ``σ = max(|b|, |g|)`` so that the row's
      entries are of order one whatever the integrals' scale (Clarabel equilibrates the
      matrix once, when the solver is built, and keeps that scaling through updates);
    - per robot, ``s = (u_max, k_u b_i + δu_i)`` in the second-order cone of dimension 3;
    - per robot, ``s = ω_max ∓ (−k_ω g_i + δω_i)`` in the nonnegative cone.

    Parameters
    ----------
    n : int
        Number of robots.
    k_u, k_omega : ndarray, shape (n,)
        Step-II gains (validated by the caller).
    u_max, omega_max : float
        Limits (``math.inf``: none; its rows are left out).
    condition : {"inequality", "equality"}
        ``≥ A`` or ``= A``.
    options : dict, optional
        Clarabel settings (default :data:`SOLVER_OPTIONS`).
    """

    ACCEPTED: ClassVar[tuple[str, ...]] = ("Solved", "AlmostSolved")
    """Clarabel statuses whose solution is used (cvxpy's ``optimal`` and ``optimal_inaccurate``)."""

    def __init__(
        self,
        n: int,
        k_u: np.ndarray,
        k_omega: np.ndarray,
        u_max: float,
        omega_max: float,
        condition: str = "inequality",
        options: dict[str, Any] | None = None,
    ):
        import clarabel
        import scipy.sparse as sp

        _check_condition(condition)
        self.n, self.k_u, self.k_omega = n, np.asarray(k_u, float), np.asarray(k_omega, float)
        self.u_max, self.omega_max = u_max, omega_max
        self._clarabel = clarabel
        nv = 3 * n
        soc = math.isfinite(u_max)
        box = math.isfinite(omega_max)
        self._soc_row = 1  # first row of the second-order cones
        self._box_row = 1 + 3 * n * soc  # first row of the turn-rate rows
        m = self._box_row + 2 * n * box
        indptr, indices, data = [0], [], []
        for j in range(nv):  # column by column (CSC); row 0 first in each column
            rows, vals = [0], [0.0]
            if j < 2 * n and soc:
                rows.append(self._soc_row + 3 * (j // 2) + 1 + j % 2)
                vals.append(-1.0)
            if j >= 2 * n and box:
                i = j - 2 * n
                rows += [self._box_row + 2 * i, self._box_row + 2 * i + 1]
                vals += [1.0, -1.0]
            indices += rows
            data += vals
            indptr.append(len(indices))
        self._A = sp.csc_matrix(
            (np.array(data), np.array(indices, np.int64), np.array(indptr, np.int64)), shape=(m, nv)
        )
        self._row0 = np.array(indptr[:-1])  # positions of the condition row's entries in A's values
        self._P = 2.0 * sp.identity(nv, format="csc")  # the objective Σ‖δu_i‖² + Σ δω_i², as cvxpy writes it
        self._q = np.zeros(nv)
        self._rhs = np.zeros(m)
        self._cones = [clarabel.ZeroConeT(1) if condition == "equality" else clarabel.NonnegativeConeT(1)]
        self._cones += [clarabel.SecondOrderConeT(3)] * (n if soc else 0)
        self._cones += [clarabel.NonnegativeConeT(2 * n)] if box else []
        self._settings = clarabel.DefaultSettings()
        self._settings.verbose = False
        for key in ("presolve_enable", "input_sparse_dropzeros"):  # data updates need the problem
            if hasattr(self._settings, key):  # as given, its explicit zeros kept (a fixed sparsity)
                setattr(self._settings, key, False)
        for key, value in (SOLVER_OPTIONS if options is None else options).items():
            setattr(self._settings, key, value)
        self._solver: Any = None
        self.updates_data = False  # whether the solver is updated in place (else built each call)
        self.builds = 0  # solvers built

    def input_scale(self, b: np.ndarray, g: np.ndarray, A: float) -> float:
        """The unit ``τ`` of the inputs in the solver (which solves for ``x/τ``).

        The largest of the size of the minimum-norm input of eq. (8), ``|A|/√Z`` with
        ``Z = Σ|b_i|² + Σg_i²``, and of the base inputs ``k_u|b_i|``, ``k_ω|g_i|``: Clarabel's
        absolute tolerances then act on numbers of order one whatever the integrals' scale.

        Parameters
        ----------
        b : ndarray, shape (n, 2)
        g : ndarray, shape (n,)
        A : float
            The integrals of eq. (8).

        Returns
        -------
        float
            ``τ > 0`` (1 where every candidate is zero).
        """
        z = float((b * b).sum() + (g * g).sum())
        base = max(float((self.k_u * np.hypot(b[:, 0], b[:, 1])).max()), float((self.k_omega * np.abs(g)).max()))
        tau = max(abs(A) / math.sqrt(z), base)
        return tau if tau > 0 and math.isfinite(tau) else 1.0

    def solve(self, b: np.ndarray, g: np.ndarray, A: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Solve the program for the integrals of eq. (8), updating the solver's data in place.

        Parameters
        ----------
        b : ndarray, shape (n, 2)
        g : ndarray, shape (n,)
        A : float
            The integrals of eq. (8) (validated by the caller); ``b`` and ``g`` must not both
            be zero (the caller answers that case in closed form).

        Returns
        -------
        (ndarray, ndarray) or None
            ``δu`` (n, 2) and ``δω`` (n,) as the solver returned them, or None when it did not
            report ``Solved``/``AlmostSolved`` (or raised).
        """
        n = self.n
        sigma = max(float(np.abs(b).max()), float(np.abs(g).max()))
        tau = self.input_scale(b, g, A)
        values = self._A.data
        values[self._row0[: 2 * n]] = -b.ravel() / sigma
        values[self._row0[2 * n :]] = g / sigma
        rhs = self._rhs
        rhs[0] = -A / (sigma * tau)
        if math.isfinite(self.u_max):
            cones = rhs[self._soc_row : self._box_row].reshape(n, 3)
            cones[:, 0] = self.u_max / tau
            cones[:, 1:] = self.k_u[:, None] * b / tau
        if math.isfinite(self.omega_max):
            kg = self.k_omega * g
            rhs[self._box_row :: 2] = (self.omega_max + kg) / tau
            rhs[self._box_row + 1 :: 2] = (self.omega_max - kg) / tau
        try:
            if self.updates_data:
                self._solver.update(A=values, b=rhs)
            else:
                self._solver = self._clarabel.DefaultSolver(self._P, self._q, self._A, rhs, self._cones, self._settings)
                self.builds += 1
                allowed = getattr(self._solver, "is_data_update_allowed", None)
                self.updates_data = bool(allowed is not None and allowed())
            result = self._solver.solve()
        except Exception:  # a panic or a refused update: rebuild next time, the caller falls back
            self._solver, self.updates_data = None, False
            return None
        status = str(result.status).rsplit(".", 1)[-1]
        if status not in self.ACCEPTED:
            return None
        x = np.asarray(result.x, float)
        if x.shape != (3 * n,) or not np.all(np.isfinite(x)):
            return None
        x *= tau
        return x[: 2 * n].reshape(n, 2), x[2 * n :].copy()


class CvxpyProgram:
    """The bounded program built once with cvxpy Parameters (DPP), re-solved by Clarabel.

    The reference formulation: what :class:`ClarabelProgram` writes by hand, cvxpy derives.
    Parameters as :class:`ClarabelProgram`; ``problem`` is the :class:`cvxpy.Problem`.
    """

    def __init__(
        self,
        n: int,
        k_u: np.ndarray,
        k_omega: np.ndarray,
        u_max: float,
        omega_max: float,
        condition: str = "inequality",
        options: dict[str, Any] | None = None,
    ):
        import cvxpy as cp

        _check_condition(condition)
        self.options = dict(SOLVER_OPTIONS if options is None else options)
        self._b = cp.Parameter((n, 2), name="b")
        self._g = cp.Parameter(n, name="g")
        self._A = cp.Parameter(name="A")
        self._du = cp.Variable((n, 2), name="du")
        self._dw = cp.Variable(n, name="domega")
        gain = cp.sum(cp.multiply(self._b, self._du)) - self._g @ self._dw
        cons = [gain == self._A if condition == "equality" else gain >= self._A]
        if math.isfinite(u_max):
            u = cp.multiply(np.asarray(k_u, float)[:, None], self._b) + self._du
            cons.append(cp.SOC(np.full(n, u_max), u, axis=1))
        if math.isfinite(omega_max):
            w = cp.multiply(-np.asarray(k_omega, float), self._g) + self._dw
            cons += [w <= omega_max, -w <= omega_max]
        self.problem = cp.Problem(cp.Minimize(cp.sum_squares(self._du) + cp.sum_squares(self._dw)), cons)
        assert self.problem.is_dpp()

    def solve(self, b: np.ndarray, g: np.ndarray, A: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Re-solve the program for the integrals of eq. (8) (the Parameters re-filled).

        Parameters
        ----------
        b : ndarray, shape (n, 2)
        g : ndarray, shape (n,)
        A : float
            The integrals of eq. (8) (validated by the caller).

        Returns
        -------
        (ndarray, ndarray) or None
            ``δu`` (n, 2) and ``δω`` (n,), or None unless cvxpy reports ``optimal`` or
            ``optimal_inaccurate``.
        """
        import cvxpy as cp

        self._b.value = b
        self._g.value = g
        self._A.value = A
        try:
            self.problem.solve(solver=cp.CLARABEL, **self.options)
        except cp.SolverError:
            return None
        if self.problem.status not in ("optimal", "optimal_inaccurate") or self._du.value is None:
            return None
        return np.array(self._du.value), np.array(self._dw.value)
