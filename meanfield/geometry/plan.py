"""Floor plans: a polygonal room, convex or not, with holes (pillars, furniture).

A :class:`~meanfield.geometry.region.Region`.

A plan is any valid shapely polygon, read from WKT (``[domain] kind = "plan"``,
``wkt = "POLYGON ((...), (...))"``) or GeoJSON (``file = "plan.geojson"``), lengths in
metres.  Every wall, of the outline and of the holes, has zero flux (the grid's cut cells
close it, docs page *Discretisation*) and reflects the humans: a step is followed along its
segment and mirrored at the first wall it meets, so no step, however long, carries a human
through a corner or a pillar (:meth:`Plan.reflect`).  ``exits`` are segments of the walls
through which people leave (:mod:`meanfield.geometry.exits`); ``doors`` are segments across the
openings between rooms, each of which passes at most the crowd's capacity (:mod:`meanfield.geometry.doors`).

Registered as region ``plan`` (:mod:`meanfield.plugins`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.capabilities import RegionCapabilities, declares
from meanfield.errors import ParameterError
from meanfield.geometry._wall_loops import reflect_steps, robot_steps
from meanfield.geometry.doors import check_doors
from meanfield.geometry.region import (
    BoundaryPart,
    convex_polygon,
    exit_list,
    refuse_overlapping_exits,
    regular_file,
    sample_by_rejection,
    square_lattice,
)

__all__ = ["Plan", "plan_from_table", "polygon_pieces", "polygon_rings"]


def polygon_pieces(polygon: Any) -> list[Any]:
    """The pieces of a shapely polygon (itself) or multipolygon (its polygons)."""
    return list(getattr(polygon, "geoms", [polygon]))


def polygon_rings(polygon: Any) -> list[Any]:
    """Every ring of a shapely polygon, or of each piece of a multipolygon: outlines and holes."""
    return [r for piece in polygon_pieces(polygon) for r in (piece.exterior, *piece.interiors)]


class Plan:
    """A room given as a polygon with holes.

    Parameters
    ----------
    polygon : shapely.Polygon
        The walkable area: valid, non-empty, one piece (holes allowed).
    exits : sequence of segments, optional
        Parts of the walls that are exits, ``((x0, y0), (x1, y1))`` each.
    frame : (x0, x1, y0, y1), optional
        The rectangle the plan is drawn in, holding it: its :attr:`bounds`, hence the grid's lattice.
        By default the polygon's bounding box; a plan a region was blocked from during a run keeps
        the frame of the plan before, so the grid's cells stay where they were
        (:mod:`meanfield.geometry.blocking`).
    pieces : bool, default False
        Allow a plan in several pieces (a ``MULTIPOLYGON``): what is left of a plan when a region blocked
        during a run cuts it in two, each piece with its exits (:mod:`meanfield.geometry.blocking`).  A plan
        that is read is one piece.
    doors : sequence of segments, optional
        The inner doors, ``((x0, y0), (x1, y1))`` each: a segment across an opening between two rooms, from
        one jamb (a wall) to the other, through the plan (:mod:`meanfield.geometry.doors`).
    """

    kind = "plan"
    reflects_along_paths = True  # reflect needs the step's start (see Plan.reflect)

    def __init__(self, polygon: Any, exits: Any = (), frame: tuple[float, float, float, float] | None = None,
                 pieces: bool = False, doors: Any = ()):  # fmt: skip
        import shapely

        shapes = (shapely.Polygon, shapely.MultiPolygon) if pieces else shapely.Polygon
        if not isinstance(polygon, shapes):
            raise ParameterError("wkt", getattr(polygon, "geom_type", type(polygon).__name__), "a POLYGON")
        if not polygon.is_valid:
            reason = shapely.is_valid_reason(polygon)
            raise ParameterError("wkt", reason, "a valid polygon (no self-intersection, holes inside the outline)")
        if polygon.is_empty or polygon.area <= 0:
            raise ParameterError("wkt", "an empty polygon", "a polygon with an area > 0")
        self.polygon = shapely.normalize(polygon)
        shapely.prepare(self.polygon)
        self._diameter: float | None = None
        self._walls: Any = None  # the WallIndex, built at the first step
        self._edges = self._segments()
        self._inset: dict[float, Any] = {}
        self._frame = None if frame is None else self._check_frame(frame)
        self.exits = self._check_exits(exits or ())
        self.doors = check_doors(self.polygon, doors or (), self.exits, 1e-9 * self.diameter)

    def _check_frame(self, frame: Any) -> tuple[float, float, float, float]:
        """``frame`` as four floats, refused (named ``frame``) unless it holds the polygon."""
        x0, x1, y0, y1 = (float(v) for v in frame)
        px0, py0, px1, py1 = self.polygon.bounds
        if not (x0 <= px0 and px1 <= x1 and y0 <= py0 and py1 <= y1):
            raise ParameterError("frame", frame, f"a rectangle (x0, x1, y0, y1) holding the plan {self.polygon.bounds}")
        return (x0, x1, y0, y1)

    def _check_exits(self, exits: Any) -> tuple:
        """Exit segments ``((x0, y0), (x1, y1))``, each on the plan's boundary (outline or hole)."""
        import shapely

        out = []
        tol = 1e-9 * self.diameter
        for k, e in enumerate(exit_list(exits, "exits")):
            try:
                (ax_, ay_), (bx, by) = e
                seg = ((float(ax_), float(ay_)), (float(bx), float(by)))
            except (TypeError, ValueError):
                raise ParameterError(f"exits[{k}]", e, "a segment [[x0, y0], [x1, y1]]") from None
            if seg[0] == seg[1] or not self.polygon.boundary.buffer(tol).covers(shapely.LineString(seg)):
                raise ParameterError(f"exits[{k}]", e, "a segment of two distinct points on the plan's walls")
            out.append(seg)
        refuse_overlapping_exits(out, tol, "exits")
        return tuple(out)

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_wkt(cls, text: str) -> Plan:
        """A plan from a WKT ``POLYGON`` (metres)."""
        import shapely

        try:
            geom = shapely.from_wkt(text)
        except Exception as exc:  # shapely's GEOSException and friends
            raise ParameterError("wkt", str(text)[:80], f"a WKT POLYGON ({exc})") from None
        return cls(geom)

    @classmethod
    def from_geojson(cls, source: str | Path | dict) -> Plan:
        """A plan from a GeoJSON Polygon (a file, or the parsed object; a Feature's geometry is taken)."""
        import shapely

        if not isinstance(source, dict):
            path = regular_file(source, "an existing GeoJSON file")
            try:
                source = json.loads(path.read_text())
            except OSError as exc:
                raise ParameterError("file", str(path), f"a readable GeoJSON file ({exc.strerror})") from None
            except ValueError as exc:
                raise ParameterError("file", str(path), f"valid JSON ({exc})") from None
        if source.get("type") == "Feature":
            source = source.get("geometry") or {}
        if source.get("type") != "Polygon":
            raise ParameterError("file", source.get("type"), "a GeoJSON Polygon (or a Feature holding one)")
        return cls(shapely.geometry.shape(source))

    @classmethod
    def from_dxf(cls, path: str | Path, **layers: str | None) -> Plan:
        """A plan from a DXF drawing, ``layers`` naming its ``walls``, ``obstacles`` and ``exits``
        layers (:func:`meanfield.geometry.dxf.read_dxf`, which documents the conventions)."""
        from meanfield.geometry.dxf import read_dxf

        return cls(*read_dxf(path, **layers))

    @property
    def is_convex(self) -> bool:
        """Whether the room is convex: no holes, and its convex hull adds no area beyond round-off
        (relative ``1e-12``).  The paper's theory assumes it; the results that need it ask."""
        return convex_polygon(self.polygon)

    # ------------------------------------------------------------------ the Region interface
    @property
    def bounds(self) -> tuple[float, float, float, float]:
        if self._frame is None:  # the polygon's box, once (a plan's polygon is not changed)
            x0, y0, x1, y1 = self.polygon.bounds
            self._frame = (x0, x1, y0, y1)
        return self._frame

    @property
    def center(self) -> tuple[float, float]:
        c = self.polygon.centroid
        return (float(c.x), float(c.y))

    @property
    def area(self) -> float:
        return float(self.polygon.area)

    @property
    def diameter(self) -> float:
        if self._diameter is None:
            v = np.asarray(self.polygon.convex_hull.exterior.coords)  # (the hull's: the same, and one ring for pieces)
            d = v[:, None, :] - v[None, :, :]
            self._diameter = float(np.sqrt((d**2).sum(-1)).max())
        return self._diameter

    def _shape(self, tol: float) -> Any:
        """The plan grown by ``tol`` (shrunk for ``tol < 0``; cached)."""
        import shapely

        if tol not in self._inset:
            g = self.polygon.buffer(tol, join_style="mitre") if tol else self.polygon
            shapely.prepare(g)
            self._inset[tol] = g
        return self._inset[tol]

    def contains(self, x: Any, y: Any, tol: float | None = None) -> np.ndarray:
        """Membership of the closed plan (walls included); ``tol > 0`` grows it, ``tol < 0`` shrinks it."""
        import shapely

        x = np.asarray(x, float)
        y = np.asarray(y, float)
        tol = 1e-12 * self.diameter if tol is None else float(tol)
        return shapely.intersects_xy(self._shape(tol), x, y)

    def _segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Start points and vectors of every wall segment (outline and holes)."""
        starts, vecs = [], []
        for ring in polygon_rings(self.polygon):
            c = np.asarray(ring.coords)
            starts.append(c[:-1])
            vecs.append(np.diff(c, axis=0))
        return np.vstack(starts), np.vstack(vecs)

    def _index(self) -> Any:
        """The plan's :class:`~meanfield.geometry.walls.WallIndex` (built at the first step)."""
        if self._walls is None:
            from meanfield.geometry.walls import WallIndex

            self._walls = WallIndex(*self._edges, self.bounds)
        return self._walls

    def _first_hit(self, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each step ``start → end``: the fraction ``t`` of it at the first wall met (``inf``:
        none) and that wall's index (only the walls near a short step are tested,
        :class:`~meanfield.geometry.walls.WallIndex`)."""
        return self._index().first_hit(start, end)

    def _walk(self, loop: Any, start: np.ndarray, end: np.ndarray, *options: Any) -> np.ndarray:
        """Run a loop of :mod:`meanfield.geometry._wall_loops` on the steps ``start → end``, ``end`` changed in
        place."""
        work = end if end.dtype == np.float64 and end.flags.c_contiguous else np.ascontiguousarray(end, float)
        loop(np.ascontiguousarray(start, float), work, *self._index().tables(), *options)
        if work is not end:
            end[...] = work
        return end

    def reflect(self, points: np.ndarray, previous: np.ndarray | None = None) -> np.ndarray:
        """Mirror, in place, every step that met a wall: followed from ``previous`` to ``points``.

        Each step is a segment; at its first crossing with a wall (outline or hole) the rest
        of the step is mirrored across that wall, and the mirrored remainder is followed
        again (up to 8 bounces, then the point is projected); one compiled pass per step,
        :func:`meanfield.geometry._wall_loops.reflect_steps` (docs/buildings.md: walls reflect).
        Without ``previous`` only the points outside are projected onto the plan.
        """
        if previous is None:
            return self.project(points)
        self._walk(reflect_steps, previous, points)
        outside = ~self.contains(points[:, 0], points[:, 1])
        if outside.any():  # a corner hit twice in a row, or a step of more than 8 bounces
            points[outside] = self.project(points[outside].copy())
        return points

    def stop_at_walls(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Cut, in place, each step ``start → end`` just before the first wall it meets (robots:
        no robot goes through a wall or a pillar; :func:`meanfield.geometry._wall_loops.robot_steps`)."""
        return self._walk(robot_steps, start, end, False)

    def slide_along_walls(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Follow, in place, each step ``start → end`` up to the first wall, then along it.

        What the step has left after the wall is projected on the wall's direction and
        followed again (stopping at the next wall), so that a robot driven into a pillar
        or a wall at an angle goes round it instead of stopping dead; a slide whose straight
        chord would cut a corner is not taken (the step stops at the wall), so no robot's
        step ever crosses a wall (robots, :meth:`~meanfield.signs.robots.RobotTeam.advance`; one
        compiled pass per step, :func:`meanfield.geometry._wall_loops.robot_steps`).
        """
        return self._walk(robot_steps, start, end, True)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest point of the plan, in place, for the points outside."""
        import shapely

        out = ~self.contains(points[:, 0], points[:, 1])
        if out.any():
            lines = shapely.shortest_line(self.polygon, shapely.points(points[out]))
            points[out] = shapely.get_coordinates(lines)[::2]  # each line's first point: on the plan
        return points

    def sample_uniform(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points drawn uniformly from the plan, by rejection from its bounding box."""
        return sample_by_rejection(self, n, rng)

    def cut_cells(
        self, x_edges: np.ndarray, y_edges: np.ndarray, dx: float, dy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Volume fractions and face apertures, by clipping every cell and face with the plan (shapely)."""
        import shapely

        XL, YL = np.meshgrid(x_edges[:-1], y_edges[:-1], indexing="ij")
        boxes = shapely.box(XL, YL, XL + dx, YL + dy)
        frac = np.clip(shapely.area(shapely.intersection(boxes, self.polygon)) / (dx * dy), 0.0, 1.0)

        walls = self.polygon.boundary

        def aperture(xa, ya, xb, yb, length):
            ends = np.stack([np.stack([xa, ya], -1), np.stack([xb, yb], -1)], axis=-2)
            segs = shapely.linestrings(ends.reshape(-1, 2, 2)).reshape(xa.shape)
            inside = shapely.length(shapely.intersection(segs, self.polygon))
            on_wall = shapely.length(shapely.intersection(segs, walls))  # a face along a wall is closed
            return np.clip((inside - on_wall) / length, 0.0, 1.0)

        XF, YF = np.meshgrid(x_edges[1:-1], y_edges[:-1], indexing="ij")
        ax = aperture(XF, YF, XF, YF + dy, dy)
        XF, YF = np.meshgrid(x_edges[:-1], y_edges[1:-1], indexing="ij")
        ay = aperture(XF, YF, XF + dx, YF, dx)
        return frac, ax, ay

    def cells_meeting(self, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
        import shapely

        XL, YL = np.meshgrid(x_edges[:-1], y_edges[:-1], indexing="ij")
        XR, YR = np.meshgrid(x_edges[1:], y_edges[1:], indexing="ij")
        return shapely.area(shapely.intersection(shapely.box(XL, YL, XR, YR), self.polygon)) > 0

    def robot_region(self, margin: float) -> Plan:
        """Where robots may stand: the plan shrunk by ``margin`` (itself for 0)."""
        if margin <= 0:
            return self
        inner = self.polygon.buffer(-margin, join_style="mitre")
        pieces = len(polygon_pieces(self.polygon))
        if inner.is_empty or len(polygon_pieces(inner)) != pieces:
            raise ParameterError("robots.margin", margin, "a margin that leaves each piece of the plan in one piece")
        return Plan(inner, pieces=pieces > 1)

    def lattice(self, n: int) -> np.ndarray:
        """``n`` evenly spread points of the plan (:func:`~meanfield.geometry.region.square_lattice`)."""
        return square_lattice(self, n, tol=0.0)

    def boundary_parts(self) -> tuple[BoundaryPart, ...]:
        """The exits, and the walls: the outline and every hole's boundary without the exits."""
        import shapely

        rings = polygon_rings(self.polygon)
        if not self.exits:
            return tuple(BoundaryPart("wall", np.asarray(r.coords)) for r in rings)
        exits_cut = shapely.MultiLineString([list(e) for e in self.exits]).buffer(1e-9 * self.diameter)
        parts = [BoundaryPart("exit", np.asarray(e, float)) for e in self.exits]
        for ring in rings:
            walls = shapely.line_merge(ring.difference(exits_cut))
            for line in getattr(walls, "geoms", [walls]):
                if not line.is_empty:
                    parts.append(BoundaryPart("wall", np.asarray(line.coords)))
        return tuple(parts)

    def neumann_eigenvalue(self) -> float | None:
        """No closed form for a plan (see :func:`analysis.poincare.neumann_eigenvalue`)."""
        return None

    def to_shapely(self, resolution: int = 0) -> Any:
        return self.polygon

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"kind": "plan", "wkt": self.polygon.wkt}
        if self.exits:
            d["exits"] = [[list(a), list(b)] for a, b in self.exits]
        if self.doors:
            d["doors"] = [[list(a), list(b)] for a, b in self.doors]
        return d

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, Plan) and self.polygon.equals(other.polygon) and self.exits == other.exits
                and self.doors == other.doors)  # fmt: skip

    def __hash__(self) -> int:
        return hash(self.polygon.wkt)

    def __repr__(self) -> str:
        return f"Plan({self.polygon.wkt[:60]}{'...' if len(self.polygon.wkt) > 60 else ''})"


