"""Walking distances from robots (geodesic Voronoi, first legs) and the coverage that uses them (issue 31, item 1).

Exact answers: in a convex room the walking distance is the straight one and the pull (walking or
routed) is Lloyd's ``C − R``; round one corner the geodesic is two straight legs (the first exact, the rest within the
8-neighbour links' bound); the pull is ``−½ ∂H/∂R`` of the walking
Lloyd cost, checked by finite differences.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, Grid, ParameterError
from meanfield.controllers.coverage import CoverageController
from meanfield.geometry.plan import Plan
from meanfield.geometry.sight import SightLines
from meanfield.geometry.walking import WalkingDistances
from meanfield.signs.robots import RobotTeam

# two 4 m rooms side by side, a 1 m gap in the wall between them at its top (y in [3, 4])
TWO_ROOMS = Plan.from_wkt("POLYGON ((0 0, 3.9 0, 3.9 3, 4.1 3, 4.1 0, 8 0, 8 4, 0 4, 0 0))")


def test_in_a_convex_room_the_walking_distance_is_the_straight_one():
    grid = Grid(Domain.box(5.0, 3.0), (20, 12))
    walk = WalkingDistances(grid)
    R = np.array([[0.3, 0.4], [4.1, 2.9]])
    f = walk.from_points(R)
    straight = np.hypot(walk.xy[None, :, 0] - R[:, 0, None], walk.xy[None, :, 1] - R[:, 1, None])
    np.testing.assert_allclose(f.distance, straight, rtol=0, atol=1e-12)
    np.testing.assert_allclose(f.leg * straight[..., None], walk.xy[None] - R[:, None], rtol=0, atol=1e-12)


def test_round_a_corner_the_walking_distance_is_two_straight_legs():
    """From low in the left room to low in the right one the geodesic bends at the gap's two lower corners."""
    grid = Grid(TWO_ROOMS, (80, 40))  # 0.1 m cells
    walk = WalkingDistances(grid)
    R = np.array([[1.02, 0.53]])
    f = walk.from_points(R)
    for target in ((6.95, 0.55), (7.55, 1.05), (5.05, 0.25)):
        c = int(np.argmin(np.hypot(*(walk.xy - target).T)))
        x = walk.xy[c]
        first, rest = math.dist(R[0], (3.9, 3.0)), 0.2 + math.dist((4.1, 3.0), x)
        # straight to the anchor, then the 8-neighbour links: at most 1/cos(22.5°) long, a cell's diagonal at the corner
        assert first + rest <= f.distance[0, c] <= first + rest / math.cos(math.pi / 8) + math.hypot(grid.dx, grid.dy)
        corner = np.array([3.9, 3.0]) - R[0]
        # the first leg heads for the gap's lower-left corner (a cell beside it)
        assert np.degrees(np.arccos(f.leg[0, c] @ corner / np.linalg.norm(corner))) < 3.0


def test_every_anchor_is_seen_or_next_to_the_start_and_never_the_start_for_another_cell():
    grid = Grid(TWO_ROOMS, (40, 20))
    sight = SightLines(TWO_ROOMS)
    walk = WalkingDistances(grid, sight)
    R = np.array([[1.0, 1.0], [3.7, 3.6], [6.0, 0.5]])
    f = walk.from_points(R)
    start = walk.cell_of(R)
    m = len(walk.cells)
    for i in range(len(R)):
        others = np.arange(m) != start[i]
        assert (f.anchor[i, others] != start[i]).all()
        assert np.isfinite(f.distance[i]).all() and (f.distance[i] >= 0).all()
        lengths = np.hypot(f.leg[i, others, 0], f.leg[i, others, 1])
        np.testing.assert_allclose(lengths, 1.0, rtol=0, atol=1e-12)
        a = f.anchor[i]
        seen = sight.visible(np.broadcast_to(walk.xy[start[i]], (m, 2)), walk.xy[a])
        neighbour = np.abs(walk.xy[a] - walk.xy[start[i]]).max(axis=1) <= grid.dx * 1.0001
        assert (seen | neighbour).all()


def test_a_point_s_trees_are_kept_per_cell_and_equal_a_fresh_computation():
    grid = Grid(TWO_ROOMS, (40, 20))
    walk = WalkingDistances(grid)
    R = np.array([[1.0, 1.0], [6.0, 0.5], [1.02, 1.03]])  # the first and last share a cell
    f = walk.from_points(R)
    assert len(walk._trees) == 2
    fresh = WalkingDistances(grid).from_points(R[::-1])
    np.testing.assert_array_equal(fresh.distance, f.distance[::-1])
    np.testing.assert_array_equal(fresh.anchor, f.anchor[::-1])


def test_one_point_s_walks_to_some_cells_are_those_columns_of_every_walk_to_the_bit():
    """``walk_to`` (the routed pull's walk to a hidden centroid's cell) gives the columns of ``from_points``, round
    the wall, from a fresh store and from one that holds the tree, and a full store is emptied as by from_points."""
    grid = Grid(TWO_ROOMS, (40, 20))
    R = np.array([[1.0, 1.0], [6.0, 0.5], [3.7, 3.6]])
    f = WalkingDistances(grid, SightLines(TWO_ROOMS)).from_points(R)
    walk = WalkingDistances(grid, SightLines(TWO_ROOMS))
    walk.keep = 2
    rng = np.random.default_rng(3)
    for i in (0, 1, 0, 2):  # the third call reuses a kept tree; the fourth finds the store full
        cells = np.sort(rng.choice(len(walk.cells), 60, replace=False))
        distance, leg = walk.walk_to(R[i], cells)
        np.testing.assert_array_equal(distance, f.distance[i, cells])
        np.testing.assert_array_equal(leg, f.leg[i, cells])
        assert len(walk._trees) <= 2
    hidden = f.distance[0] > np.hypot(*(walk.xy - R[0]).T) + 1e-9  # cells beyond the wall: the walk bends
    assert hidden.sum() > 100


