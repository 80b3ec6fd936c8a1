"""The bounded β/γ program (analysis.bounded): constraints, closed forms, shortfall, plugin, and
its three solvers (the exact dual, Clarabel's native API, cvxpy) agreeing with each other."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.bounded import (
    METHODS,
    BoundedBetaGamma,
    achievable_range,
    bounded_inputs_exact,
    bounded_strategy_for,
)
from analysis.bounded_cone import SOLVER_OPTIONS
from meanfield import ClosedLoop, MinimumNormBetaGamma, ParameterError, paper_scenario, plugins

CONE_METHODS = ("clarabel", "cvxpy")


def _problem(seed: int, n: int = 16, scale: float = 0.02):
    rng = np.random.default_rng(seed)
    b = rng.normal(scale=scale, size=(n, 2))
    g = rng.normal(scale=scale, size=n)
    A = float(rng.normal(scale=0.01))
    return b, g, A


def _achieved(b, g, out) -> float:
    return float((b * out.du).sum() - (g * out.domega).sum())


def _check_constraints(b, g, A, out, k_u, k_omega, u_max, omega_max, condition, tol=1e-7):
    """Every constraint of the program, from the returned inputs alone."""
    u = k_u * b + out.du
    w = -k_omega * g + out.domega
    if math.isfinite(u_max):
        assert np.all(np.hypot(u[:, 0], u[:, 1]) <= u_max)  # never above, not even by round-off
    if math.isfinite(omega_max):
        assert np.all(np.abs(w) <= omega_max)
    done = _achieved(b, g, out)
    np.testing.assert_allclose(out.shortfall, A - done, atol=1e-15, rtol=1e-12)
    scale = 1e-6 * (abs(A) + 1e-3)
    lo, hi = out.achievable
    if out.feasible:
        if condition == "inequality":
            assert done >= A - scale
        else:
            assert abs(done - A) <= scale
    else:  # the closest reachable value
        assert A > hi or A < lo
        np.testing.assert_allclose(done, hi if A > hi else lo, rtol=tol, atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("condition", ["inequality", "equality"])
@pytest.mark.parametrize("seed", range(12))
def test_solution_satisfies_every_constraint(method, condition, seed):
    b, g, A = _problem(seed)
    A *= 1 + 5 * (seed % 3)  # some reachable, some not
    s = BoundedBetaGamma(16, 10.0, 10.0, 0.2, 3.0, condition=condition, method=method)
    out = s(b, g, A)
    _check_constraints(b, g, A, out, 10.0, 10.0, 0.2, 3.0, condition)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(1, 8),
    k_u=st.floats(0.0, 20.0),
    k_omega=st.floats(0.0, 20.0),
    u_max=st.one_of(st.none(), st.floats(1e-3, 2.0)),
    omega_max=st.one_of(st.none(), st.floats(1e-3, 5.0)),
    A=st.floats(-1.0, 1.0),
    condition=st.sampled_from(["inequality", "equality"]),
)
def test_exact_solution_constraints_property(seed, n, k_u, k_omega, u_max, omega_max, A, condition):
    rng = np.random.default_rng(seed)
    b = rng.normal(scale=0.1, size=(n, 2))
    g = rng.normal(scale=0.1, size=n)
    out = bounded_inputs_exact(b, g, A, k_u, k_omega, u_max, omega_max, condition)
    U = math.inf if u_max is None else u_max
    W = math.inf if omega_max is None else omega_max
    _check_constraints(b, g, A, out, k_u, k_omega, U, W, condition)


@pytest.mark.parametrize("method", CONE_METHODS)
@pytest.mark.parametrize("condition", ["inequality", "equality"])
@pytest.mark.parametrize("seed", range(8))
def test_clarabel_agrees_with_the_exact_dual(method, condition, seed):
    """Two independent solutions of one program: an interior-point solver and the 1-D dual."""
    b, g, A = _problem(seed)
    A *= 0.3  # mostly reachable, so the cone program is really solved
    a = BoundedBetaGamma(16, 10.0, 10.0, 0.2, 3.0, condition=condition, method=method)(b, g, A)
    e = bounded_inputs_exact(b, g, A, 10.0, 10.0, 0.2, 3.0, condition)
    assert a.feasible == e.feasible
    np.testing.assert_allclose(a.du, e.du, atol=1e-6 * 0.2)
    np.testing.assert_allclose(a.domega, e.domega, atol=1e-6 * 3.0)
    effort = lambda o: (o.du**2).sum() + (o.domega**2).sum()  # noqa: E731
    assert effort(e) <= effort(a) * (1 + 1e-6) + 1e-15


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("A", [-0.7, -1e-3, 0.0, 2e-3, 0.9])
def test_unconstrained_equality_is_the_closed_form_minimum_norm_choice(method, A):
    b, g, _ = _problem(3, n=5, scale=1.0)
    out = BoundedBetaGamma(5, 2.0, 3.0, None, None, condition="equality", method=method)(b, g, A)
    ref = MinimumNormBetaGamma()(b, g, A)
    np.testing.assert_allclose(out.du, ref.du, atol=1e-7)
    np.testing.assert_allclose(out.domega, ref.domega, atol=1e-7)
    assert out.feasible and abs(out.shortfall) <= 1e-7


@pytest.mark.parametrize("method", METHODS)
def test_unconstrained_inequality_is_min_norm_for_positive_A_and_zero_for_negative(method):
    b, g, _ = _problem(4, n=6, scale=1.0)
    s = BoundedBetaGamma(6, 1.0, 1.0, None, None, method=method)
    pos = s(b, g, 0.4)
    ref = MinimumNormBetaGamma()(b, g, 0.4)
    np.testing.assert_allclose(pos.du, ref.du, atol=1e-7)
    np.testing.assert_allclose(pos.domega, ref.domega, atol=1e-7)
    neg = s(b, g, -0.4)  # V₂ already decreases faster than promised: no extra effort
    np.testing.assert_allclose(neg.du, 0.0, atol=1e-7)
    np.testing.assert_allclose(neg.domega, 0.0, atol=1e-7)
    assert neg.shortfall < 0 and neg.feasible


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("seed", range(6))
def test_closed_form_within_limits_is_returned_with_zero_shortfall(method, seed):
    """Where the minimum-norm inputs already respect the limits, the program returns them."""
    b, g, A = _problem(seed, n=8, scale=0.01)
    A = abs(A)
    k_u, k_w = 2.0, 2.0
    ref = MinimumNormBetaGamma()(b, g, A)
    u = k_u * b + ref.du
    w = -k_w * g + ref.domega
    u_max = 1.01 * np.hypot(u[:, 0], u[:, 1]).max()  # just above what the closed form needs
    omega_max = 1.01 * np.abs(w).max()
    for condition in ("inequality", "equality"):
        out = BoundedBetaGamma(8, k_u, k_w, u_max, omega_max, condition=condition, method=method)(b, g, A)
        assert out.feasible
        assert abs(out.shortfall) <= 1e-7 * A
        np.testing.assert_allclose(out.du, ref.du, atol=1e-6 * u_max)
        np.testing.assert_allclose(out.domega, ref.domega, atol=1e-6 * omega_max)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("seed", range(10))
def test_shortfall_is_zero_exactly_when_A_is_reachable(method, seed):
    """shortfall = max(0, A − c_max) with c_max = Σ(u_max|b_i| − k_u|b_i|²) + Σ(ω_max|g_i| − k_ω g_i²)."""
    b, g, _ = _problem(seed)
    k_u, k_w, U, W = 10.0, 10.0, 0.2, 3.0
    nb = np.hypot(b[:, 0], b[:, 1])
    c_max = (U * nb - k_u * nb**2).sum() + (W * np.abs(g) - k_w * g**2).sum()
    assert achievable_range(b, g, np.full(16, k_u), np.full(16, k_w), U, W)[1] == pytest.approx(c_max, rel=1e-14)
    s = BoundedBetaGamma(16, k_u, k_w, U, W, method=method)
    for A in (0.5 * c_max, 0.999 * c_max, 1.001 * c_max, 3 * c_max):
        out = s(b, g, A)
        if A <= c_max:
            assert out.feasible and out.shortfall <= 1e-7 * abs(A)
        else:
            assert not out.feasible
            reach = U * nb.sum() + W * np.abs(g).sum()  # the 1e-12 margin inside the limits costs 1e-12 of it
            assert out.shortfall == pytest.approx(A - c_max, rel=1e-9, abs=2e-12 * reach)
            # the maximiser: every robot at full speed along b_i, full turn rate against g_i
            # (the totals are kept a relative 1e-12 inside the limits)
            u = k_u * b + out.du
            np.testing.assert_allclose(u, U * b / nb[:, None], rtol=2e-12)
            np.testing.assert_allclose(-k_w * g + out.domega, -W * np.sign(g), rtol=2e-12)


@pytest.mark.parametrize("method", METHODS)
def test_limits_can_bind_with_zero_shortfall(method):
    """The converse of the closed-form test does not hold: the minimum-norm inputs may break a
    limit while another robot makes up the difference, so the shortfall is still zero."""
    b = np.array([[1.0, 0.0], [0.5, 0.0]])
    g = np.zeros(2)
    ref = MinimumNormBetaGamma()(b, g, 1.3)  # δu_1 = 1.04 > u_max = 1
    assert np.hypot(*ref.du[0]) > 1.0
    out = BoundedBetaGamma(2, 0.0, 0.0, 1.0, None, method=method)(b, g, 1.3)
    assert out.feasible and abs(out.shortfall) <= 1e-7
    np.testing.assert_allclose(out.du, [[1.0, 0.0], [0.6, 0.0]], atol=1e-6)
    assert out.speed_binding.tolist() == [True, False]


@pytest.mark.parametrize("method", METHODS)
def test_base_input_beyond_the_limit_is_brought_back_even_when_A_is_negative(method):
    b = np.array([[0.1, 0.0], [0.0, 0.001]])
    g = np.array([0.0, 0.0])
    out = BoundedBetaGamma(2, 10.0, 1.0, 0.5, 1.0, method=method)(b, g, -1.0)
    u = 10.0 * b + out.du
    np.testing.assert_allclose(u, [[0.5, 0.0], [0.0, 0.01]], atol=1e-7)  # robot 0 clipped to its limit
    assert out.speed_binding.tolist() == [True, False]


@pytest.mark.parametrize("method", METHODS)
def test_zero_integrals_give_zero_inputs_and_the_whole_A_as_shortfall(method):
    out = BoundedBetaGamma(3, 1.0, 1.0, 0.2, 1.0, method=method)(np.zeros((3, 2)), np.zeros(3), 0.5)
    assert not out.feasible and out.shortfall == 0.5
    np.testing.assert_array_equal(out.du, 0.0)
    np.testing.assert_array_equal(out.domega, 0.0)


def test_program_is_dpp_and_built_once():
    s = BoundedBetaGamma(4, 1.0, 1.0, 0.2, 1.0, method="cvxpy")
    problem = s.program.problem
    assert problem.is_dpp()
    for seed in range(3):
        b, g, A = _problem(seed, n=4)
        s(b, g, 0.1 * abs(A))
        assert s.program.problem is problem
    assert s.last is not None and s.last.solve_seconds > 0


@pytest.mark.parametrize("method", CONE_METHODS)
def test_per_robot_gains(method):
    b, g, A = _problem(7, n=3, scale=0.05)
    k_u = np.array([0.0, 1.0, 5.0])
    k_w = np.array([2.0, 0.0, 1.0])
    a = BoundedBetaGamma(3, k_u, k_w, 0.2, 0.5, method=method)(b, g, abs(A))
    e = bounded_inputs_exact(b, g, abs(A), k_u, k_w, 0.2, 0.5)
    np.testing.assert_allclose(a.du, e.du, atol=1e-7)
    _check_constraints(b, g, abs(A), e, k_u[:, None], k_w, 0.2, 0.5, "inequality")


# ---------------------------------------------------------------------- the three solvers
def _random_program(seed: int):
    """1-16 robots, integrals at a scale in 1e-3..1 (some robots' exactly zero), scalar or
    per-robot gains, limits or none, ``A`` anywhere in the reachable range and beyond it."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 17))
    scale = 10 ** rng.uniform(-3, 0)
    b = rng.normal(scale=scale, size=(n, 2))
    g = rng.normal(scale=scale, size=n)
    b[rng.random(n) < 0.15] = 0.0
    g[rng.random(n) < 0.15] = 0.0
    k_u = rng.uniform(0, 20, n) if rng.random() < 0.5 else float(rng.uniform(0, 20))
    k_w = float(rng.uniform(0, 20))
    u_max = None if rng.random() < 0.2 else float(10 ** rng.uniform(-2, 0.5))
    omega_max = None if rng.random() < 0.2 else float(10 ** rng.uniform(-1, 1))
    U, W = (math.inf if x is None else x for x in (u_max, omega_max))
    hi = achievable_range(b, g, np.broadcast_to(k_u, (n,)), np.full(n, k_w), U, W)[1]
    A = float(rng.uniform(-1.2, 1.2)) * (hi if math.isfinite(hi) else scale**2 * n)
    condition = "equality" if rng.random() < 0.5 else "inequality"
    return b, g, A, k_u, k_w, u_max, omega_max, condition


def _gap_tolerance(optimum) -> float:
    """Clarabel's stopping gap ``ε = tol_gap_abs + tol_gap_rel·f*`` on the objective
    ``f = Σ‖δu_i‖² + Σδω_i²``.  ``f`` is 2-strongly convex, so a point within ``ε`` of the
    optimal value lies within ``√ε`` of the minimiser: ``‖x − x*‖² ≤ ε``."""
    f = float((optimum.du**2).sum() + (optimum.domega**2).sum())
    return SOLVER_OPTIONS["tol_gap_abs"] + SOLVER_OPTIONS["tol_gap_rel"] * f


def _distance2(x, y) -> float:
    return float(((x.du - y.du) ** 2).sum() + ((x.domega - y.domega) ** 2).sum())


def _check_all(b, g, A, out, k_u, k_w, u_max, omega_max, condition):
    U, W = (math.inf if x is None else x for x in (u_max, omega_max))
    _check_constraints(b, g, A, out, np.broadcast_to(k_u, (len(g),))[:, None], k_w, U, W, condition)


@pytest.mark.parametrize("block", range(3))
def test_fast_solvers_agree_with_cvxpy_to_its_tolerance(block):
    """The exact dual (the default) and Clarabel's native API against the cvxpy formulation on
    150 seeded random programs: the same feasibility and reachable range, every constraint,
    and solutions within the solvers' gap tolerance of each other (``‖x − x_cvxpy‖² ≤ ε``).
    Over 2000 such programs the largest distance was 0.05 ε; cvxpy is the least accurate of
    the three where the inputs are small (its tolerances act on the unscaled objective)."""
    failures = 0
    for seed in range(50 * block, 50 * block + 50):
        b, g, A, k_u, k_w, u_max, omega_max, condition = problem = _random_program(seed)
        strategies = {m: BoundedBetaGamma(len(g), k_u, k_w, u_max, omega_max, condition, m) for m in METHODS}
        out = {m: s(b, g, A) for m, s in strategies.items()}
        ref = out["cvxpy"]
        eps = _gap_tolerance(out["exact"])
        failures += sum(s.cone_failures for s in strategies.values())
        for m in ("exact", "clarabel"):
            assert out[m].feasible == ref.feasible, (seed, m)
            assert out[m].achievable == ref.achievable
            assert _distance2(out[m], ref) <= eps, (seed, m, _distance2(out[m], ref) / eps)
            _check_all(b, g, A, out[m], *problem[3:])
    assert failures == 0  # the cone solvers' own solutions, not the exact dual's fallback


def _edge(name: str):
    b, g, _ = _problem(5, n=6, scale=0.02)
    k, U, W, condition = 10.0, 0.2, 3.0, "inequality"
    if name == "idle robots":
        b[[1, 4]], g[[1, 2]] = 0.0, 0.0
    k = 0.0 if name == "zero gains" else k
    U = None if name == "turn limit only" else U
    W = None if name == "speed limit only" else W
    lo, hi = achievable_range(b, g, np.full(6, k), np.full(6, k), U or math.inf, W or math.inf)
    A = {"A at the reachable maximum": hi, "A just above it": hi * (1 + 1e-9)}.get(name, 0.5 * hi)
    if name.startswith("equality"):
        condition = "equality"
        A = {"equality, A at the reachable minimum": lo, "equality, A below it": 1.5 * lo}.get(name, 0.5 * lo)
    if not math.isfinite(hi):
        A = 0.01
    return b, g, A, k, k, U, W, condition


EDGES = [
    "A at the reachable maximum", "A just above it", "equality, A at the reachable minimum", "equality, A below it",
    "equality, A negative and reachable", "idle robots", "zero gains", "speed limit only", "turn limit only",
]  # fmt: skip


@pytest.mark.parametrize("method", CONE_METHODS)
@pytest.mark.parametrize("name", EDGES)
def test_cone_solvers_agree_with_the_exact_dual_on_edge_cases(method, name):
    """The feasible set reduced to one point (``A`` on the edge of the reachable range), beyond
    it, robots with zero integrals, zero gains, one limit only."""
    b, g, A, k_u, k_w, u_max, omega_max, condition = problem = _edge(name)
    s = BoundedBetaGamma(6, k_u, k_w, u_max, omega_max, condition, method)
    out = s(b, g, A)
    exact = bounded_inputs_exact(*problem)
    assert s.cone_failures == 0
    assert out.feasible == exact.feasible
    assert _distance2(out, exact) <= _gap_tolerance(exact)
    atol = 1e-6 * min(x for x in (u_max, omega_max, 1.0) if x is not None)  # as at the paper's scale
    np.testing.assert_allclose(out.du, exact.du, atol=atol)
    np.testing.assert_allclose(out.domega, exact.domega, atol=atol)
    _check_all(b, g, A, out, *problem[3:])
    _check_all(b, g, A, exact, *problem[3:])


def test_native_clarabel_is_built_once_and_its_data_updated():
    s = BoundedBetaGamma(16, 10.0, 10.0, 0.2, 3.0, method="clarabel")
    for seed in range(5):
        b, g, _ = _problem(seed)
        hi = achievable_range(b, g, s.k_u, s.k_omega, 0.2, 3.0)[1]
        out = s(b, g, 0.5 * hi)
        assert _distance2(out, bounded_inputs_exact(b, g, 0.5 * hi, 10.0, 10.0, 0.2, 3.0)) <= 1e-10 * 0.2**2
    assert (s.cone_solves, s.cone_failures, s.program.builds, s.program.updates_data) == (5, 0, 1, True)


def test_native_clarabel_is_built_each_call_where_data_updates_are_refused(monkeypatch):
    import clarabel

    class NoUpdates:
        def __init__(self, *args):
            self._solver = clarabel.DefaultSolver(*args)

        def solve(self):
            return self._solver.solve()

        def is_data_update_allowed(self):
            return False

    s = BoundedBetaGamma(16, 10.0, 10.0, 0.2, 3.0, method="clarabel")
    monkeypatch.setattr(s.program, "_clarabel", SimpleNamespace(DefaultSolver=NoUpdates))
    for seed in range(3):
        b, g, A = _problem(seed)
        A = 0.3 * abs(A)
        exact = bounded_inputs_exact(b, g, A, 10.0, 10.0, 0.2, 3.0)
        assert _distance2(s(b, g, A), exact) <= _gap_tolerance(exact)
    assert (s.program.builds, s.program.updates_data, s.cone_failures) == (3, False, 0)


@pytest.mark.parametrize("method", CONE_METHODS)
def test_a_cone_solver_failure_falls_back_to_the_exact_dual(method, monkeypatch):
    s = BoundedBetaGamma(16, 10.0, 10.0, 0.2, 3.0, method=method)
    monkeypatch.setattr(s.program, "solve", lambda b, g, A: None)
    b, g, A = _problem(2)
    out = s(b, g, 0.3 * abs(A))
    exact = bounded_inputs_exact(b, g, 0.3 * abs(A), 10.0, 10.0, 0.2, 3.0)
    np.testing.assert_array_equal(out.du, exact.du)
    np.testing.assert_array_equal(out.domega, exact.domega)
    assert (s.cone_solves, s.cone_failures) == (1, 1) and out.feasible


def test_native_clarabel_meets_A_relative_to_its_size_with_tiny_limits():
    """Where cvxpy's absolute tolerances fail (``tests/verification/test_properties.py``, the xfail finding),
    the native program, written in units of the inputs' own scale, meets ``A``."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        n = int(rng.integers(1, 7))
        b, g = 1e-10 * rng.normal(size=(n, 2)), 1e-10 * rng.normal(size=n)
        A = abs(rng.normal()) * 1e-20 * n
        out = BoundedBetaGamma(n, 10.0, 10.0, 1e-7, 1e-7, method="clarabel")(b, g, A)
        exact = bounded_inputs_exact(b, g, A, 10.0, 10.0, 1e-7, 1e-7)
        assert out.feasible and abs(out.shortfall) <= 1e-6 * A  # the finding's criterion
        np.testing.assert_allclose(out.du, exact.du, atol=1e-6 * 1e-7)
        np.testing.assert_allclose(out.domega, exact.domega, atol=1e-6 * 1e-7)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"n": 0}, "n"),
        ({"n": 2.5}, "n"),
        ({"u_max": -0.1}, "u_max"),
        ({"u_max": 0.0}, "u_max"),
        ({"omega_max": -1.0}, "omega_max"),
        ({"omega_max": float("nan")}, "omega_max"),
        ({"k_u": -1.0}, "k_u"),
        ({"k_omega": [1.0, 2.0, 3.0]}, "k_omega"),
        ({"condition": "approximately"}, "condition"),
        ({"method": "gurobi"}, "method"),
    ],
)
def test_bad_arguments_are_refused_by_name(kwargs, name):
    args = {"n": 2, "k_u": 1.0, "k_omega": 1.0, "u_max": 0.2, "omega_max": 1.0, **kwargs}
    with pytest.raises(ParameterError) as exc:
        BoundedBetaGamma(**args)
    assert exc.value.name == name


@pytest.mark.parametrize("method", METHODS)
def test_bad_integrals_are_refused(method):
    s = BoundedBetaGamma(2, 1.0, 1.0, 0.2, 1.0, method=method)
    with pytest.raises(ParameterError, match="b, g"):
        s(np.zeros((3, 2)), np.zeros(2), 0.1)
    with pytest.raises(ParameterError, match="finite"):
        s(np.zeros((2, 2)), np.zeros(2), float("nan"))


def test_plugin_builds_the_strategy_from_the_scenario():
    sc = paper_scenario().with_values({"robots.u_max": 0.1, "controller.beta_gamma": "bounded"})
    factory = plugins.load("beta_gamma", "bounded")
    assert factory is bounded_strategy_for
    s = factory(sc)
    assert isinstance(s, BoundedBetaGamma)
    assert s.method == "exact" and s.program is None  # the fastest solver, exact
    assert (s.n, s.u_max, s.omega_max) == (16, 0.1, 3.0)
    assert np.all(s.k_u == 10.0)


def test_closed_loop_with_bounded_strategy_never_commands_beyond_the_limits():
    sc = paper_scenario(seed=2).with_values(
        {"robots.u_max": 0.1, "controller.beta_gamma": "bounded", "t_final": 1.0, "record_every": 1}
    )
    loop = ClosedLoop(sc)
    assert isinstance(loop.controller.strategy, BoundedBetaGamma)
    commanded, reported, applied = [], [], []

    def record(lp):
        commanded.append(lp.last.command.state.u.copy())
        reported.append(lp.last.command.state.shortfall)
        applied.append(lp.last.shortfall_applied)

    summary = loop.run(progress=False, callback=record).summary
    speeds = np.hypot(*np.concatenate(commanded).T)
    assert speeds.max() <= 0.1  # the commands themselves, before any saturation
    assert summary["saturated_fraction"] == 0
    assert summary["limits_binding_fraction"] > 0  # the paper scenario is limit-bound
    # nothing clipped: the shortfall the strategy reports is the one the robots apply
    assert len(applied) == sc.steps and max(reported) > 0
    np.testing.assert_allclose(applied, reported, rtol=1e-9)


def test_clipped_min_norm_hides_its_shortfall_which_the_loop_measures():
    sc = paper_scenario(seed=2).with_values({"robots.u_max": 0.1, "t_final": 0.2, "record_every": 1})
    ds = ClosedLoop(sc).run(progress=False).dataset
    ok = np.isfinite(ds["shortfall"].values)
    np.testing.assert_allclose(ds["shortfall"].values[ok], 0.0, atol=1e-9)  # min-norm meets A before clipping
    assert np.nanmin(ds["shortfall_applied"].values) > 0  # the clipping loses part of it


def test_unknown_strategy_is_refused_with_the_installed_names():
    with pytest.raises(ParameterError) as exc:
        paper_scenario().with_values({"controller.beta_gamma": "fastest"})
    assert exc.value.name == "controller.beta_gamma"
    assert "bounded" in str(exc.value)


def test_closed_loop_summary_is_the_same_with_every_solver():
    """A short run in which ``A`` is within the robots' reach at some steps (u_max = 40), so
    that the program is really solved: the same summary with each solver as with cvxpy's."""
    sc = paper_scenario(seed=1).with_values({"controller.beta_gamma": "bounded", "t_final": 0.3, "robots.u_max": 40.0})
    summaries, counts = {}, {}
    for method in METHODS:
        loop = ClosedLoop(sc)
        s = loop.controller.strategy
        loop.controller.strategy = BoundedBetaGamma(s.n, s.k_u, s.k_omega, s.u_max, s.omega_max, method=method)
        summaries[method] = loop.run(progress=False).summary
        counts[method] = (loop.controller.strategy.cone_solves, loop.controller.strategy.unreachable_solves)
    cone, unreachable = counts["cvxpy"]
    assert cone > 0 and unreachable > 0  # both kinds of steps
    assert counts["clarabel"] == counts["cvxpy"] and counts["exact"] == (0, unreachable)
    timing = {"wall_seconds", "steps_per_second"}
    ref = summaries["cvxpy"]
    for method in ("exact", "clarabel"):
        for key, value in ref.items():
            if key in timing or not isinstance(value, int | float):
                continue
            np.testing.assert_allclose(summaries[method][key], value, rtol=1e-6, atol=1e-12, err_msg=f"{method} {key}")
