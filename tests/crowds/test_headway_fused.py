"""The headway door model's fused lanes (docs page *Congestion*, "The headway door model"; issue 42, "Cost").

* :func:`~meanfield.crowds._headway_loops.lane_headways` gives, in one walk of each human's neighbours, the numbers
  of one :func:`~meanfield.crowds._headway_loops.headways` per turned lane, to the last bit: compiled against its
  numpy twin and against ``K`` separate calls, for random crowds, several sets of turns, lanes and reaches,
  inactive and non-finite humans and standing ones (``e = 0``);
* with walls, each turned lane is cut where :meth:`~meanfield.geometry.walls.WallIndex.first_hit` says, as
  (H4) did with one ray cast for all the turned rays;
* :func:`~meanfield.crowds._headway_loops.choose_lanes` picks numpy's ``argmax`` of ``f cos θ`` (the first of equal
  gains) and turns the route as numpy does;
* :meth:`~meanfield.crowds.headway.Headway.choose_direction` equals the per-turn reference it replaced, and its
  numbers do not depend on numba's threads.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield._compiled import core as compiled
from meanfield.crowds._cell_list import cell_list
from meanfield.crowds._headway_loops import (
    NO_WALLS,
    LaneWalls,
    choose_lanes,
    headways,
    lane_headways,
)
from meanfield.crowds.congestion import Linear, Weidmann
from meanfield.crowds.headway import TURNS, Headway, boundary_walls

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")

JAM = math.sqrt(2.0 / (math.sqrt(3.0) * 5.4))

TURN_SETS = {
    "route only": (0.0,),
    "(H4)": TURNS,
    "three": (0.0, 0.3, -0.3),
    "nine": tuple(math.radians(a) for a in (0, -10, 10, -20, 20, -40, 40, -60, 60)),
}


def crowd(n, rng, width):
    """A random crowd with standing, inactive and non-finite humans, and two at the same point."""
    x = rng.uniform(0.0, width, (n, 2))
    e = rng.normal(size=(n, 2))
    e /= np.hypot(*e.T)[:, None]
    e[::7] = 0.0  # some stand
    active = rng.random(n) > 0.15
    x[5] = np.nan
    x[9] = [np.inf, 1.0]
    x[12] = x[13]
    return x, e, active


def per_turn(x, e, active, turns, lane, reach, cells):
    """The reference: one :func:`headways` per turned lane, the lanes turned in numpy."""
    out = np.empty((len(x), len(turns)))
    col = np.empty(len(x))
    for q, a in enumerate(turns):
        c, s = math.cos(a), math.sin(a)
        turned = np.column_stack([c * e[:, 0] - s * e[:, 1], s * e[:, 0] + c * e[:, 1]])
        out[:, q] = headways(x, turned, active, lane, reach, cells, col)
    return out


def cos_sin(turns):
    return np.array([math.cos(a) for a in turns]), np.array([math.sin(a) for a in turns])


@pytest.mark.parametrize("turns", list(TURN_SETS), ids=str)
@pytest.mark.parametrize(
    "seed, n, width, lane, reach",
    [(0, 400, 10.0, JAM, 3.0), (1, 300, 6.0, 0.3, 1.5), (2, 500, 20.0, 0.6, 4.0), (3, 200, 3.0, JAM, 0.7)],
)
def test_the_fused_lanes_are_the_per_turn_headways_to_the_last_bit(turns, seed, n, width, lane, reach):
    x, e, active = crowd(n, np.random.default_rng(seed), width)
    cells = cell_list(x, active, JAM)
    c, s = cos_sin(TURN_SETS[turns])
    fused = lane_headways(x, e, active, c, s, lane, reach, cells, np.empty((n, len(c))))
    ref = per_turn(x, e, active, TURN_SETS[turns], lane, reach, cells)
    assert np.array_equal(fused, ref)
    assert np.isinf(fused[::7]).all()  # those standing have no lane
    assert np.isinf(fused[~active]).all()
    assert np.isfinite(fused).sum() > n // 4 and np.isinf(fused[active]).sum() > 0
    with compiled.numpy_path():
        twin = lane_headways(x, e, active, c, s, lane, reach, cells, np.empty((n, len(c))))
    assert np.array_equal(twin, ref)


@pytest.mark.parametrize("h", [JAM / 2, JAM, 2.5])
def test_the_fused_lanes_do_not_depend_on_the_cells(h):
    """The search walks any cell width to the same minima (the cells only order the search)."""
    x, e, active = crowd(400, np.random.default_rng(4), 9.0)
    c, s = cos_sin(TURNS)
    fused = lane_headways(x, e, active, c, s, JAM, 3.0, cell_list(x, active, h), np.empty((400, len(c))))
    assert np.array_equal(fused, per_turn(x, e, active, TURNS, JAM, 3.0, cell_list(x, active, JAM)))


def bottleneck_walls():
    from meanfield import Domain

    room = Domain.from_wkt("POLYGON ((0 0, 10 0, 10 3.5, 12 3.5, 12 4.5, 10 4.5, 10 8, 0 8, 0 0))")
    return boundary_walls(room)


@pytest.mark.parametrize("seed", [0, 1])
def test_walls_cut_the_turned_lanes_where_the_first_hit_says(seed):
    """(H4)'s walls: each turned ray ``X → X + R t`` cut at ``t_hit R + d/2`` (the route's own lane never), as
    :meth:`~meanfield.geometry.walls.WallIndex.first_hit` casts it; for every human, active or not."""
    index = bottleneck_walls()
    rng = np.random.default_rng(seed)
    x, e, active = crowd(300, rng, 1.0)
    x = x * [12.0, 8.0]  # over the whole room, the door's nook and a little beyond
    x[20:30] = rng.uniform(-0.5, 12.5, (10, 2))
    cells = cell_list(x, active, JAM)
    c, s = cos_sin(TURNS)
    reach, half = 3.0, 0.5 * JAM
    walls = LaneWalls(index.a, index.e, (0.0, 12.0, 0.0, 8.0), reach)
    fused = lane_headways(x, e, active, c, s, JAM, reach, cells, np.empty((300, len(c))), walls, half)
    ref = per_turn(x, e, active, TURNS, JAM, reach, cells)
    turned = np.stack([np.column_stack([ci * e[:, 0] - si * e[:, 1], si * e[:, 0] + ci * e[:, 1]])
                       for ci, si in zip(c[1:], s[1:], strict=True)])  # fmt: skip
    start = np.broadcast_to(x, turned.shape).reshape(-1, 2)
    t, _ = index.first_hit(start, start + reach * turned.reshape(-1, 2))
    cut = (t * reach + half).reshape(len(c) - 1, 300).T
    ref[:, 1:] = np.minimum(ref[:, 1:], cut)
    assert np.array_equal(fused, ref)
    assert np.sum(fused[:, 1:] < per_turn(x, e, active, TURNS, JAM, reach, cells)[:, 1:]) > 100  # walls cut lanes
    assert np.isfinite(fused[~active]).any()  # the inactive are cut too, as the single ray cast did
    with compiled.numpy_path():
        twin = lane_headways(x, e, active, c, s, JAM, reach, cells, np.empty((300, len(c))), walls, half)
    assert np.array_equal(twin, ref)


def test_a_ray_from_outside_the_walls_lattice_meets_every_wall():
    index = bottleneck_walls()
    walls = LaneWalls(index.a, index.e, (0.0, 12.0, 0.0, 8.0), 3.0)
    x = np.array([[-1.0, 4.0], [13.0, 4.2], [5.0, 4.0]])
    e = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    active = np.ones(3, bool)
    c, s = cos_sin((0.0, 0.5))
    out = lane_headways(x, e, active, c, s, JAM, 3.0, cell_list(x, active, JAM), np.empty((3, 2)), walls, 0.25)
    # human 0 at x = -1 looks 0.5 rad left of east: the wall x = 0 at 1/cos(0.5) m
    assert out[0, 1] == pytest.approx(1.0 / math.cos(0.5) + 0.25, rel=1e-12)
    assert out[1, 1] == pytest.approx(1.0 / math.cos(0.5) + 0.25, rel=1e-12)  # from x = 13 the door's wall x = 12
    assert math.isinf(out[2, 1]) and math.isinf(out[0, 0])  # from the middle nothing within 3 m; lane 0 uncut


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_choice_is_numpy_s_argmax_of_the_progress(seed):
    rng = np.random.default_rng(seed)
    n, c, s = 500, *cos_sin(TURNS)
    f = rng.choice([0.0, 0.25, 0.5, 1.0], size=(n, len(c)))  # many ties
    f[::9, 3] = math.nan
    head = rng.uniform(0.3, 4.0, (n, len(c)))
    e = rng.normal(size=(n, 2))
    e[::5] = 0.0
    got = [np.empty(n), np.empty(n), np.empty((n, 2))]
    choose_lanes(f, head, e, c, s, *got)
    want = [np.empty(n), np.empty(n), np.empty((n, 2))]
    with compiled.numpy_path():
        choose_lanes(f, head, e, c, s, *want)
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    best = np.argmax(f * c, axis=1)  # the rule itself, once more
    assert np.array_equal(want[0], head[np.arange(n), best])
    assert np.sum(best > 0) > 50 and np.sum(best == 0) > 50


def reference_choice(model, x, e, active, cells):
    """(H4) as it was: one :func:`headways` per turn, one ray cast for all the turned rays, numpy's argmax."""
    n, k = len(x), len(model.turns)
    c = np.array([math.cos(a) for a in model.turns])[:, None]
    sn = np.array([math.sin(a) for a in model.turns])[:, None]
    turned = np.empty((k, n, 2))
    turned[:, :, 0] = c * e[:, 0] - sn * e[:, 1]
    turned[:, :, 1] = sn * e[:, 0] + c * e[:, 1]
    s = np.empty((k, n))
    for i in range(k):
        headways(x, turned[i], active, model.lane, model.reach, cells, s[i])
    if model.walls is not None and k > 1:
        start = np.broadcast_to(x, (k - 1, n, 2)).reshape(-1, 2)
        t, _ = model.walls.first_hit(start, start + model.reach * turned[1:].reshape(-1, 2))
        np.minimum(s[1:], (t * model.reach + 0.5 * model.jam_spacing).reshape(k - 1, n), out=s[1:])
    f = model.speed_factor(s)
    best = np.argmax(f * c, axis=0)
    pick = np.arange(n)
    return s[best, pick], f[best, pick], turned[best, pick]


