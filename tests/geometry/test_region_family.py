"""One region family: Domain builds every region and returns the right implementation of the shape
(a box, a convex polygon, or a plan), from vertices, WKT, GeoJSON, DXF or shapely; convexity is
reported (``is_convex``, Payne–Weinberger), never a reason to refuse a room."""

from __future__ import annotations

import math

import numpy as np
import pytest

shapely = pytest.importorskip("shapely")

from meanfield import Domain, ParameterError  # noqa: E402
from meanfield.geometry.plan import Plan  # noqa: E402

L_ROOM = [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]  # area 3, re-entrant corner at (1, 1)


def test_a_non_convex_polygon_is_a_plan_not_a_refusal():
    room = Domain.polygon(L_ROOM, exits=[((2, 0.25), (2, 0.75))])
    assert isinstance(room, Plan) and not room.is_convex
    assert room.area == pytest.approx(3.0, rel=1e-15)
    assert room.contains(np.array([1.5]), np.array([0.5]))[0] and not room.contains(np.array([1.5]), np.array([1.5]))[0]
    assert room.exits == (((2.0, 0.25), (2.0, 0.75)),)
    arrow = Domain.polygon([(0, 0), (2, 0), (1, 0.3), (1, 2)])  # the arrow head the old check refused
    assert isinstance(arrow, Plan) and not arrow.is_convex


def test_a_convex_polygon_stays_a_domain_in_closed_form():
    pentagon = [(math.cos(a), math.sin(a)) for a in 2 * np.pi / 5 * np.arange(5)]
    dom = Domain.polygon(pentagon)
    assert isinstance(dom, Domain) and dom.kind == "polygon" and dom.is_convex


def test_wkt_gives_a_box_a_polygon_or_a_plan():
    assert Domain.from_wkt("POLYGON ((1 2, 4 2, 4 3, 1 3, 1 2))") == Domain.box(3.0, 1.0, (1.0, 2.0))
    # a vertex on the bottom edge changes no shape: still the box
    assert Domain.from_wkt("POLYGON ((0 0, 0.5 0, 1 0, 1 1, 0 1, 0 0))") == Domain.box(1.0, 1.0)
    tri = Domain.from_wkt("POLYGON ((0 0, 1 0, 0 1, 0 0))")
    assert isinstance(tri, Domain) and tri.kind == "polygon" and tri.area == pytest.approx(0.5, rel=1e-15)
    holed = Domain.from_wkt("POLYGON ((0 0, 4 0, 4 4, 0 4, 0 0), (1 1, 2 1, 2 2, 1 2, 1 1))", exits=[((4, 1), (4, 2))])
    assert isinstance(holed, Plan) and not holed.is_convex and holed.area == pytest.approx(15.0, rel=1e-15)
    assert holed.exits == (((4.0, 1.0), (4.0, 2.0)),)
    box = Domain.from_wkt("POLYGON ((0 0, 2 0, 2 1, 0 1, 0 0))", exits=[((2, 0.2), (2, 0.8))])
    assert box.kind == "box" and box.exits == (((2.0, 0.2), (2.0, 0.8)),)


def test_geojson_and_shapely_give_the_same_regions():
    geo = {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [[list(p) for p in [*L_ROOM, L_ROOM[0]]]]}}
    from_geo = Domain.from_geojson(geo)
    assert isinstance(from_geo, Plan) and from_geo == Domain.polygon(L_ROOM)
    assert Domain.from_shapely(shapely.box(0, 0, 2, 3)) == Domain.box(2.0, 3.0)


def test_dxf_gives_a_plan_with_its_exits(tmp_path):
    from tests.geometry.test_dxf import write_dxf

    path = tmp_path / "room.dxf"
    write_dxf(path)
    room = Domain.from_dxf(path)
    assert isinstance(room, Plan) and room == Plan.from_dxf(path)
    convex = tmp_path / "square.dxf"
    write_dxf(convex, outline=[(0, 0), (100, 0), (100, 100), (0, 100)], pillars=(), doors=(((100, 10), (100, 30)),))
    square = Domain.from_dxf(convex)
    assert square == Domain.box(1.0, 1.0, exits=[((1.0, 0.1), (1.0, 0.3))])


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: Domain.from_wkt("POLYGON ((0 0, 1 1, 1 0, 0 1, 0 0))"), "wkt"),  # a bow tie
        (lambda: Domain.from_wkt("LINESTRING (0 0, 1 1)"), "wkt"),
        (lambda: Domain.from_wkt("POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0))", exits=[((5, 5), (6, 6))]), "exits[0]"),
        (lambda: Domain.from_geojson({"type": "Point", "coordinates": [0, 0]}), "file"),
    ],
)
def test_bad_rooms_are_refused_naming_the_argument(call, name):
    with pytest.raises(ParameterError) as info:
        call()
    assert info.value.name == name


def test_convexity_is_reported_where_a_result_needs_it():
    from analysis import payne_weinberger_bound

    assert payne_weinberger_bound(Domain.polygon(L_ROOM)) is None  # not convex: no bound, never a number
    square = Domain.from_wkt("POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0))")
    assert payne_weinberger_bound(square) == pytest.approx(math.pi**2 / 2.0, rel=1e-15)


@pytest.mark.parametrize(
    ("build", "name"),
    [
        (lambda ex: Domain.box(1.0, 1.0, exits=ex), "domain.exits"),
        (lambda ex: Domain.from_wkt("POLYGON ((0 0, 1 0, 1 1, 0.5 1, 0.5 2, 0 2, 0 0))", exits=ex), "exits"),
    ],
    ids=["box", "plan"],
)
def test_exits_that_are_not_a_list_or_overlap_are_refused_by_name(build, name):
    """``exits = "door"`` was read as the segments 'd', 'o', ...; a duplicate or overlapping exit was
    accepted, counted no one and doubled the evacuation bound's width (issue "Nothing lost", item 7)."""
    with pytest.raises(ParameterError) as info:
        build("door")
    assert info.value.name == name and "a list of segments" in str(info.value)
    door = ((1.0, 0.2), (1.0, 0.6))
    for second in (door, ((1.0, 0.4), (1.0, 0.8)), ((1.0, 0.6), (1.0, 0.2))):
        with pytest.raises(ParameterError) as info:
            build([door, second])
        assert info.value.name == f"{name}[1]" and "overlap exits[0]" in str(info.value)
    assert len(build([door, ((1.0, 0.6), (1.0, 0.8))]).exits) == 2  # exits that touch at an end are two doors
