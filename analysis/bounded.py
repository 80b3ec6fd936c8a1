"""Bounded β/γ design: the robots' extra inputs under speed limits (an exact dual; Clarabel, cvxpy).

The paper's Step-II law (eq. (8)) is ``u_i = k_u b_i + δu_i``, ``ω_i = -k_ω g_i + δω_i``,
and (semi-discrete, exactly)

.. math::

    \\dot V_2 = -\\int α|∇ρ̃|^2 - \\sum_i k_u|b_i|^2 - \\sum_i k_ω g_i^2
              + A - \\Big(\\sum_i b_i·δu_i - \\sum_i g_i δω_i\\Big).

The paper asks ``Σ b_i·δu_i − Σ g_i δω_i = A`` through its β/γ weights, and ignores that a
real robot has ``‖u_i‖ ≤ u_max`` and ``|ω_i| ≤ ω_max``.  This module chooses the extra
inputs by the convex program of ``docs/controller.md``, *Choosing β and γ*
(``#choosing-beta-and-gamma``)::

    minimise    Σ‖δu_i‖² + Σ δω_i²                      (least effort)
    subject to  Σ b_i·δu_i − Σ g_i δω_i ≥ A              (V₂ decreases as promised)
                ‖k_u b_i + δu_i‖ ≤ u_max                 (second-order cones)
                |−k_ω g_i + δω_i| ≤ ω_max

When no input within the limits reaches ``A`` (the robots are too few or too slow), the
inputs maximise ``Σ b_i·δu_i − Σ g_i δω_i`` instead, and the *shortfall*
``A − (Σ b_i·δu_i − Σ g_i δω_i) > 0`` enters ``dV₂/dt`` as the input of Theorem 2's ISS
bound.  An infeasible program is therefore not an error: it is a reported shortfall.

Condition ``"inequality"`` (default) spends no effort when ``A < 0`` (V₂ already decreases
faster than promised); ``"equality"`` is the paper's condition ``= A``, whose solution
without limits is exactly the closed-form minimum-norm choice
``δu_i = A b_i / Z``, ``δω_i = −A g_i / Z``, ``Z = Σ|b_i|² + Σ g_i²``.

Three solvers of the same program, chosen by ``method``:

- ``"exact"`` (default, the fastest): :func:`bounded_inputs_exact`, the program solved
  exactly through its one-dimensional dual (for a fixed multiplier the robots decouple);
- ``"clarabel"``: Clarabel's native API, the solver built once and its data updated each
  call (:class:`analysis.bounded_cone.ClarabelProgram`);
- ``"cvxpy"``: the program built once with cvxpy Parameters (disciplined parametrised
  programming, DPP) and re-solved by Clarabel (:class:`analysis.bounded_cone.CvxpyProgram`),
  the reference formulation.

The interior-point solvers agree with the exact dual to their tolerance (about 1e-6 of the
limits at the paper's scale; ``tests/analysis/test_bounded.py``, ``benchmarks/bench_bounded.py``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Literal

import numpy as np

from analysis.bounded_cone import SOLVER_OPTIONS, ClarabelProgram, CvxpyProgram
from meanfield.capabilities import BetaGammaCapabilities, declares
from meanfield.controllers.backstepping import ExtraInputs
from meanfield.errors import ParameterError, limit_or_inf
from meanfield.scenarios.scenario import Scenario

__all__ = [
    "CONDITIONS",
    "METHODS",
    "BoundedInputs",
    "BoundedBetaGamma",
    "bounded_inputs_exact",
    "achievable_range",
    "bounded_strategy_for",
]

CONDITIONS = ("inequality", "equality")
"""How the extra inputs must meet ``A``: at least (``≥ A``) or exactly (the paper's ``= A``)."""

METHODS = ("exact", "clarabel", "cvxpy")
"""The solvers of the program: the exact 1-D dual, Clarabel's native API, cvxpy (DPP) + Clarabel."""


@dataclass
class BoundedInputs(ExtraInputs):
    """Extra inputs of the bounded program, with what the limits did.

    Attributes
    ----------
    du, domega, shortfall
        As :class:`~meanfield.controllers.backstepping.ExtraInputs`; ``shortfall`` is ``A`` minus what the
        inputs achieve (``> 0`` only when the limits make ``A`` unreachable, or, with
        condition ``"equality"``, ``< 0`` when ``A`` lies below the reachable range).
    feasible : bool
        Whether the condition on ``A`` could be met within the limits.
    speed_binding, turn_binding : ndarray of bool, shape (n,)
        Robots whose total input sits on the speed (turn-rate) limit.
    achievable : (float, float)
        The range of ``Σ b_i·δu_i − Σ g_i δω_i`` reachable within the limits.
    solve_seconds : float
        Wall time of this solve.
    """

    feasible: bool = True
    speed_binding: np.ndarray | None = None
    turn_binding: np.ndarray | None = None
    achievable: tuple[float, float] = (-math.inf, math.inf)
    solve_seconds: float = 0.0


def _gains(name: str, k: float | np.ndarray, n: int) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(k, float), (n,)) if np.ndim(k) == 0 else np.asarray(k, float)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ParameterError(name, k, f"a gain >= 0 or {n} gains >= 0")
    return np.array(arr)


