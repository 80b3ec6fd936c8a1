"""Compiled loops against their numpy twins (meanfield._compiled.core, meanfield.crowds._field_loops).

Which results are the same on both paths, and how:

* every compiled loop of the crowd agrees with its numpy twin to round-off on one call;
* a closed loop on the compiled path follows the numpy path's trajectory to round-off
  amplified over 100 steps (the chaotic loop amplifies round-off, so whole runs agree in
  distribution, not bit for bit);
* each path alone is deterministic: the same seed gives identical numbers.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, GaussianKernel, ParameterError, paper_scenario
from meanfield._compiled import core as compiled
from meanfield._compiled.core import PARALLEL_CHUNK, empty_array
from meanfield._compiled.philox import ZIG_FI, ZIG_KI, ZIG_WI, noise_key, standard_normals
from meanfield.crowds._field_loops import bilinear_at, gaussian_field_at
from meanfield.crowds._point_mass_loops import euler_maruyama
from meanfield.signs.robots import navigation_velocity
from meanfield.signs.sampled_field import SampledNavigationField

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")


def both(kernel, *args):
    """The loop's result on the compiled path and on the numpy path (arguments copied for each)."""
    fresh = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
    fast = kernel(*fresh)
    assert kernel._ready, f"{kernel.name} did not run compiled"  # else both sides would be numpy
    with compiled.numpy_path():
        ref = kernel(*[a.copy() if isinstance(a, np.ndarray) else a for a in args])
    return fast, ref, fresh


@needs_numba
@pytest.mark.parametrize("masked", [False, True])
def test_gaussian_field_matches_numpy_and_the_reference_evaluation(masked):
    rng = np.random.default_rng(3)
    pts, robots, theta = rng.uniform(0, 1, (500, 2)), rng.uniform(0, 1, (7, 2)), rng.uniform(0, 6.3, 7)
    k = GaussianKernel(0.2, 0.05)
    visible = rng.uniform(size=(7, 500)) < 0.6 if masked else np.ones((0, 0), bool)
    args = (pts, robots, theta, k.c, 1 / k.eta)
    _, _, fresh = both(gaussian_field_at, *args, visible, 0.01, np.empty((500, 2)), np.empty(500, bool))
    fast, ref = fresh[-2], np.empty((500, 2))
    with compiled.numpy_path():
        gaussian_field_at(*args, visible, 0.01, ref, np.empty(500, bool))
    exact = navigation_velocity(k, robots, theta, pts, visible if masked else None)
    assert np.max(np.abs(fast - ref)) <= 1e-15 and np.max(np.abs(fast - exact)) <= 1e-15
    reached = fresh[-1]
    assert np.array_equal(reached, np.hypot(exact[:, 0], exact[:, 1]) >= 0.01)
    assert 0 < reached.sum() < 500  # the flag separates the crowd here


@needs_numba
def test_bilinear_matches_numpy_and_is_exact_on_bilinear_fields():
    rng = np.random.default_rng(4)
    xs, ys = np.linspace(0, 2, 9), np.linspace(-1, 1, 7)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    vx, vy = 1 + 2 * X - 3 * Y + 0.5 * X * Y, -X * Y + 4.0  # bilinear: reproduced exactly
    pts = np.column_stack([rng.uniform(0, 2, 1000), rng.uniform(-1, 1, 1000)])
    h = (xs[1] - xs[0], ys[1] - ys[0])
    fast, ref, _ = both(
        bilinear_at, vx, vy, 0.0, -1.0, 1 / h[0], 1 / h[1], pts, 0.0, np.empty((1000, 2)), np.empty(1000, bool)
    )
    assert np.max(np.abs(fast - ref)) <= 1e-14
    px, py = pts[:, 0], pts[:, 1]
    assert np.allclose(fast[:, 0], 1 + 2 * px - 3 * py + 0.5 * px * py, atol=1e-13, rtol=0)
    assert np.allclose(fast[:, 1], -px * py + 4.0, atol=1e-13, rtol=0)


