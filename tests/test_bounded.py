"""The bounded β/γ program (analysis.bounded): constraints, closed forms, shortfall, plugin."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.bounded import (
    BoundedBetaGamma,
    achievable_range,
    bounded_inputs_exact,
    bounded_strategy_for,
)
from meanfield import ClosedLoop, MinimumNormBetaGamma, ParameterError, paper_scenario, plugins

METHODS = ("clarabel", "exact")


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


@pytest.mark.parametrize("condition", ["inequality", "equality"])
@pytest.mark.parametrize("seed", range(8))
def test_clarabel_agrees_with_the_exact_dual(condition, seed):
    """Two independent solutions of one program: an interior-point solver and the 1-D dual."""
    b, g, A = _problem(seed)
    A *= 0.3  # mostly reachable, so the cone program is really solved
    a = BoundedBetaGamma(16, 10.0, 10.0, 0.2, 3.0, condition=condition)(b, g, A)
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
    s = BoundedBetaGamma(4, 1.0, 1.0, 0.2, 1.0)
    problem = s._problem
    assert problem.is_dpp()
    for seed in range(3):
        b, g, A = _problem(seed, n=4)
        s(b, g, 0.1 * abs(A))
        assert s._problem is problem
    assert s.last is not None and s.last.solve_seconds > 0


def test_per_robot_gains():
    b, g, A = _problem(7, n=3, scale=0.05)
    k_u = np.array([0.0, 1.0, 5.0])
    k_w = np.array([2.0, 0.0, 1.0])
    a = BoundedBetaGamma(3, k_u, k_w, 0.2, 0.5)(b, g, abs(A))
    e = bounded_inputs_exact(b, g, abs(A), k_u, k_w, 0.2, 0.5)
    np.testing.assert_allclose(a.du, e.du, atol=1e-7)
    _check_constraints(b, g, abs(A), e, k_u[:, None], k_w, 0.2, 0.5, "inequality")


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