def _check_integrals(b: np.ndarray, g: np.ndarray, A: float, n: int) -> tuple[np.ndarray, np.ndarray, float]:
    b = np.asarray(b, float)
    g = np.asarray(g, float)
    if b.shape != (n, 2) or g.shape != (n,):
        raise ParameterError("b, g", (b.shape, g.shape), f"arrays of shapes ({n}, 2) and ({n},)")
    A = float(A)
    if not (np.all(np.isfinite(b)) and np.all(np.isfinite(g)) and math.isfinite(A)):
        raise ParameterError("b, g, A", "non-finite values", "finite integrals")
    return b, g, A


def achievable_range(
    b: np.ndarray, g: np.ndarray, k_u: np.ndarray, k_omega: np.ndarray, u_max: float, omega_max: float
) -> tuple[float, float]:
    """Range of ``Σ b_i·δu_i − Σ g_i δω_i`` over inputs within the limits (closed form).

    Each robot's term is a linear function over a disk (a segment): its maximum is
    ``u_max|b_i| − k_u|b_i|²`` and its minimum ``−u_max|b_i| − k_u|b_i|²``; likewise
    ``ω_max|g_i| − k_ω g_i²`` and ``−ω_max|g_i| − k_ω g_i²``.  A zero integral with an
    infinite limit contributes 0 (``0·∞`` read as 0).
    """
    nb = np.hypot(b[:, 0], b[:, 1])
    ng = np.abs(g)
    with np.errstate(invalid="ignore"):
        reach = np.where(nb > 0, u_max * nb, 0.0).sum() + np.where(ng > 0, omega_max * ng, 0.0).sum()
    base = -(k_u * nb * nb).sum() - (k_omega * ng * ng).sum()
    return float(base - reach), float(base + reach)


def _half_widths(nb: np.ndarray, limit: float) -> np.ndarray:
    """``L/|b_i|``: how far the scale of robot ``i`` may move from ``−k_i`` (∞ for ``b_i = 0``)."""
    with np.errstate(divide="ignore"):
        return np.where(nb > 0, limit / np.where(nb > 0, nb, 1.0), math.inf)