def test_bilinear_agrees_with_the_sampled_field():
    rng = np.random.default_rng(5)
    f = SampledNavigationField(GaussianKernel(0.2, 0.05), (0, 1, 0, 1), (21, 21))
    f.update(rng.uniform(0, 1, (5, 2)), rng.uniform(0, 6, 5))
    pts = rng.uniform(-0.1, 1.1, (300, 2))  # some outside: the nearest edge's value
    got = bilinear_at(f.vx, f.vy, 0.0, 0.0, 20.0, 20.0, pts, 0.0, np.empty((300, 2)), np.empty(300, bool))
    assert np.max(np.abs(got - f.at_points(pts))) <= 1e-15


KEY = noise_key(2024)
NOBODY = np.empty(0, bool)


def em_args(noise, dt, amp, box, standing=NOBODY, step=5):
    """``euler_maruyama``'s arguments after the positions and drifts (the noise of ``KEY`` at ``step``)."""
    return (noise, dt, amp, box, standing, *KEY, np.uint64(step), ZIG_KI, ZIG_WI, ZIG_FI)


@needs_numba
@pytest.mark.parametrize("walls", [True, False])
def test_euler_maruyama_matches_numpy_and_the_domain_reflection(walls):
    rng = np.random.default_rng(6)
    x = rng.uniform(0, 1, (400, 2))
    drift = rng.normal(size=(400, 2))
    amp = np.full((1, 1), 1.7)  # long steps: several bounces
    box = np.array([0.0, 1.0, 0.0, 2.0]) if walls else np.empty(0)
    moved, moved_ref, fresh = both(euler_maruyama, x, drift, *em_args(np.empty((400, 2)), 0.3, amp, box))
    assert moved is True and moved_ref is True
    noise = standard_normals(2024, 5, np.empty((400, 2)))  # the draws of (seed, step, human)
    assert np.array_equal(fresh[2], noise)
    fast, ref = fresh[0], _numpy_result(euler_maruyama, x, drift, *em_args(np.empty((400, 2)), 0.3, amp, box))
    assert np.max(np.abs(fast - ref)) <= 1e-14
    free = x + 0.3 * drift + 1.7 * noise
    if walls:
        assert np.max(np.abs(fast - Domain.box(1.0, 2.0).reflect(free))) <= 1e-14
        assert (fast >= 0).all() and (fast[:, 0] <= 1).all() and (fast[:, 1] <= 2).all()
    else:
        assert np.max(np.abs(fast - free)) <= 1e-15
    per_human = rng.uniform(0, 1, (400, 1))
    _, _, fresh = both(euler_maruyama, x, drift, *em_args(np.empty((400, 2)), 0.3, per_human, box))
    ref = _numpy_result(euler_maruyama, x, drift, *em_args(np.empty((400, 2)), 0.3, per_human, box))
    assert np.max(np.abs(fresh[0] - ref)) <= 1e-14


@needs_numba
def test_euler_maruyama_gives_the_same_numbers_on_one_and_two_threads_and_in_any_chunks():
    import numba

    rng = np.random.default_rng(8)
    n = 3 * PARALLEL_CHUNK + 17  # several chunks, the last one short
    x = rng.uniform(0, 1, (n, 2))
    drift = rng.normal(size=(n, 2))
    box = np.array([0.0, 1.0, 0.0, 1.0])
    standing = rng.uniform(size=n) < 0.2
    before = numba.get_num_threads()
    results = []
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            y = x.copy()
            noise = np.empty((n, 2))
            assert euler_maruyama(y, drift, *em_args(noise, 0.1, np.full((1, 1), 0.3), box, standing))
            results.append((y, noise))
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(results[0][0], results[1][0]) and np.array_equal(results[0][1], results[1][1])
    y, noise = results[0]
    assert not noise[standing].any()  # those standing: no noise
    drawn = standard_normals(2024, 5, np.empty((n, 2)))
    assert np.array_equal(noise[~standing], drawn[~standing])
    # humans 100..: the same draws when the crowd is cut elsewhere (the counter is the human's index)
    assert np.array_equal(standard_normals(2024, 5, np.empty((n - 100, 2)), first=100), drawn[100:])
    ref = _numpy_result(euler_maruyama, x, drift, *em_args(np.empty((n, 2)), 0.1, np.full((1, 1), 0.3), box, standing))
    assert np.max(np.abs(y - ref)) <= 1e-14


def _numpy_result(kernel, x, *args):
    """``x`` after the numpy twin of an in-place loop."""
    x = x.copy()
    with compiled.numpy_path():
        kernel(x, *args)
    return x


