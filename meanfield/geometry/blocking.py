"""A region that becomes a wall during a run: a scenario's ``block`` event (docs page *Buildings*, "Events").

``[[events]] time = t, block = "POLYGON ((...))"``: from time ``t`` on, the polygon is wall (smoke, a
fire, a collapsed ceiling).  Ω becomes ``Ω ∖ B`` (:func:`blocked_region`), a
:class:`~meanfield.geometry.plan.Plan` drawn in the frame of the region before, so the grid keeps its
lattice and only the cells ``B`` cuts change; :class:`WallsChange` carries the new Ω, its grid (the same
cells, cut again), its sight lines and its robot region to every part that declares ``walls_changed``
(:func:`tell_walls_changed`).  The people standing in ``B`` step out to its nearest edge.

A block may cut Ω in pieces, each with an exit of its own (a corridor blocked across): Ω is then a plan in pieces
(a ``MULTIPOLYGON``), its people walk to the exits of their piece, and an exit's routes leave the cells of the
other pieces without one (``φ = inf``, heading 0; :class:`~meanfield.geometry.geodesic.ExitEikonal`).

Refused when the scenario is read (naming ``events[i].block``; :func:`blocked_region`): a block that is not a
valid polygon, lies outside Ω, meets an exit (close the exit with ``close_exit`` instead: an exit in a wall
would no longer be on Ω's boundary), covers Ω, or leaves a piece without an exit (it would cut the people in it
off from every exit); and, by the scenario, a ``close_exit`` that leaves a piece without an open exit while
another piece still has one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["ReactsToWalls", "WallsChange", "blocked_region", "exit_pieces", "tell_walls_changed"]

PIECE_AREA = 1e-6
"""Pieces of ``Ω ∖ B`` smaller than this share of Ω's area are clipping round-off, dropped."""


def blocked_region(region: Any, block: Any, name: str = "block") -> Any:
    """``Ω ∖ B``: ``region`` with the polygon ``block`` (WKT or shapely) made wall.

    Returns a :class:`~meanfield.geometry.plan.Plan` with the same exits, in the same order, drawn in
    ``region``'s frame (its :attr:`bounds`), so a grid on it has the same cells; in pieces when the block
    cuts Ω, each piece with an exit.

    Raises
    ------
    ParameterError
        Naming ``name``: a block that is not one valid polygon, a region that cannot be blocked (a disk,
        a stand-in), a block outside Ω, one that meets an exit, one that covers Ω, one that leaves a piece
        without an exit (it cuts the people in it off from every exit).
    """
    import shapely

    from meanfield.geometry.exits import exit_segments, exits_on
    from meanfield.geometry.plan import Plan, polygon_pieces
    from meanfield.geometry.region import wkt_polygon

    polygon = block if isinstance(block, shapely.Polygon) else wkt_polygon(block, name)
    kind = getattr(region, "kind", None)
    if kind not in ("box", "polygon", "plan"):
        raise ParameterError(name, f"a block in a {kind!r} region", "a region of kind 'box', 'polygon' or 'plan'")
    omega = region.to_shapely()
    tol = PIECE_AREA * omega.area
    overlap = omega.intersection(polygon).area
    if overlap <= tol:
        if overlap > 0.0:  # inside the plan, but too small to be a wall of it
            raise ParameterError(
                name, f"a block of {overlap:.3g} in the plan",
                f"a block covering more than {tol:.3g} (a {PIECE_AREA:g} share of the plan's area {omega.area:.4g})",
            )  # fmt: skip
        raise ParameterError(name, polygon.wkt, f"a polygon that overlaps the plan (bounds {omega.bounds})")
    rest = omega.difference(polygon)
    pieces = [p for p in polygon_pieces(rest) if p.geom_type == "Polygon" and p.area > tol]
    if not pieces:
        raise ParameterError(name, "a block that covers the plan", "a region that leaves room to walk")
    segs = exit_segments(region)
    for k, seg in enumerate(segs):
        if polygon.intersects(shapely.LineString(seg)):
            raise ParameterError(
                name, f"a block that meets exit {k}", f"a region clear of the exits (close exit {k} with close_exit)"
            )
    if len(segs) and any(not exits_on(p, segs, 1e-9 * region.diameter) for p in pieces):  # (no exits: none to reach)
        raise ParameterError(
            name, "a block that cuts people off from every exit", "a region whose every side still has an exit"
        )
    exits = [tuple(map(tuple, seg)) for seg in segs]
    rest = shapely.Polygon(pieces[0].exterior, list(pieces[0].interiors)) if len(pieces) == 1 else (
        shapely.MultiPolygon(pieces))  # fmt: skip
    doors = [d for d in getattr(region, "doors", ()) if _still_a_door(rest, d, exits, region.diameter)]
    return Plan(rest, exits, frame=region.bounds, pieces=len(pieces) > 1, doors=doors)


def _still_a_door(rest: Any, door: Any, exits: list, diameter: float) -> bool:
    """Whether the inner ``door`` still crosses the plan ``rest`` left by a block from wall to wall (a door the
    block covered, or one it left in the open, is no longer one)."""
    from meanfield.geometry.doors import check_doors

    try:
        check_doors(rest, [door], exits, 1e-9 * diameter)
    except ParameterError:
        return False
    return True


def exit_pieces(region: Any) -> list[list[int]]:
    """For each piece of ``region`` (one for a region in one piece), the exits on its boundary."""
    from meanfield.geometry.exits import exit_segments, exits_on
    from meanfield.geometry.plan import polygon_pieces

    segs = exit_segments(region)
    return [exits_on(p, segs, 1e-9 * region.diameter) for p in polygon_pieces(region.to_shapely())]


@dataclass(frozen=True)
class WallsChange:
    """What a ``block`` event changes, told to every part that reacts to walls (:class:`ReactsToWalls`).

    Attributes
    ----------
    region : Plan
        Ω from now on (:func:`blocked_region`).
    grid : Grid
        The grid on it: the same cells, cut by the new walls.
    sight : SightLines
        Its sight lines (the block hides what is behind it).
    robot_region : Region
        Where the robots may stand from now on.
    target : ndarray
        ``ρ_*`` on the new grid.
    blocked : shapely.Polygon
        The region that became wall.
    """

    region: Any
    grid: Any
    sight: Any
    robot_region: Any
    target: np.ndarray
    blocked: Any


@runtime_checkable
class ReactsToWalls(Protocol):
    """A part told when a region becomes wall during a run (a scenario's ``[[events]] block``; docs page *Buildings*,
    "Events"): a crowd, its engine, view or guidance, a controller."""

    def walls_changed(self, change: WallsChange) -> None:
        """The walls are ``change``'s from now on."""
        ...


def tell_walls_changed(parts: Any, change: WallsChange) -> None:
    """Tell each of ``parts`` that reacts to walls (:class:`ReactsToWalls`) what the walls are now (a ``block``
    event)."""
    for part in parts:
        if isinstance(part, ReactsToWalls):
            part.walls_changed(change)
