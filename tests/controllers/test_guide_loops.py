"""The guide's per-step loops, compiled (issue 45, "Small crowds fast"): each against its numpy twin, bit for bit.

* :func:`meanfield.controllers._guide_loops.share_moments` (each cell's robot within its share and the robots'
  moments) against its twin and the guide's code before it (a compiled ``owners`` call and three ``np.bincount`` per
  share): the same owners, masses and moments, with walls and without, ties to the first robot, robots without a
  share, shares without robots or cells, a robot at NaN (as the compiled ``owners`` gave it);
* :func:`meanfield.geometry._walking_loops.nearest_walk` (the routed pull's walk to a robot's cell nearest its
  centroid) against its twin and against :meth:`~meanfield.geometry.walking.WalkingDistances.walk_to` followed by the
  nearest cell, the code before it, round a wall, and with cells no route reaches (a plan a block cut in pieces);
* :func:`meanfield.geometry._walking_loops.tree_anchors` (each cell's nearest ancestor in sight on Dijkstra's trees)
  against its twin, the pointer jumping before it; the trees planted on the graph as directed are the undirected
  ones;
* :func:`meanfield.controllers._queue_loops.label_search` (the guide's search for its signs' labels) against its twin,
  the guide's search before it, and the sums of the compiled loops against ``np.sum``;
* :func:`meanfield.signs._reach_loops.boxes_on_grid` (the cells the signs reach, laid on the grid) against its twin
  (the boxed test against the whole grid's is ``tests/signs/test_kernels.py``'s).
"""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from meanfield import Grid
from meanfield._compiled import core as compiled
from meanfield.controllers._coverage_loops import owners
from meanfield.controllers._guide_loops import share_moments
from meanfield.geometry._walking_loops import nearest_walk, tree_anchors
from meanfield.geometry.plan import Plan
from meanfield.geometry.sight import SightLines
from meanfield.geometry.walking import WalkingDistances

needs_numba = pytest.mark.skipif(not compiled.enabled(), reason="numba is not installed, or MEANFIELD_COMPILED=0")

TWO_ROOMS = Plan.from_wkt("POLYGON ((0 0, 3.9 0, 3.9 3, 4.1 3, 4.1 0, 8 0, 8 4, 0 4, 0 0))")
"""Two 4 m rooms side by side, a 1 m gap at the top of the wall between them."""


def _both(loop, *args):
    fast = loop(*[a.copy() if isinstance(a, np.ndarray) else a for a in args])
    assert loop._ready, f"{loop.name} did not run compiled"
    with compiled.numpy_path():
        ref = loop(*[a.copy() if isinstance(a, np.ndarray) else a for a in args])
    return fast, ref


@needs_numba
@pytest.mark.parametrize("hidden", [True, False])
def test_share_moments_are_its_numpy_twins_bit_for_bit(hidden):
    rng = np.random.default_rng(4)
    m, n, k = 500, 9, 4
    xy = rng.uniform(0, 10, (m, 2))
    robots = rng.uniform(0, 10, (n, 2))
    robots[5] = robots[2]  # a tie: the first robot listed wins
    team = np.array([0, 1, 0, 2, -1, 0, 1, 3, 2], np.intp)  # robot 4 without a share; share 3 without cells
    share = rng.integers(-1, k - 1, m).astype(np.intp)  # cells of no share; share 3 has none
    share[:20] = 4  # a share no robot has
    w = rng.uniform(0, 1, m) * (rng.uniform(size=m) < 0.8)  # cells without weight
    cells = rng.permutation(800)[:m].astype(np.intp)
    seen = rng.uniform(size=(n, 800)) < 0.3
    seen[5] = seen[2]
    args = (xy, robots, team, share, w, seen, cells, hidden)
    out = (np.empty(m, np.intp), np.empty(n), np.empty(n), np.empty(n))
    fast, ref = _both(share_moments, *args, *out)
    for a, b in zip(fast, ref, strict=True):
        np.testing.assert_array_equal(a, b)
    owner, mass = fast[0], fast[1]
    assert (owner[:20] == -1).all() and (owner[share < 0] == -1).all() and 5 not in owner
    assert mass[4] == 0 and mass[7] == 0 and (mass[[0, 1, 2, 3]] > 0).all()
    assert np.array_equal(team[owner[owner >= 0]], share[owner >= 0])  # each cell's robot is of its share

    for k in (0, 1, 2):  # the guide's code before: a compiled owners call and three bincounts per share
        mine, here = np.flatnonzero(team == k), np.flatnonzero(share == k)
        local = owners(xy[here], robots[mine], seen[mine], cells[here], hidden, np.empty(len(here), np.intp))
        assert np.array_equal(owner[here], mine[local])
        assert np.array_equal(mass[mine], np.bincount(local, weights=w[here], minlength=len(mine)))
        assert np.array_equal(fast[2][mine], np.bincount(local, weights=w[here] * xy[here, 0], minlength=len(mine)))

    robots[1] = np.nan  # a robot nowhere: its share's cells go to its other robot, as the compiled owners gave them
    owner, mass, _, _ = share_moments(xy, robots, team, share, w, seen, cells, hidden, *out)
    mine, here = np.flatnonzero(team == 1), np.flatnonzero(share == 1)
    local = owners(xy[here], robots[mine], seen[mine], cells[here], hidden, np.empty(len(here), np.intp))
    assert np.array_equal(owner[here], mine[local]) and 1 not in owner and mass[1] == 0


