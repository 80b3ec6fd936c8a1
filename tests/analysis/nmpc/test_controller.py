"""The NMPC controller (analysis.nmpc.controller): the plugin, the limits every step, determinism,
a plan better than standing still, spread solves, the paper scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.nmpc import NMPCController, nmpc_controller_for
from meanfield import ClosedLoop, Domain, ParameterError, paper_scenario, plugins
from tests.analysis.nmpc.conftest import controller_for, small_scenario


def test_non_box_domain_is_refused():
    sc = (
        paper_scenario()
        .replace(domain=Domain.disk(0.5, (0.5, 0.5)))
        .with_values({"controller.kind": "nmpc", "target.center": [0.5, 0.5]})
    )
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)
    assert exc.value.name == "domain"


def test_plugin_is_the_factory():
    assert plugins.load("controller", "nmpc") is nmpc_controller_for
    assert "nmpc" in plugins.available("controller")


# the real-time solver (the default), with move blocking and one QP per period, and IPOPT
SOLVERS = [{}, {"spread": False}, {"blocks": [1, 2], "max_iter": 1}, {"solver": "ipopt"}]
SOLVER_IDS = ["sqp-defaults", "sqp-whole-solves", "sqp-blocked-1-iteration", "ipopt"]


@pytest.mark.parametrize("options", SOLVERS, ids=SOLVER_IDS)
def test_inputs_respect_the_limits_every_step(options):
    loop = ClosedLoop(small_scenario(**options))
    c = loop.controller
    assert isinstance(c, NMPCController)
    u_max, w_max = loop.robots.u_max, loop.robots.omega_max
    seen = []

    def check(lp):
        s = lp.last.command.state
        assert np.all(np.hypot(s.u[:, 0], s.u[:, 1]) <= u_max * (1 + 1e-6))
        assert np.all(np.abs(s.omega) <= w_max)
        assert math.isnan(s.shortfall) and np.isfinite(s.A)  # diagnostics from backstepping
        seen.append(np.hypot(s.u[:, 0], s.u[:, 1]).max())

    result = loop.run(progress=False, callback=check)
    assert result.summary["status"] == "completed" and len(seen) == 10
    assert result.summary["saturated_fraction"] == 0.0  # nothing left for the loop to saturate
    assert max(seen) > 0.9 * u_max  # the limit binds: the test is not vacuous
    solves = 5 if not c.options.spread else 3 if c.options.iteration_limit == 1 else 1  # (dt = period / 2)
    assert len(c.stats) >= solves and all(s["seconds"] > 0 for s in c.stats)
    for s in c.stats:  # the solver's own solution, before projection
        assert s["max_speed_solver"] <= u_max * (1 + 1e-6) and s["max_turn_rate_solver"] <= w_max * (1 + 1e-6)
    assert len(c.backstepping_seconds) == result.summary["steps"] + 1  # + the final frame's diagnostics


@pytest.mark.parametrize("options", SOLVERS, ids=SOLVER_IDS)
def test_compiled_function_is_deterministic(small_loop, options):
    c = controller_for(small_loop, **options)
    rho_c = c.restrict(small_loop.density)
    pos, heads = small_loop.robots.positions.copy(), small_loop.robots.headings.copy()
    guess = c.initial_guess(rho_c, pos, heads)
    a = c.solve(rho_c, pos, heads, guess)
    b = c.solve(rho_c, pos, heads, guess)
    assert a.status == b.status and a.iterations == b.iterations
    for name in ("u", "omega", "positions", "headings", "rho"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.cost == b.cost


@pytest.mark.parametrize("options", [{"max_iter": 100}, {"solver": "ipopt"}], ids=["sqp", "ipopt"])
def test_plan_improves_its_predicted_cost_over_zero_input(small_loop, options):
    """Crowd on the left, target on the right, robots at the crowd: over a 1.5 s horizon the
    plan must beat standing still, and turn the signs towards the target."""
    lp = small_loop
    c = controller_for(lp, **options)
    rho_c = c.restrict(lp.crowd.density())
    pos, heads = lp.robots.positions.copy(), lp.robots.headings.copy()
    plan = c.solve(rho_c, pos, heads)
    assert plan.success, plan.status
    H, n = c.options.horizon, c.n
    zero = c.predicted_cost(rho_c, pos, heads, np.zeros((H, n, 2)), np.zeros((H, n)))
    planned = c.predicted_cost(rho_c, pos, heads, plan.u, plan.omega)
    # the compiled problem and the numerical rollout are the same model
    assert planned == pytest.approx(plan.cost, rel=1e-6)
    np.testing.assert_allclose(plan.rho, c.model.predict(rho_c, pos, heads, plan.u, plan.omega)[0], atol=1e-10)
    assert planned < 0.9 * zero
    vx, _ = c.model.face_velocity(plan.positions[-1], plan.headings[-1])
    vx0, _ = c.model.face_velocity(pos, heads)
    assert vx.sum() > max(vx0.sum(), 0.0)  # the field now points towards the target (+x)


def test_a_spread_solve_gives_the_plan_of_the_whole_solve_applied_from_its_start(small_loop):
    """``spread``: the robots hold still until the first plan, one slice per control step, and
    the plan is the one solving at once gives, applied from the time the solve started."""
    obs = ClosedLoop(small_scenario()).observe()
    whole = controller_for(small_loop, step=0.1, period=0.6, spread=False)
    whole.robot_inputs(obs.density, obs.field, 0.0)
    spread = controller_for(small_loop, step=0.1, period=0.6)  # spread: the default
    inputs = [spread.robot_inputs(obs.density, obs.field, 0.05 * i) for i in range(12)]
    first = spread.stats[0]
    assert first["slices"] >= 3 and first["t"] == 0.0 and first["slowest_slice"] <= first["seconds"]
    for state in inputs[: first["slices"] - 1]:  # before the plan is adopted
        assert not state.u.any() and not state.omega.any()
    for name in ("u", "omega", "positions", "headings", "rho"):
        assert np.array_equal(getattr(spread.plan, name), getattr(whole.plan, name)), name
    assert len(spread.stats) == 1  # the next solve is due at t = 0.6
    for i in range(first["slices"] - 1, 12):  # index by the time since the solve started (step 0.1)
        assert np.array_equal(inputs[i].u, whole.plan.u[min(int(0.05 * i / 0.1 + 1e-9), 2)])


def test_paper_scenario_runs_with_nmpc():
    sc = paper_scenario().with_values(
        {"controller.kind": "nmpc", "t_final": 0.2, "controller.options.nmpc.horizon": 2,
         "controller.options.nmpc.cells": 6}  # fmt: skip
    )
    loop = ClosedLoop(sc)
    result = loop.run(progress=False)
    assert result.summary["status"] == "completed"
    assert result.summary["max_robot_speed"] <= 0.2 * (1 + 1e-12)
    assert np.isfinite(result.dataset["V2"].values[1:]).all()
    summary = loop.controller.summary()
    assert summary["solves"] >= 1 and summary["ratio_solve_over_backstepping"] > 0
