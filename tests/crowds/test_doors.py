"""The inner doors' queues (docs page *Congestion*, "The doors' capacity";
:meth:`~meanfield.crowds.point_mass.PointMassEngine.cap_doors`,
:func:`~meanfield.crowds._point_mass_loops.hold_at_doors`).

* over every window of steps a door's net flow is at most ``1 + q τ`` (the bound the credit's bookkeeping
  gives: the credit carried into a window is at most one person), and with a queue always at it exactly ``q τ``
  within one person, with and without noise;
* the nearest to the door passes first, the held stay where their step started and pass first at the next
  step that crosses; a step back through the door one last passed is free and gives its place back;
* the compiled queues equal their numpy twin to the last bit;
* the door models that cap the exits cap the plan's doors at ``q_max`` per metre; the count does not.
"""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from meanfield._compiled import core as compiled
from meanfield.crowds.congestion import Linear
from meanfield.errors import ParameterError


def corridor(n, sigma, capacity, seed=0):
    """A 4 m × 2 m corridor cut across at x = 2 by a door (its whole width), ``n`` people at x < 2, capped."""
    import shapely

    from meanfield.crowds.point_mass import PointMassEngine
    from meanfield.geometry.plan import Plan

    plan = Plan(shapely.box(0.0, 0.0, 4.0, 2.0), doors=[((2.0, 0.0), (2.0, 2.0))])
    rng = np.random.default_rng(seed)
    x = np.column_stack([rng.uniform(0.2, 1.99, n), rng.uniform(0.1, 1.9, n)])
    engine = PointMassEngine(x, plan, sigma, rng)
    engine.cap_doors(np.array([capacity]))
    return engine


@pytest.mark.parametrize("capacity", [3.0, 1.2, 0.5])
@pytest.mark.parametrize("sigma", [0.0, 0.05])
def test_a_door_passes_its_capacity_and_at_most_one_person_more(capacity, sigma):
    engine = corridor(60, sigma, capacity)
    drift = np.tile([0.5, 0.0], (engine.n, 1))
    dt, steps = 0.05, 200
    beyond = [0]
    for step in range(1, steps + 1):
        engine.step(drift, (step - 1) * dt, dt)
        beyond.append(int(np.count_nonzero(engine.positions[:, 0] > 2.0)))
    beyond = np.asarray(beyond)
    for a in range(steps):  # every window [a, b] of whole steps: the net flow
        passed = beyond[a + 1 :] - beyond[a]
        tau = dt * np.arange(1, steps - a + 1)
        assert np.all(passed <= 1.0 + capacity * tau + 1e-9)
    first, last = 60, 200  # (the queue has formed by 3 s, and 60 people outlast 7 s at 3 persons/s)
    assert beyond[last] < 60
    assert abs((beyond[last] - beyond[first]) - capacity * dt * (last - first)) <= 1.0 + 1e-9


def test_the_nearest_passes_first_and_the_held_wait_where_they_were():
    engine = corridor(3, 0.0, 0.5)
    x = np.array([[1.9, 1.0], [1.95, 0.5], [1.8, 1.5]])
    engine.positions[:] = x
    engine.step(np.tile([10.0, 0.0], (3, 1)), 0.0, 0.05)  # all three would cross
    assert (engine.positions[:, 0] > 2.0).tolist() == [False, True, False]  # human 1 was nearest
    np.testing.assert_array_equal(engine.positions[[0, 2]], x[[0, 2]])
    for step in range(1, 39):  # 1.9 s later: not yet a whole credit; they keep trying
        engine.step(np.tile([10.0, 0.0], (3, 1)) * [[1], [0], [1]], step * 0.05, 0.05)
    np.testing.assert_array_equal(engine.positions[[0, 2]], x[[0, 2]])
    for step in (39, 40):  # 2 s after the first: the next, the nearest of the two
        engine.step(np.tile([10.0, 0.0], (3, 1)) * [[1], [0], [1]], step * 0.05, 0.05)
    assert (engine.positions[:, 0] > 2.0).tolist() == [True, True, False]


