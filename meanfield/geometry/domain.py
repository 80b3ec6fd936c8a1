"""The region Ω: the entry point to every region, and the convex shapes in closed form.

:class:`Domain` builds every :class:`~meanfield.geometry.region.Region` the toolkit has:
``Domain.box``, ``Domain.disk`` and ``Domain.polygon`` (registered as region kinds ``box``,
``disk``, ``polygon``, :mod:`meanfield.plugins`), and ``Domain.from_wkt``,
``Domain.from_geojson``, ``Domain.from_dxf`` and ``Domain.from_shapely`` for a room drawn
elsewhere.  Each returns the right implementation of the shape it is given: an axis-aligned
rectangle is a box, a convex polygon without holes is a polygon (both answered here in closed
form), and anything else, a room with re-entrant corners or holes, is a
:class:`~meanfield.geometry.plan.Plan`.  Nothing is refused for not being convex: the paper
(Section III) assumes a convex Ω, and the results that need it say so where they are
computed (``is_convex``; the Payne–Weinberger bound, :func:`analysis.poincare.payne_weinberger_bound`).

The domain tests membership, reflects a point that stepped outside back in (the
reflecting walls of the human SDE, eq. (1)), projects a point onto Ω (robots are kept
inside Ω), samples it, cuts grid cells (:mod:`meanfield.geometry.cut_cells`), and splits its
boundary into walls and exits (:meth:`Domain.boundary_parts`).  Every question about
the shape is answered here: box and disk in closed form, the polygon by its edges; no
other module asks which shape Ω is.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np

from meanfield.capabilities import RegionCapabilities
from meanfield.errors import ParameterError
from meanfield.geometry.region import (
    BoundaryPart,
    Region,
    convex_polygon,
    exit_list,
    refuse_overlapping_exits,
    sample_by_rejection,
    square_lattice,
)

__all__ = ["Domain"]

Segment = tuple[tuple[float, float], tuple[float, float]]

DomainKind = Literal["box", "disk", "polygon"]


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ParameterError(name, value, "a finite number")
    return value


@dataclass(frozen=True)
class Domain:
    """A convex, bounded region Ω, and the builder of every region.

    Do not call the constructor directly; use :meth:`box`, :meth:`disk` or :meth:`polygon`
    (or :meth:`from_wkt`, :meth:`from_geojson`, :meth:`from_dxf`, :meth:`from_shapely`), which
    validate their arguments and return the right implementation.  This class answers for a
    convex polygon, by its edges; the box and the disk are its subclasses, which answer in
    closed form (no method asks which shape it is).

    Attributes
    ----------
    kind : {"box", "disk", "polygon"}
        The shape.
    vertices : ndarray, shape (m, 2)
        Counter-clockwise vertices (box and polygon); empty for a disk.
    center : tuple of float
        Centre of the disk, or the centroid of the vertices.
    radius : float
        Radius of the disk; 0 for polygons.
    exits : tuple of segments
        Parts of the boundary that are exits (doors), each ``((x0, y0), (x1, y1))`` on ∂Ω;
        the rest of ∂Ω is wall.  Empty by default (the paper's closed room).
    """

    capabilities: ClassVar[RegionCapabilities] = RegionCapabilities()
    """What the ``box``, ``disk`` and ``polygon`` region kinds declare
    (:class:`~meanfield.capabilities.RegionCapabilities`)."""

    kind: DomainKind
    vertices: np.ndarray = field(repr=False)
    center: tuple[float, float]
    radius: float = 0.0
    exits: tuple[Segment, ...] = ()

    # ------------------------------------------------------------------ builders
    @classmethod
    def box(
        cls, width: float = 1.0, height: float = 1.0, origin: tuple[float, float] = (0.0, 0.0), exits: Any = ()
    ) -> Domain:
        """Axis-aligned rectangle ``[x0, x0 + width] × [y0, y0 + height]``.

        Parameters
        ----------
        width, height : float
            Side lengths, both > 0.
        origin : (float, float)
            Lower-left corner.
        exits : list of segments, optional
            Boundary segments that are exits (:meth:`with_exits`).
        """
        width = _finite("width", width)
        height = _finite("height", height)
        if width <= 0:
            raise ParameterError("width", width, "a number > 0")
        if height <= 0:
            raise ParameterError("height", height, "a number > 0")
        x0 = _finite("origin[0]", origin[0])
        y0 = _finite("origin[1]", origin[1])
        v = np.array([[x0, y0], [x0 + width, y0], [x0 + width, y0 + height], [x0, y0 + height]], float)
        return _Box("box", v, (x0 + width / 2, y0 + height / 2), 0.0)._exits(exits)

    @classmethod
    def disk(cls, radius: float = 1.0, center: tuple[float, float] = (0.0, 0.0), exits: Any = ()) -> Domain:
        """Disk of the given radius (> 0) around ``center`` (``exits``: see :meth:`with_exits`)."""
        radius = _finite("radius", radius)
        if radius <= 0:
            raise ParameterError("radius", radius, "a number > 0")
        c = (_finite("center[0]", center[0]), _finite("center[1]", center[1]))
        return _Disk("disk", np.zeros((0, 2)), c, radius)._exits(exits)

    @classmethod
    def polygon(cls, vertices: Any, exits: Any = ()) -> Region:
        """The simple polygon through ``vertices`` (either orientation, no repeated end point).

        A convex polygon is a :class:`Domain` (kind ``"polygon"``, answered in closed form); a
        polygon that is not convex, an L-shaped room say, is a :class:`~meanfield.geometry.plan.Plan`
        (its walls followed segment by segment).  ``is_convex`` tells which; the paper's theory
        assumes a convex Ω (docs page *Poincaré constant*).  ``exits``: boundary segments that are
        exits (:meth:`with_exits`).

        Raises
        ------
        ParameterError
            If fewer than 3 vertices, non-finite values, repeated points, collinear
            consecutive vertices of a convex polygon, or a self-intersecting polygon.
        """
        v = np.asarray(vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3:
            raise ParameterError("vertices", v.shape, "an array of shape (m, 2) with m >= 3")
        if not np.all(np.isfinite(v)):
            raise ParameterError("vertices", "non-finite values", "finite coordinates")
        if np.allclose(v[0], v[-1]):
            v = v[:-1]
        e = np.roll(v, -1, axis=0) - v
        if np.any(np.hypot(e[:, 0], e[:, 1]) == 0):
            raise ParameterError("vertices", "repeated vertex", "distinct consecutive vertices")
        cross = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
        scale = np.max(np.abs(v - v.mean(axis=0))) ** 2
        tol = 1e-12 * scale
        if np.any(cross > tol) and np.any(cross < -tol):  # turns both ways: not convex, a plan
            return cls.from_shapely(_simple_polygon(v), exits)
        if np.any(np.abs(cross) <= tol):
            raise ParameterError("vertices", "collinear consecutive vertices", "a strictly convex vertex list")
        if np.all(cross < 0):
            v = v[::-1].copy()
        # A star polygon turns the same way at every vertex but winds more than once.
        ang = np.arctan2(e[:, 1], e[:, 0])
        turn = np.mod(np.diff(np.r_[ang, ang[0]]) + np.pi, 2 * np.pi) - np.pi
        if abs(abs(turn.sum()) - 2 * np.pi) > 1e-6:
            raise ParameterError("vertices", "a self-intersecting polygon", "a simple convex polygon")
        c = v.mean(axis=0)
        return cls("polygon", v, (float(c[0]), float(c[1])), 0.0)._exits(exits)

    @classmethod
    def from_shapely(cls, polygon: Any, exits: Any = ()) -> Region:
        """The region of a shapely ``Polygon`` (metres), as the right implementation.

        An axis-aligned rectangle is :meth:`box`, a convex polygon without holes :meth:`polygon`,
        anything else (re-entrant corners, holes) a :class:`~meanfield.geometry.plan.Plan`.
        Vertices on a straight edge are dropped first (they change no shape).

        Parameters
        ----------
        polygon : shapely.Polygon
            Valid, non-empty, one piece; holes allowed.
        exits : sequence of segments, optional
            Parts of the walls that are exits, ``((x0, y0), (x1, y1))`` each.
        """
        import shapely

        from meanfield.geometry.plan import Plan

        plan = Plan(polygon, exits)  # validates the polygon and the exits
        shape = shapely.simplify(plan.polygon, 0.0)
        if len(shape.interiors) or not convex_polygon(shape):
            return plan
        v = np.asarray(shape.exterior.coords, float)[:-1]
        x0, y0 = v.min(axis=0)
        x1, y1 = v.max(axis=0)
        corners = {(x0, y0), (x1, y0), (x1, y1), (x0, y1)}
        if len(v) == 4 and {(float(a), float(b)) for a, b in v} == corners:
            return cls.box(x1 - x0, y1 - y0, (x0, y0), exits=plan.exits)
        return cls.polygon(v, exits=plan.exits)

    @classmethod
    def from_wkt(cls, text: str, exits: Any = ()) -> Region:
        """The region of a WKT ``POLYGON`` (metres; holes allowed), as :meth:`from_shapely` chooses it."""
        from meanfield.geometry.plan import Plan

        return cls.from_shapely(Plan.from_wkt(text).polygon, exits)

    @classmethod
    def from_geojson(cls, source: Any, exits: Any = ()) -> Region:
        """The region of a GeoJSON Polygon (a file, or the parsed object; a Feature's geometry is
        taken), as :meth:`from_shapely` chooses it."""
        from meanfield.geometry.plan import Plan

        return cls.from_shapely(Plan.from_geojson(source).polygon, exits)

    @classmethod
    def from_dxf(cls, path: Any, exits: Any = (), **layers: str | None) -> Region:
        """The region of a DXF drawing (its walls, obstacles and exits on layers named by ``layers``:
        :func:`meanfield.geometry.dxf.read_dxf`), as :meth:`from_shapely` chooses it; ``exits`` are
        added to those the drawing holds."""
        from meanfield.geometry.plan import Plan

        plan = Plan.from_dxf(path, **layers)
        return cls.from_shapely(plan.polygon, (*plan.exits, *tuple(exits)))

    @property
    def is_convex(self) -> bool:
        """True: a box, a disk and a :meth:`polygon` that is a Domain are convex."""
        return True

    def _exits(self, exits: Any) -> Domain:
        return self.with_exits(exits) if exits is not None and len(exits) else self

    # ------------------------------------------------------------------ geometry
    @functools.cached_property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` of the bounding box (computed once: the domain is frozen)."""
        v = self.vertices
        return (float(v[:, 0].min()), float(v[:, 0].max()), float(v[:, 1].min()), float(v[:, 1].max()))

    @functools.cached_property
    def box_walls(self) -> np.ndarray:
        """``(x0, x1, y0, y1)`` of a box, empty for any other shape: the ``box`` of the compiled passes that
        fold a box's walls into a step (:func:`meanfield.crowds._point_mass_loops.euler_maruyama`,
        :func:`~meanfield.signs._robot_loops.robot_euler`). Not to be changed; left writable, since numba compiles a
        read-only array as another type (a second compilation of each pass)."""
        return np.array((), float)

    @functools.cached_property
    def _corners(self) -> tuple[np.ndarray, np.ndarray]:
        """``(xmin, ymin)`` and ``(xmax, ymax)`` as arrays (read-only), for :meth:`project`."""
        x0, x1, y0, y1 = self.bounds
        lo, hi = np.array([x0, y0]), np.array([x1, y1])
        lo.flags.writeable = hi.flags.writeable = False
        return lo, hi

    @property
    def area(self) -> float:
        """Area |Ω|."""
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))

    @property
    def diameter(self) -> float:
        """Largest distance between two points of Ω."""
        d = self.vertices[:, None, :] - self.vertices[None, :, :]
        return float(np.sqrt((d**2).sum(-1)).max())

    def _edges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Edge start points, unit outward normals and offsets (n·x <= offset inside)."""
        v = self.vertices
        e = np.roll(v, -1, axis=0) - v
        n = np.stack([e[:, 1], -e[:, 0]], axis=1)  # outward for CCW order
        n /= np.hypot(n[:, 0], n[:, 1])[:, None]
        off = np.einsum("ij,ij->i", n, v)
        return v, n, off

    def contains(self, x: Any, y: Any, tol: float | None = None) -> np.ndarray:
        """Whether points lie in the closed domain (boundary included, up to ``tol``).

        The default ``tol`` is ``1e-12 × diameter``, so points that round-off put a few
        ulps outside the wall (projections, vertices) still count as inside.
        """
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        if tol is None:
            tol = 1e-12 * self.diameter
        _, n, off = self._edges()
        inside = np.ones(np.broadcast(x, y).shape, bool)
        for k in range(len(off)):
            inside &= n[k, 0] * x + n[k, 1] * y <= off[k] + tol
        return inside

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Mirror points that left Ω back inside (reflecting walls), in place.

        The box folds each coordinate (any number of bounces).  Disk and polygon
        mirror across the violated wall; a point that is still outside after a few
        reflections (only possible for a step longer than the domain) is projected.

        Parameters
        ----------
        points : ndarray, shape (N, 2)
            Positions, modified in place and returned.
        """
        _, n, off = self._edges()
        for _ in range(4):
            moved = False
            for k in range(len(off)):
                d = points @ n[k] - off[k]
                out = d > 0
                if out.any():
                    points[out] -= 2.0 * d[out, None] * n[k]
                    moved = True
            if not moved:
                return points
        return self.project(points)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest point of Ω for each row of ``points`` (in place); inside points unchanged."""
        out = ~self.contains(points[:, 0], points[:, 1])
        if not out.any():
            return points
        p = points[out]
        v = self.vertices
        e = np.roll(v, -1, axis=0) - v
        best = np.full(len(p), np.inf)
        proj = p.copy()
        for k in range(len(v)):
            t = np.clip(((p - v[k]) @ e[k]) / (e[k] @ e[k]), 0.0, 1.0)
            q = v[k] + t[:, None] * e[k]
            d = ((p - q) ** 2).sum(1)
            better = d < best
            best[better] = d[better]
            proj[better] = q[better]
        points[out] = proj
        return points

    def sample_uniform(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points drawn uniformly from Ω by rejection from the bounding box."""
        return sample_by_rejection(self, n, rng)

    def to_shapely(self, resolution: int = 4096) -> Any:
        """This domain as a shapely polygon (a disk becomes a ``resolution``-gon)."""
        import shapely

        return shapely.Polygon(self.vertices)

    # ------------------------------------------------------------------ the Region interface
    def cut_cells(
        self, x_edges: np.ndarray, y_edges: np.ndarray, dx: float, dy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Volume fractions ``(nx, ny)`` and face apertures of the lattice ``x_edges × y_edges``.

        The box's cells are all whole; the disk's are exact in closed form; the polygon's
        are clipped with shapely where its wall crosses them (:mod:`meanfield.geometry.cut_cells`).
        ``dx``, ``dy`` are the lattice spacings.
        """
        from meanfield.geometry.cut_cells import convex_polygon_cut_cells

        _, normal, offset = self._edges()
        return convex_polygon_cut_cells(normal, offset, self.to_shapely(), x_edges, y_edges, dx, dy)

    def cells_meeting(self, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
        """Mask ``(nx, ny)`` of the lattice cells whose interior meets Ω."""
        import shapely

        XL, YL = np.meshgrid(x_edges[:-1], y_edges[:-1], indexing="ij")
        XR, YR = np.meshgrid(x_edges[1:], y_edges[1:], indexing="ij")

        boxes = shapely.box(XL, YL, XR, YR)
        return shapely.area(shapely.intersection(boxes, self.to_shapely())) > 0

    def robot_region(self, margin: float) -> Domain:
        """Where robots may stand: Ω inset by ``margin`` (Ω itself for ``margin <= 0``).

        Raises
        ------
        ParameterError
            For a polygon with ``margin > 0`` (named ``robots.margin``), or a margin that
            leaves no room.
        """
        if margin <= 0:
            return self
        raise ParameterError("robots.margin", margin, "0 for a polygon domain (a margin needs a box or a disk)")

    def lattice(self, n: int) -> np.ndarray:
        """``n`` points of Ω on a regular lattice (the paper's 4×4 robots for n = 16).

        A box gets a cell-centred ``cols × rows`` lattice (``cols = ceil(sqrt(n))``), the last
        row centred if it is partial; other shapes get the smallest square lattice over the
        bounding box with at least ``n`` points inside Ω, of which ``n`` evenly spaced ones.
        """
        return square_lattice(self, n)

    def boundary_parts(self) -> tuple[BoundaryPart, ...]:
        """∂Ω as walls and exits: each exit segment, and the walls between them.

        The disk's boundary is the polyline of :meth:`to_shapely` (4096 vertices).
        """
        import shapely

        ring = self.to_shapely().exterior
        if not self.exits:
            return (BoundaryPart("wall", np.asarray(ring.coords)),)
        doors = shapely.MultiLineString([list(e) for e in self.exits])
        walls = shapely.line_merge(ring.difference(doors.buffer(1e-9 * self.diameter)))
        parts = [BoundaryPart("exit", np.asarray(e, float)) for e in self.exits]
        for line in getattr(walls, "geoms", [walls]):
            if not line.is_empty:
                parts.append(BoundaryPart("wall", np.asarray(line.coords)))
        return tuple(parts)

    def with_exits(self, exits: Any) -> Domain:
        """The same shape with boundary segments ``[((x0, y0), (x1, y1)), ...]`` tagged as exits.

        Raises
        ------
        ParameterError
            (named ``domain.exits``) if a segment is degenerate or does not lie on ∂Ω.
        """
        import shapely

        segs: list[Segment] = []
        ring = self.to_shapely().exterior
        tol = 1e-9 * self.diameter + self._exit_tolerance()
        for k, e in enumerate(exit_list(exits)):
            try:
                (ax_, ay_), (bx, by) = e
                seg = ((float(ax_), float(ay_)), (float(bx), float(by)))
            except (TypeError, ValueError):
                raise ParameterError(f"domain.exits[{k}]", e, "a segment [[x0, y0], [x1, y1]]") from None
            if not all(map(math.isfinite, (*seg[0], *seg[1]))) or seg[0] == seg[1]:
                raise ParameterError(f"domain.exits[{k}]", e, "two distinct finite end points")
            if shapely.LineString(seg).hausdorff_distance(ring) > tol and not ring.buffer(tol).covers(
                shapely.LineString(seg)
            ):
                raise ParameterError(f"domain.exits[{k}]", e, "a segment on the boundary of Ω")
            segs.append(seg)
        refuse_overlapping_exits(segs, tol)
        return type(self)(self.kind, self.vertices, self.center, self.radius, tuple(segs))

    def neumann_eigenvalue(self) -> float | None:
        """μ₂, the first non-zero Neumann eigenvalue of −Δ on Ω, where it has a closed form.

        Rectangle: ``π² / max(width, height)²``; disk: ``(j'₁,₁ / R)²`` (``j'₁,₁ ≈ 1.8412``, the
        first zero of J₁'); None for a polygon (see :func:`analysis.poincare.exact_neumann_eigenvalue`).
        """
        return None

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (for TOML)."""
        d = self._table()
        if self.exits:
            d["exits"] = [[list(a), list(b)] for a, b in self.exits]
        return d

    def _table(self) -> dict[str, Any]:
        """The ``[domain]`` table of the shape, without its exits."""
        return {"kind": "polygon", "vertices": self.vertices.tolist()}

    def _exit_tolerance(self) -> float:
        """How far an exit may lie from the outline (beyond round-off): 0 for straight walls."""
        return 0.0

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Domain:
        """Inverse of :meth:`to_dict` (the registry's region factories; unknown keys are refused)."""
        from meanfield.geometry.region import region_from_table

        return region_from_table(d)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Domain):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(repr(self.to_dict()))

    def __repr__(self) -> str:
        return f"Domain(kind={self.kind!r}, center={self.center!r}, radius={self.radius!r}, exits={self.exits!r})"



class _Box(Domain):
    """An axis-aligned rectangle (``Domain.box``): every question in closed form, the walls folded."""

    @functools.cached_property
    def box_walls(self) -> np.ndarray:
        """``(x0, x1, y0, y1)``: the ``box`` the compiled passes fold into a step (see :attr:`Domain.box_walls`)."""
        return np.array(self.bounds, float)

    def contains(self, x: Any, y: Any, tol: float | None = None) -> np.ndarray:
        """Whether points lie in the closed box (boundary included, up to ``tol``; see :meth:`Domain.contains`)."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        if tol is None:
            tol = 1e-12 * self.diameter
        x0, x1, y0, y1 = self.bounds
        return (x >= x0 - tol) & (x <= x1 + tol) & (y >= y0 - tol) & (y <= y1 + tol)

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Fold each coordinate back into the box (any number of bounces), in place."""
        x0, x1, y0, y1 = self.bounds
        for k, (lo, hi) in enumerate(((x0, x1), (y0, y1))):
            col = points[:, k]
            out = (col < lo) | (col > hi)
            if out.any():
                period = 2.0 * (hi - lo)
                s = np.mod(col[out] - lo, period)
                col[out] = lo + np.where(s > hi - lo, period - s, s)
        return points

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest point of the box (in place): the corners as rows, two broadcast ufuncs (``np.clip`` per
        column costs three times as much)."""
        lo, hi = self._corners
        np.maximum(points, lo, out=points)
        np.minimum(points, hi, out=points)
        return points

    def cut_cells(
        self, x_edges: np.ndarray, y_edges: np.ndarray, dx: float, dy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every cell and face of the box's lattice is whole."""
        nx, ny = len(x_edges) - 1, len(y_edges) - 1
        return np.ones((nx, ny)), np.ones((nx - 1, ny)), np.ones((nx, ny - 1))

    def cells_meeting(self, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
        """Every cell of the box's lattice."""
        return np.ones((len(x_edges) - 1, len(y_edges) - 1), bool)

    def robot_region(self, margin: float) -> Domain:
        """The box inset by ``margin`` (the box itself for ``margin <= 0``; see :meth:`Domain.robot_region`)."""
        if margin <= 0:
            return self
        x0, x1, y0, y1 = self.bounds
        if x1 - x0 <= 2 * margin or y1 - y0 <= 2 * margin:
            raise ParameterError("robots.margin", margin, f"less than half the box's sides ({self.bounds})")
        return Domain.box(x1 - x0 - 2 * margin, y1 - y0 - 2 * margin, (x0 + margin, y0 + margin))

    def lattice(self, n: int) -> np.ndarray:
        """A cell-centred ``cols × rows`` lattice (``cols = ceil(sqrt(n))``), the last row centred if partial."""
        x0, x1, y0, y1 = self.bounds
        cols = math.ceil(math.sqrt(n))
        rows = math.ceil(n / cols)
        pts = []
        for r in range(rows):
            k = min(cols, n - r * cols)
            y = y0 + (r + 0.5) * (y1 - y0) / rows
            for c in range(k):
                pts.append((x0 + (c + 0.5 + (cols - k) / 2) * (x1 - x0) / cols, y))
        return np.array(pts, float)

    def neumann_eigenvalue(self) -> float | None:
        """``π² / max(width, height)²``."""
        x0, x1, y0, y1 = self.bounds
        return math.pi**2 / max(x1 - x0, y1 - y0) ** 2

    def _table(self) -> dict[str, Any]:
        x0, x1, y0, y1 = self.bounds
        return {"kind": "box", "width": x1 - x0, "height": y1 - y0, "origin": [x0, y0]}


class _Disk(Domain):
    """A disk (``Domain.disk``): every question in closed form; its outline a 4096-gon where shapely draws it."""

    @functools.cached_property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` of the bounding box."""
        cx, cy = self.center
        r = self.radius
        return (cx - r, cx + r, cy - r, cy + r)

    @property
    def area(self) -> float:
        """``π R²``."""
        return math.pi * self.radius**2

    @property
    def diameter(self) -> float:
        """``2 R``."""
        return 2 * self.radius

    def contains(self, x: Any, y: Any, tol: float | None = None) -> np.ndarray:
        """Whether points lie in the closed disk (boundary included, up to ``tol``; see :meth:`Domain.contains`)."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        if tol is None:
            tol = 1e-12 * self.diameter
        cx, cy = self.center
        return (x - cx) ** 2 + (y - cy) ** 2 <= (self.radius + tol) ** 2

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Mirror points that left the disk across its circle (radially), in place."""
        cx, cy = self.center
        dx = points[:, 0] - cx
        dy = points[:, 1] - cy
        r = np.hypot(dx, dy)
        out = r > self.radius
        if out.any():
            rr = r[out]
            new = np.maximum(2 * self.radius - rr, 0.0)
            new = np.minimum(new, self.radius)
            scale = new / rr
            points[out, 0] = cx + dx[out] * scale
            points[out, 1] = cy + dy[out] * scale
        return points

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest point of the disk (in place): outside points pulled radially onto the circle."""
        cx, cy = self.center
        dx = points[:, 0] - cx
        dy = points[:, 1] - cy
        r = np.hypot(dx, dy)
        out = r > self.radius
        if out.any():
            s = self.radius / r[out]
            points[out, 0] = cx + dx[out] * s
            points[out, 1] = cy + dy[out] * s
        return points

    def to_shapely(self, resolution: int = 4096) -> Any:
        """The disk as a shapely ``resolution``-gon."""
        import shapely

        return shapely.Point(self.center).buffer(self.radius, quad_segs=max(resolution // 4, 8))

    def cut_cells(
        self, x_edges: np.ndarray, y_edges: np.ndarray, dx: float, dy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The disk's cut cells, exact in closed form (:func:`meanfield.geometry.cut_cells.disk_cut_cells`)."""
        from meanfield.geometry.cut_cells import disk_cut_cells

        return disk_cut_cells(self.center, self.radius, x_edges, y_edges, dx, dy)

    def cells_meeting(self, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
        """Cells whose nearest point to the centre lies in the open disk."""
        XL, YL = np.meshgrid(x_edges[:-1], y_edges[:-1], indexing="ij")
        XR, YR = np.meshgrid(x_edges[1:], y_edges[1:], indexing="ij")
        cx, cy = self.center
        dx = np.clip(cx, XL, XR) - cx
        dy = np.clip(cy, YL, YR) - cy
        return dx * dx + dy * dy < self.radius**2

    def robot_region(self, margin: float) -> Domain:
        """The disk of radius ``R - margin`` (the disk itself for ``margin <= 0``)."""
        if margin <= 0:
            return self
        if margin >= self.radius:
            raise ParameterError("robots.margin", margin, f"less than the disk's radius {self.radius}")
        return Domain.disk(self.radius - margin, self.center)

    def neumann_eigenvalue(self) -> float | None:
        """``(j'₁,₁ / R)²`` (``j'₁,₁ ≈ 1.8412``, the first zero of J₁')."""
        from scipy.special import jnp_zeros

        return float(jnp_zeros(1, 1)[0] / self.radius) ** 2

    def _table(self) -> dict[str, Any]:
        return {"kind": "disk", "radius": self.radius, "center": list(self.center)}

    def _exit_tolerance(self) -> float:
        return 2 * math.pi * self.radius / 4096  # the 4096-gon's chord against the circle


def _simple_polygon(vertices: np.ndarray) -> Any:
    """The shapely polygon through ``vertices``, refused (naming ``vertices``) unless simple."""
    import shapely

    poly = shapely.Polygon(vertices)
    if not poly.is_valid:
        reason = shapely.is_valid_reason(poly)
        raise ParameterError("vertices", f"a self-intersecting polygon ({reason})", "a simple polygon")
    return poly
