"""Ω: builders and their validation, geometry, membership, reflection and projection."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from meanfield import Domain, ParameterError
from tests.conftest import PENTAGON


# ---------------------------------------------------------------------- builders
@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: Domain.box(0.0, 1.0), "width"),
        (lambda: Domain.box(1.0, -2.0), "height"),
        (lambda: Domain.box(float("nan"), 1.0), "width"),
        (lambda: Domain.box(1.0, 1.0, origin=(math.inf, 0.0)), "origin[0]"),
        (lambda: Domain.disk(0.0), "radius"),
        (lambda: Domain.disk(float("nan")), "radius"),
        (lambda: Domain.polygon([(0, 0), (1, 0)]), "vertices"),
        (lambda: Domain.polygon([(0, 0), (1, 0), (float("nan"), 1)]), "vertices"),
        # a bow tie: turns both ways and crosses itself
        (lambda: Domain.polygon([(0, 0), (1, 1), (1, 0), (0, 1)]), "vertices"),
        # collinear consecutive vertices
        (lambda: Domain.polygon([(0, 0), (1, 0), (2, 0), (1, 1)]), "vertices"),
        # a pentagram turns the same way at every vertex but is self-intersecting
        (
            lambda: Domain.polygon([(math.cos(a), math.sin(a)) for a in np.pi / 2 + 4 * np.pi / 5 * np.arange(5)]),
            "vertices",
        ),
    ],
)
def test_builders_refuse_bad_input(call, name):
    with pytest.raises(ParameterError) as info:
        call()
    assert info.value.name == name


def test_polygon_accepts_clockwise_and_closed_lists():
    ccw = Domain.polygon(PENTAGON)
    cw = Domain.polygon(PENTAGON[::-1])
    closed = Domain.polygon([*PENTAGON, PENTAGON[0]])
    assert cw == ccw
    assert closed == ccw
    assert len(ccw.vertices) == 5


def test_area_and_diameter_exact():
    box = Domain.box(2.0, 0.5, origin=(1.0, -3.0))
    assert box.area == pytest.approx(1.0, rel=1e-15)
    assert box.diameter == pytest.approx(math.hypot(2.0, 0.5), rel=1e-15)
    assert box.bounds == (1.0, 3.0, -3.0, -2.5)
    disk = Domain.disk(0.7, center=(1.0, 2.0))
    assert disk.area == pytest.approx(math.pi * 0.49, rel=1e-15)
    assert disk.diameter == pytest.approx(1.4, rel=1e-15)
    poly = Domain.polygon(PENTAGON)
    assert poly.area == pytest.approx(shapely.Polygon(PENTAGON).area, rel=1e-14)
    d = max(math.dist(p, q) for p in PENTAGON for q in PENTAGON)
    assert poly.diameter == pytest.approx(d, rel=1e-15)


def test_contains_matches_shapely(domain, rng):
    x0, x1, y0, y1 = domain.bounds
    p = rng.uniform([x0 - 0.2, y0 - 0.2], [x1 + 0.2, y1 + 0.2], size=(4000, 2))
    ours = domain.contains(p[:, 0], p[:, 1])
    shape = domain.to_shapely()
    theirs = shapely.contains_xy(shape, p[:, 0], p[:, 1])
    # points within 1e-3 of the boundary may differ for the 4096-gon disk; skip those
    near = shapely.distance(shape.boundary, shapely.points(p)) < 1e-3
    assert np.array_equal(ours[~near], theirs[~near])
    assert ours.sum() > 1000


def test_sample_uniform_inside(domain, rng):
    p = domain.sample_uniform(3000, rng)
    assert p.shape == (3000, 2)
    assert domain.contains(p[:, 0], p[:, 1]).all()


# ---------------------------------------------------------------------- walls
def test_box_reflect_exact_mirror():
    box = Domain.box(1.0, 2.0, origin=(0.0, 0.0))
    p = np.array([[1.25, 0.5], [-0.25, 1.9], [0.3, 2.5], [0.5, -0.1], [0.4, 1.0]])
    out = box.reflect(p.copy())
    expected = np.array([[0.75, 0.5], [0.25, 1.9], [0.3, 1.5], [0.5, 0.1], [0.4, 1.0]])
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-15)


def test_box_reflect_folds_many_bounces():
    box = Domain.box(1.0, 1.0)
    # x = 3.3: 3.3 -> fold with period 2 -> 1.3 -> mirror at 1 -> 0.7
    out = box.reflect(np.array([[3.3, -2.2]]))
    np.testing.assert_allclose(out, [[0.7, 0.2]], atol=1e-14)


def test_disk_reflect_radial_mirror():
    disk = Domain.disk(1.0, center=(0.5, -0.5))
    d = np.array([0.6, 0.8])
    p = np.array([0.5, -0.5]) + 1.2 * d
    out = disk.reflect(p[None, :].copy())
    np.testing.assert_allclose(out[0], np.array([0.5, -0.5]) + 0.8 * d, atol=1e-15)


def test_polygon_reflect_across_edge():
    poly = Domain.polygon([(0, 0), (2, 0), (2, 2), (0, 2)])  # a square given as a polygon
    out = poly.reflect(np.array([[1.0, -0.3], [2.4, 1.0]]))
    np.testing.assert_allclose(out, [[1.0, 0.3], [1.6, 1.0]], atol=1e-15)


def test_reflect_far_outside_lands_inside(domain, rng):
    c = np.asarray(domain.center)
    p = c + rng.normal(scale=50.0, size=(5000, 2))
    out = domain.reflect(p)
    assert domain.contains(out[:, 0], out[:, 1]).all()


def test_project_is_nearest_point(domain, rng):
    x0, x1, y0, y1 = domain.bounds
    p = rng.uniform([x0 - 1, y0 - 1], [x1 + 1, y1 + 1], size=(500, 2))
    inside = domain.contains(p[:, 0], p[:, 1])
    q = domain.project(p.copy())
    assert domain.contains(q[:, 0], q[:, 1], tol=1e-12).all()
    np.testing.assert_array_equal(q[inside], p[inside])
    # distance to the projection equals the distance to Ω (shapely; the disk is a 4096-gon)
    shape = domain.to_shapely()
    dist = shapely.distance(shape, shapely.points(p[~inside]))
    ours = np.hypot(*(q[~inside] - p[~inside]).T)
    np.testing.assert_allclose(ours, dist, rtol=0, atol=1e-6 if domain.kind == "disk" else 1e-12)


# ---------------------------------------------------------------------- serialisation
def test_dict_round_trip(domain):
    assert Domain.from_dict(domain.to_dict()) == domain


def test_from_dict_refuses_unknown_kind_and_keys():
    with pytest.raises(ParameterError) as info:
        Domain.from_dict({"kind": "torus"})
    assert info.value.name == "domain.kind"
    with pytest.raises(ParameterError):
        Domain.from_dict({"kind": "box", "radius": 1.0})


def test_contains_includes_the_vertices():
    """``contains`` documents the closed domain (boundary included): every vertex is in Ω."""
    poly = Domain.polygon(PENTAGON)
    v = poly.vertices
    assert poly.contains(v[:, 0], v[:, 1]).all()
    box = Domain.box(1.1, 0.9, origin=(-0.3, 0.7))
    v = box.vertices
    assert box.contains(v[:, 0], v[:, 1]).all()