def bounded_inputs_exact(
    b: np.ndarray,
    g: np.ndarray,
    A: float,
    k_u: float | np.ndarray,
    k_omega: float | np.ndarray,
    u_max: float | None,
    omega_max: float | None,
    condition: Literal["inequality", "equality"] = "inequality",
) -> BoundedInputs:
    """Exact solution of the bounded program through its one-dimensional dual.

    For a multiplier ``λ`` of the condition on ``A`` the program decouples per robot:
    ``δu_i`` is the projection of ``λ b_i`` onto the disk ``‖k_u b_i + δu‖ ≤ u_max``,
    which lies on the line of ``b_i``: ``δu_i = s_i(λ) b_i`` with
    ``s_i = clip(λ, −k_u − u_max/|b_i|, −k_u + u_max/|b_i|)``; likewise
    ``δω_i = −t_i(λ) g_i`` with ``t_i = clip(λ, −k_ω − ω_max/|g_i|, −k_ω + ω_max/|g_i|)``.
    The achieved value ``c(λ) = Σ|b_i|² s_i + Σ g_i² t_i`` is non-decreasing and
    piecewise linear, so ``c(λ) = A`` is solved exactly between two breakpoints.  These are
    the KKT conditions of the program, which is convex and strictly feasible in its cones
    (``δu_i = −k_u b_i``, ``δω_i = k_ω g_i``), so the solution is the program's optimum.

    Parameters
    ----------
    b : ndarray, shape (n, 2)
    g : ndarray, shape (n,)
    A : float
        The integrals of eq. (8).
    k_u, k_omega : float or ndarray, shape (n,)
        Step-II gains (>= 0).
    u_max, omega_max : float or None
        Limits (None: none).
    condition : {"inequality", "equality"}
        ``≥ A`` (λ ≥ 0) or ``= A`` (λ free).

    Returns
    -------
    BoundedInputs
        The inputs, the shortfall and what the limits did.
    """
    t0 = time.perf_counter()
    n = np.shape(b)[0] if np.ndim(b) == 2 else -1
    b, g, A = _check_integrals(b, g, A, n)
    ku = _gains("k_u", k_u, n)
    kw = _gains("k_omega", k_omega, n)
    U = limit_or_inf("u_max", u_max)
    W = limit_or_inf("omega_max", omega_max)
    if condition not in CONDITIONS:
        raise ParameterError("condition", condition, " or ".join(map(repr, CONDITIONS)))
    return _exact(b, g, A, ku, kw, U, W, condition, achievable_range(b, g, ku, kw, U, W), t0)


def _exact(
    b: np.ndarray,
    g: np.ndarray,
    A: float,
    ku: np.ndarray,
    kw: np.ndarray,
    U: float,
    W: float,
    condition: str,
    achievable: tuple[float, float],
    t0: float,
) -> BoundedInputs:
    """:func:`bounded_inputs_exact` on validated arguments (the strategy's fast path)."""
    nb = np.hypot(b[:, 0], b[:, 1])
    ng = np.abs(g)
    lo, hi = achievable
    n = len(g)
    # robots' speed scales, then turn scales: c(λ) = Σ w_j clip(λ, low_j, high_j)
    w = np.concatenate((nb * nb, ng * ng))
    half = np.concatenate((_half_widths(nb, U), _half_widths(ng, W)))
    k = np.concatenate((ku, kw))
    low = -k - half
    high = -k + half
    lam_min = 0.0 if condition == "inequality" else -math.inf
    feasible = A <= hi and (condition == "inequality" or A >= lo)
    if w.sum() == 0:
        lam = 0.0  # every integral is zero: no input changes the value; least effort
    elif condition == "inequality" and float(w @ np.clip(0.0, low, high)) >= A:
        lam = 0.0  # the condition already holds at the least-effort point
    elif not feasible:
        lam = math.inf if A > hi else -math.inf  # the input that comes closest to A
    else:
        # candidate multipliers: the breakpoints of c(λ), where a robot enters or leaves a limit
        knots = np.concatenate((low, high))
        knots = np.sort(knots[np.isfinite(knots) & (knots > lam_min)])
        first = lam_min if math.isfinite(lam_min) else (knots[0] - 1.0 if knots.size else -1.0)
        pts = np.concatenate(([first], knots))
        vals = np.clip(pts[:, None], low, high) @ w
        if vals[-1] < A or vals[0] > A:  # beyond the breakpoints c(λ) is linear with the unconstrained slope
            slope = w[half == math.inf].sum()
            lam = pts[-1] + (A - vals[-1]) / slope if vals[-1] < A else pts[0] - (vals[0] - A) / slope
        else:
            j = int(np.searchsorted(vals, A, side="left"))
            if vals[j] == A:
                lam = float(pts[j])
            else:
                lam = float(pts[j - 1] + (A - vals[j - 1]) * (pts[j] - pts[j - 1]) / (vals[j] - vals[j - 1]))
    scale = np.clip(lam, low, high)
    if math.isinf(lam):  # every robot on its limit: finite scales from the clip
        scale = np.where(np.isfinite(scale), scale, 0.0)
    du = scale[:n, None] * b
    dw = -scale[n:] * g
    return _finish(b, g, A, ku, kw, U, W, du, dw, feasible, (lo, hi), time.perf_counter() - t0)


