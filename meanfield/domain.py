"""The workspace Ω: a convex, bounded region of the plane.

The paper (Section III) assumes Ω ⊂ R² convex and bounded with a Lipschitz boundary.
Three shapes are supported: an axis-aligned rectangle (``Domain.box``), a disk
(``Domain.disk``) and a convex polygon (``Domain.polygon``).  A polygon that is not
convex is refused, because the paper's Poincaré and Lyapunov arguments rely on it.

The domain knows how to test membership, reflect a point that stepped outside back in
(the reflecting walls of the human SDE, eq. (1)), and project a point onto Ω (robots
are kept inside Ω).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["Domain"]

DomainKind = Literal["box", "disk", "polygon"]


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ParameterError(name, value, "a finite number")
    return value


@dataclass(frozen=True)
class Domain:
    """A convex, bounded workspace Ω.

    Do not call the constructor directly; use :meth:`box`, :meth:`disk` or
    :meth:`polygon`, which validate their arguments.

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
    """

    kind: DomainKind
    vertices: np.ndarray = field(repr=False)
    center: tuple[float, float]
    radius: float = 0.0

    # ------------------------------------------------------------------ builders
    @classmethod
    def box(cls, width: float = 1.0, height: float = 1.0, origin: tuple[float, float] = (0.0, 0.0)) -> Domain:
        """Axis-aligned rectangle ``[x0, x0 + width] × [y0, y0 + height]``.

        Parameters
        ----------
        width, height : float
            Side lengths, both > 0.
        origin : (float, float)
            Lower-left corner.
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
        return cls("box", v, (x0 + width / 2, y0 + height / 2), 0.0)

    @classmethod
    def disk(cls, radius: float = 1.0, center: tuple[float, float] = (0.0, 0.0)) -> Domain:
        """Disk of the given radius (> 0) around ``center``."""
        radius = _finite("radius", radius)
        if radius <= 0:
            raise ParameterError("radius", radius, "a number > 0")
        c = (_finite("center[0]", center[0]), _finite("center[1]", center[1]))
        return cls("disk", np.zeros((0, 2)), c, radius)

    @classmethod
    def polygon(cls, vertices: Any) -> Domain:
        """Convex polygon through ``vertices`` (either orientation, no repeated end point).

        Raises
        ------
        ParameterError
            If fewer than 3 vertices, non-finite values, repeated or collinear points,
            or the polygon is not convex (the paper's theory assumes convex Ω).
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
        if np.any(np.abs(cross) <= tol):
            raise ParameterError("vertices", "collinear consecutive vertices", "a strictly convex vertex list")
        if not (np.all(cross > 0) or np.all(cross < 0)):
            raise ParameterError(
                "vertices",
                "a non-convex polygon",
                "a convex polygon (the paper's theory assumes convex Ω)",
            )
        if np.all(cross < 0):
            v = v[::-1].copy()
        # A star polygon turns the same way at every vertex but winds more than once.
        ang = np.arctan2(e[:, 1], e[:, 0])
        turn = np.mod(np.diff(np.r_[ang, ang[0]]) + np.pi, 2 * np.pi) - np.pi
        if abs(abs(turn.sum()) - 2 * np.pi) > 1e-6:
            raise ParameterError("vertices", "a self-intersecting polygon", "a simple convex polygon")
        c = v.mean(axis=0)
        return cls("polygon", v, (float(c[0]), float(c[1])), 0.0)

    # ------------------------------------------------------------------ geometry
    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` of the bounding box."""
        if self.kind == "disk":
            cx, cy = self.center
            r = self.radius
            return (cx - r, cx + r, cy - r, cy + r)
        v = self.vertices
        return (float(v[:, 0].min()), float(v[:, 0].max()), float(v[:, 1].min()), float(v[:, 1].max()))

    @property
    def area(self) -> float:
        """Area |Ω|."""
        if self.kind == "disk":
            return math.pi * self.radius**2
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))

    @property
    def diameter(self) -> float:
        """Largest distance between two points of Ω."""
        if self.kind == "disk":
            return 2 * self.radius
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
        if self.kind == "disk":
            cx, cy = self.center
            return (x - cx) ** 2 + (y - cy) ** 2 <= (self.radius + tol) ** 2
        if self.kind == "box":
            x0, x1, y0, y1 = self.bounds
            return (x >= x0 - tol) & (x <= x1 + tol) & (y >= y0 - tol) & (y <= y1 + tol)
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
        if self.kind == "box":
            x0, x1, y0, y1 = self.bounds
            for k, (lo, hi) in enumerate(((x0, x1), (y0, y1))):
                col = points[:, k]
                out = (col < lo) | (col > hi)
                if out.any():
                    period = 2.0 * (hi - lo)
                    s = np.mod(col[out] - lo, period)
                    col[out] = lo + np.where(s > hi - lo, period - s, s)
            return points
        if self.kind == "disk":
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
        if self.kind == "box":
            x0, x1, y0, y1 = self.bounds
            np.clip(points[:, 0], x0, x1, out=points[:, 0])
            np.clip(points[:, 1], y0, y1, out=points[:, 1])
            return points
        if self.kind == "disk":
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
        x0, x1, y0, y1 = self.bounds
        out = np.empty((0, 2))
        while len(out) < n:
            m = max(2 * (n - len(out)), 16)
            p = np.column_stack([rng.uniform(x0, x1, m), rng.uniform(y0, y1, m)])
            out = np.vstack([out, p[self.contains(p[:, 0], p[:, 1])]])
        return out[:n].copy()

    def to_shapely(self, resolution: int = 4096) -> Any:
        """This domain as a shapely polygon (a disk becomes a ``resolution``-gon)."""
        import shapely

        if self.kind == "disk":
            return shapely.Point(self.center).buffer(self.radius, quad_segs=max(resolution // 4, 8))
        return shapely.Polygon(self.vertices)

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (for TOML)."""
        if self.kind == "box":
            x0, x1, y0, y1 = self.bounds
            return {"kind": "box", "width": x1 - x0, "height": y1 - y0, "origin": [x0, y0]}
        if self.kind == "disk":
            return {"kind": "disk", "radius": self.radius, "center": list(self.center)}
        return {"kind": "polygon", "vertices": self.vertices.tolist()}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Domain:
        """Inverse of :meth:`to_dict`; unknown keys are refused."""
        d = dict(d)
        kind = d.pop("kind", "box")
        allowed = {"box": {"width", "height", "origin"}, "disk": {"radius", "center"}, "polygon": {"vertices"}}
        if kind not in allowed:
            raise ParameterError("domain.kind", kind, "one of 'box', 'disk', 'polygon'")
        unknown = set(d) - allowed[kind]
        if unknown:
            raise ParameterError("domain", f"unknown key(s) {sorted(unknown)}", f"keys {sorted(allowed[kind])}")
        try:
            if kind == "box":
                return cls.box(d.get("width", 1.0), d.get("height", 1.0), tuple(d.get("origin", (0, 0))))
            if kind == "disk":
                return cls.disk(d.get("radius", 1.0), tuple(d.get("center", (0, 0))))
            if "vertices" not in d:
                raise ParameterError("vertices", None, "a list of [x, y] vertices")
            return cls.polygon(d["vertices"])
        except ParameterError as exc:
            raise ParameterError(f"domain.{exc.name}", exc.value, exc.allowed) from None
        except (TypeError, ValueError) as exc:
            raise ParameterError("domain", str(exc), f"a valid {kind} description") from None

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Domain):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(repr(self.to_dict()))