@needs_numba
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("n", [50, 2 * PARALLEL_CHUNK + 50])
def test_euler_maruyama_moves_nobody_when_a_drift_is_not_finite(bad, n):
    rng = np.random.default_rng(7)
    x = rng.uniform(0, 1, (n, 2))
    drift = rng.normal(size=(n, 2))
    drift[n - 13, 1] = bad  # one value, late in the array: the rows before it must not have moved either
    box = np.array([0.0, 1.0, 0.0, 1.0])
    args = em_args(np.empty((n, 2)), 0.01, np.full((1, 1), 0.1), box)
    moved, moved_ref, fresh = both(euler_maruyama, x, drift, *args)
    assert moved is False and moved_ref is False
    assert np.array_equal(fresh[0], x)


@needs_numba
def test_closed_loop_follows_the_numpy_path_and_each_path_is_deterministic():
    sc = paper_scenario(seed=2).replace(t_final=1.0)

    def final(numpy_path: bool):
        loop = ClosedLoop(sc)
        if numpy_path:
            with compiled.numpy_path():
                for _ in range(100):
                    loop.step()
        else:
            for _ in range(100):
                loop.step()
        return loop.crowd.positions.copy(), loop.robots.positions.copy()

    fast, fast_again, ref = final(False), final(False), final(True)
    assert all(np.array_equal(a, b) for a, b in zip(fast, fast_again, strict=True))
    assert np.max(np.abs(fast[0] - ref[0])) <= 1e-9 and np.max(np.abs(fast[1] - ref[1])) <= 1e-9


def _never_compiles(x):  # numba cannot type a Python set of strings built from an array
    return {str(v) for v in x}


def _fallback_of(x):
    return x * 2.0


def test_a_loop_that_does_not_compile_falls_back_with_one_warning(monkeypatch):
    kernel = compiled.compiled(fallback=_fallback_of)(_never_compiles)
    monkeypatch.setattr(compiled, "_failures", {})
    monkeypatch.setattr(compiled, "_override", True)
    monkeypatch.setattr(compiled, "_selected", None)  # (the remembered selection follows _override)
    if not compiled.numba_available():
        pytest.skip("numba is not installed: nothing compiles, nothing to warn about")
    with pytest.warns(compiled.CompiledFallbackWarning, match="_never_compiles") as record:
        out = kernel(np.arange(3.0))
    assert np.array_equal(out, [0.0, 2.0, 4.0]) and len(record) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the second call: no second warning
        assert np.array_equal(kernel(np.arange(2.0)), [0.0, 2.0])
    assert "_never_compiles" in next(iter(compiled.status()["fallbacks"]))


def _doubled(x):
    return 2.0 * x


def test_a_loops_first_call_compiles_with_the_collector_off_and_restores_it(monkeypatch):
    if not compiled.numba_available():
        pytest.skip("numba is not installed: nothing compiles")
    import gc

    monkeypatch.setattr(compiled, "_override", True)
    monkeypatch.setattr(compiled, "_selected", None)
    kernel = compiled.compiled(fallback=_doubled)(_doubled)
    seen = []
    real = kernel._compile

    def compile_watched():
        seen.append(gc.isenabled())
        return real()

    monkeypatch.setattr(kernel, "_compile", compile_watched)
    was = gc.isenabled()
    try:
        gc.enable()
        assert np.array_equal(kernel(np.arange(3.0)), [0.0, 2.0, 4.0]) and kernel._ready
        assert seen == [False] and gc.isenabled()  # off while compiling, on again after
        with compiled.collector_paused():  # a collector its caller had turned off stays off
            assert not gc.isenabled()
            with compiled.collector_paused():
                assert not gc.isenabled()
            assert not gc.isenabled()
        assert gc.isenabled()
        gc.disable()
        with compiled.collector_paused():
            pass
        assert not gc.isenabled()
    finally:
        (gc.enable if was else gc.disable)()


def _allocations(n):  # (compiled: its module's empty_array is then the intrinsic, not for Python)
    a = empty_array(n, np.float64)
    b = empty_array((n, 3), np.int64)
    c = empty_array((2, n, 2), np.uint64)
    d = empty_array(n, np.bool_)
    for i in range(n):
        a[i] = 0.5 * i
        d[i] = i % 2 == 0
        for j in range(3):
            b[i, j] = 3 * i + j
        for k in range(2):
            for j in range(2):
                c[k, i, j] = 100 * k + 10 * i + j
    return a, b, c, d


