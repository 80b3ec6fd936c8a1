"""Floor plans from DXF drawings: the outline, the obstacles and the exits, each on its own layer.

:func:`read_dxf` reads the model space of a DXF file with ezdxf (imported on first use) and
returns the walkable polygon and the exit segments that :class:`~meanfield.geometry.plan.Plan` takes
(``Plan.from_dxf``, or ``[domain] kind = "plan"`` with ``file = "plan.dxf"``).

The conventions are those of the pedestrian simulators' converters: the DXF → WKT converter
of the JuPedSim project (the walkable area's outline on one layer, ``jps-walkablearea``, as
one closed polyline; holes on an obstacle layer, ``jps-obstacles``, each one closed polyline
or one circle) and SUMO's ``dxf2jupedsim.py`` (layers ``walkable_areas`` and ``obstacles``).
A file drawn for them is read with ``walls="jps-walkablearea", obstacles="jps-obstacles"``
(or ``walkable_areas``).  Here:

- **walls** (default layer ``walls``): the room's outline, the boundary of the walkable area
  (the inner faces of the walls), exactly one closed LWPOLYLINE or POLYLINE (closed flag
  set, or the last vertex on the first), *or* LINE entities that ``shapely.polygonize``
  closes into exactly one polygon, each of them on its boundary (a stray line would be a
  wall the crowd walks through, so it is refused).  Not both.
- **obstacles** (default ``obstacles``): pillars and furniture, each a closed polyline or a
  CIRCLE (an inscribed polygon whose sides stray at most 1 mm from the circle); each must lie
  inside the outline (it may touch it, or another obstacle); they are cut out as holes.
- **exits** (default ``exits``): each a LINE or a polyline of two vertices, a segment
  ``((x0, y0), (x1, y1))`` on the walls (outline or obstacle).  JuPedSim draws exits as
  polygons; those are refused here, since an exit of a :class:`~meanfield.geometry.plan.Plan` is a
  part of its wall.

Layer names match without regard to case (as in CAD programs).  The walls layer must exist
and hold the outline; the obstacles and exits layers may be absent under their default names
(a room without pillars or doors), but a name given otherwise must exist, and ``""`` or None
reads none.  Polyline arcs (bulges) become polylines within 1 mm of ezdxf's Bézier form of
the arc (itself within 0.03 % of the radius).  Texts, dimensions, hatches and points are
skipped; any other entity on these layers (ARC, SPLINE, a block INSERT: explode it first) is
refused.  Blocks and paper space are not read.

Units: lengths are in metres.  A header ``$INSUNITS`` of mm, cm, dm, inches or feet is
scaled to metres; unitless (0) or absent is read as metres; any other unit is refused.

Every refusal is a :class:`~meanfield.errors.ParameterError` before anything runs: named
``file`` (not a DXF, or a bad entity, given by its type, layer and handle), or the layer's
keyword (``walls``, ``obstacles``, ``exits``) for a missing layer, listing those that exist.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from meanfield.errors import ParameterError
from meanfield.geometry.region import regular_file

__all__ = ["read_dxf", "Segment", "UNITS"]

Segment = tuple[tuple[float, float], tuple[float, float]]
"""An exit: its two end points ``((x0, y0), (x1, y1))`` in metres."""

UNITS: dict[int, tuple[str, float, int]] = {
    0: ("unitless (read as metres)", 1.0, 1),
    6: ("m", 1.0, 1),
    14: ("dm", 1.0, 10),
    5: ("cm", 1.0, 100),
    4: ("mm", 1.0, 1000),
    1: ("in", 0.0254, 1),
    2: ("ft", 0.3048, 1),
}
"""The ``$INSUNITS`` codes read: ``{code: (name, factor, divisor)}``, metres = length · factor / divisor
(a divisor, so that 2500 mm is exactly 2.5 m)."""

CURVE_TOLERANCE = 1e-3
"""Metres: how far the sides of a circle's polygon (or of an arc's, from ezdxf's Bézier form) may stray."""

_POLYLINES = ("LWPOLYLINE", "POLYLINE")
_SKIPPED = frozenset({"TEXT", "MTEXT", "DIMENSION", "HATCH", "POINT", "LEADER", "MULTILEADER", "ATTDEF"})


