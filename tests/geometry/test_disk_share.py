"""The share of a disk inside Ω (meanfield.geometry.disk_share) against closed forms.

* beside a straight wall, ``1 − (acos(d/r) − (d/r)√(1 − d²/r²))/π`` (the circular segment), for a
  box, the same box as a polygon and a wall at a slant to the lattice: within 0.01;
* in a right-angled corner a quarter, on a wall a half, in the middle 1 exactly;
* around a round column of radius ``a`` (a hole in a plan), ``1 − a²/r²`` for a disk that holds it;
* a narrow corridor of width ``w < 2r``: ``(the strip's chord area) / (π r²)`` at its axis;
* a bad radius or spacing is refused, naming it; a large room gets a coarser lattice, capped.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield.errors import ParameterError
from meanfield.geometry.disk_share import MAX_TABLE_CELLS, disk_share, segment_share
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
