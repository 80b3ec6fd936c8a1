"""Exits balanced by their capacities (issue 31, item 2): the clearing time (B1), the offsets against a brute-force
optimum, the potential's field, closed exits, Step II's identity on the balanced potential, bad options."""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, GaussianKernel, Grid, NavigationField, ParameterError
from meanfield.controllers.backstepping import MinimumNormBetaGamma, SaturatingAlpha
from meanfield.controllers.evacuation import EvacuationController
from meanfield.controllers.exit_assignment import ExitAssignment, clearing_time
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import ExitEikonal
from meanfield.geometry.target import gaussian_target
from meanfield.scenarios.scenario import builtin_scenarios
from tests.conftest import lyapunov_v2, smooth_density

EPS = 1e-30  # complex step


def test_the_clearing_time_of_a_point_queue():
    # three persons at 0, 1, 2 s through 1 person/s: the queue holds them back to 3 s
    assert clearing_time(np.array([2.0, 0.0, 1.0]), np.ones(3), 1.0) == pytest.approx(3.0)
    # a latecomer after the queue has cleared leaves at its arrival plus its own passage
    assert clearing_time(np.array([0.0, 10.0]), np.array([2.0, 1.0]), 1.0) == pytest.approx(11.0)
    # the last half person is "everyone out": a quarter person far away does not count
    assert clearing_time(np.array([0.0, 50.0]), np.array([4.0, 0.25]), 2.0) == pytest.approx(2.125)
    assert clearing_time(np.array([1.0]), np.array([0.4]), 1.0) == 0.0


def _corridor(n_cells=60, length=30.0, people=200, centre=6.0, std=3.0, widths=(2.0, 2.0)):
    """A straight corridor, exits at both ends: d_0 = x, d_1 = L − x; the crowd a normal law round ``centre``."""
    x = (np.arange(n_cells) + 0.5) * length / n_cells
    dist = np.stack([x, length - x])[:, :, None]  # (K, nx, 1)
    volume = np.full((n_cells, 1), length / n_cells)
    rho = np.exp(-0.5 * ((x - centre) / std) ** 2)[:, None]
    rho /= (rho * volume).sum()
    return ExitAssignment(dist, np.array(widths), volume, people, 1.34, 1.8), rho, x


def test_the_offsets_reach_the_best_watershed_found_by_brute_force():
    """In a corridor every assignment that a watershed can make is a split point: the iteration's makespan is
    within half a cell's walk of the best split's."""
    a, rho, x = _corridor()
    persons = a.people * rho[:, 0] * a.volume
    best = min(
        max(clearing_time(a.arrival[0, :s], persons[:s], a.capacity[0]),
            clearing_time(a.arrival[1, s:], persons[s:], a.capacity[1]))  # fmt: skip
        for s in range(len(x) + 1)
    )
    tau = a.solve(rho)
    assert tau[0] > 0 and tau[1] == 0  # the crowded west exit carries the wait
    nearest = float(a.clearing_times(persons, np.zeros(2)).max())
    assert a.makespan <= best + 0.5 * (x[1] - x[0]) / 1.34 + 1e-9
    assert a.makespan < 0.8 * nearest  # here balancing pays: the nearest exits' makespan is 1.25 times longer
    assert (a.assign(tau)[x > 20] == 1).all() and (a.assign(tau)[x < 3] == 0).all()


def test_balancing_that_does_not_pay_keeps_everyone_on_the_nearest_exit():
    a, rho, _ = _corridor(people=1)  # one person: no queue worth balancing
    assert (a.solve(rho) == 0).all()
    a, rho, _ = _corridor(centre=15.0, std=4.0)  # a symmetric crowd: the nearest exits are balanced already
    assert np.abs(a.solve(rho)).max() < 1.0


def test_a_closed_exit_takes_no_one():
    a, rho, _ = _corridor()
    a.open = np.array([False, True])
    a.solve(rho)
    assert (a.assign(a.offsets) == 1).all()
    phi = a.potential()
    np.testing.assert_allclose(phi, a.distances[1], rtol=0, atol=1e-12)


def _hall(**values):
    coverage = {"controller.kind": "coverage", "view.memory": "none",
                "controller.options.coverage.potential": "balanced"}  # fmt: skip
    return builtin_scenarios()["hall-crowded-west"](seed=0).with_values({"t_final": 0.2, **coverage, **values})


