"""Floor plans from DXF (meanfield.geometry.dxf): an L-shaped room with a pillar and a door, read back exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

ezdxf = pytest.importorskip("ezdxf")
shapely = pytest.importorskip("shapely")

from meanfield import ClosedLoop, ParameterError, load_scenario, paper_scenario  # noqa: E402
from meanfield.geometry.dxf import read_dxf  # noqa: E402
from meanfield.geometry.plan import Plan  # noqa: E402

# the room of tests/geometry/test_plan.py, L_WITH_PILLAR, drawn in centimetres: 1 m × 1 m less a 0.6 m square,
# a 0.1 m pillar, a 0.2 m door in the east wall
L_CM = [(0, 0), (100, 0), (100, 40), (40, 40), (40, 100), (0, 100)]
PILLAR_CM = [(15, 15), (25, 15), (25, 25), (15, 25)]
DOOR_CM = ((100, 10), (100, 30))
L_WITH_PILLAR = (
    "POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0), (0.15 0.15, 0.25 0.15, 0.25 0.25, 0.15 0.25, 0.15 0.15))"
)
INSUNITS = {"m": 6, "cm": 5, "mm": 4, "km": 7}


def scaled(points, k):
    return [(x * k, y * k) for x, y in points]


def write_dxf(
    path,
    *,
    units="cm",
    k=1,
    outline=L_CM,
    walls="lwpolyline",
    pillars=(PILLAR_CM,),
    circles=(),
    doors=(DOOR_CM,),
    layers=("walls", "obstacles", "exits"),
    extra=None,
):
    """An L-shaped room in ``units`` (coordinates of the centimetre drawing times ``k``)."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = INSUNITS[units]
    msp = doc.modelspace()
    wall, obstacle, exit_ = layers
    for name in layers:
        doc.layers.add(name)
    pts = scaled(outline, k)
    if walls == "lwpolyline":
        msp.add_lwpolyline(pts, close=True, dxfattribs={"layer": wall})
    elif walls == "polyline":
        msp.add_polyline2d(pts, close=True, dxfattribs={"layer": wall})
    else:  # one LINE per wall
        for a, b in zip(pts, pts[1:] + pts[:1], strict=True):
            msp.add_line(a, b, dxfattribs={"layer": wall})
    for p in pillars:
        msp.add_lwpolyline(scaled(p, k), close=True, dxfattribs={"layer": obstacle})
    for (cx, cy), r in circles:
        msp.add_circle((cx * k, cy * k), r * k, dxfattribs={"layer": obstacle})
    for a, b in doors:
        msp.add_line(scaled([a], k)[0], scaled([b], k)[0], dxfattribs={"layer": exit_})
    if extra is not None:
        extra(msp)
    doc.saveas(path)
    return path


@pytest.mark.parametrize(
    ("units", "k", "walls"), [("cm", 1, "lwpolyline"), ("mm", 10, "polyline"), ("m", 0.01, "lines")]
)
def test_an_l_shaped_room_with_a_pillar_and_a_door_reads_back_exactly(tmp_path, units, k, walls):
    path = write_dxf(tmp_path / "plan.dxf", units=units, k=k, walls=walls)
    polygon, exits = read_dxf(path)
    assert polygon.area == pytest.approx(1.0 - 0.36 - 0.01, rel=1e-12, abs=0)
    assert len(polygon.interiors) == 1
    assert polygon.equals(shapely.from_wkt(L_WITH_PILLAR))
    if units != "m":  # cm and mm divide exactly: the door is the float literal
        assert exits == [((1.0, 0.1), (1.0, 0.3))]
    else:  # 100 * 0.01 and friends carry a rounding of their own
        assert exits == [((100 * k, 10 * k), (100 * k, 30 * k))]
    plan = Plan.from_dxf(path)
    assert plan == Plan(shapely.from_wkt(L_WITH_PILLAR), exits)