@needs_numba
def test_the_walk_to_a_robots_nearest_cell_is_walk_to_s_nearest_column_bit_for_bit():
    plan = TWO_ROOMS
    walk = WalkingDistances(Grid(plan, (40, 20)), SightLines(plan))
    rng = np.random.default_rng(11)
    robots = plan.sample_uniform(6, rng)
    owner = rng.integers(0, 6, len(walk.cells)).astype(np.intp)
    for cut in (False, True):
        for i, target in enumerate(plan.sample_uniform(6, rng)):
            start = int(walk._planted(robots[i : i + 1])[0])
            D, anchor = walk._trees[start]
            if cut:  # the right room beyond reach (a block cut the plan): its cells' trees end at inf
                D = (
                    np.where(walk.xy[:, 0] > 4.0, np.inf, D)
                    if robots[i, 0] < 4.0
                    else np.where(walk.xy[:, 0] < 4.0, np.inf, D)
                )
                walk._trees[start] = D, anchor
            fast, ref = _both(nearest_walk, walk.xy, D, anchor, owner, i, robots[i], target, np.empty(3))
            np.testing.assert_array_equal(fast, ref)
            owned = np.flatnonzero(owner == i)  # the code before: every walk to the robot's cells, then the nearest
            distance, leg = walk.walk_to(robots[i], owned)
            reached = np.isfinite(distance)
            mine = owned[reached]
            t = np.argmin(np.hypot(walk.xy[mine, 0] - target[0], walk.xy[mine, 1] - target[1]))
            d, e = walk.walk_to_nearest(robots[i], owner, i, target)
            assert d == distance[reached][t] and np.array_equal(e, leg[reached][t])
            assert np.array_equal(d * e, distance[reached][t] * leg[reached][t])
    nobody = np.full(len(walk.cells), -1, np.intp)  # a robot that owns no cell: no walk
    d, e = walk.walk_to_nearest(robots[0], nobody, 0, robots[1])
    assert d == np.inf and np.array_equal(e, [0.0, 0.0])


@needs_numba
def test_the_trees_anchors_are_the_pointer_jumping_s_fixed_point():
    """:func:`tree_anchors` against its twin (pointer jumping) on the trees of every start cell of two rooms, with
    cells no tree reaches; and a tree planted from scratch is the one the undirected Dijkstra plants."""
    from scipy.sparse.csgraph import dijkstra

    walk = WalkingDistances(Grid(TWO_ROOMS, (40, 20)), SightLines(TWO_ROOMS))
    starts = np.arange(0, len(walk.cells), 7)
    D, pred = dijkstra(walk.graph, directed=False, indices=starts, return_predecessors=True)
    seen = walk.sight.cell_rows(walk.grid, walk.xy[starts]).reshape(len(starts), -1)[:, walk.cells]
    seen |= pred == starts[:, None]
    seen[np.arange(len(starts)), starts] = True
    with compiled.numpy_path():
        jumped = tree_anchors(pred, seen, np.empty(pred.shape, np.int64))
    walk._plant(starts, walk.xy[starts])  # the trees (directed: the graph holds each link both ways) and anchors
    for row, k in enumerate(starts):
        np.testing.assert_array_equal(walk._trees[int(k)][0], D[row])
        np.testing.assert_array_equal(walk._trees[int(k)][1], jumped[row])
    pred[:, :15] = -9999  # cells no tree reaches (a plan in pieces)
    fast, ref = _both(tree_anchors, np.ascontiguousarray(pred), seen, np.empty(pred.shape, np.int64))
    np.testing.assert_array_equal(fast, ref)
    assert (fast[:, :15] == np.arange(15)).all() and (fast != np.arange(len(walk.cells))).any()


@needs_numba
def test_sums_in_the_compiled_loops_are_numpy_s_to_the_bit():
    """The exits' loops sum as ``np.sum`` does (:func:`meanfield.controllers._queue_loops._pairwise_sum`): every length
    up to a few blocks of 128 and long ones, terms of mixed signs over 16 orders of magnitude."""
    from meanfield._compiled.core import compile_inner
    from meanfield.controllers._queue_loops import _pairwise_sum

    pairwise = compile_inner(_pairwise_sum)
    rng = np.random.default_rng(3)
    for n in [*range(300), 1000, 1024, 1031, 2376, 8191, 8192, 8200, 20011]:
        a = rng.standard_normal(n) * 10.0 ** rng.integers(-8, 8, n)
        assert 0.0 + pairwise(a, 0, n) == a.sum(), n
        if n > 10:
            assert 0.0 + pairwise(a, 3, n - 7) == a[3:-4].sum(), n  # (a range inside the array)


