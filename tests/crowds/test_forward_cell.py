"""The forward-cell door model (docs page *Congestion*, "The forward-cell door model").

Its cells ahead (the part of one's Voronoi cell ahead of one that one sees) and its density (that cell pooled with
the whole cells of the neighbours ahead) are checked against exact answers: a hexagonal lattice at any angle to the
walk reads its density ``2/(√3 s²)`` along every turn, lanes ``1/(s ℓ)``, a human alone the half of its square,
one beside a wall the half the wall leaves, one facing an exit the half less the corners the walls beside it hide,
one by a corridor's mouth what it sees of the corridor; a crowd placed at random reads nearer its density pooled.
The compiled loop agrees with its numpy twin, and with itself on one and on two threads; the following cone agrees
with its twin, stops a walk into one standing and lets one follow a leader walking away.  A human alone walks at
the free speed.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest
import shapely

from meanfield._compiled import core as compiled
from meanfield._compiled.core import PARALLEL_CHUNK
from meanfield.crowds._cell_list import cell_list
from meanfield.crowds._contact_loops import contact_noise, following_cone
from meanfield.crowds._forward_cell_loops import forward_cells, forward_densities
from meanfield.crowds.congestion import Linear
from meanfield.crowds.forward_cell import CELL_REACH, ForwardCell, wall_segments
from meanfield.crowds.headway import TURNS
from meanfield.geometry.plan import Plan
from meanfield.simulation.loop import ClosedLoop
from tests.crowds.test_agent_congestion import bottleneck

COS, SIN = np.cos(TURNS), np.sin(TURNS)
NO_WALL = np.empty((0, 2))
D = math.sqrt(2.0 / (math.sqrt(3.0) * 5.4))  # the jam spacing at ρ_max = 5.4


def _areas(x, e, active=None, walls=(NO_WALL, NO_WALL), reach=CELL_REACH):
    active = np.ones(len(x), bool) if active is None else active
    out = np.empty((len(x), len(COS)))
    return forward_cells(x, e, active, COS, SIN, reach, *walls, cell_list(x, active, D), out)


def _densities(x, e, active=None, walls=(NO_WALL, NO_WALL), reach=CELL_REACH):
    active = np.ones(len(x), bool) if active is None else active
    out = np.empty((len(x), len(COS)))
    return forward_densities(x, e, active, COS, SIN, reach, *walls, cell_list(x, active, D), out)


def _along(angle, n):
    return np.tile([math.cos(angle), math.sin(angle)], (n, 1))


@pytest.mark.parametrize("angle", [0.0, 0.3, math.pi / 6, 1.0, 2.5])
def test_a_hexagonal_lattice_reads_its_density_along_every_turn(angle):
    s = 0.7
    pts = np.array([[i * s + 0.5 * s * (j % 2), j * s * math.sqrt(3) / 2] for j in range(21) for i in range(21)])
    a = _areas(pts, _along(angle, len(pts)))
    centre = 10 * 21 + 10
    exact = np.full(len(COS), 2.0 / (math.sqrt(3.0) * s * s))
    assert 0.5 / a[centre] == pytest.approx(exact, rel=1e-12)
    assert _densities(pts, _along(angle, len(pts)))[centre] == pytest.approx(exact, rel=1e-12)  # pooled: a count


def test_lanes_read_one_over_the_headway_times_their_spacing():
    headway, spacing = 0.9, 0.4
    pts = np.array([[i * headway, j * spacing] for j in range(12) for i in range(30)])
    a = _areas(pts, _along(0.0, len(pts)))
    exact = np.full(len(COS), 1.0 / (headway * spacing))
    assert 0.5 / a[6 * 30 + 15] == pytest.approx(exact, rel=1e-12)
    assert _densities(pts, _along(0.0, len(pts)))[6 * 30 + 15] == pytest.approx(exact, rel=1e-12)
    # the last of a lane, with nobody ahead in the square, has its half of the square's width ahead of it
    last = 6 * 30 + 29
    assert a[last, 0] == pytest.approx(CELL_REACH * spacing, rel=1e-12)


def test_one_alone_has_half_its_square_a_wall_cuts_it_and_an_exit_does_not():
    plan = Plan(shapely.box(0, 0, 20, 20), exits=[((20.0, 8.0), (20.0, 12.0))])
    walls = wall_segments(plan)
    assert len(walls[0]) == 5  # the exit is not a wall: the east side is two walls beside it
    alone = _areas(np.array([[10.0, 10.0]]), _along(0.0, 1), walls=walls)
    assert alone[0] == pytest.approx(np.full(len(COS), 2.0 * CELL_REACH**2), rel=1e-12)
    assert _densities(np.array([[10.0, 10.0]]), _along(0.0, 1), walls=walls)[0] == pytest.approx(
        np.full(len(COS), 1.0 / (4.0 * CELL_REACH**2)), rel=1e-12
    )
    near_wall = _areas(np.array([[10.0, 1.0]]), _along(0.0, 1), walls=walls)  # walking east, the wall 1 m south
    assert near_wall[0, 0] == pytest.approx(CELL_REACH * (CELL_REACH + 1.0), rel=1e-12)
    at_exit = _areas(np.array([[19.5, 10.0]]), _along(0.0, 1), walls=walls)  # facing the exit, 0.5 m from it
    # it sees through the 4 m exit; the walls beside it hide two triangles of the square's corners beyond them,
    # between the wall and the ray through the exit's end (legs 0.25 m and 1 m)
    hidden = 0.5 * (0.5 * (CELL_REACH - 2.0) / 2.0) * (CELL_REACH - 2.0)
    assert at_exit[0, 0] == pytest.approx(2.0 * CELL_REACH**2 - 2.0 * hidden, rel=1e-9)


def test_one_in_a_room_by_a_corridor_s_mouth_sees_into_the_corridor_as_far_as_the_corner_lets_it():
    """The room 10 m × 8 m, a corridor 2 m wide and long from its east wall (y 3 to 5), a human at (9.5, 2.5)
    alone, walking east: ahead of it within its square, the room's strip 0.5 m × 5.5 m and the corridor's part it
    sees past the corner (10, 3), where ``y >= x − 7``, 2 m² of the corridor's 4: 4.75 m².  The corridor's lower
    wall, whose back it faces, hides nothing a second time."""
    poly = shapely.from_wkt("POLYGON ((0 0, 10 0, 10 3, 12 3, 12 5, 10 5, 10 8, 0 8, 0 0))")
    walls = wall_segments(Plan(poly, exits=[((12.0, 3.0), (12.0, 5.0))]))
    a = _areas(np.array([[9.5, 2.5]]), _along(0.0, 1), walls=walls)
    assert a[0, 0] == pytest.approx(4.75, rel=1e-7)
    with compiled.numpy_path():
        assert _areas(np.array([[9.5, 2.5]]), _along(0.0, 1), walls=walls) == pytest.approx(a, rel=1e-12)


def _crowd(n, seed=3):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 9.0, (n, 2))
    e = rng.normal(size=(n, 2))
    e /= np.hypot(e[:, 0], e[:, 1])[:, None]
    e[::17] = 0.0  # some stand
    active = rng.random(n) > 0.1
    plan = Plan(shapely.box(0, 0, 9, 9), exits=[((9.0, 3.0), (9.0, 5.0))])
    return x, e, active, wall_segments(plan)


def test_a_crowd_placed_at_random_reads_nearer_its_density_pooled_than_by_one_cell():
    """Poisson at 2.5 persons/m²: one's own cell ahead reads 4.75 on average on this draw (4.35–5.02 on draws 0–3:
    ``1/A`` is biased), pooled with the neighbours' cells ahead 2.87 (2.68–2.87)."""
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, 30.0, (2250, 2))
    e = _along(0.0, len(x))
    inner = np.all((x > 5.0) & (x < 25.0), axis=1)
    single = 0.5 / _areas(x, e)[inner, 0]
    pooled = _densities(x, e)[inner, 0]
    assert single.mean() > 1.6 * 2.5 and pooled.mean() < 1.2 * 2.5