def test_a_full_store_of_trees_keeps_every_cell_a_call_needs():
    grid = Grid(TWO_ROOMS, (40, 20))
    walk = WalkingDistances(grid)
    walk.keep = 2
    walk.from_points(np.array([[1.0, 1.0], [6.0, 0.5]]))
    R = np.array([[6.0, 0.5], [3.0, 1.5]])  # one cell kept, one new: the store is full
    f = walk.from_points(R)  # (it once dropped the kept cell's tree and failed to find it)
    assert len(walk._trees) == 2
    fresh = WalkingDistances(grid).from_points(R)
    np.testing.assert_array_equal(fresh.distance, f.distance)
    np.testing.assert_array_equal(fresh.anchor, f.anchor)


def _coverage(region, cells, metric):
    grid = Grid(region, cells)
    return CoverageController(None, grid, SightLines(region), metric=metric), grid


@pytest.mark.parametrize("metric", ["walking", "routed"])
def test_in_a_convex_room_walking_and_routed_coverage_pull_as_straight_coverage(metric):
    rng = np.random.default_rng(3)
    other, grid = _coverage(Domain.box(4.0, 3.0), (16, 12), metric)
    straight, _ = _coverage(Domain.box(4.0, 3.0), (16, 12), "straight")
    assert other.metric == metric and straight.metric == "straight"
    R = rng.uniform((0.1, 0.1), (3.9, 2.9), (4, 2))
    w = rng.random(grid.shape)
    pw, idle_w = other.pulls(R, w)
    ps, idle_s = straight.pulls(R, w)
    np.testing.assert_allclose(pw, ps, rtol=0, atol=1e-12)
    assert np.array_equal(idle_w, idle_s)


def test_routed_coverage_walks_to_a_hidden_centroid_and_goes_straight_to_a_seen_one():
    cov, grid = _coverage(TWO_ROOMS, (40, 20), "routed")
    X, Y = grid.centers
    R = np.array([[1.0, 1.0]])
    right = np.where((X > 5.0) & (Y < 2.0), 1.0, 0.0)  # behind the wall: the walk's first leg, to the gap
    pull, _ = cov.pulls(R, right)
    c, _ = cov.centroids(R, right)
    f = cov.walking.from_points(R)
    leg = f.leg[0, f.distance[0] > 0]
    assert pull[0] @ (c[0] - R[0]) < np.linalg.norm(pull[0]) * np.linalg.norm(c[0] - R[0])  # not straight at C
    gap = np.array([3.9, 3.0]) - R[0]
    assert np.degrees(np.arccos(pull[0] @ gap / np.linalg.norm(pull[0]) / np.linalg.norm(gap))) < 5.0
    assert len(leg)
    left = np.where((X < 3.0) & (Y < 2.0), 1.0, 0.0)  # in sight: straight to the centroid
    pull, _ = cov.pulls(R, left)
    c, _ = cov.centroids(R, left)
    np.testing.assert_allclose(pull[0], c[0] - R[0], rtol=0, atol=1e-12)


def test_the_walking_pull_is_the_descent_direction_of_lloyd_s_walking_cost():
    """``H(R) = Σ_c w_c |c| d_owner(c)(c)²``: ``dH/dε`` along ``R + ε p`` equals ``−2 Σ_i M_i |p_i|²``."""
    cov, grid = _coverage(TWO_ROOMS, (40, 20), "walking")
    rng = np.random.default_rng(7)
    R = np.array([[1.03, 1.07], [6.07, 0.58], [3.03, 3.52]])
    w = rng.random(grid.shape)
    wv = w.ravel()[cov._cells] * cov._volume

    def H(points):
        f = cov.walking.from_points(points)
        d = f.distance[f.owners(), np.arange(len(cov._cells))]
        return float((wv * d**2).sum())

    p, idle = cov.pulls(R, w)
    f = cov.walking.from_points(R)
    M = np.bincount(f.owners(), weights=wv, minlength=len(R))
    assert not idle.any() and (np.hypot(*p.T) > 0.1).all()
    eps = 1e-4
    fd = (H(R + eps * p) - H(R - eps * p)) / (2 * eps)
    assert fd == pytest.approx(-2.0 * float((M * (p**2).sum(axis=1)).sum()), rel=1e-3)
    assert fd < 0


def test_a_robot_walks_round_the_wall_to_the_people_of_the_next_room():
    """All the weight low in the right room, the robot low in the left: straight coverage drives it into the
    wall between the rooms, where it stays; walking coverage takes it through the gap into the right room."""
    ends = {}
    for metric in ("straight", "routed", "walking"):
        cov, grid = _coverage(TWO_ROOMS, (40, 20), metric)
        X, Y = grid.centers
        w = np.where((X > 5.0) & (Y < 2.0), 1.0, 0.0)
        team = RobotTeam(np.array([[1.0, 1.0]]), np.zeros(1), u_max=1.5, omega_max=1.0)
        for _ in range(200):  # 20 s at 0.1 s
            pull, _ = cov.pulls(team.positions, w)
            team.step(pull, np.zeros(1), 0.1, TWO_ROOMS)
        ends[metric] = team.positions[0].copy()
    assert ends["straight"][0] < 4.0  # held at the wall
    for metric in ("routed", "walking"):
        assert ends[metric][0] > 5.0 and ends[metric][1] < 2.5, metric  # among the people


def test_an_unknown_metric_is_refused_naming_the_option():
    with pytest.raises(ParameterError, match=r"controller\.options\.coverage\.metric"):
        _coverage(TWO_ROOMS, (8, 4), "manhattan")