def test_on_the_crowded_hall_the_signs_field_sends_the_east_of_the_crowd_east():
    loop = ClosedLoop(_hall())
    law = loop.controller.law
    assert isinstance(law, EvacuationController) and law.potential == "balanced"
    loop.step()
    tau = law.assignment.offsets
    assert tau[0] > 5.0 and tau[1] == 0.0  # the west door, where everyone stands, waits
    gx, _ = loop.grid.to_cells(law.grad_phi)
    X, Y = loop.grid.centers
    row = np.abs(Y - 10.25) < 0.3
    assert (gx[row & (X < 2.5)] > 0).all()  # by the west door: down φ is west
    assert (gx[row & (X > 12.0) & (X < 28.0)] < 0).all()  # east of the crowd's middle: down φ is east
    s = loop.controller.summary()
    assert s["exit_offsets"] == pytest.approx(list(tau)) and s["balanced_makespan"] > 0


def test_closing_an_exit_balances_again_over_the_open_ones():
    loop = ClosedLoop(_hall(events=[{"time": 0.1, "close_exit": 1}], t_final=0.3))
    loop.run(progress=False)
    law = loop.controller.law
    assert law.assignment.open.tolist() == [True, False]
    np.testing.assert_allclose(law.grad_phi[0], loop.grid.gradient(np.where(np.isfinite(law.assignment.distances[0]),
                               law.assignment.distances[0], 0.0))[0], rtol=0, atol=1e-12)  # fmt: skip


def test_step_two_identity_holds_for_the_balanced_potential_between_two_solutions():
    """dV₂/dt = S − Σ k_u|b_i|² − Σ k_ω g_i² by complex-step differentiation, with φ solved at this instant."""
    room = Domain.box(1.0, 1.0, exits=[((0.0, 0.4), (0.0, 0.6)), ((1.0, 0.4), (1.0, 0.6))])
    grid = Grid(room, (20, 20))
    target = gaussian_target(grid, (0.2, 0.5), 0.15)
    segs = exit_segments(room)
    eikonal = ExitEikonal(grid, segs)
    distances = np.stack([ExitEikonal(grid, segs[k : k + 1]).distance for k in range(2)])
    assignment = ExitAssignment(distances, np.full(2, 0.2), grid.volume, 400, 0.3, 1.8)
    ctrl = EvacuationController(
        grid, target, 0.003, SaturatingAlpha(0.1, 0.2), 1.0, 2.0, MinimumNormBetaGamma(), None, "model",
        phi=eikonal.distance, v_free=0.3, rho_max=4.0, potential="balanced", eikonal=eikonal, assignment=assignment,
    )  # fmt: skip
    kernel = GaussianKernel(0.5, 0.03)
    X, _ = grid.centers
    rho = smooth_density(grid) * np.exp(-((X - 0.25) ** 2) / 0.02) + 0.05
    rho /= grid.integrate(rho)
    rng = np.random.default_rng(2)
    R, th = rng.uniform(0.1, 0.9, (5, 2)), rng.uniform(0, 2 * np.pi, 5)
    field = NavigationField(kernel, grid, R, th)
    st = ctrl.robot_inputs(rho, field)
    assert assignment.offsets[0] > 0  # balanced, not the distance
    rho_dot = ctrl.density_rate(rho, field.velocity())

    dV = lyapunov_v2(ctrl, kernel, rho + 1j * EPS * rho_dot, R + 1j * EPS * st.u, th + 1j * EPS * st.omega).imag / EPS
    action = (st.b**2).sum() + 2.0 * (st.g**2).sum()
    expected = -st.dissipation - action
    scale = abs(st.dissipation) + abs(st.A) + action
    assert abs(dV - expected) <= 1e-9 * scale, (dV, expected)


@pytest.mark.parametrize(
    ("key", "value"),
    [("specific_flow", 0.0), ("specific_flow", "fast"), ("rebalance_period", -1.0), ("potential", "b")],
)
def test_bad_balance_options_are_refused_naming_them(key, value):
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(_hall(**{f"controller.options.coverage.{key}": value}))
    assert exc.value.name == f"controller.options.coverage.{key}"


def test_the_rebalance_period_sets_how_often_the_offsets_are_solved():
    loop = ClosedLoop(_hall(**{"controller.options.coverage.rebalance_period": 0.25, "t_final": 1.0}))
    law = loop.controller.law
    calls = []
    solve = law.assignment.solve
    law.assignment.solve = lambda rho: calls.append(loop.t) or solve(rho)
    loop.run(progress=False)
    assert calls == pytest.approx([0.0, 0.3, 0.6, 0.9]) and math.isclose(law.rebalance_period, 0.25)


