"""The share of a disk inside Ω (meanfield.geometry.disk_share) against closed forms.

* beside a straight wall, ``1 − (acos(d/r) − (d/r)√(1 − d²/r²))/π`` (the circular segment), for a
  box, the same box as a polygon and a wall at a slant to the lattice: within 0.01;
* in a right-angled corner a quarter, on a wall a half, in the middle 1 exactly;
* around a round column of radius ``a`` (a hole in a plan), ``1 − a²/r²`` for a disk that holds it;
* a narrow corridor of width ``w < 2r``: ``(the strip's chord area) / (π r²)`` at its axis;
* a bad radius or spacing is refused, naming it; a large room gets a coarser lattice, capped;
* the halves ahead of and behind a direction: beside a straight wall, walking into it
  ``2 s − 1`` ahead and 1 behind (within 0.02 beyond one lattice cell of the wall), along it ``s``
  both; on the wall ``1 − θ/π`` at an angle ``θ`` from the inward normal; at random points and
  directions of a box and of a slanted triangle, against a fine polar quadrature of the half disk
  (done here, without the table): within 0.02 at 95 % of the points, within the angular reading's
  1/16 (a kink between two of the 16 directions) at all.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield.errors import ParameterError
from meanfield.geometry.disk_share import MAX_TABLE_CELLS, disk_share, half_disk_share, segment_share
from meanfield.geometry.domain import Domain

R = 0.6


@pytest.mark.parametrize("room", [Domain.box(10.0, 8.0), Domain.polygon([(0, 0), (10, 0), (10, 8), (0, 8)])])
def test_beside_a_straight_wall_the_circular_segment(room):
    share = disk_share(room, R)
    d = np.linspace(0.0, 1.0, 41)
    assert np.abs(share.at(np.c_[d, np.full_like(d, 4.0)]) - segment_share(d, R)).max() < 0.01
    assert np.abs(share.at(np.c_[np.full_like(d, 5.0), 8.0 - d]) - segment_share(d, R)).max() < 0.01
    assert share.at(np.array([[0.0, 0.0], [10.0, 8.0]])) == pytest.approx([0.25, 0.25], abs=0.01)
    assert share.at(np.array([[0.0, 4.0]]))[0] == pytest.approx(0.5, abs=0.01)
    assert np.all(share.at(np.array([[5.0, 4.0], [2.0, 2.0], [8.3, 6.1]])) == 1.0)


def test_a_wall_at_a_slant_to_the_lattice():
    room = Domain.polygon([(0.0, 0.0), (10.0, 3.0), (6.0, 9.0)])
    share = disk_share(room, R)
    normal = np.array([-3.0, 10.0]) / math.hypot(3.0, 10.0)
    d = np.linspace(0.0, 1.0, 41)
    points = np.array([5.0, 1.5]) + d[:, None] * normal
    assert np.abs(share.at(points) - segment_share(d, R)).max() < 0.01


def test_around_a_round_column():
    """A column of radius 0.2 m (a hole) inside the disk takes ``0.2² / 0.6²`` of it."""
    import shapely

    plan = Domain.from_shapely(shapely.box(0.0, 0.0, 10.0, 8.0).difference(shapely.Point(5.0, 4.0).buffer(0.2, 64)))
    share = disk_share(plan, R)
    exact = 1.0 - (0.2 / R) ** 2  # the polygon's area is 0.1 % under the circle's
    assert share.at(np.array([[5.0, 4.3], [5.25, 4.0], [4.7, 3.8]])) == pytest.approx(np.full(3, exact), abs=0.01)


def test_in_a_narrow_corridor():
    """At the axis of a corridor 0.8 m wide the disk keeps the strip ``|y| < 0.4``: ``1 − 2 × segment(0.4)``."""
    room = Domain.box(10.0, 0.8)
    share = disk_share(room, R)
    exact = 1.0 - 2.0 * (1.0 - segment_share(0.4, R))
    assert share.at(np.array([[5.0, 0.4]]))[0] == pytest.approx(float(exact), abs=0.01)


def test_bad_input_is_refused_naming_it():
    room = Domain.box(1.0, 1.0)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ParameterError, match="radius"):
            disk_share(room, bad)
    with pytest.raises(ParameterError, match="spacing"):
        disk_share(room, R, spacing=0.0)


def test_a_large_room_is_tabulated_coarser_within_the_cap():
    share = disk_share(Domain.box(700.0, 700.0), R)
    assert share.table.size <= MAX_TABLE_CELLS * 1.01
    assert share.spacing > R / 8
    d = np.linspace(0.0, 1.0, 21)
    assert np.abs(share.at(np.c_[d, np.full_like(d, 350.0)]) - segment_share(d, R)).max() < 0.06


def test_the_halves_beside_a_straight_wall_in_closed_form():
    halves = half_disk_share(Domain.box(10.0, 8.0), R)
    d = np.linspace(0.0, 1.0, 41)
    x = np.c_[d, np.full_like(d, 4.0)]  # the west wall, x = 0
    s = segment_share(d, R)
    whole, ahead, behind = halves.at(x, np.tile([-1.0, 0.0], (len(d), 1)))  # into the wall
    assert np.abs(whole - s).max() < 0.01
    off = d >= halves.disk.spacing  # within a lattice cell of the wall the reading smooths the half's edge
    assert np.abs(ahead - (2 * s - 1))[off].max() < 0.02 and np.abs(behind - 1.0)[off].max() < 0.02
    assert np.abs(ahead - (2 * s - 1)).max() < 0.05 and np.abs(behind - 1.0).max() < 0.05
    _, ahead, behind = halves.at(x, np.tile([0.0, 2.5], (len(d), 1)))  # along it (a direction of any length)
    assert np.abs(ahead - s).max() < 0.01 and np.abs(behind - s).max() < 0.01
    theta = np.linspace(0.0, math.pi, 37)  # on the wall, at θ from the inward normal
    _, ahead, behind = halves.at(np.tile([0.0, 4.0], (len(theta), 1)), np.c_[np.cos(theta), np.sin(theta)])
    assert np.abs(ahead - (1 - theta / math.pi)).max() < 0.05  # on the wall: the lattice's smoothing, as above
    np.testing.assert_allclose(ahead + behind, 1.0, atol=0.02)
    assert halves.at(np.array([[5.0, 4.0]]), np.array([[0.3, -0.7]]))[1][0] == 1.0  # a whole disk: 1 exactly


@pytest.mark.parametrize(
    "room", [Domain.box(10.0, 8.0), Domain.polygon([(0.0, 0.0), (10.0, 3.0), (6.0, 9.0)])], ids=["box", "slanted"]
)
def test_the_halves_against_a_polar_quadrature(room):
    halves = half_disk_share(room, R)
    rng = np.random.default_rng(1)
    p = rng.uniform([0.0, 0.0], [10.0, 9.0], size=(1200, 2))
    p = p[room.contains(p[:, 0], p[:, 1])][:150]
    angle = rng.uniform(0.0, 2 * math.pi, len(p))
    whole, ahead, behind = halves.at(p, np.c_[np.cos(angle), np.sin(angle)])
    r = R * np.sqrt((np.arange(100) + 0.5) / 100)  # equal areas
    t = 2 * math.pi * (np.arange(360) + 0.5) / 360
    x = p[:, 0, None, None] + r[None, :, None] * np.cos(t)[None, None, :]
    y = p[:, 1, None, None] + r[None, :, None] * np.sin(t)[None, None, :]
    inside = room.contains(x.ravel(), y.ravel()).reshape(x.shape)
    front = (np.cos(t[None, :] - angle[:, None]) > 0)[:, None, :]
    reference = (inside & front).sum(axis=(1, 2)) / (front.sum(axis=(1, 2)) * len(r))
    # the reading in the angle is linear between directions π/8 apart: where the half's share has a kink
    # (a wall along the direction) between two of them, it errs by up to 1/16; within 0.02 at 95 % of points
    error = np.abs(ahead - reference)
    assert error.max() < 1 / 16 + 0.01 and np.percentile(error, 95) < 0.02
    assert np.abs(behind - (2 * inside.mean(axis=(1, 2)) - reference)).max() < 1 / 16 + 0.02
    assert np.all((ahead >= 0) & (ahead <= 1) & (behind >= 0) & (behind <= 1))


def test_the_halves_refuse_a_bad_number_of_directions():
    with pytest.raises(ParameterError) as info:
        half_disk_share(Domain.box(2.0, 2.0), R, directions=5)
    assert info.value.name == "directions"
    room = Domain.box(2.0, 2.0)
    with pytest.raises(ParameterError) as info:  # a whole disk's table of another radius
        half_disk_share(room, R, disk=disk_share(room, 0.3))
    assert info.value.name == "disk"
    given, built = half_disk_share(room, R, disk=disk_share(room, R)), half_disk_share(room, R)
    assert np.array_equal(given.ahead, built.ahead) and np.array_equal(given.disk.table, built.disk.table)