def test_layers_are_named_at_will_and_without_regard_to_case(tmp_path):
    path = write_dxf(tmp_path / "plan.dxf", layers=("Room", "PILLARS", "Doors"))
    plan = Plan.from_dxf(path, walls="room", obstacles="Pillars", exits="DOORS")
    assert plan.exits == ((((1.0, 0.1), (1.0, 0.3))),) and len(plan.polygon.interiors) == 1
    # the default obstacles and exits layers may be absent: a room without pillars or doors
    bare = Plan.from_dxf(path, walls="Room")
    assert bare.exits == () and not bare.polygon.interiors and bare.area == pytest.approx(0.64, rel=1e-12)
    assert Plan.from_dxf(path, walls="Room", obstacles="pillars", exits="").exits == ()


def test_a_round_pillar_is_an_inscribed_polygon_within_a_millimetre(tmp_path):
    path = write_dxf(tmp_path / "plan.dxf", pillars=(), circles=[((20, 70), 5)])
    polygon, _ = read_dxf(path)
    (hole,) = polygon.interiors
    v = shapely.get_coordinates(hole)[:-1]
    n = len(v)
    assert n >= 16 and 0.05 * (1 - math.cos(math.pi / n)) <= 1e-3  # sagitta of a side <= 1 mm
    assert max(abs(math.hypot(x - 0.2, y - 0.7) - 0.05) for x, y in v) < 1e-15
    assert polygon.area == pytest.approx(0.64 - 0.5 * n * 0.05**2 * math.sin(2 * math.pi / n), rel=1e-12)


def test_an_arc_in_a_polyline_is_followed(tmp_path):
    doc = ezdxf.new("R2010")  # a unit square whose top wall is a half circle bulging out (bulge 1)
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 1), (0, 1, 0)]
    doc.modelspace().add_lwpolyline(pts, format="xyb", close=True, dxfattribs={"layer": "walls"})
    doc.saveas(tmp_path / "arc.dxf")
    polygon, _ = read_dxf(tmp_path / "arc.dxf")
    top = shapely.get_coordinates(polygon.exterior)
    top = top[top[:, 1] > 1]
    assert len(top) > 16 and np.abs(np.hypot(top[:, 0] - 0.5, top[:, 1] - 1) - 0.5).max() < 1e-3
    assert polygon.area == pytest.approx(1 + math.pi / 8, abs=math.pi / 2 * 1e-3)


def test_a_scenario_toml_with_a_dxf_plan_runs_the_closed_loop(tmp_path, monkeypatch):
    import tomli_w

    write_dxf(tmp_path / "plan.dxf")
    table = paper_scenario(seed=0).replace(t_final=2.0).to_dict()
    table["domain"] = {"kind": "plan", "file": "plan.dxf"}
    table["target"]["center"] = [0.9, 0.2]
    path = tmp_path / "l.toml"
    path.write_text(tomli_w.dumps(table))
    monkeypatch.chdir(tmp_path)  # a relative file is read from the working directory, as a GeoJSON's
    sc = load_scenario(path)
    assert isinstance(sc.domain, Plan) and sc.domain.polygon.equals(shapely.from_wkt(L_WITH_PILLAR))
    assert sc.domain.exits == (((1.0, 0.1), (1.0, 0.3)),)
    loop = ClosedLoop(sc)
    s = loop.run(progress=False).summary
    assert s["status"] == "completed" and s["scenario"]["domain"]["kind"] == "plan"
    assert s["scenario"]["domain"]["exits"] == [[[1.0, 0.1], [1.0, 0.3]]]  # the run's record needs no DXF
    gone = np.isnan(loop.crowd.positions).any(axis=1)  # those who left have no position
    assert gone.any() and s["evacuated_per_exit"] == [int(gone.sum())]  # through the DXF's door
    x = loop.crowd.positions[~gone]
    assert sc.domain.contains(x[:, 0], x[:, 1]).all()
    assert sc.domain.contains(*loop.robots.positions.T).all()


def _open_wall(msp):
    msp.add_lwpolyline([(0, 0), (50, 0), (50, 50)], dxfattribs={"layer": "walls"})