class _Drawing:
    """The DXF's model space by layer, in metres."""

    def __init__(self, path: str | Path):
        import ezdxf

        self.path = regular_file(path, "an existing DXF file")
        self.name = self.path.name
        try:
            doc = ezdxf.readfile(self.path)
        except (OSError, ValueError, ezdxf.DXFError) as exc:
            raise ParameterError("file", str(path), f"a readable DXF file ({exc})") from None
        code = int(doc.header.get("$INSUNITS", 0) or 0)
        if code not in UNITS:
            units = ", ".join(name for name, _, _ in UNITS.values())
            raise ParameterError("file", f"{self.name}: $INSUNITS = {code}", f"drawing units among {units}")
        _, self.factor, self.divisor = UNITS[code]
        self.layers: dict[str, list[Any]] = {}
        names = {layer.dxf.name for layer in doc.layers}
        for e in doc.modelspace():
            names.add(e.dxf.layer)
            self.layers.setdefault(e.dxf.layer.lower(), []).append(e)
        self.names = sorted(names, key=str.lower)

    def xy(self, v: Any) -> tuple[float, float]:
        """A vertex in metres (its z dropped)."""
        return (float(v[0]) * self.factor / self.divisor, float(v[1]) * self.factor / self.divisor)

    def item(self, e: Any, what: str = "") -> str:
        """An entity named for a message: file, layer, type and handle."""
        return f"{self.name}, layer {e.dxf.layer}: {what}{e.dxftype()} handle {e.dxf.handle}"

    def entities(self, keyword: str, layer: str | None, required: bool) -> list[Any]:
        """The entities of a layer (texts and the like left out); [] for an absent optional layer."""
        if not layer:
            if keyword == "walls":
                raise ParameterError(keyword, layer, "a layer name")
            return []
        if layer.lower() not in {n.lower() for n in self.names}:
            if not required:
                return []
            listed = ", ".join(map(repr, self.names))
            raise ParameterError(keyword, layer, f"a layer of {self.name} (it has {listed})")
        return [e for e in self.layers.get(layer.lower(), []) if e.dxftype() not in _SKIPPED]

    def vertices(self, e: Any) -> list[tuple[float, float]]:
        """A polyline's vertices in metres, its arcs followed to :data:`CURVE_TOLERANCE`."""
        from ezdxf import path

        if e.dxftype() == "POLYLINE" and (e.is_polygon_mesh or e.is_poly_face_mesh):
            raise ParameterError("file", self.item(e, "mesh "), "a 2D polyline")
        distance = CURVE_TOLERANCE * self.divisor / self.factor
        pts = [self.xy(v) for v in path.make_path(e).flattening(distance)]
        return [p for k, p in enumerate(pts) if k == 0 or p != pts[k - 1]]

    def ring(self, e: Any, role: str) -> Any:
        """A closed polyline or a circle as a valid shapely polygon."""
        import shapely

        if e.dxftype() == "CIRCLE" and role == "an obstacle":
            cx, cy = self.xy(e.ocs().to_wcs(e.dxf.center))
            r = float(e.dxf.radius) * self.factor / self.divisor
            # the sides of an inscribed n-gon stray r (1 - cos(π/n)) <= CURVE_TOLERANCE from the circle
            n = max(16, math.ceil(math.pi / math.acos(max(1.0 - CURVE_TOLERANCE / r, -1.0)))) if r > 0 else 0
            pts = [(cx + r * math.cos(2 * math.pi * k / n), cy + r * math.sin(2 * math.pi * k / n)) for k in range(n)]
        elif e.dxftype() in _POLYLINES:
            pts = self.vertices(e)
            if not e.is_closed and (len(pts) < 4 or pts[0] != pts[-1]):
                allowed = f"{role}: a closed polyline (closed flag set, or ending on its first vertex)"
                raise ParameterError("file", self.item(e, "open "), allowed)
        else:
            kinds = "a closed polyline or a CIRCLE" if role == "an obstacle" else "a closed polyline or LINEs"
            raise ParameterError("file", self.item(e), f"{role}: {kinds} (explode blocks and curves first)")
        try:
            poly = shapely.Polygon(pts)
        except (ValueError, shapely.errors.GEOSException):
            poly = None
        if poly is None or poly.area <= 0 or not poly.is_valid:
            reason = "no area" if poly is None or poly.area <= 0 else shapely.is_valid_reason(poly)
            raise ParameterError("file", self.item(e), f"{role}: a simple closed polyline with an area ({reason})")
        return poly

    def outline(self, ents: list[Any], layer: str) -> Any:
        """The walls layer's outline: one closed polyline, or LINEs closing into one polygon."""
        import shapely

        lines = [e for e in ents if e.dxftype() == "LINE"]
        rings = [self.ring(e, "the outline") for e in ents if e.dxftype() != "LINE"]
        if not ents:
            raise ParameterError("walls", layer, f"a layer holding the outline ({layer!r} of {self.name} is empty)")
        if rings and lines:
            handles = ", ".join(e.dxf.handle for e in ents)
            value = f"{self.name}, layer {layer}: polylines and LINEs (handles {handles})"
            raise ParameterError("file", value, "the outline as one closed polyline or as LINEs, not both")
        if len(rings) > 1:
            handles = ", ".join(e.dxf.handle for e in ents)
            value = f"{self.name}, layer {layer}: {len(rings)} closed polylines (handles {handles})"
            raise ParameterError("file", value, "exactly one closed outline (pillars go on the obstacles layer)")
        if rings:
            return rings[0]
        segs = [shapely.LineString([self.xy(e.dxf.start), self.xy(e.dxf.end)]) for e in lines]
        found = list(shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.union_all(segs))))) if segs else []
        if len(found) != 1:
            value = f"{self.name}, layer {layer}: {len(lines)} LINEs enclosing {len(found)} polygons"
            allowed = "LINEs that close into exactly one room (no gap; pillars go on the obstacles layer)"
            raise ParameterError("file", value, allowed)
        tol = 1e-9 * _size(found[0])
        walls = found[0].boundary.buffer(tol)
        for e, seg in zip(lines, segs, strict=True):
            if not walls.covers(seg):
                raise ParameterError("file", self.item(e, "stray "), "LINEs that all lie on the room's outline")
        return found[0]


