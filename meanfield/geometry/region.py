"""The :class:`Region` interface: the region Ω as geometry, its boundary as walls and exits.

The first of the closed loop's three interfaces (:mod:`meanfield.interfaces` holds the
other two); :class:`meanfield.geometry.domain.Domain` builds every implementation of it (its
convex shapes, and :class:`~meanfield.geometry.plan.Plan` for the rest).  This module imports only
the toolkit's foundations (:mod:`meanfield.errors`, :mod:`meanfield.plugins`), so that every
module of the geometry can name it; it also reads a scenario's ``[domain]`` table into a region
through the registry (:func:`region_from_table`) and tells whether a polygon is convex
(:func:`convex_polygon`).
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

from meanfield import plugins
from meanfield.errors import ParameterError

__all__ = [
    "BoundaryPart",
    "Region",
    "sample_by_rejection",
    "square_lattice",
    "region_keywords",
    "region_from_table",
    "convex_polygon",
    "CONVEX_RTOL",
    "exit_list",
    "refuse_overlapping_exits",
    "regular_file",
    "wkt_polygon",
]


@dataclass(frozen=True)
class BoundaryPart:
    """One piece of ∂Ω: a polyline tagged ``"wall"`` (zero flux, reflecting) or ``"exit"`` (a door).

    Attributes
    ----------
    kind : {"wall", "exit"}
    points : ndarray, shape (m, 2)
        The polyline's vertices in order (metres).
    """

    kind: Literal["wall", "exit"]
    points: np.ndarray

    @property
    def length(self) -> float:
        """Length of the polyline."""
        d = np.diff(self.points, axis=0)
        return float(np.hypot(d[:, 0], d[:, 1]).sum())


@runtime_checkable
class Region(Protocol):
    """The region Ω as geometry (:class:`meanfield.geometry.domain.Domain` implements it).

    Ω is a bounded polygon, possibly with holes (a disk is an exact curved special case),
    whose boundary is split into walls and exits.  Box and disk answer every question
    below in closed form; a general polygon through shapely.
    """

    @property
    def kind(self) -> str:
        """The registered name of the shape (``"box"``, ``"disk"``, ``"polygon"``, ...)."""
        ...

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)``."""
        ...

    @property
    def center(self) -> tuple[float, float]: ...

    @property
    def area(self) -> float: ...

    @property
    def diameter(self) -> float: ...

    def contains(self, x: Any, y: Any, tol: float | None = None) -> np.ndarray:
        """Membership of the closed region, elementwise."""
        ...

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Mirror, in place, the points that left Ω back inside (reflecting walls).

        A region whose class sets ``reflects_along_paths = True`` (a plan with re-entrant
        corners or holes) is called as ``reflect(points, previous)`` by the crowd, with the
        steps' starts, so that it can follow each step and stop none going through a wall.
        """
        ...

    def project(self, points: np.ndarray) -> np.ndarray:
        """Nearest point of Ω, in place, for the points outside."""
        ...

    def sample_uniform(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points drawn uniformly from Ω."""
        ...

    def cut_cells(
        self, x_edges: np.ndarray, y_edges: np.ndarray, dx: float, dy: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cut cells of the lattice ``x_edges × y_edges`` (spacings ``dx``, ``dy``): volume
        fractions ``(nx, ny)`` and the open fractions of the interior x-faces ``(nx-1, ny)``
        and y-faces ``(nx, ny-1)`` (docs page *Discretisation*)."""
        ...

    def cells_meeting(self, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
        """Mask of the lattice cells whose interior meets Ω."""
        ...

    def robot_region(self, margin: float) -> Region:
        """Where robots may stand: Ω inset by ``margin`` (Ω itself for 0)."""
        ...

    def lattice(self, n: int) -> np.ndarray:
        """``n`` evenly spread points of Ω (the robots' grid layout)."""
        ...

    def boundary_parts(self) -> tuple[BoundaryPart, ...]:
        """∂Ω as walls and exits (every hole's boundary is wall)."""
        ...

    def to_shapely(self) -> Any:
        """Ω as a shapely polygon (holes as interiors)."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """The scenario's ``[domain]`` table: ``{"kind": name, ...}``."""
        ...


CONVEX_RTOL = 1e-12
"""A polygon is convex when its convex hull adds no area beyond this relative round-off."""


def convex_polygon(shape: Any) -> bool:
    """Whether a shapely polygon is convex: no holes, and its convex hull adds no area beyond
    round-off (relative :data:`CONVEX_RTOL`)."""
    if getattr(shape, "geom_type", None) != "Polygon" or len(shape.interiors):
        return False
    area = float(shape.area)
    return area > 0 and (float(shape.convex_hull.area) - area) <= CONVEX_RTOL * area


def regular_file(path: Any, what: str, name: str = "file") -> Any:
    """``path`` as an existing regular file (a :class:`pathlib.Path`), refused (named ``name``) otherwise, never
    with a traceback.

    A path too long for the system, a device or a special file (``/proc/self/mem``) and a
    missing file are refused alike; the value in the message is cut to 200 characters.
    """
    from pathlib import Path

    text = str(path)
    shown = text if len(text) <= 200 else text[:200] + f"... ({len(text)} characters)"
    try:
        p = Path(path)
        ok = p.is_file() and not p.resolve().is_relative_to("/proc")  # /proc: files that are not data
    except (OSError, ValueError) as exc:
        raise ParameterError(name, shown, f"{what} (the path cannot be used: {exc.__class__.__name__})") from None
    if not ok:
        raise ParameterError(name, shown, what)
    return p


def wkt_polygon(text: Any, name: str, pieces: bool = False) -> Any:
    """The shapely polygon of ``text`` (WKT), refused, naming ``name``, unless it is one valid polygon of positive area
    (or, with ``pieces``, a valid multipolygon too): a group's region, a region blocked during a run."""
    import shapely

    kinds = ("Polygon", "MultiPolygon") if pieces else ("Polygon",)
    what = 'a polygon in WKT, "POLYGON ((x0 y0, x1 y1, ...))"'
    if not isinstance(text, str):
        raise ParameterError(name, text, what)
    try:
        polygon = shapely.from_wkt(text)
    except Exception:  # noqa: BLE001 - shapely's GEOS errors have no common public type
        raise ParameterError(name, text, what) from None
    if polygon is None or polygon.geom_type not in kinds or polygon.is_empty:
        got = "an empty geometry" if polygon is None or polygon.is_empty else f"a {polygon.geom_type}"
        raise ParameterError(name, got, "exactly one " + what[2:])
    if not polygon.is_valid or polygon.area <= 0:
        reason = shapely.is_valid_reason(polygon) if not polygon.is_valid else "no area"
        raise ParameterError(name, reason, "a valid polygon with an area > 0")
    return polygon


def exit_list(exits: Any, name: str = "domain.exits") -> list[Any]:
    """``exits`` as a list of candidate segments, refused (named ``name``) unless it is a list.

    A string is refused as a whole (``exits = "door"`` is not four segments ``'d'``, ``'o'``, ...).
    """
    if isinstance(exits, str | bytes) or not hasattr(exits, "__iter__"):
        raise ParameterError(name, exits, "a list of segments [[[x0, y0], [x1, y1]], ...]")
    return list(exits)


def refuse_overlapping_exits(segments: Any, tol: float, name: str = "domain.exits") -> None:
    """Refuse (named ``name[k]``) an exit that overlaps an earlier one along a length above ``tol``.

    Two exits sharing a stretch of wall would count its people twice and its width twice in the
    evacuation bound; exits that touch at an end point are fine.
    """
    import shapely

    lines = [shapely.LineString(s) for s in segments]
    for k in range(1, len(lines)):
        for j in range(k):
            shared = lines[k].intersection(lines[j].buffer(tol, cap_style="flat"))
            if shared.length > 2 * tol:
                raise ParameterError(
                    f"{name}[{k}]", [list(p) for p in segments[k]], f"an exit that does not overlap exits[{j}]"
                )


def sample_by_rejection(region: Any, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points drawn uniformly from ``region`` by rejection from its bounding box."""
    x0, x1, y0, y1 = region.bounds
    out = np.empty((0, 2))
    while len(out) < n:
        m = max(2 * (n - len(out)), 16)
        p = np.column_stack([rng.uniform(x0, x1, m), rng.uniform(y0, y1, m)])
        out = np.vstack([out, p[region.contains(p[:, 0], p[:, 1])]])
    return out[:n].copy()


def square_lattice(region: Any, n: int, tol: float | None = None) -> np.ndarray:
    """``n`` points of ``region``: the smallest square lattice over its bounding box with at least
    ``n`` points inside (``contains(..., tol)``), of which ``n`` evenly spaced ones."""
    x0, x1, y0, y1 = region.bounds
    m = math.ceil(math.sqrt(n))
    while True:
        xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
        ys = y0 + (np.arange(m) + 0.5) * (y1 - y0) / m
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        inside = region.contains(X, Y, tol=tol)
        if inside.sum() >= n:
            cand = np.column_stack([X[inside], Y[inside]])
            return cand[np.round(np.linspace(0, len(cand) - 1, n)).astype(int)]
        m += 1


def _keywords(factory: Any) -> tuple[set[str], set[str]] | None:
    """The keyword parameters of ``factory`` and the required ones; None if it takes any."""
    try:
        sig = inspect.signature(factory)
    except (TypeError, ValueError):
        return None
    names: set[str] = set()
    required: set[str] = set()
    for p in sig.parameters.values():
        if p.kind is p.VAR_KEYWORD:
            return None
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            names.add(p.name)
            if p.default is p.empty:
                required.add(p.name)
    return names, required


def region_keywords(kind: Any) -> set[str] | None:
    """The ``[domain]`` keys (besides ``kind``) a registered region kind takes; None if unknown or any."""
    if not isinstance(kind, str) or kind not in plugins.available("region"):
        return None
    keywords = _keywords(plugins.load("region", kind))
    return None if keywords is None else keywords[0]


def region_from_table(table: dict[str, Any]) -> Any:
    """The region a scenario's ``[domain]`` table describes, built by its registered factory.

    ``kind`` (default ``"box"``) names a region registered in :mod:`meanfield.plugins`
    (built in: ``"box"``, ``"disk"``, ``"polygon"``, ``"plan"``); the other keys are passed to that
    factory as keyword arguments (for a box, ``width``, ``height``, ``origin``).

    Parameters
    ----------
    table : dict
        The ``[domain]`` table.

    Returns
    -------
    Region
        What the factory returns (a :class:`~meanfield.geometry.domain.Domain` or a
        :class:`~meanfield.geometry.plan.Plan` for the built-ins).

    Raises
    ------
    ParameterError
        Named ``domain.kind`` for an unregistered kind (listing the registered ones);
        ``domain`` for a key the factory does not take (listing those it does) or a
        malformed table; ``domain.<field>`` for a missing required key or a value the
        factory refuses (its own field name, prefixed).
    """
    if not isinstance(table, dict):
        raise ParameterError("domain", table, "a table")
    rest = dict(table)
    kind = rest.pop("kind", "box")
    kinds = plugins.available("region")
    if kind not in kinds:
        raise ParameterError("domain.kind", kind, "one of " + ", ".join(map(repr, kinds)))
    factory = plugins.load("region", kind)
    keywords = _keywords(factory)
    if keywords is not None:
        allowed, required = keywords
        unknown = set(rest) - allowed
        if unknown:
            raise ParameterError("domain", f"unknown key(s) {sorted(unknown)}", f"keys {sorted(allowed)}")
        missing = sorted(required - set(rest))
        if missing:
            raise ParameterError(f"domain.{missing[0]}", None, f"a value (the {kind!r} region requires it)")
    try:
        return factory(**rest)
    except ParameterError as exc:
        raise ParameterError(f"domain.{exc.name}", exc.value, exc.allowed) from None
    except (TypeError, ValueError, LookupError) as exc:
        raise ParameterError("domain", str(exc), f"a valid {kind} description") from None