def _allocations_numpy(n):
    i = np.arange(n)
    c = 100 * np.arange(2)[:, None, None] + 10 * i[None, :, None] + np.arange(2)[None, None, :]
    return 0.5 * i, np.arange(3 * n, dtype=np.int64).reshape(n, 3), c.astype(np.uint64), i % 2 == 0


def test_empty_array_is_np_empty_on_both_paths(monkeypatch):
    if not compiled.numba_available():
        pytest.skip("numba is not installed: nothing compiles")
    monkeypatch.setattr(compiled, "_override", True)
    monkeypatch.setattr(compiled, "_selected", None)
    plain = compiled.empty_array((2, 3), np.int64)  # from Python: np.empty
    assert plain.shape == (2, 3) and plain.dtype == np.int64 and plain.flags.c_contiguous
    kernel = compiled.compiled(fallback=_allocations_numpy)(_allocations)
    got = kernel(5)
    assert kernel._ready
    for x, ref in zip(got, _allocations_numpy(5), strict=True):
        assert x.dtype == ref.dtype and x.shape == ref.shape and x.flags.c_contiguous and x.flags.writeable
        assert x.strides == ref.strides and np.array_equal(x, ref)
    assert kernel(0)[2].shape == (2, 0, 2)


def test_empty_array_compiles_no_overload_where_np_empty_does():
    numba = pytest.importorskip("numba")
    from numba.core import event

    allocate = compiled._empty_intrinsic()

    @numba.njit
    def by_intrinsic(n):  # a shape and dtype no loop of the toolkit asks for
        out = allocate((n, 2, 3), np.uint16)
        out[:] = 7
        return out

    @numba.njit
    def by_numpy(n):
        out = np.empty((n, 3, 2), np.uint16)
        out[:] = 7
        return out

    def compiled_names(function):
        with event.install_recorder("numba:compile") as record:
            out = function(4)
        names = [e.data["dispatcher"].py_func.__qualname__ for _, e in record.buffer if e.is_start]
        return out, names

    out, names = compiled_names(by_intrinsic)
    assert out.shape == (4, 2, 3) and out.dtype == np.uint16 and (out == 7).all() and out.flags.c_contiguous
    assert "test_empty_array_compiles_no_overload_where_np_empty_does.<locals>.by_intrinsic" in names
    assert not [n for n in names if n.startswith(("ol_np_empty", "_ol_array_allocate"))]
    out, names = compiled_names(by_numpy)  # the recorder does see np.empty's overload when there is one
    assert out.shape == (4, 3, 2) and [n for n in names if n.startswith("ol_np_empty")]


def test_empty_array_s_arrays_are_freed():
    numba = pytest.importorskip("numba")
    from numba.core.runtime import _nrt_python as nrt
    from numba.core.runtime import rtsys

    allocate = compiled._empty_intrinsic()

    @numba.njit
    def churn(n):
        total = 0.0
        for r in range(50):
            a = allocate((n, 3), np.float64)
            for i in range(n):
                a[i, 0] = r
            total += a[n - 1, 0]
        return total

    assert churn(4) == sum(range(50))
    was = numba.config.NRT_STATS
    nrt.memsys_enable_stats()
    try:
        before = rtsys.get_allocation_stats()
        for _ in range(20):
            churn(4)
        after = rtsys.get_allocation_stats()
    finally:
        if not was:
            nrt.memsys_disable_stats()
    assert after.mi_alloc - before.mi_alloc == 1000  # each array allocated once and freed once: nothing leaks
    assert after.mi_free - before.mi_free == 1000


def test_the_environment_variable_selects_the_numpy_path(monkeypatch):
    monkeypatch.setattr(compiled, "_override", True)
    monkeypatch.setattr(compiled, "_selected", None)
    monkeypatch.setattr(compiled, "_environment", True)
    monkeypatch.setenv("MEANFIELD_COMPILED", "0")
    compiled.use_compiled(None)  # follow the environment, read now
    assert not compiled.enabled() and compiled.status()["enabled"] is False
    monkeypatch.setenv("MEANFIELD_COMPILED", "1")
    compiled.use_compiled(None)
    assert compiled.enabled() == compiled.numba_available()