def test_a_step_back_through_the_door_is_free_and_gives_its_place_back():
    from meanfield.crowds._point_mass_loops import hold_at_doors

    doors = np.array([[[2.0, 0.0], [2.0, 2.0]]])
    q, dt = np.array([1.0]), 0.05
    waiting, last, sign = np.full(2, -1), np.full(2, -1), np.zeros(2, dtype=np.int8)
    idx = np.array([0, 1])
    start = np.array([[1.95, 1.0], [1.5, 1.0]])
    x = start + [[0.1, 0.0], [0.0, 0.0]]  # human 0 crosses forward
    credit = hold_at_doors(idx, start, x, doors, q, np.array([1.0]), waiting, last, sign, dt)
    assert credit[0] == pytest.approx(1.0 + q[0] * dt - 1.0) and last.tolist() == [0, -1]
    back = x.copy()
    x = back - [[0.1, 0.0], [0.0, 0.0]]  # and back: its place is given back, it no longer counts as through
    credit = hold_at_doors(idx, back, x, doors, q, credit, waiting, last, sign, dt)
    assert credit[0] == pytest.approx(min(q[0] * dt, 1.0) + q[0] * dt + 1.0) and last.tolist() == [-1, -1]
    start = x.copy()  # both cross now: the door is as if nobody had passed, one person's credit (an idle door's)
    x = start + [[0.1, 0.0], [0.6, 0.0]]
    credit = hold_at_doors(idx, start, x, doors, q, credit, waiting, last, sign, dt)
    assert last.tolist() == [0, -1] and waiting.tolist() == [-1, 0]  # the nearest passes, the other waits
    np.testing.assert_array_equal(x[1], start[1])
    assert credit[0] == pytest.approx(q[0] * dt)


def door_step(seed):
    """One step of 300 humans at four doors, some waiting, some stepping back, some capped out."""
    rng = np.random.default_rng(seed)
    n, m = 400, 300
    idx = np.sort(rng.choice(n, m, replace=False))
    doors = np.array([[[1.0, 0.0], [1.0, 2.0]], [[3.0, 0.0], [3.0, 2.0]], [[0.0, 1.0], [4.0, 1.0]],
                      [[2.0, 0.5], [2.5, 0.5]]])  # fmt: skip
    previous = rng.uniform([0.0, 0.0], [4.0, 2.0], (n, 2))
    x = previous + rng.normal(0.0, 0.3, (n, 2))
    waiting = np.where(rng.random(n) < 0.2, rng.integers(0, 4, n), -1).astype(np.intp)
    last = np.where(rng.random(n) < 0.5, rng.integers(0, 4, n), -1).astype(np.intp)
    sign = rng.choice(np.array([-1, 1], dtype=np.int8), n)
    credit = rng.uniform(0.0, 2.5, 4)
    previous[idx[3]] = previous[idx[4]]  # two equally near: the first of them first
    x[idx[3]] = x[idx[4]]
    return idx, previous, x, doors, np.array([1.8, 3.6, 0.9, 2.0]), credit, waiting, last, sign, 0.05


@pytest.mark.parametrize("seed", range(8))
def test_the_compiled_door_queues_are_their_numpy_twin_s(seed):
    from meanfield.crowds._point_mass_loops import hold_at_doors

    runs = []
    for path in ("compiled", "numpy"):
        idx, previous, x, doors, q, credit, waiting, last, sign, dt = door_step(seed)
        before = x.copy()
        with compiled.numpy_path() if path == "numpy" else contextlib.nullcontext():
            out = hold_at_doors(idx, previous, x, doors, q, credit, waiting, last, sign, dt)
        runs.append((x, out, waiting, last, sign))
    assert hold_at_doors._ready or not compiled.enabled()  # (the compiled path ran)
    assert not np.array_equal(runs[0][0], before) and np.any(runs[0][2] >= 0)  # (some were held)
    for a, b in zip(*runs, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)


def test_a_door_capacity_that_means_nothing_is_refused():
    engine = corridor(5, 0.0, 1.0)
    for bad in ([0.0], [-1.0], [np.inf], [1.0, 2.0]):
        with pytest.raises(ParameterError) as exc:
            engine.cap_doors(np.array(bad))
        assert exc.value.name == "door capacity"


@pytest.mark.parametrize("model", ["headway", "forward-cell"])
def test_the_door_models_that_cap_the_exits_cap_the_plan_s_doors(model):
    from meanfield.scenarios.scenario import builtin_scenarios
    from meanfield.simulation.loop import ClosedLoop

    office = builtin_scenarios()["office"](seed=0).with_values({"t_final": 0.2, "crowd.guidance": "geodesic"})
    engine = ClosedLoop(office.with_values({"crowd.door_model": model})).crowd.engine
    np.testing.assert_allclose(engine._door_capacity, np.full(8, Linear().capacity()[0] * 1.0))  # 1 m doors
    counted = ClosedLoop(office.with_values({"crowd.door_model": "count"})).crowd.engine
    assert counted._door_capacity is None