def test_the_compiled_cells_are_the_numpy_twin_s_and_the_standing_read_half_their_cell():
    x, e, active, walls = _crowd(400)
    fast = _areas(x, e, active, walls)
    with compiled.numpy_path():
        slow = _areas(x, e, active, walls)
    fast_rho = _densities(x, e, active, walls)
    with compiled.numpy_path():
        slow_rho = _densities(x, e, active, walls)
    assert np.all(fast_rho[~active] == 0.0) and np.allclose(fast_rho, slow_rho, rtol=1e-12, atol=0.0)
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
        one = _areas(x, e, active, walls), _densities(x, e, active, walls)
        numba.set_num_threads(2)
        two = _areas(x, e, active, walls), _densities(x, e, active, walls)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])


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


@pytest.mark.parametrize("path", ["compiled", "numpy"])
def test_the_cone_s_noise_share_is_contact_noise_s_to_the_last_bit_and_leaves_the_walk_as_it_was(path):
    """(H5) from the cone's own search of the contacts: the same ``φ`` and ``∇φ`` as :func:`contact_noise`'s
    separate pass, a heap of more contacts than the buffers first hold among them, and the same walk as without."""
    x, e, active, _ = _crowd(300, seed=7)
    x = x * 0.5
    x[:40] = 2.0 + 0.05 * np.random.default_rng(4).normal(size=(40, 2))  # 39 contacts each: buffers grow
    walk = e * np.random.default_rng(2).uniform(0.0, 1.34, (len(x), 1))
    cells = cell_list(x, active, D)
    with compiled.numpy_path() if path == "numpy" else contextlib.nullcontext():
        phi, grad = np.full(len(x), np.nan), np.full((len(x), 2), np.nan)
        fused = following_cone(np.empty_like(walk), walk, x, active, D, 1.34, cells, (phi, grad), 3.0)
        alone = following_cone(np.empty_like(walk), walk, x, active, D, 1.34, cells)
        ref_phi, ref_grad = np.empty(len(x)), np.empty((len(x), 2))
        contact_noise(x, active, D, cells, ref_phi, ref_grad, 3.0)
    assert np.array_equal(fused, alone)
    assert np.array_equal(phi, ref_phi) and np.array_equal(grad, ref_grad)
    assert (phi[active] < 1.0).sum() > 50 and np.all(phi[~active] == 1.0) and np.all(grad[~active] == 0.0)


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