def test_use_compiled_refuses_what_is_not_a_choice():
    with pytest.raises(ParameterError) as exc:
        compiled.use_compiled("yes")
    assert exc.value.name == "on" and "True, False or None" in str(exc.value)


@needs_numba
@pytest.mark.parametrize("schedule", ["constant", "saturating"])
@pytest.mark.parametrize("gains", ["scalar", "per-robot"])
def test_the_fused_law_matches_the_numpy_law(schedule, gains):
    from meanfield import Grid, NavigationField
    from meanfield.controllers.backstepping import BacksteppingController, ConstantAlpha, SaturatingAlpha

    rng = np.random.default_rng(7)
    grid = Grid(Domain.box(1.0, 1.5), cells=(17, 23))
    X, Y = grid.centers
    target = grid.normalize(np.exp(-((X - 0.8) ** 2 + (Y - 1.2) ** 2) / 0.05))
    alpha = ConstantAlpha(0.3) if schedule == "constant" else SaturatingAlpha(0.2, 2.0)
    n = 5
    k_u = 10.0 if gains == "scalar" else rng.uniform(1, 10, n)
    kernel = GaussianKernel(0.2, 0.05)

    def law():
        return BacksteppingController(grid, target, 0.015, alpha, k_u=k_u, k_omega=7.0)

    fused, plain = law(), law()
    assert fused.fused.which(target, NavigationField(kernel, grid, [[0.5, 0.5]], [0.0])) is not None
    for t in (0.0, 0.01, 0.02):  # the first call without, the next ones with the previous v_d
        rho = grid.normalize(rng.uniform(0.2, 2.0, grid.shape))
        field = NavigationField(kernel, grid, rng.uniform(0, 1, (n, 2)) * [1.0, 1.5], rng.uniform(0, 6.3, n))
        fast = fused.robot_inputs(rho, field, t, 0.01)
        with compiled.numpy_path():
            ref = plain.robot_inputs(rho, field, t, 0.01)
        for name in ("u", "omega", "b", "g", "rho_tilde"):
            a, r = getattr(fast, name), getattr(ref, name)
            assert np.max(np.abs(a - r)) <= 1e-12 * max(1.0, np.max(np.abs(r))), name
        for name in ("v_d", "v_tilde"):
            for a, r in zip(getattr(fast, name), getattr(ref, name), strict=True):
                assert np.max(np.abs(a - r)) <= 1e-12 * np.max(np.abs(r)), name
        for name in ("A", "dissipation", "shortfall"):
            assert getattr(fast, name) == pytest.approx(getattr(ref, name), rel=1e-12, abs=1e-300), name
        # the law's identity (eq. (8)): Σ b_i·u_i - g_i ω_i = Σ k_u |b_i|² + k_ω g_i² + A on the fused path too
        lhs = (fast.b * fast.u).sum() - (fast.g * fast.omega).sum()
        rhs = (np.reshape(k_u, (-1, 1)) * fast.b**2).sum() + (7.0 * fast.g**2).sum() + fast.A
        assert lhs == pytest.approx(rhs, rel=1e-12)
    from meanfield.controllers._law_loops import paper_law

    assert paper_law._ready and not compiled.status()["fallbacks"]  # it did run compiled


@needs_numba
def test_plan_loops_match_numpy():
    from meanfield.geometry._sight_loops import segments_clear
    from meanfield.signs._masked_loops import face_moments, masked_face_kernels

    rng = np.random.default_rng(8)
    walls = rng.uniform(0, 1, (12, 2, 2))
    a, e = walls[:, 0].copy(), (walls[:, 1] - walls[:, 0]).copy()
    p, q = rng.uniform(0, 1, (3000, 2)), rng.uniform(0, 1, (3000, 2))
    q[:10] = a[:10]  # segments ending on a wall's end: touching is not crossing
    fast, ref, _ = both(segments_clear, p, q, a, e, np.empty(3000, bool))
    assert np.array_equal(fast, ref) and 0 < fast.sum() < 3000
    n, nx, ny = 4, 9, 7
    f = [rng.uniform(size=(n, m)) for m in (nx - 1, ny, nx, ny - 1, nx - 1, ny, nx, ny - 1)]
    sx, sy = rng.uniform(size=(n, nx - 1, ny)) < 0.7, rng.uniform(size=(n, nx, ny - 1)) < 0.7

    def out():
        return tuple(np.empty((n, nx - 1, ny)) for _ in range(3)) + tuple(np.empty((n, nx, ny - 1)) for _ in range(3))

    fast, ref, _ = both(masked_face_kernels, *f, sx, sy, out())
    assert all(np.max(np.abs(x - y)) <= 1e-15 for x, y in zip(fast, ref, strict=True))
    Wx, Wy = rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1))
    fast, ref, _ = both(face_moments, *fast, Wx, Wy, np.empty((6, n)))
    assert np.max(np.abs(fast - ref)) <= 1e-13


