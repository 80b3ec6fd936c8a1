"""The crowd's loops on numba's threads give the same numbers on any number of threads (issue 32).

Each loop that runs chunks of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans on ``prange``
(the field at each human, the lattice field's interpolation, the binning, the Euler–Maruyama step
with its counter-based noise) is run on one and on two threads over several chunks and compared
bit for bit, and against its numpy twin; then a whole closed loop of point masses.
"""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ClosedLoop, GaussianKernel
from meanfield._compiled import core as compiled
from meanfield._compiled.blas import numpy_gemm_found
from meanfield._compiled.core import PARALLEL_CHUNK
from meanfield.crowds._field_loops import bilinear_at, gaussian_field_at
from meanfield.crowds._kde_loops import BINNING_PARTS, _banded_numpy, banded_products, linear_binning_into
from meanfield.crowds.kde import _bands
from meanfield.geometry.grid import linear_binning
from meanfield.scenarios.scenario import stadium_scenario
from meanfield.signs._lattice_loops import _lattice_numpy, lattice_products

numba = pytest.importorskip("numba")
needs_two = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba has one thread here")


def on_threads(threads, call):
    """``call()`` with numba on ``threads`` threads (the count restored after)."""
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        return call()
    finally:
        numba.set_num_threads(before)


N = 5 * PARALLEL_CHUNK + 123  # several chunks, the last one short


@needs_two
def test_the_field_at_each_human_is_the_same_on_one_and_two_threads():
    rng = np.random.default_rng(11)
    pts, robots, theta = rng.uniform(0, 10, (N, 2)), rng.uniform(0, 10, (9, 2)), rng.uniform(0, 6.3, 9)
    k = GaussianKernel(0.5, 2.0)

    def exact():
        out, reached = np.empty((N, 2)), np.empty(N, bool)
        gaussian_field_at(pts, robots, theta, k.c, 1 / k.eta, np.ones((9, 0), bool), 0.05, out, reached)
        return out, reached

    vx, vy = rng.normal(size=(40, 30)), rng.normal(size=(40, 30))

    def sampled():
        out, reached = np.empty((N, 2)), np.empty(N, bool)
        bilinear_at(vx, vy, 0.0, 0.0, 3.9, 2.9, pts, 0.5, out, reached)
        return out, reached

    for call in (exact, sampled):
        one, two = on_threads(1, call), on_threads(2, call)
        assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
        with compiled.numpy_path():
            ref = call()
        assert np.max(np.abs(one[0] - ref[0])) <= 1e-14
        assert 0 < one[1].sum() < N  # the flags separate the crowd: they were compared on both sides


@needs_two
def test_the_binning_is_the_same_on_one_and_two_threads_and_sums_to_the_crowd():
    rng = np.random.default_rng(12)
    pts = rng.uniform(-0.2, 1.2, (N, 2))  # some beyond the outer centres: they go to the edge
    assert (N + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK >= BINNING_PARTS - 2  # several parts

    def binned():
        return linear_binning_into(pts, 0.0, 0.0, 1 / 50, 1 / 40, np.empty((50, 40)))

    one, two = on_threads(1, binned), on_threads(2, binned)
    assert np.array_equal(one, two)
    ref = linear_binning(pts, (0.0, 0.0), (1 / 50, 1 / 40), (50, 40))
    assert np.max(np.abs(one - ref)) <= 1e-12
    assert abs(one.sum() - N) <= 1e-9 * N  # each point's weights sum to 1


@needs_two
def test_a_closed_loop_of_point_masses_is_the_same_on_one_and_two_threads():
    sc = stadium_scenario(seed=4).with_values({"crowd.n": 3 * PARALLEL_CHUNK + 5, "robots.n": 6})
    sc = sc.replace(t_final=10 * sc.dt)

    def final():
        loop = ClosedLoop(sc)
        for _ in range(10):
            loop.step()
        return loop.crowd.positions.copy(), loop.robots.positions.copy()

    one, two = on_threads(1, final), on_threads(2, final)
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
    assert np.all(np.isfinite(one[0]))


@needs_two
def test_a_plans_walls_and_exits_are_the_same_on_one_and_two_threads():
    from meanfield.geometry.exits import exit_segments, leaving
    from meanfield.scenarios.scenario import load_scenario

    plan = load_scenario("office").domain
    rng = np.random.default_rng(13)
    start = plan.sample_uniform(N, rng)
    end = start + rng.normal(scale=0.8, size=start.shape)  # long steps: many cross walls and exits
    segs = exit_segments(plan)

    def walls_and_exits():
        moved = end.copy()
        plan.reflect(moved, start)
        gone = leaving(start, end, segs, 0.3, 0.5, np.random.default_rng(14))
        return moved, gone

    one, two = on_threads(1, walls_and_exits), on_threads(2, walls_and_exits)
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])
    assert plan.contains(one[0][:, 0], one[0][:, 1], tol=1e-9).all()
    assert 0 < (one[1] >= 0).sum() < N  # some steps leave, through the exits: compared on both sides
    with compiled.numpy_path():
        ref = walls_and_exits()
    assert np.max(np.abs(one[0] - ref[0])) <= 1e-12 and np.array_equal(one[1], ref[1])