def _finish(
    b: np.ndarray,
    g: np.ndarray,
    A: float,
    ku: np.ndarray,
    kw: np.ndarray,
    U: float,
    W: float,
    du: np.ndarray,
    dw: np.ndarray,
    feasible: bool,
    achievable: tuple[float, float],
    seconds: float,
) -> BoundedInputs:
    """Project the totals onto the limits (removes a solver's round-off), report the shortfall.

    The totals are kept a relative 1e-12 inside each limit, and the extra inputs are
    recomputed until ``k_u b_i + δu_i`` and ``−k_ω g_i + δω_i``, as the controller will form
    them, are within the limits in floating point too.
    """
    kb = ku[:, None] * b
    kg = -kw * g
    u = kb + du
    w = kg + dw
    shrink = 1.0 - 1e-12
    for _ in range(8):
        speed = np.hypot(u[:, 0], u[:, 1])
        over = speed > U * shrink
        if math.isfinite(U) and over.any():
            u[over] *= (U * shrink / speed[over])[:, None]
        if math.isfinite(W):
            w = np.clip(w, -W * shrink, W * shrink)
        du = u - kb
        dw = w - kg
        u_back = kb + du
        w_back = kg + dw
        if np.all(np.hypot(u_back[:, 0], u_back[:, 1]) <= U) and np.all(np.abs(w_back) <= W):
            break
        shrink *= 1.0 - 1e-9  # round-off of the recomposition exceeded the margin: tighten
    speed = np.hypot(u[:, 0], u[:, 1])
    done = float((b * du).sum() - (g * dw).sum())
    rtol = 1e-7
    return BoundedInputs(
        du=du,
        domega=dw,
        shortfall=A - done,
        feasible=feasible,
        speed_binding=speed >= U * (1 - rtol) if math.isfinite(U) else np.zeros(len(g), bool),
        turn_binding=np.abs(w) >= W * (1 - rtol) if math.isfinite(W) else np.zeros(len(g), bool),
        achievable=achievable,
        solve_seconds=seconds,
    )