def test_a_process_started_with_the_variable_off_runs_and_reports_the_numpy_path():
    import json
    import os
    import subprocess
    import sys

    code = (
        "import json; from meanfield import run, paper_scenario; "
        "s = run(paper_scenario(0).replace(t_final=0.05), progress=False).summary; "
        "print(json.dumps(s['compiled_loops']))"
    )
    env = dict(os.environ, MEANFIELD_COMPILED="0")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report["enabled"] is False and report["fallbacks"] == {}


@needs_numba
def test_saturation_matches_numpy_and_keeps_every_input_within_its_limit():
    from meanfield.signs._robot_loops import limit_inputs

    rng = np.random.default_rng(9)
    u, w = rng.normal(scale=0.3, size=(50, 2)), rng.normal(scale=4.0, size=50)
    for u_max, w_max in ((0.2, 3.0), (np.inf, 3.0), (0.2, np.inf)):
        _, _, (*_, u_fast, w_fast) = both(
            limit_inputs, u, w, u_max, w_max, 1 - 4 * np.finfo(float).eps, 1e-6, np.empty((50, 2)), np.empty(50)
        )
        u_ref, w_ref = np.empty((50, 2)), np.empty(50)
        with compiled.numpy_path():
            limit_inputs(u, w, u_max, w_max, 1 - 4 * np.finfo(float).eps, 1e-6, u_ref, w_ref)
        fast, ref = (u_fast, w_fast), (u_ref, w_ref)
        assert np.max(np.abs(fast[0] - ref[0])) <= 1e-16 and np.array_equal(fast[1], ref[1])
        assert (np.hypot(fast[0][:, 0], fast[0][:, 1]) <= u_max).all() and (np.abs(fast[1]) <= w_max).all()
        inside = np.hypot(u[:, 0], u[:, 1]) <= u_max
        assert np.array_equal(fast[0][inside], u[inside])  # within the limit: unchanged


@needs_numba
def test_input_report_matches_numpy_and_counts_what_the_limits_did():
    from meanfield.signs._robot_loops import input_report
    from meanfield.signs.robots import RobotTeam, saturate_inputs

    rng = np.random.default_rng(10)
    u, w = rng.normal(scale=0.3, size=(40, 2)), rng.normal(scale=4.0, size=40)
    for u_max, w_max in ((0.2, 3.0), (np.inf, 3.0), (0.2, np.inf), (np.inf, np.inf)):
        ua, wa = saturate_inputs(u, w, u_max, w_max)
        fast, ref, _ = both(input_report, u, w, ua, wa, u_max, w_max, 1e-6)
        assert fast == ref
        team = RobotTeam(positions=np.zeros((40, 2)), headings=np.zeros(40), u_max=u_max, omega_max=w_max)
        # exact answers: the counts from their definitions, the maxima from the applied inputs
        assert fast[3] == int(team.at_limit(u, w).sum())
        cut = (np.hypot(u[:, 0], u[:, 1]) > u_max).any() or (np.abs(w) > w_max).any()
        assert fast[2] == cut
        assert fast[0] == np.hypot(ua[:, 0], ua[:, 1]).max() and fast[1] == np.abs(wa).max()


