"""The forward-cell door model (docs page *Congestion*, "The forward-cell door model").

Its density, ``1/(2 A)`` with ``A`` the part of one's Voronoi cell ahead, is checked against exact answers: a
hexagonal lattice at any angle to the walk reads its density ``2/(√3 s²)`` along every turn, lanes ``1/(s ℓ)``, a
human alone the half of its square, one beside a wall the half cut by it, one in front of an exit the whole
half.  The compiled loop agrees with its numpy twin, and with itself on one and on two threads; the soft core
and the following cone agree with their twins; the cone stops a walk into one standing and lets one follow a
leader walking away.  A human alone walks at the free speed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from meanfield._compiled import core as compiled
from meanfield._compiled.core import PARALLEL_CHUNK
from meanfield.crowds._forward_cell_loops import forward_cells
from meanfield.crowds._headway_loops import cell_list, following_cone
from meanfield.crowds.congestion import Linear
from meanfield.crowds.forward_cell import CELL_REACH, ForwardCell, wall_segments
from meanfield.crowds.headway import TURNS
from meanfield.geometry.plan import Plan

COS, SIN = np.cos(TURNS), np.sin(TURNS)
NO_WALL = np.empty((0, 2))
D = math.sqrt(2.0 / (math.sqrt(3.0) * 5.4))  # the jam spacing at ρ_max = 5.4


def _areas(x, e, active=None, walls=(NO_WALL, NO_WALL), reach=CELL_REACH):
    active = np.ones(len(x), bool) if active is None else active
    out = np.empty((len(x), len(COS)))
    return forward_cells(x, e, active, COS, SIN, reach, *walls, cell_list(x, active, D), out)


def _along(angle, n):
    return np.tile([math.cos(angle), math.sin(angle)], (n, 1))


@pytest.mark.parametrize("angle", [0.0, 0.3, math.pi / 6, 1.0, 2.5])
def test_a_hexagonal_lattice_reads_its_density_along_every_turn(angle):
    s = 0.7
    pts = np.array([[i * s + 0.5 * s * (j % 2), j * s * math.sqrt(3) / 2] for j in range(21) for i in range(21)])
    a = _areas(pts, _along(angle, len(pts)))
    centre = 10 * 21 + 10
    assert 0.5 / a[centre] == pytest.approx(np.full(len(COS), 2.0 / (math.sqrt(3.0) * s * s)), rel=1e-12)


def test_lanes_read_one_over_the_headway_times_their_spacing():
    headway, spacing = 0.9, 0.4
    pts = np.array([[i * headway, j * spacing] for j in range(12) for i in range(30)])
    a = _areas(pts, _along(0.0, len(pts)))
    assert 0.5 / a[6 * 30 + 15] == pytest.approx(np.full(len(COS), 1.0 / (headway * spacing)), rel=1e-12)
    # the last of a lane, with nobody ahead in the square, has its half of the square's width ahead of it
    last = 6 * 30 + 29
    assert a[last, 0] == pytest.approx(CELL_REACH * spacing, rel=1e-12)


def test_one_alone_has_half_its_square_a_wall_cuts_it_and_an_exit_does_not():
    plan = Plan(shapely.box(0, 0, 20, 20), exits=[((20.0, 8.0), (20.0, 12.0))])
    walls = wall_segments(plan)
    assert len(walls[0]) == 5  # the exit is not a wall: the east side is two walls beside it
    alone = _areas(np.array([[10.0, 10.0]]), _along(0.0, 1), walls=walls)
    assert alone[0] == pytest.approx(np.full(len(COS), 2.0 * CELL_REACH**2), rel=1e-12)
    near_wall = _areas(np.array([[10.0, 1.0]]), _along(0.0, 1), walls=walls)  # walking east, the wall 1 m south
    assert near_wall[0, 0] == pytest.approx(CELL_REACH * (CELL_REACH + 1.0), rel=1e-12)
    at_exit = _areas(np.array([[19.5, 10.0]]), _along(0.0, 1), walls=walls)  # facing the exit, 0.5 m from it
    assert at_exit[0, 0] == pytest.approx(2.0 * CELL_REACH**2, rel=1e-12)


def _crowd(n, seed=3):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 9.0, (n, 2))
    e = rng.normal(size=(n, 2))
    e /= np.hypot(e[:, 0], e[:, 1])[:, None]
    e[::17] = 0.0  # some stand
    active = rng.random(n) > 0.1
    plan = Plan(shapely.box(0, 0, 9, 9), exits=[((9.0, 3.0), (9.0, 5.0))])
    return x, e, active, wall_segments(plan)


def test_the_compiled_cells_are_the_numpy_twin_s_and_the_standing_read_half_their_cell():
    x, e, active, walls = _crowd(400)
    fast = _areas(x, e, active, walls)
    with compiled.numpy_path():
        slow = _areas(x, e, active, walls)
    assert np.all(np.isinf(fast[~active])) and np.all(np.isinf(slow[~active]))
    assert np.allclose(fast[active], slow[active], rtol=1e-12, atol=0.0)
    standing = active & (e[:, 0] == 0.0)
    assert standing.any() and np.all(fast[standing] == fast[standing, :1])  # every turn: half the cell
    assert np.all(fast[active] > 0.0)


def test_the_cells_are_the_same_on_one_and_two_threads():
    numba = pytest.importorskip("numba")
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here")
    x, e, active, walls = _crowd(5 * PARALLEL_CHUNK + 123, seed=5)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = _areas(x, e, active, walls)
        numba.set_num_threads(2)
        two = _areas(x, e, active, walls)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one, two)


def test_the_following_cone_is_its_numpy_twin_s_and_touches_only_those_who_touch():
    x, e, active, _ = _crowd(300, seed=7)
    x = x * 0.5  # dense enough that many touch
    rng = np.random.default_rng(2)
    walk = e * rng.uniform(0.0, 1.34, (len(x), 1))
    cells = cell_list(x, active, D)
    fast = following_cone(np.empty_like(walk), walk, x, active, D, 1.34, cells)
    with compiled.numpy_path():
        slow = following_cone(np.empty_like(walk), walk, x, active, D, 1.34, cells)
    assert np.allclose(fast, slow, rtol=0.0, atol=1e-12)
    r = np.hypot(*(x[:, None, :] - x[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(r, np.inf)
    touching = ((r < D) & active[None, :]).any(axis=1) & active
    assert touching.sum() > 50
    assert np.array_equal(fast[~touching], walk[~touching]) and not np.allclose(fast[touching], walk[touching])


def test_the_following_cone_stops_a_walk_into_one_standing_and_lets_one_follow_a_leader_walking_away():
    x = np.array([[0.0, 0.0], [0.9 * D, 0.0]])
    active = np.ones(2, bool)
    cells = cell_list(x, active, D)
    standing = np.array([[1.0, 0.3], [0.0, 0.0]])
    v = following_cone(np.empty_like(standing), standing, x, active, D, 0.0, cells)
    assert v[0] == pytest.approx([0.0, 0.3], abs=1e-15)  # slides past it, walks no nearer
    leaving = np.array([[1.0, 0.0], [0.6, 0.0]])
    v = following_cone(np.empty_like(leaving), leaving, x, active, D, 0.0, cells)
    assert v[0] == pytest.approx([0.6, 0.0], abs=1e-15)  # follows at the leader's pace, where (H2) stood
    assert v[1] == pytest.approx([0.6, 0.0], abs=1e-15)  # the leader walks on (the follower walks toward it)
    # three contacts round one human: the nearest feasible walk is a corner of the polygon
    x3 = np.array([[0.0, 0.0], [0.4, 0.0], [0.0, 0.4], [-0.3, -0.3]])
    walk3 = np.array([[1.0, 1.0], [0.2, 0.0], [0.0, 0.5], [0.0, 0.0]])
    a3 = np.ones(4, bool)
    v3 = following_cone(np.empty_like(walk3), walk3, x3, a3, D, 0.0, cell_list(x3, a3, D))
    assert v3[0] == pytest.approx([0.2, 0.5], abs=1e-15)


def test_one_alone_walks_free_and_one_touching_the_person_ahead_follows_no_faster():
    model = ForwardCell(Linear(1.34, 5.4))
    x = np.array([[0.0, 0.0], [0.9 * D, 0.0], [30.0, 0.0]])
    v = np.array([[1.34, 0.0], [1.34, 0.0], [1.34, 0.0]])
    model.slow_down(v, x, None)
    assert v[2, 0] == pytest.approx(1.34 * (1.0 - 1.0 / (4.0 * CELL_REACH**2) / 5.4), rel=1e-12)
    # the one behind touches the one ahead, which walks on at the free speed: it follows at that pace, no faster
    assert v[0, 0] <= v[1, 0] + 1e-12
    assert v[1, 0] > 0.9 * 1.34