@needs_numba
@pytest.mark.parametrize("seed", range(4))
def test_the_label_search_is_its_numpy_twin_bit_for_bit(seed):
    """:func:`meanfield.controllers._queue_loops.label_search` (the guide's search for its signs' labels) against its
    twin, the guide's search before it: the same labels, the same costs, with readers and cells no robot reaches,
    a closed exit and labels no route takes from some of their readers (seed 3: every cost inf, nothing changes)."""
    from meanfield.controllers._queue_loops import label_search
    from meanfield.controllers.exit_assignment import LAST_PERSON, ArrivalOrder

    rng = np.random.default_rng(seed)
    k_exits, m, n = 4, 700, 6
    arrival = np.round(rng.uniform(0, 40, (k_exits, m)), 1)
    arrival[1, rng.uniform(size=m) < 0.05] = np.inf  # cells exit 1 cannot be reached from
    open_k = np.array([0, 1, 2]) if seed == 3 else np.arange(k_exits)
    best_walk = arrival[open_k].min(axis=0)
    persons = np.where(rng.uniform(size=m) < 0.3, 0.0, rng.exponential(0.5 + seed, m))
    with np.errstate(invalid="ignore"):
        walked = persons * (arrival - best_walk)
    reader = np.where(rng.uniform(size=m) < 0.4, -1, rng.integers(0, n, m))
    plan = open_k[np.argmin(arrival[open_k], axis=0)]
    has = np.bincount(reader[reader >= 0], weights=persons[reader >= 0], minlength=n) > 0
    has[2] = False
    start = rng.choice(open_k, n) if seed == 3 else np.zeros(n, np.intp)  # seed 3: some start where none walks
    queues = ArrivalOrder(arrival)
    capacity = np.array([1.2, 2.4, 0.6, 1.8])
    total = float(persons.sum())
    out = {}
    for twin in (False, True):
        labels = start.copy()
        with compiled.numpy_path() if twin else contextlib.nullcontext():
            costs = label_search(reader, plan, persons, queues.order, queues.arrival, capacity, open_k, LAST_PERSON,
                                 walked, total, has, labels, 3, np.empty(m, np.intp), np.empty(m),
                                 np.empty(k_exits), np.empty(k_exits))  # fmt: skip
        out[twin] = labels, costs
    assert label_search._ready
    np.testing.assert_array_equal(out[False][0], out[True][0])
    assert out[False][1] == out[True][1]
    best, first = out[False][1]
    assert best <= first and (out[False][0][~has] == start[~has]).all()
    assert (best < first and np.isfinite(best)) if seed < 3 else best == first == np.inf


def test_the_guide_s_pulls_take_a_team_of_other_robots_as_before():
    """:meth:`GuideController.pulls` with more robots than its team (those beyond it have no share: held, pulled
    nowhere) and with the team's own robots: the robots of the team pulled as with the team alone."""
    from meanfield import ClosedLoop
    from meanfield.scenarios.scenario import builtin_scenarios

    loop = ClosedLoop(builtin_scenarios()["office"](seed=0))
    for _ in range(12):
        loop.step()
    c = loop.controller
    robots = np.asarray(loop.robots.positions, float)
    w = c.weight(loop.density, loop.t)
    alone = c.pulls(robots, c._share, w)
    more = c.pulls(np.vstack([robots, robots[:2] + 0.25]), c._share, w)
    np.testing.assert_array_equal(more[: len(robots)], alone)
    np.testing.assert_array_equal(more[len(robots) :], 0.0)
    assert np.abs(alone).sum() > 0


@needs_numba
@pytest.mark.parametrize("hidden", [True, False])
def test_the_signs_boxes_on_the_grid_are_their_numpy_twins(hidden):
    """:func:`meanfield.signs._reach_loops.boxes_on_grid` (each robot's box of reached cells laid on the grid, on the
    cells of Ω it sees) against its twin: boxes at the grid's edges and overlapping, a cell without volume."""
    from meanfield.signs._reach_loops import boxes_on_grid

    rng = np.random.default_rng(6)
    n, nx, ny, bx, by = 5, 30, 20, 9, 7
    inside = rng.uniform(size=(n, bx, by)) < 0.6
    i0 = np.array([0, nx - bx, 4, 4, 11], np.intp)
    j0 = np.array([0, ny - by, 2, 3, 13], np.intp)
    active = rng.uniform(size=(nx, ny)) < 0.9
    seen = rng.uniform(size=(n, nx, ny)) < 0.7
    fast, ref = _both(boxes_on_grid, inside, i0, j0, active, seen, hidden, np.empty((n, nx, ny), bool))
    np.testing.assert_array_equal(fast, ref)
    assert fast[:, ~active].sum() == 0 and (fast[0, bx:, :] == 0).all() and fast.sum() > 100