@needs_two
def test_the_count_in_the_target_is_the_same_on_one_and_two_threads():
    from meanfield.geometry._target_loops import count_in_disk

    pts = np.random.default_rng(15).uniform(0, 1, (N, 2))
    pts[[3, N - 2]] = np.nan  # those who left: counted nowhere
    one = on_threads(1, lambda: count_in_disk(pts, 0.6, 0.4, 0.3))
    two = on_threads(2, lambda: count_in_disk(pts, 0.6, 0.4, 0.3))
    inside = np.hypot(pts[:, 0] - 0.6, pts[:, 1] - 0.4) <= 0.3
    assert one == two == int(inside.sum()) > 0


needs_numpy_blas = pytest.mark.skipif(not numpy_gemm_found(), reason="numpy's BLAS has no ILP64 cblas_dgemm here")


@needs_two
@needs_numpy_blas
def test_the_binned_estimates_products_are_numpys_on_one_and_two_threads():
    """The bands of ``Fx C Fyᵀ`` on threads (issue 45, item 3): numpy's numbers to the bit, on one and two threads,
    on the stadium's sizes (a 128² grid, its 256² fine lattice) with Gaussian factors and their bands."""
    rng = np.random.default_rng(13)
    centres, fine = (np.arange(128) + 0.5) / 128, (np.arange(256) + 0.5) / 256
    fx = np.exp(-0.5 * (centres[:, None] - fine[None, :]) ** 2 / 0.03**2)
    fy = np.exp(-0.5 * (centres[:, None] - fine[None, :] - 0.01) ** 2 / 0.04**2)
    counts = rng.poisson(15.0, (256, 256)).astype(float)
    bx, by = (np.array(_bands(f), np.int64) for f in (fx, fy))
    assert (bx[:, 3] - bx[:, 2] < 256).any()  # banded: some bands skip columns

    def products():
        return banded_products(fx, counts, bx, fy, by, np.empty((128, 256)), np.empty((128, 128)))

    one, two = on_threads(1, products), on_threads(2, products)
    want = _banded_numpy(fx, counts, bx, fy, by, np.empty((128, 256)), np.empty((128, 128)))
    assert np.array_equal(one, want) and np.array_equal(two, want)


@needs_two
@needs_numpy_blas
def test_the_sampled_lattice_is_numpys_on_one_and_two_threads():
    """The sampled field's two products side by side (issue 45, item 3): ``axᵀ fy`` and ``ayᵀ fy`` as numpy's
    ``@`` gives them, to the bit, on one and two threads, at the stadium's 257² nodes and 64 robots."""
    rng = np.random.default_rng(14)
    ax, ay, fy = rng.standard_normal((64, 257)), rng.standard_normal((64, 257)), rng.standard_normal((64, 257))

    def products():
        return lattice_products(ax, ay, fy, np.empty((257, 257)), np.empty((257, 257)))

    one, two = on_threads(1, products), on_threads(2, products)
    assert np.array_equal(one[0], ax.T @ fy) and np.array_equal(one[1], ay.T @ fy)
    assert np.array_equal(two[0], one[0]) and np.array_equal(two[1], one[1])
    want = _lattice_numpy(ax, ay, fy, np.empty((257, 257)), np.empty((257, 257)))
    assert np.array_equal(want[0], one[0]) and np.array_equal(want[1], one[1])