def test_the_balanced_signs_send_part_of_the_crowded_hall_to_the_idle_door():
    """Point masses by the west door, 8 robots with coverage: with the balanced potential people leave by the east
    door too; with the nearest-exit potential nearly nobody does (the informed crowd: nobody)."""
    out = {}
    for potential in ("balanced", "distance"):
        sc = builtin_scenarios()["hall-crowded-west"](seed=1).with_values(
            {"controller.kind": "coverage", "view.memory": "none", "controller.options.coverage.potential": potential,
             "t_final": 60.0}  # fmt: skip
        )
        out[potential] = ClosedLoop(sc).run(progress=False).summary["evacuated_per_exit"]
    assert out["balanced"][1] >= 40 and out["distance"][1] <= 5, out


@pytest.mark.parametrize("seed", range(4))
def test_the_sorted_queues_give_each_exit_s_clearing_time_to_the_bit(seed):
    """:class:`ArrivalOrder` sorts each exit's cells once and reads (B1) over the whole row, the cells assigned
    elsewhere holding nobody: the same ``T_k`` as :func:`clearing_time` of the exit's own cells, and the same last
    counted arrival, on the compiled loop and on its numpy twin (ties of arrival, empty exits and unreachable
    cells included)."""
    from meanfield._compiled import core as compiled
    from meanfield.controllers.exit_assignment import LAST_PERSON, ArrivalOrder

    rng = np.random.default_rng(seed)
    k_exits, m = 3, 400
    arrival = np.round(rng.uniform(0, 30, (k_exits, m)), 1)  # rounded: many ties
    arrival[2, rng.uniform(size=m) < 0.1] = np.inf  # cells exit 2 cannot be reached from
    persons = np.where(rng.uniform(size=m) < 0.3, 0.0, rng.exponential(0.4, m))
    exit_of = rng.integers(0, 2 if seed == 3 else k_exits, m)  # seed 3: exit 2 takes nobody
    exit_of[(exit_of == 2) & ~np.isfinite(arrival[2])] = 0
    capacity = np.array([1.8, 3.6, 0.9])
    queues = ArrivalOrder(arrival)
    exits = np.arange(k_exits)
    fast = queues.times(exit_of, persons, capacity, exits, LAST_PERSON)
    with compiled.numpy_path():
        twin = queues.times(exit_of, persons, capacity, exits, LAST_PERSON)
    for k in range(k_exits):
        mine = exit_of == k
        expected = clearing_time(arrival[k, mine], persons[mine], capacity[k])
        assert fast[0][k] == expected and twin[0][k] == expected
        a, p = arrival[k, mine], persons[mine]
        order = np.argsort(a, kind="stable")
        due = np.cumsum(p[order][::-1])[::-1] >= LAST_PERSON
        assert fast[1][k] == twin[1][k] == (a[order][due].max() if due.any() else 0.0)
    assert (fast[0][:2] > 0).all() and (fast[0][2] == 0.0) == (seed == 3)
    only = queues.times(exit_of, persons, capacity, np.array([1]), LAST_PERSON)  # the exits asked for alone
    assert only[0][1] == fast[0][1] and only[0][0] == only[0][2] == 0.0


def test_each_cell_s_exit_is_np_argmin_s_to_the_bit():
    """:func:`~meanfield.controllers._queue_loops.assign_exits` (the assignment of eq. (B1) in one compiled pass) is
    ``np.argmin(a + τ)`` along the exits, its numpy twin: ties to the first exit, cells no exit reaches (``inf``
    everywhere: exit 0), closed exits (``τ = inf``), a NaN to the first; and :meth:`ExitAssignment.assign` is it over
    the open exits."""
    from meanfield._compiled import core as compiled
    from meanfield.controllers._queue_loops import assign_exits

    rng = np.random.default_rng(2)
    k_exits, m = 4, 600
    arrival = np.round(rng.uniform(0, 30, (k_exits, m)), 0)  # rounded: many ties
    arrival[:, :5] = np.inf  # no exit reaches these
    arrival[2, 5:40] = np.inf
    arrival[1, 40] = arrival[3, 41] = arrival[0, 42] = np.nan
    for tau in (np.zeros(k_exits), np.array([0.5, 0.0, np.inf, 2.0]), np.round(rng.uniform(0, 5, k_exits))):
        expected = np.argmin(arrival + tau[:, None], axis=0)
        fast = assign_exits(arrival, tau, np.empty(m, np.intp))
        with compiled.numpy_path():
            twin = assign_exits(arrival, tau, np.empty(m, np.intp))
        np.testing.assert_array_equal(fast, expected)
        np.testing.assert_array_equal(twin, expected)
    assert assign_exits._ready or not compiled.enabled()
    hall = builtin_scenarios()["hall"](seed=0)
    loop = ClosedLoop(hall)
    a = loop.controller.assignment
    a.open = np.array([True, False, True, True])
    tau = np.array([1.0, 0.0, 3.0, 0.5])
    expected = np.argmin(a.arrival + np.where(a.open, tau, np.inf)[:, None], axis=0)
    np.testing.assert_array_equal(a.assign(tau), expected)
    assert 1 not in a.assign(tau)