BAD = [
    # (what write_dxf gets, read_dxf keywords, error name, words in the message)
    ({"layers": ("Room", "obstacles", "exits")}, {}, "walls", ["'walls'", "'Room'", "'obstacles'"]),
    ({}, {"obstacles": "Pillars"}, "obstacles", ["'Pillars'", "'walls'"]),
    ({"extra": _open_wall}, {}, "file", ["layer walls: open LWPOLYLINE handle", "closed polyline"]),
    ({"pillars": ([(60, 60), (70, 60), (70, 70), (60, 70)],)}, {}, "file", ["layer obstacles", "inside the outline"]),
    ({"pillars": ([(-1, 39), (101, 39), (101, 41), (-1, 41)],)}, {}, "file", ["LWPOLYLINE handle", "inside"]),
    ({"pillars": (PILLAR_CM, [(40, 0), (50, 0), (50, 40), (40, 40)])}, {}, "file", ["2 pieces", "one piece"]),
    ({"doors": (((100, 10), (90, 30)),)}, {}, "file", ["layer exits: LINE handle", "on the walls"]),
    ({"units": "km"}, {}, "file", ["$INSUNITS = 7", "mm"]),
]


@pytest.mark.parametrize(("dxf", "layers", "name", "words"), BAD)
def test_bad_dxf_plans_are_refused_naming_the_item(tmp_path, dxf, layers, name, words):
    path = write_dxf(tmp_path / "plan.dxf", **dxf)
    with pytest.raises(ParameterError) as exc:
        read_dxf(path, **layers)
    assert exc.value.name == name
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))


def _handle_of(path, layer, dxftype):
    return next(
        e.dxf.handle for e in ezdxf.readfile(path).modelspace() if e.dxf.layer == layer and e.dxftype() == dxftype
    )


def test_the_refusals_name_the_entity_by_its_handle(tmp_path):
    # an open polyline on the walls layer
    doc = ezdxf.new("R2010")
    doc.modelspace().add_lwpolyline([(0, 0), (1, 0), (1, 1), (0, 1)], dxfattribs={"layer": "walls"})
    doc.saveas(tmp_path / "open.dxf")
    handle = _handle_of(tmp_path / "open.dxf", "walls", "LWPOLYLINE")
    with pytest.raises(ParameterError, match=f"open LWPOLYLINE handle {handle}\\b") as exc:
        read_dxf(tmp_path / "open.dxf")
    assert exc.value.name == "file" and "layer walls" in str(exc.value)
    # two outlines
    doc = ezdxf.new("R2010")
    for x in (0, 2):
        doc.modelspace().add_lwpolyline([(x, 0), (x + 1, 0), (x + 1, 1)], close=True, dxfattribs={"layer": "walls"})
    doc.saveas(tmp_path / "two.dxf")
    with pytest.raises(ParameterError, match="2 closed polylines .*exactly one closed outline"):
        read_dxf(tmp_path / "two.dxf")
    # an exit of three vertices, and an exit drawn as a circle
    for name, add in [
        ("bent", lambda m: m.add_lwpolyline([(100, 10), (100, 20), (100, 30)], dxfattribs={"layer": "exits"})),
        ("round", lambda m: m.add_circle((100, 20), 5, dxfattribs={"layer": "exits"})),
    ]:
        path = write_dxf(tmp_path / f"{name}.dxf", doors=(), extra=add)
        dxftype = "LWPOLYLINE" if name == "bent" else "CIRCLE"
        handle = _handle_of(path, "exits", dxftype)
        with pytest.raises(ParameterError, match=f"{dxftype} handle {handle}.*a LINE, or a polyline of two") as exc:
            read_dxf(path)
        assert exc.value.name == "file"
    # walls drawn as LINEs with a gap, and a stray LINE inside the room
    doc = ezdxf.new("R2010")
    for a, b in [((0, 0), (1, 0)), ((1, 0), (1, 1)), ((1, 1), (0, 1)), ((0, 1), (0, 0.5))]:
        doc.modelspace().add_line(a, b, dxfattribs={"layer": "walls"})
    doc.saveas(tmp_path / "gap.dxf")
    with pytest.raises(ParameterError, match="4 LINEs enclosing 0 polygons"):
        read_dxf(tmp_path / "gap.dxf")
    doc.modelspace().add_line((0, 0.5), (0, 0), dxfattribs={"layer": "walls"})
    stray = doc.modelspace().add_line((0.5, 0.2), (0.5, 0.8), dxfattribs={"layer": "walls"}).dxf.handle
    doc.saveas(tmp_path / "stray.dxf")
    with pytest.raises(ParameterError, match=f"stray LINE handle {stray}"):
        read_dxf(tmp_path / "stray.dxf")


