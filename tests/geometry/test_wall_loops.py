"""A plan's walls, compiled (meanfield.geometry._wall_loops): the same walls and points as the numpy twins.

What is checked, and how:

* each compiled loop against its numpy twin on random steps in the office and in an L with a
  pillar, short steps (the cell's walls) and long ones (every wall), few steps (the twin's
  full test) and many (its look-ups): the same wall hit, positions to 1e-12;
* exact answers: a step at a right angle into a wall, steps that bounce two to four times
  in a square (the unfolded path, folded back), a step through a corner (ties to the
  lowest wall, then the projection), a step that ends on a wall, a robot that stops or
  slides;
* properties (hypothesis): no reflected step ends inside a pillar or outside the plan, no
  robot's step crosses a wall, on both paths;
* ``use_compiled(False)`` and ``MEANFIELD_COMPILED=0`` run the numpy twins.
"""

from __future__ import annotations

import os
import subprocess
import sys
from contextlib import nullcontext

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meanfield._compiled import core as compiled
from meanfield.geometry._wall_loops import first_hits, reflect_steps, robot_steps
from meanfield.geometry.plan import Plan
from meanfield.geometry.walls import FULL_TEST_BELOW, segment_hits
from meanfield.scenarios.scenario import builtin_scenarios

needs_numba = pytest.mark.skipif(not compiled.enabled(), reason="numba is not installed, or MEANFIELD_COMPILED=0")

SQUARE = "POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0))"
L_WITH_PILLAR = (
    "POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0), (0.15 0.15, 0.25 0.15, 0.25 0.25, 0.15 0.25, 0.15 0.15))"
)
PILLAR = (0.15, 0.25, 0.15, 0.25)  # x0, x1, y0, y1 of the L's pillar


def _office() -> Plan:
    return builtin_scenarios()["office"](seed=0).domain


PLANS = {"office": _office, "pillar": lambda: Plan.from_wkt(L_WITH_PILLAR)}