@needs_numba
def test_limit_inputs_is_saturation_and_report_in_one_pass_and_flags_non_finite_commands():
    from meanfield.signs._robot_loops import _saturate_numpy, input_report, limit_inputs

    rng = np.random.default_rng(12)
    u, w = rng.normal(scale=0.3, size=(40, 2)), rng.normal(scale=4.0, size=40)
    shrink = 1 - 4 * np.finfo(float).eps
    for u_max, w_max in ((0.2, 3.0), (np.inf, 3.0), (0.2, np.inf), (np.inf, np.inf)):
        fast, ref, (_, _, _, _, _, _, u_out, w_out) = both(
            limit_inputs, u, w, u_max, w_max, shrink, 1e-6, np.empty((40, 2)), np.empty(40)
        )
        assert fast == ref and fast[4] is True
        ua, wa = _saturate_numpy(u, w, u_max, w_max, shrink, np.empty((40, 2)), np.empty(40))
        assert np.array_equal(u_out, ua) and np.array_equal(w_out, wa)  # the same arithmetic as the numpy twin
        assert fast[:4] == input_report(u, w, ua, wa, u_max, w_max, 1e-6)
    for bad in ((0, 1), (3, 0)):
        ub, wb = u.copy(), w.copy()
        ub[bad] = np.nan
        fast, ref, _ = both(limit_inputs, ub, wb, 0.2, 3.0, shrink, 1e-6, np.empty((40, 2)), np.empty(40))
        assert fast[4] is False and ref[4] is False
    wb = w.copy()
    wb[5] = np.inf
    fast, ref, _ = both(limit_inputs, u, wb, 0.2, 3.0, shrink, 1e-6, np.empty((40, 2)), np.empty(40))
    assert fast[4] is False and ref[4] is False


@needs_numba
def test_count_in_disk_matches_numpy_and_skips_those_who_left():
    from meanfield.geometry._target_loops import count_in_disk

    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.6, 0.8], [0.5, 0.5], [np.nan, np.nan], [2.0, 2.0]])
    fast, ref, _ = both(count_in_disk, pts, 0.0, 0.0, 1.0)
    assert fast == ref == 4  # the boundary counts (1, 0), (0.6, 0.8); the NaN row does not
    big = np.random.default_rng(11).uniform(-1, 1, (5000, 2))
    fast, ref, _ = both(count_in_disk, big, 0.1, -0.2, 0.7)
    assert fast == ref


@needs_numba
@pytest.mark.parametrize("clamp", [False, True])
def test_the_robots_euler_step_is_numpys_bit_for_bit_and_wraps_headings_into_0_2pi(clamp):
    from meanfield._compiled.core import NO_BOX
    from meanfield.signs._robot_loops import robot_euler

    rng = np.random.default_rng(13)
    n = 500
    pos, u = rng.uniform(-3, 3, (n, 2)), rng.uniform(-1, 1, (n, 2))
    pos[7] = np.nan  # stays NaN, clamped or not (as np.maximum/np.minimum keep it)
    heads = np.concatenate([rng.uniform(-20, 20, n - 4), [0.0, -1e-18, 2 * np.pi, -2 * np.pi]])
    omega = rng.uniform(-50, 50, n)
    box = np.array([-1.0, 2.0, -2.5, 0.5]) if clamp else NO_BOX
    fast_out, ref_out = np.empty(n), np.empty(n)
    _, _, fresh = both(robot_euler, pos, heads, u, omega, 0.01, box, fast_out)
    with compiled.numpy_path():
        ref_pos = pos.copy()
        robot_euler(ref_pos, heads, u, omega, 0.01, box, ref_out)
    assert np.array_equal(fresh[0], ref_pos, equal_nan=True)  # the positions, moved in place
    assert np.array_equal(fresh[6], ref_out)  # the headings, np.mod's to the bit
    assert np.all((ref_out >= 0) & (ref_out <= 2 * np.pi))
    moved = pos + 0.01 * u
    if clamp:  # Domain.project's clamp, to the bit
        from meanfield.geometry.domain import Domain

        expected = Domain.box(3.0, 3.0, origin=(-1.0, -2.5)).project(moved.copy())
        assert np.array_equal(fresh[0], expected, equal_nan=True)
        assert np.nanmin(fresh[0][:, 0]) == -1.0 and np.nanmax(fresh[0][:, 1]) == 0.5  # some were outside
    else:
        assert np.array_equal(fresh[0], moved, equal_nan=True)