def _size(geom: Any) -> float:
    x0, y0, x1, y1 = geom.bounds
    return max(x1 - x0, y1 - y0)


def read_dxf(
    path: str | Path, *, walls: str = "walls", obstacles: str | None = "obstacles", exits: str | None = "exits"
) -> tuple[Any, list[Segment]]:
    """A floor plan from a DXF file: the walkable polygon and the exit segments, in metres.

    Parameters
    ----------
    path : str or Path
        The DXF file (ASCII or binary); only its model space is read.
    walls : str
        The layer of the room's outline: one closed polyline, or LINEs that close into one
        polygon (module docstring).
    obstacles : str or None
        The layer of the holes: closed polylines and circles inside the outline.  Under its
        default name it may be absent; ``""`` or None reads no obstacles.
    exits : str or None
        The layer of the exits: LINEs or two-vertex polylines on the walls.  Under its
        default name it may be absent; ``""`` or None reads no exits.

    Returns
    -------
    polygon : shapely.Polygon
        The outline minus the obstacles: valid, one piece.
    exits : list of Segment
        The exits in drawing order, ``((x0, y0), (x1, y1))`` each.

    Raises
    ------
    ParameterError
        Named ``file`` for a file that is not DXF or cannot be read, drawing units other
        than those of :data:`UNITS`, and a bad entity (its layer, type and handle in the
        value): an open or self-intersecting polyline on the walls or obstacles layer,
        several outlines, LINEs that do not close into one room, an obstacle outside the
        outline, obstacles that cut the room in pieces, an exit that is not a segment or not
        on a wall.  Named ``walls``, ``obstacles`` or ``exits`` for a missing layer (listing
        those of the file).

    Examples
    --------
    >>> polygon, exits = read_dxf("plan.dxf", walls="Room", obstacles="Pillars", exits="Doors")  # doctest: +SKIP
    """
    import shapely

    dwg = _Drawing(path)
    outline = dwg.outline(dwg.entities("walls", walls, required=True), walls)
    holes = []
    for e in dwg.entities("obstacles", obstacles, required=obstacles != "obstacles"):
        hole = dwg.ring(e, "an obstacle")
        if not outline.covers(hole):
            raise ParameterError("file", dwg.item(e), f"an obstacle inside the outline (layer {walls})")
        holes.append(hole)
    polygon = shapely.normalize(outline.difference(shapely.union_all(holes))) if holes else outline
    if not isinstance(polygon, shapely.Polygon) or polygon.area <= 0:
        pieces = len(getattr(polygon, "geoms", ())) or (0 if polygon.is_empty else 1)
        value = f"{dwg.name}, layer {obstacles}: obstacles leaving {pieces} pieces of the room"
        raise ParameterError("file", value, "obstacles that leave the room in one piece")
    out: list[Segment] = []
    edges = polygon.boundary.buffer(1e-9 * _size(polygon))
    for e in dwg.entities("exits", exits, required=exits != "exits"):
        pts = dwg.vertices(e) if e.dxftype() in _POLYLINES and not e.is_closed else []
        if e.dxftype() == "LINE":
            pts = [dwg.xy(e.dxf.start), dwg.xy(e.dxf.end)]
        if len(pts) != 2 or pts[0] == pts[1]:
            raise ParameterError("file", dwg.item(e), "an exit: a LINE, or a polyline of two distinct vertices")
        if not edges.covers(shapely.LineString(pts)):
            raise ParameterError("file", dwg.item(e), "an exit on the walls (outline or obstacle)")
        out.append((pts[0], pts[1]))
    return polygon, out


def plan_parts_from_table(
    file: str | Path,
    exits: Any,
    walls_layer: str | None,
    obstacles_layer: str | None,
    exits_layer: str | None,
) -> tuple[Any, Any]:
    """The polygon and exits of a scenario's ``[domain] kind = "plan"``, ``file = "*.dxf"``.

    The layers come from ``walls_layer``, ``obstacles_layer``, ``exits_layer`` (None: the
    defaults of :func:`read_dxf`), and a missing layer is named by that key.  The exits come
    from the DXF, or from the table's ``exits`` if the DXF has none: both is refused as
    ambiguous (``exits_layer = ""`` ignores the DXF's).
    """
    layers = {"walls": walls_layer, "obstacles": obstacles_layer, "exits": exits_layer}
    try:
        polygon, found = read_dxf(file, **{k: v for k, v in layers.items() if v is not None})
    except ParameterError as exc:
        if exc.name in layers:
            raise ParameterError(f"{exc.name}_layer", exc.value, exc.allowed) from None
        raise
    if found and exits:
        layer = exits_layer or "exits"
        where = f"{Path(file).name} has {len(found)} on layer {layer!r}"
        allowed = f"exits in one place: {where} (drop these, or set exits_layer = '')"
        raise ParameterError("exits", exits, allowed)
    return polygon, found or exits