@declares(RegionCapabilities())
def plan_from_table(
    wkt: str | None = None,
    file: str | None = None,
    exits: Any = (),
    walls_layer: str | None = None,
    obstacles_layer: str | None = None,
    exits_layer: str | None = None,
    doors: Any = (),
) -> Plan:
    """Registry factory (kind ``region``, name ``plan``): ``wkt = "POLYGON ((...))"``,
    ``file = "plan.geojson"`` or ``file = "plan.dxf"`` (lengths in metres),
    ``exits = [[[x0, y0], [x1, y1]], ...]`` and the inner doors ``doors = [[[x0, y0], [x1, y1]], ...]``
    (:mod:`meanfield.geometry.doors`).  A DXF's layers are named by ``walls_layer``, ``obstacles_layer``,
    ``exits_layer`` (:mod:`meanfield.geometry.dxf`, which also reads its exits)."""
    if (wkt is None) == (file is None):
        raise ParameterError("wkt", "wkt and file" if wkt else "neither wkt nor file", "exactly one of wkt, file")
    if file is not None and str(file).lower().endswith(".dxf"):
        from meanfield.geometry.dxf import plan_parts_from_table

        return Plan(*plan_parts_from_table(file, exits, walls_layer, obstacles_layer, exits_layer), doors=doors)
    layers = {"walls_layer": walls_layer, "obstacles_layer": obstacles_layer, "exits_layer": exits_layer}
    for key, value in layers.items():
        if value is not None:
            raise ParameterError(key, value, 'a layer name only with a DXF file (file = "plan.dxf")')
    plan = Plan.from_wkt(wkt) if wkt is not None else Plan.from_geojson(file)
    return Plan(plan.polygon, exits, doors=doors) if exits or doors else plan