@pytest.mark.parametrize("seed", range(3))
def test_a_pass_of_the_price_iteration_is_the_assignment_then_its_clearing_times(seed):
    """:func:`~meanfield.controllers._queue_loops.assigned_clearing_times` (one compiled call per pass of the price
    iteration) gives the exits of :func:`assign_exits` and the clearing times of :func:`clearing_times` on them, to the
    bit, compiled and on its numpy twin, with a closed exit and cells no exit reaches."""
    from meanfield._compiled import core as compiled
    from meanfield.controllers._queue_loops import assign_exits, assigned_clearing_times, clearing_times
    from meanfield.controllers.exit_assignment import LAST_PERSON, ArrivalOrder

    rng = np.random.default_rng(seed)
    k_exits, m = 3, 500
    arrival = np.round(rng.uniform(0, 30, (k_exits, m)), 1)
    arrival[2, rng.uniform(size=m) < 0.1] = np.inf
    persons = np.where(rng.uniform(size=m) < 0.3, 0.0, rng.exponential(0.4, m))
    capacity = np.array([1.8, 3.6, 0.9])
    tau = np.array([0.0, rng.uniform(0, 5), np.inf if seed == 2 else rng.uniform(0, 5)])  # seed 2: exit 2 closed
    exits = np.array([0, 1]) if seed == 2 else np.arange(k_exits)
    queues = ArrivalOrder(arrival)
    exit_of = assign_exits(arrival, tau, np.empty(m, np.intp))
    expected = clearing_times(queues.order, queues.arrival, exit_of, persons, capacity, exits, LAST_PERSON,
                              np.empty(k_exits), np.empty(k_exits))  # fmt: skip
    for twin in (False, True):
        with compiled.numpy_path() if twin else contextlib.nullcontext():
            out = np.empty(m, np.intp)
            got = assigned_clearing_times(arrival, tau, queues.order, queues.arrival, persons, capacity, exits,
                                          LAST_PERSON, out, np.empty(k_exits), np.empty(k_exits))  # fmt: skip
        np.testing.assert_array_equal(out, exit_of)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])
    assert assigned_clearing_times._ready or not compiled.enabled()


@pytest.mark.parametrize("closed", [None, 1])
def test_the_price_iteration_in_one_call_is_its_numpy_twin_to_the_bit(closed):
    """:func:`~meanfield.controllers._queue_loops.price_iteration` (the passes of :meth:`ExitAssignment.solve` in one
    compiled call, the mean summed as ``np.mean`` does) against its twin, the passes as the solution ran them before:
    the same least makespan, its offsets and the last pass's, on the crowded hall with its exits open or one closed."""
    from meanfield._compiled import core as compiled
    from meanfield.controllers._queue_loops import price_iteration
    from meanfield.controllers.exit_assignment import ITERATIONS, LAST_PERSON

    loop = ClosedLoop(builtin_scenarios()["hall-crowded-west"](seed=1))
    loop.step()
    a = loop.controller.assignment
    if closed is not None:
        a.open = np.arange(len(a.capacity)) != closed
    persons = a.people * np.maximum(np.real(loop.density)[a.active], 0.0) * a.volume
    k, m = a.arrival.shape
    exits = np.flatnonzero(a.open)
    out = {}
    for twin in (False, True):
        tau, best_tau = np.where(a.open, np.linspace(0.0, 3.0, k), 0.0), np.empty(k)
        with compiled.numpy_path() if twin else contextlib.nullcontext():
            best = price_iteration(a.arrival, a.open, tau, ITERATIONS, a._order.order, a._order.arrival, persons,
                                   np.asarray(a.capacity, float), exits, LAST_PERSON / len(exits),
                                   np.empty(m, np.intp), np.empty(k), np.empty(k), np.empty(k), best_tau)  # fmt: skip
        out[twin] = best, best_tau, tau
    assert price_iteration._ready or not compiled.enabled()
    assert out[False][0] == out[True][0] and np.isfinite(out[False][0])
    np.testing.assert_array_equal(out[False][1], out[True][1])
    np.testing.assert_array_equal(out[False][2], out[True][2])
    if closed is not None:
        assert out[False][1][closed] == 0.0 and out[False][2][closed] == 0.0