@pytest.mark.parametrize("reach", [0.0, -1.0, float("inf"), float("nan")])
def test_a_reach_that_bounds_no_cell_is_refused_naming_it(reach):
    with pytest.raises(ValueError, match="reach"):
        ForwardCell(Linear(1.34, 5.4), reach=reach)


def test_the_forward_cell_is_the_point_masses_default_and_auto_each_kind_s_own():
    """``crowd.door_model = "auto"`` (the default) is the first model a crowd kind declares: the forward cell for the
    point masses (the headway from 2026-12-05 to 2026-12-06), whose crowd then walks it; the density and the bodies
    declare none and take ``"auto"``, and ``"count"``, the default before, which a scenario recorded then holds (a
    run's ``summary.json`` is read again as it was)."""
    sc = bottleneck("linear", t_final=1.0)
    assert sc.crowd.door_model == "auto" and sc.door_model == "forward-cell"
    assert ClosedLoop(sc).crowd.door_model == "forward-cell"
    assert sc.with_values({"crowd.door_model": "count"}).door_model == "count"
    assert sc.with_values({"crowd.door_model": "headway"}).door_model == "headway"
    for kind, congestion in (("fokker-planck", "linear"), ("jupedsim", "none")):
        assert bottleneck(congestion, **{"crowd.kind": kind}).crowd.door_model == "auto"
        recorded = bottleneck(congestion, **{"crowd.kind": kind}).to_dict()
        recorded["crowd"]["door_model"] = "count"
        assert type(sc).from_dict(recorded).crowd.door_model == "count"