@pytest.mark.parametrize("diagram", [Linear(), Weidmann()], ids=["linear", "weidmann"])
@pytest.mark.parametrize("walled", [False, True])
def test_the_direction_is_the_per_turn_reference_s_to_the_last_bit(diagram, walled):
    from meanfield import Domain

    room = Domain.from_wkt("POLYGON ((0 0, 10 0, 10 3.5, 12 3.5, 12 4.5, 10 4.5, 10 8, 0 8, 0 0))")
    model = Headway(diagram, region=room if walled else None)
    rng = np.random.default_rng(5)
    x, e, active = crowd(400, rng, 1.0)
    x = x * [10.0, 8.0]
    cells = cell_list(x, active, model.jam_spacing)
    got = model.choose_direction(x, e, active, cells)
    want = reference_choice(model, x, e, active, cells)
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b)
    assert np.sum(np.any(got[2] != e, axis=1)) > 20  # some turn


@needs_numba
def test_the_fused_lanes_do_not_depend_on_the_threads():
    """Above one chunk the loops run on numba's threads: each human writes its own row, so one thread and every
    thread give the same numbers."""
    import numba

    if not compiled.enabled():
        pytest.skip("the compiled path is off (MEANFIELD_COMPILED=0): nothing to compare")
    from meanfield.crowds._headway_loops import _choose_compiled, _lanes_compiled

    x, e, active = crowd(12000, np.random.default_rng(6), 45.0)
    cells = cell_list(x, active, JAM)
    index = bottleneck_walls()
    walls = LaneWalls(index.a * 4.0, index.e * 4.0, (0.0, 48.0, 0.0, 32.0), 3.0)
    c, s = cos_sin(TURNS)
    before = numba.get_num_threads()
    runs = []
    try:
        for threads in sorted({1, before}):
            numba.set_num_threads(threads)
            out = lane_headways(x, e, active, c, s, JAM, 3.0, cells, np.empty((len(x), len(c))), walls, 0.5 * JAM)
            f = Linear().speed_factor(5.4 * (JAM / out) ** 2)
            got = [np.empty(len(x)), np.empty(len(x)), np.empty((len(x), 2))]
            choose_lanes(f, out, e, c, s, *got)
            runs.append((out, *got))
    finally:
        numba.set_num_threads(before)
    assert _lanes_compiled._threaded is not None and _choose_compiled._threaded is not None  # the threaded versions
    for a, b in zip(runs[0], runs[-1], strict=True):
        assert np.array_equal(a, b)
    with compiled.numpy_path():
        twin = lane_headways(x, e, active, c, s, JAM, 3.0, cells, np.empty((len(x), len(c))), walls, 0.5 * JAM)
    assert np.array_equal(runs[0][0], twin)