def _steps(plan: Plan, n: int, scale: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    start = plan.sample_uniform(n, rng)
    return start, start + scale * plan.diameter * rng.normal(size=start.shape)


def both(kernel, *args):
    """The loop's result on the compiled path and on the numpy path (arguments copied for each)."""
    fast = kernel(*[a.copy() if isinstance(a, np.ndarray) else a for a in args])
    assert kernel._ready, f"{kernel.name} did not run compiled"  # else both sides would be numpy
    with compiled.numpy_path():
        ref = kernel(*[a.copy() if isinstance(a, np.ndarray) else a for a in args])
    return fast, ref


def _path(on: bool):
    """The compiled path (as selected) for ``on``, else the numpy path."""
    return nullcontext() if on else compiled.numpy_path()


def _in_pillar(p: np.ndarray) -> np.ndarray:
    x0, x1, y0, y1 = PILLAR
    return (p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1)


# ----------------------------------------------------------------------------- compiled = numpy twin
@needs_numba
@pytest.mark.parametrize("name", list(PLANS))
@pytest.mark.parametrize("n", [200, 20_000])  # the twin's full test, then its look-ups
def test_first_hits_match_the_numpy_twin_and_the_test_against_every_wall(name, n):
    plan = PLANS[name]()
    a, e, near, box = plan._index().tables()
    assert (n * len(a) > FULL_TEST_BELOW) == (n > 200)
    hits = 0
    for seed, scale in enumerate((0.002, 0.02, 0.2, 2.0)):  # within a cell, across cells, bouncing
        start, end = _steps(plan, n, scale, seed)
        (t, k), (t_ref, k_ref) = both(first_hits, start, end, a, e, near, box, np.empty(n), np.empty(n, np.intp))
        hit = np.isfinite(t_ref)
        hits += hit.sum()
        assert np.array_equal(np.isfinite(t), hit)
        assert np.array_equal(k, k_ref) and np.max(np.abs(t[hit] - t_ref[hit])) <= 1e-12
        assert np.all(k[~hit] == 0)
        full = segment_hits(start, end - start, a[None], e[None])  # every wall, the lowest index of the smallest t
        assert np.array_equal(k[hit], np.argmin(full, axis=1)[hit])
    assert hits > n // 2


@needs_numba
@pytest.mark.parametrize("name", list(PLANS))
@pytest.mark.parametrize("n", [200, 20_000])
def test_reflected_stopped_and_slid_steps_match_the_numpy_twins(name, n):
    plan = PLANS[name]()
    tables = plan._index().tables()
    loops = {"reflect": (reflect_steps,), "stop": (robot_steps, False), "slide": (robot_steps, True)}
    changed = dict.fromkeys(loops, 0)
    for seed, scale in enumerate((0.002, 0.02, 0.2, 2.0)):
        start, end = _steps(plan, n, scale, seed)
        for what, (kernel, *options) in loops.items():
            fast, ref = both(kernel, start, end, *tables, *options)
            assert np.max(np.abs(fast - ref)) <= 1e-12, what
            changed[what] += np.count_nonzero(np.any(fast != end, axis=1))
        assert not np.isfinite(plan._first_hit(start, fast)[0]).any()  # the slides: no wall crossed
    assert all(c > n // 2 for c in changed.values()), changed  # many steps did meet a wall


@needs_numba
def test_long_steps_bounce_several_times_on_both_paths():
    plan = Plan.from_wkt(L_WITH_PILLAR)
    start, end = _steps(plan, 2000, 3.0, 11)  # steps of ~4 m in a 1 m room
    fast, ref = both(reflect_steps, start, end, *plan._index().tables())
    assert np.max(np.abs(fast - ref)) <= 1e-12
    # the bounces of one step: following it by hand, one wall at a time, gives the same point
    a, e, near, box = plan._index().tables()
    s, q = start.copy(), end.copy()
    bounces = np.zeros(len(s), int)
    for _ in range(8):
        t, k = first_hits(s, q, a, e, near, box, np.empty(len(s)), np.empty(len(s), np.intp))
        hit = np.isfinite(t) & ~np.all(s == q, axis=1)
        x = s[hit] + t[hit, None] * (q[hit] - s[hit])
        n = np.column_stack([-e[k[hit], 1], e[k[hit], 0]]) / np.hypot(e[k[hit], 0], e[k[hit], 1])[:, None]
        r = q[hit] - x
        q[hit] = x + r - 2.0 * (r * n).sum(1)[:, None] * n
        s[hit] = x
        bounces += hit
    assert (bounces >= 3).sum() > 100
    assert np.max(np.abs(q - fast)) <= 1e-12


# ----------------------------------------------------------------------------- exact answers
def test_a_step_at_a_right_angle_into_a_wall_comes_back_by_what_it_went_past():
    square, pillar = Plan.from_wkt(SQUARE), Plan.from_wkt(L_WITH_PILLAR)
    out = square.reflect(np.array([[1.2, 0.5], [0.3, -0.25]]), np.array([[0.5, 0.5], [0.3, 0.5]]))
    np.testing.assert_allclose(out, [[0.8, 0.5], [0.3, 0.25]], rtol=0, atol=1e-12)
    out = pillar.reflect(np.array([[0.2, 0.2]]), np.array([[0.1, 0.2]]))  # into the pillar's left face, x = 0.15
    np.testing.assert_allclose(out, [[0.1, 0.2]], rtol=0, atol=1e-12)


@pytest.mark.parametrize("on", [True, False])
def test_steps_that_bounce_two_to_four_times_end_where_the_unfolded_path_folds_back(on):
    with _path(on):
        square = Plan.from_wkt(SQUARE)
        d = np.array([[3.2, 0.0], [2.3, 1.7], [-2.9, 0.05], [0.0, 2.6]])  # 3, 4, 3 and 2 bounces (none at a corner)
        start = np.full_like(d, 0.5)
        unfolded = start + d
        folded = np.abs(unfolded - 2.0 * np.round(unfolded / 2.0))  # the mirror images of the unit square
        out = square.reflect(unfolded.copy(), start)
        np.testing.assert_allclose(out, folded, rtol=0, atol=1e-12)
        np.testing.assert_allclose(folded, [[0.3, 0.5], [0.8, 0.2], [0.4, 0.55], [0.5, 0.9]], rtol=0, atol=1e-12)


@pytest.mark.parametrize("on", [True, False])
def test_a_step_through_a_corner_takes_the_lowest_wall_and_ends_in_the_plan(on):
    with _path(on):
        square = Plan.from_wkt(SQUARE)
        a, e = square._edges
        start, end = np.array([[0.5, 0.5]]), np.array([[1.5, 1.5]])  # out through the corner (1, 1)
        t, k = square._first_hit(start, end)
        at_corner = np.flatnonzero(np.isfinite(segment_hits(start, end - start, a[None], e[None])[0]))
        assert t[0] == 0.5 and len(at_corner) == 2 and k[0] == at_corner.min()  # the top wall (y = 1)
        # mirrored at the top wall to (1.5, 0.5), outside; the next walls start at the corner (t = 0): projected
        np.testing.assert_allclose(square.reflect(end.copy(), start), [[1.0, 0.5]], rtol=0, atol=1e-12)
        pillar = Plan.from_wkt(L_WITH_PILLAR)
        start = np.array([[0.1, 0.1], [0.3, 0.3]])  # through the pillar's corner (0.15, 0.15); the L's (0.4, 0.4)
        end = np.array([[0.2, 0.2], [0.5, 0.5]])
        t, k = pillar._first_hit(start, end)
        np.testing.assert_array_equal(k, [6, 2])  # pillar bottom (6) before its left (9); the L's walls 2 and 3
        out = pillar.reflect(end.copy(), start)
        np.testing.assert_allclose(out, [[0.2, 0.1], [0.3, 0.5]], rtol=0, atol=1e-12)
        assert pillar.contains(out[:, 0], out[:, 1]).all() and not _in_pillar(out).any()


@pytest.mark.parametrize("on", [True, False])
def test_a_step_that_ends_on_a_wall_or_starts_on_it_stays(on):
    with _path(on):
        square = Plan.from_wkt(SQUARE)
        start = np.array([[0.5, 0.5], [0.5, 0.5], [1.0, 0.5]])
        end = np.array([[1.0, 0.5], [1.0, 1.0], [0.7, 0.6]])  # on a wall; on a corner; from a wall inwards
        t, _ = square._first_hit(start, end)
        np.testing.assert_array_equal(t, [1.0, 1.0, np.inf])  # t <= 1 counts; t = 0 does not
        np.testing.assert_array_equal(square.reflect(end.copy(), start), end)


@pytest.mark.parametrize("on", [True, False])
def test_a_robot_stops_before_a_wall_head_on_and_slides_along_it_at_an_angle(on):
    with _path(on):
        square = Plan.from_wkt(SQUARE)
        start = np.array([[0.5, 0.5], [0.5, 0.5], [0.5, 0.5]])
        end = np.array([[1.5, 0.5], [1.5, 0.8], [1.5, 1.5]])  # head on; at an angle; into the corner
        stopped = square.stop_at_walls(start, end.copy())
        head_on, angled, corner = [1 - 1e-9, 0.5], [1 - 1e-9, 0.65 - 0.3e-9], [1 - 1e-9, 1 - 1e-9]
        np.testing.assert_allclose(stopped, [head_on, angled, corner], rtol=0, atol=1e-15)
        slid = square.slide_along_walls(start, end.copy())
        # at an angle: along the wall x = 1 to y = 0.8.  Into the corner: the top wall (the lowest index of
        # the tie) at (1 - 1e-9, 1 - 1e-9), along it by 0.5 + 1e-9, stopped 1e-9 of that before x = 1
        np.testing.assert_allclose(slid, [[1 - 1e-9, 0.5], [1 - 1e-9, 0.8], [1 - 0.5e-9, 1 - 1e-9]], rtol=0, atol=1e-15)
        assert slid[0, 0] < 1.0 and slid[1, 0] < 1.0 and np.all(slid[2] < 1.0)


# ----------------------------------------------------------------------------- properties
@settings(max_examples=40, deadline=None)
@given(
    st.sampled_from(sorted(PLANS)),
    st.integers(0, 10_000),
    st.floats(0.001, 3.0),  # steps from a fraction of a lattice cell to three diameters
    st.booleans(),
)
def test_no_reflected_step_ends_in_a_pillar_or_outside_and_no_robot_crosses_a_wall(name, seed, scale, on):
    plan = PLANS[name]()
    start, end = _steps(plan, 300, scale, seed)
    with _path(on):
        out = plan.reflect(end.copy(), start)
        slid = plan.slide_along_walls(start, end.copy())
    assert plan.contains(out[:, 0], out[:, 1]).all()
    if name == "pillar":
        assert not _in_pillar(out).any() and not _in_pillar(slid).any()
    assert not np.isfinite(plan._first_hit(start, slid)[0]).any()


# ----------------------------------------------------------------------------- the switch
def _spy(monkeypatch, kernel):
    calls = []
    twin = kernel.fallback

    def spy(*args):
        calls.append(kernel.name)
        return twin(*args)

    monkeypatch.setattr(kernel, "fallback", spy)
    return calls


def test_use_compiled_false_runs_the_numpy_twins(monkeypatch):
    plan = Plan.from_wkt(L_WITH_PILLAR)
    start, end = _steps(plan, 50, 0.5, 1)
    spies = {kernel.name: _spy(monkeypatch, kernel) for kernel in (first_hits, reflect_steps, robot_steps)}
    compiled.use_compiled(False)
    try:
        plan.reflect(end.copy(), start)
        plan.slide_along_walls(start, end.copy())
        plan.stop_at_walls(start, end.copy())
        plan._first_hit(start, end)
    finally:
        compiled.use_compiled(None)  # follow MEANFIELD_COMPILED again, the default
    assert [len(calls) for calls in spies.values()] == [1, 1, 2], spies  # robot_steps: slide, then stop
    if compiled.numba_available() and compiled.enabled():
        plan.reflect(end.copy(), start)  # and back on the compiled path: the twin is not called again
        assert len(spies[reflect_steps.name]) == 1


def test_the_environment_variable_off_runs_the_numpy_twins():
    code = (
        "import numpy as np\n"
        "from meanfield._compiled import core as compiled\n"
        "from meanfield.geometry import _wall_loops as wall_loops\n"
        "from meanfield.geometry.plan import Plan\n"
        "calls = []\n"
        "twin = wall_loops.reflect_steps.fallback\n"
        "wall_loops.reflect_steps.fallback = lambda *a: calls.append(1) or twin(*a)\n"
        "plan = Plan.from_wkt('POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0))')\n"
        "out = plan.reflect(np.array([[1.2, 0.5]]), np.array([[0.5, 0.5]]))\n"
        "print(len(calls), compiled.enabled(), wall_loops.reflect_steps._ready, round(out[0, 0], 12))\n"
    )
    env = {**os.environ, "MEANFIELD_COMPILED": "0"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.split() == ["1", "False", "False", "0.8"]