def test_robot_team_advance_still_broadcasts_a_single_input():
    from meanfield.geometry.domain import Domain
    from meanfield.signs.robots import RobotTeam

    team = RobotTeam(np.array([[0.2, 0.2], [0.5, 0.5]]), np.array([0.0, 1.0]))
    team.advance(np.array([0.1, 0.0]), 0.5, 0.1, Domain.box(1.0, 1.0))  # one u and one ω for every robot
    assert np.allclose(team.positions, [[0.21, 0.2], [0.51, 0.5]]) and np.allclose(team.headings, [0.05, 1.05])


@needs_numba
def test_the_vectorised_exponential_is_within_one_ulp_of_exp():
    from meanfield._compiled.core import compile_inner
    from meanfield._compiled.vector_exp import exp_inplace

    rng = np.random.default_rng(12)
    args = np.concatenate([rng.uniform(-700, 700, 20000), rng.uniform(-1, 1, 20000), [0.0, -707.9, 699.9, -1e-300]])
    vals = args.copy()
    exp = compile_inner(exp_inplace)
    exp(vals, len(vals))
    ref = np.exp(args)
    assert np.all(np.abs(vals - ref) <= np.spacing(ref))  # 1 ulp
    below = np.array([-708.5, -1000.0, -np.inf])
    out = below.copy()
    exp(out, 3)
    assert np.array_equal(out, np.zeros(3))  # below the clamp: 0 (the callers' Gaussians are negligible there)


@needs_numba
def test_a_loop_runs_on_threads_only_above_one_chunk_and_falls_back_to_one_thread_with_one_warning(monkeypatch):
    """``parallel_over``: a small call runs (and compiles) the one-thread version only; a large one the
    threaded version, with the same numbers; a threaded version that does not compile leaves the
    one-thread version running, with one warning."""
    from meanfield.geometry._target_loops import count_in_disk

    loop = compiled.CompiledLoop(count_in_disk.loop, count_in_disk.fallback, {}, parallel_over="points")
    small = np.random.default_rng(1).uniform(0, 1, (PARALLEL_CHUNK, 2))
    large = np.random.default_rng(2).uniform(0, 1, (3 * PARALLEL_CHUNK + 1, 2))
    expected = int((np.hypot(large[:, 0] - 0.5, large[:, 1] - 0.5) <= 0.3).sum())
    assert loop(small, 0.5, 0.5, 0.3) == int((np.hypot(small[:, 0] - 0.5, small[:, 1] - 0.5) <= 0.3).sum())
    assert loop._threaded is None  # not compiled for a crowd of one chunk
    assert loop(large, 0.5, 0.5, 0.3) == expected and loop._threaded is not None

    failing = compiled.CompiledLoop(count_in_disk.loop, count_in_disk.fallback, {}, parallel_over="points")
    failing(small, 0.5, 0.5, 0.3)

    def broken():
        raise RuntimeError("no threading layer")

    monkeypatch.setattr(failing, "_compile_threaded", broken)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert failing(large, 0.5, 0.5, 0.3) == expected
        assert failing(large, 0.5, 0.5, 0.3) == expected
    messages = [str(w.message) for w in caught if issubclass(w.category, compiled.CompiledFallbackWarning)]
    assert len(messages) == 1 and "could not run on threads" in messages[0] and "no threading layer" in messages[0]


@needs_numba
def test_a_large_first_call_runs_on_threads_without_compiling_the_one_thread_version():
    """A loop's first call with more than one chunk runs the threaded version, as every later large call does
    (before, it ran the one-thread version: a million humans' first step on one thread); the one-thread version
    compiles at the first small call, and the two give the same count."""
    from meanfield.geometry._target_loops import count_in_disk

    loop = compiled.CompiledLoop(count_in_disk.loop, count_in_disk.fallback, {}, parallel_over="points")
    large = np.random.default_rng(3).uniform(0, 1, (3 * PARALLEL_CHUNK + 1, 2))
    expected = int((np.hypot(large[:, 0] - 0.5, large[:, 1] - 0.5) <= 0.3).sum())
    assert loop(large, 0.5, 0.5, 0.3) == expected
    assert loop._threaded is not None and loop._threaded.signatures  # the threaded version ran
    assert not loop._jitted.signatures  # the one-thread version did not compile
    small = large[:PARALLEL_CHUNK]
    assert loop(small, 0.5, 0.5, 0.3) == int((np.hypot(small[:, 0] - 0.5, small[:, 1] - 0.5) <= 0.3).sum())
    assert loop._jitted.signatures