def test_no_walls_is_no_cut():
    x, e, active = crowd(100, np.random.default_rng(8), 4.0)
    cells = cell_list(x, active, JAM)
    c, s = cos_sin(TURNS)
    a = lane_headways(x, e, active, c, s, JAM, 3.0, cells, np.empty((100, 7)), NO_WALLS, 0.25)
    assert np.array_equal(a, per_turn(x, e, active, TURNS, JAM, 3.0, cells))


@pytest.mark.parametrize("seed, n, h", [(0, 300, JAM), (1, 2000, 0.2), (2, 50, 3.0), (3, 1, JAM)])
def test_the_compiled_cell_list_is_the_stable_counting_sort(seed, n, h):
    """The cells' arrays, compiled and numpy, to the last bit (the width doubled alike when the box is wide)."""
    x, _, active = crowd(max(n, 20), np.random.default_rng(seed), 30.0)
    x, active = x[:n], active[:n]
    if n == 1:
        active[:] = True
    x[: n // 3] *= 40.0  # a few far away: more cells than 4 m + 64 at width h, so it doubles
    got = cell_list(x, active, h)
    with compiled.numpy_path():
        want = cell_list(x, active, h)
    for a, b in zip(got.arrays(), want.arrays(), strict=True):
        assert np.array_equal(np.asarray(a), np.asarray(b)) and type(a) is type(b)
    assert got.nx * got.ny <= 4 * len(got.order) + 64 and len(got.order) == np.sum(active & np.isfinite(x).all(1))
    empty = cell_list(x, np.zeros(n, bool), h)
    assert len(empty.order) == 0 and empty.starts.tolist() == [0, 0] and empty.sorted.shape == (0, 2)


def test_the_cell_list_sorted_in_runs_on_threads_is_the_one_run_sort():
    """Above PARALLEL_CHUNK humans the sort runs on threads, in runs of the humans; any number of runs, on one thread
    or two, gives the numpy twin's arrays to the last bit."""
    numba = pytest.importorskip("numba")
    from meanfield._compiled.core import PARALLEL_CHUNK
    from meanfield.crowds._cell_list import _cells_compiled

    n = 3 * PARALLEL_CHUNK + 77
    x, _, active = crowd(n, np.random.default_rng(11), 60.0)
    x[5] = np.nan  # one without a position: not sorted
    with compiled.numpy_path():
        want = cell_list(x, active, JAM).arrays()
    before = numba.get_num_threads()
    try:
        for threads in {1, min(2, numba.config.NUMBA_NUM_THREADS)}:
            numba.set_num_threads(threads)
            for parts in (1, 2, 3, 7, 10_000):  # (so many runs that their counts are capped)
                got = _cells_compiled(x, active, JAM, parts)
                order, starts, pos, x0, y0, h, nx, ny = got
                assert np.array_equal(order, want[0]) and np.array_equal(starts, want[1])
                assert np.array_equal(pos, want[2]) and (x0, y0) == want[3] and (h, nx, ny) == want[4:]
    finally:
        numba.set_num_threads(before)


def separate_calls(model, v, x, active, density, noise=False):
    """The reference for the one-pass step: :meth:`Headway.slow_down`'s separate calls (the cell list, the lanes,
    the diagram in numpy, the choice, the product, the contact cone, the count, (H5)'s
    :func:`~meanfield.crowds._contact_loops.contact_noise`); with ``noise``, also (H5)'s ``φ`` and ``∇φ``."""
    v = v.copy()
    model._fused = False
    try:
        rho = model.slow_down(v, x, active, 0.0, density)
    finally:
        model._fused = True
    if noise:
        return v, rho, model.noise_factor.copy(), model.noise_gradient.copy()
    return v, rho


def same_noise(model, phi, grad):
    """Whether (H5)'s ``φ`` and ``∇φ`` of the last step are ``phi`` and ``grad`` to the last bit, and touch some."""
    assert np.mean(phi < 1.0) > 0.05  # (the crowd is dense enough for contacts)
    return np.array_equal(model.noise_factor, phi) and np.array_equal(model.noise_gradient, grad)


def step_crowd(n, seed, width=10.0, height=8.0):
    """A crowd of walkers over the bottleneck's room: crowded, some standing, inactive, non-finite, two at one point,
    some outside the room."""
    rng = np.random.default_rng(seed)
    x, e, active = crowd(n, rng, 1.0)
    x = x * [width, height]
    x[20:26] = rng.uniform(-0.5, width + 2.5, (6, 2))
    v = e * rng.uniform(0.5, 1.5, (n, 1))
    v[3] = [np.nan, 1.0]  # a walk that is not finite: its direction is the walk itself
    return v, x, active


@pytest.mark.parametrize("walled", [False, True])
@pytest.mark.parametrize("counted", [False, True])
@pytest.mark.parametrize("seed, n", [(0, 400), (1, 150), (2, 900)])
def test_the_one_pass_step_is_the_separate_calls_to_the_last_bit(walled, counted, seed, n):
    """:func:`headway_step` (one compiled pass: the cell list, (H4), (H1), the choice, (H2), (H3) and the count)
    gives the numbers of the separate calls it replaced, to the last bit: velocities, headways, local densities."""
    from meanfield import Domain
    from meanfield.crowds.local_density import LocalDensity

    room = Domain.from_wkt("POLYGON ((0 0, 10 0, 10 3.5, 12 3.5, 12 4.5, 10 4.5, 10 8, 0 8, 0 0))")
    model = Headway(Linear(), region=room if walled else None)
    v, x, active = step_crowd(n, seed)
    density = LocalDensity(n, 0.5, room if walled else None) if counted else None
    want_v, want_rho, want_phi, want_grad = separate_calls(model, v, x, active, density, noise=True)
    model.noise_factor[:] = np.nan  # (the one pass writes every row)
    model.noise_gradient[:] = np.nan
    got_v = v.copy()
    got_rho = model.slow_down(got_v, x, active, 0.0, density)
    assert model._work is not None  # (the one pass ran)
    assert np.array_equal(got_v, want_v, equal_nan=True)
    assert np.array_equal(got_rho, want_rho, equal_nan=True)
    assert same_noise(model, want_phi, want_grad)
    if counted:
        assert np.mean(got_rho > 0) > 0.5  # (the crowd is dense enough to count)
    with compiled.numpy_path():  # the twin: the same headways and counts, the velocities to round-off
        twin_v = v.copy()
        twin_rho = model.slow_down(twin_v, x, active, 0.0, density)
    assert np.array_equal(twin_rho, want_rho, equal_nan=True)
    assert np.allclose(twin_v, want_v, rtol=1e-12, atol=1e-12, equal_nan=True)
    assert np.allclose(model.noise_factor, want_phi, rtol=1e-12, atol=0.0)
    assert np.allclose(model.noise_gradient, want_grad, rtol=1e-12, atol=1e-12)


def test_the_one_pass_step_reads_again_the_contacts_its_buffers_do_not_hold():
    """A human with more contacts than the buffers hold (``CONTACTS``) has its contacts read again: its cone and
    (H5)'s share of the noise are still those of the separate calls."""
    from meanfield.crowds._contact_loops import CONTACTS

    model = Headway(Linear())
    v, x, active = step_crowd(300, 5)
    rng = np.random.default_rng(5)
    x[30 : 30 + 2 * CONTACTS] = [5.0, 4.0] + rng.normal(0.0, 0.05, (2 * CONTACTS, 2))  # a heap
    active[30 : 30 + 2 * CONTACTS] = True
    want_v, _, want_phi, want_grad = separate_calls(model, v, x, active, None, noise=True)
    got_v = v.copy()
    model.slow_down(got_v, x, active, 0.0)
    assert np.array_equal(got_v, want_v, equal_nan=True)
    assert same_noise(model, want_phi, want_grad)
    assert model.noise_factor[30] < 1e-6  # (the heap's share of the noise)


def test_the_one_pass_step_reads_a_disk_wider_than_its_block_on_its_own():
    """A count's radius beyond the cells read first (``BLOCK`` cells round a human) is counted on its own."""
    from meanfield.crowds.local_density import LocalDensity

    model = Headway(Linear())
    v, x, active = step_crowd(300, 3)
    density = LocalDensity(300, 1.5)
    want_v, want_rho = separate_calls(model, v, x, active, density)
    got_v = v.copy()
    assert np.array_equal(model.slow_down(got_v, x, active, 0.0, density), want_rho)
    assert np.array_equal(got_v, want_v, equal_nan=True)


def test_the_one_pass_step_is_the_weidmann_separate_calls():
    """Another diagram than the linear one takes the separate calls (the one pass has the linear one's ``g``)."""
    from meanfield.crowds.local_density import LocalDensity

    model = Headway(Weidmann())
    assert not model._fused
    v, x, active = step_crowd(200, 4)
    got_v = v.copy()
    model.slow_down(got_v, x, active, 0.0, LocalDensity(200))
    assert model._work is None and not np.array_equal(got_v, v, equal_nan=True)


@needs_numba
def test_the_one_pass_step_does_not_depend_on_the_threads():
    """Above one chunk the one pass runs on numba's threads: each human writes its own row only, so one thread and
    every thread give the same velocities, headways and counts."""
    import numba

    from meanfield import Domain
    from meanfield.crowds._headway_loops import _step_compiled
    from meanfield.crowds.local_density import LocalDensity

    if not compiled.enabled():
        pytest.skip("the compiled path is off (MEANFIELD_COMPILED=0): nothing to compare")
    room = Domain.from_wkt("POLYGON ((0 0, 40 0, 40 14, 48 14, 48 18, 40 18, 40 32, 0 32, 0 0))")
    model = Headway(Linear(), region=room)
    v, x, active = step_crowd(12000, 7, 40.0, 32.0)
    density = LocalDensity(12000, 0.5, room)
    before = numba.get_num_threads()
    runs = []
    try:
        for threads in sorted({1, before}):
            numba.set_num_threads(threads)
            out = v.copy()
            rho = model.slow_down(out, x, active, 0.0, density)
            runs.append((out, rho, model._work.headway.copy(), model.noise_factor.copy(), model.noise_gradient.copy()))
    finally:
        numba.set_num_threads(before)
    assert _step_compiled._threaded is not None  # the threaded version ran
    for a, b in zip(runs[0], runs[-1], strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    want_v, want_rho, want_phi, want_grad = separate_calls(model, v, x, active, density, noise=True)
    assert np.array_equal(runs[0][0], want_v, equal_nan=True) and np.array_equal(runs[0][1], want_rho)
    assert np.array_equal(runs[0][3], want_phi) and np.array_equal(runs[0][4], want_grad)