class BoundedBetaGamma:
    """β/γ strategy under speed limits: the convex program of this module, solved each step.

    Parameters
    ----------
    n : int
        Number of robots.
    k_u, k_omega : float or ndarray, shape (n,)
        The controller's Step-II gains (the base inputs ``k_u b_i`` and ``−k_ω g_i``).
    u_max, omega_max : float or None
        Speed and turn-rate limits (None: none).
    condition : {"inequality", "equality"}
        ``Σ b_i·δu_i − Σ g_i δω_i ≥ A`` (default) or ``= A`` (the paper's).
    method : {"exact", "clarabel", "cvxpy"}
        The exact one-dimensional dual of :func:`bounded_inputs_exact` (default: exact, and
        the fastest, ``benchmarks/bench_bounded.py``), Clarabel's native API with the data
        updated in place, or cvxpy + Clarabel (the program built once with Parameters, DPP;
        the reference formulation).  With a cone solver, ``A`` out of reach is answered by
        the closed-form maximiser, and a solver failure by the exact dual.

    Attributes
    ----------
    last : BoundedInputs or None
        The last call's result.
    program : ClarabelProgram, CvxpyProgram or None
        The cone program of methods ``"clarabel"`` and ``"cvxpy"`` (None for ``"exact"``).
    cone_solves : int
        Calls that ran a cone solver (methods ``"clarabel"``, ``"cvxpy"``);
        ``cone_failures`` of them found no solution and were answered by the exact dual.
    closed_form_solves : int
        Calls answered without one: method ``"exact"``, or ``A`` out of reach, or every
        integral zero.
    unreachable_solves : int
        Calls whose program was infeasible (``A`` out of the robots' reach, or every
        integral zero with ``A > 0``), for any method.

    Examples
    --------
    >>> import numpy as np
    >>> s = BoundedBetaGamma(2, k_u=1.0, k_omega=1.0, u_max=0.5, omega_max=1.0)
    >>> out = s(np.array([[0.1, 0.0], [0.0, 0.2]]), np.array([0.0, 0.1]), 0.05)
    >>> bool(out.feasible), abs(out.shortfall) < 1e-6
    (True, True)
    """

    name = "bounded"
    SOLVER_OPTIONS = SOLVER_OPTIONS
    """Clarabel's tolerances for methods ``"clarabel"`` and ``"cvxpy"`` (its defaults are 1e-8)."""

    def __init__(
        self,
        n: int,
        k_u: float | np.ndarray,
        k_omega: float | np.ndarray,
        u_max: float | None,
        omega_max: float | None,
        condition: Literal["inequality", "equality"] = "inequality",
        method: Literal["exact", "clarabel", "cvxpy"] = "exact",
    ):
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ParameterError("n", n, "an integer >= 1 (the number of robots)")
        self.n = int(n)
        self.k_u = _gains("k_u", k_u, self.n)
        self.k_omega = _gains("k_omega", k_omega, self.n)
        self.u_max = limit_or_inf("u_max", u_max)
        self.omega_max = limit_or_inf("omega_max", omega_max)
        if condition not in CONDITIONS:
            raise ParameterError("condition", condition, " or ".join(map(repr, CONDITIONS)))
        if method not in METHODS:
            raise ParameterError("method", method, " or ".join(map(repr, METHODS)))
        self.condition = condition
        self.method = method
        self.last: BoundedInputs | None = None
        self.cone_solves = 0
        self.cone_failures = 0
        self.closed_form_solves = 0
        self.unreachable_solves = 0
        self.program: ClarabelProgram | CvxpyProgram | None = None
        if method != "exact":
            cone = ClarabelProgram if method == "clarabel" else CvxpyProgram
            self.program = cone(
                self.n, self.k_u, self.k_omega, self.u_max, self.omega_max, condition, self.SOLVER_OPTIONS
            )

    def __call__(self, b: np.ndarray, g: np.ndarray, A: float) -> BoundedInputs:
        """Extra inputs for the integrals ``b`` (n, 2), ``g`` (n,) and ``A`` of eq. (8)."""
        t0 = time.perf_counter()
        b, g, A = _check_integrals(b, g, A, self.n)
        ku, kw, U, W = self.k_u, self.k_omega, self.u_max, self.omega_max
        reach = achievable_range(b, g, ku, kw, U, W)
        lo, hi = reach
        unreachable = A > hi or (self.condition == "equality" and A < lo)
        self.unreachable_solves += unreachable
        out = None
        if self.program is None or unreachable or not (b.any() or g.any()):
            # method "exact", or unreachable: the closest reachable value is attained on the
            # limits, in closed form (the cone program would be infeasible; this is its minimiser)
            self.closed_form_solves += 1
        else:
            self.cone_solves += 1
            raw = self.program.solve(b, g, A)
            if raw is not None:
                out = _finish(b, g, A, ku, kw, U, W, raw[0], raw[1], True, reach, time.perf_counter() - t0)
            else:
                self.cone_failures += 1
        if out is None:  # also a cone solver's failure: A on the edge of the reachable range,
            out = _exact(b, g, A, ku, kw, U, W, self.condition, reach, t0)  # the feasible set ~ one point
        self.last = out
        return out


@declares(BetaGammaCapabilities())  # its limits are in the scenario's units: no kernel scaling
def bounded_strategy_for(scenario: Scenario) -> BoundedBetaGamma:
    """The ``bounded`` β/γ strategy of a scenario (entry point ``meanfield.beta_gamma``).

    Takes the gains from ``[controller]`` and the limits from ``[robots]``.
    """
    c = scenario.controller
    r = scenario.robots
    return BoundedBetaGamma(r.n, c.k_u, c.k_omega, r.u_max, r.omega_max)