@pytest.mark.parametrize("content", [b"not a drawing\n", bytes(range(256)) * 4])
def test_a_file_that_is_not_dxf_is_refused(tmp_path, content):
    path = tmp_path / "plan.dxf"
    path.write_bytes(content)
    with pytest.raises(ParameterError, match="a readable DXF file") as exc:
        read_dxf(path)
    assert exc.value.name == "file"
    with pytest.raises(ParameterError, match="an existing DXF file"):
        read_dxf(tmp_path / "missing.dxf")


@pytest.mark.parametrize(
    ("domain", "name", "words"),
    [
        ({"walls_layer": "Room"}, "domain.walls_layer", "'Room'"),
        ({"obstacles_layer": "Pillars"}, "domain.obstacles_layer", "'obstacles'"),
        ({"exits": [[[0, 0.1], [0, 0.2]]]}, "domain.exits", "exits in one place"),
        ({"file": "plan.DXF", "exits": [[[0, 0.1], [0, 0.5]]]}, "domain.exits", "exits in one place"),
    ],
)
def test_bad_dxf_domains_are_refused_naming_the_toml_key(tmp_path, monkeypatch, domain, name, words):
    from meanfield.scenarios.scenario import Scenario

    write_dxf(tmp_path / "plan.dxf")
    (tmp_path / "plan.DXF").write_bytes((tmp_path / "plan.dxf").read_bytes())
    monkeypatch.chdir(tmp_path)
    sc = paper_scenario(seed=0).to_dict()
    sc["domain"] = {"kind": "plan", "file": "plan.dxf", **domain}
    with pytest.raises(ParameterError) as exc:
        Scenario.from_dict(sc)
    assert exc.value.name == name and words in str(exc.value)


def test_toml_exits_serve_when_the_dxf_has_none_and_layer_keys_need_a_dxf(tmp_path):
    from meanfield.scenarios.scenario import Scenario

    path = write_dxf(tmp_path / "plan.dxf", doors=())
    sc = paper_scenario(seed=0).to_dict()
    sc["domain"] = {"kind": "plan", "file": str(path), "exits": [[[0, 0.1], [0, 0.5]]]}
    assert Scenario.from_dict(sc).domain.exits == (((0.0, 0.1), (0.0, 0.5)),)
    sc["domain"] = {"kind": "plan", "wkt": L_WITH_PILLAR, "walls_layer": "walls"}
    with pytest.raises(ParameterError, match="only with a DXF file") as exc:
        Scenario.from_dict(sc)
    assert exc.value.name == "domain.walls_layer"


def test_importing_the_plans_does_not_import_ezdxf():
    import subprocess
    import sys

    code = "import sys, meanfield, meanfield.geometry.plan, meanfield.geometry.dxf\nprint('ezdxf' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_a_bad_dxf_exits_the_cli_with_status_2(tmp_path, capsys):
    import tomli_w

    from meanfield.cli.app import main

    doc = ezdxf.new("R2010")
    handle = doc.modelspace().add_lwpolyline([(0, 0), (1, 0), (1, 1)], dxfattribs={"layer": "walls"}).dxf.handle
    doc.saveas(tmp_path / "open.dxf")
    table = paper_scenario(seed=0).to_dict()
    table["domain"] = {"kind": "plan", "file": str(tmp_path / "open.dxf")}
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps(table))
    out = tmp_path / "out"
    status = main(["run", str(path), "--out", str(out), "--quiet", "--no-figures"])
    err = capsys.readouterr().err
    assert status == 2
    assert "domain.file" in err and f"handle {handle}" in err
    assert not out.exists()  # refused before anything ran
