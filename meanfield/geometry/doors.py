"""Inner doors: the openings between the rooms of a plan, each a segment from one jamb to the other.

A plan's ``doors`` (``[domain] doors = [[[x0, y0], [x1, y1]], ...]``) say where its rooms open on each
other.  Nothing in the geometry needs them (the walls alone shape the routes, the density and the reflecting
steps); the agents' door models that cap the flow do (docs page *Congestion*, "The doors' capacity"): each
door, as each exit, passes at most the diagram's capacity ``q_max`` per metre of its width, which the density's
Godunov flux passes through every face (:meth:`~meanfield.crowds.point_mass.PointMassEngine.cap_doors`).
Without it, people converging on a 1 m door in a wall from a half circle pass it at 2.5–2.7 persons/(m·s).

A door must cross the plan from wall to wall: its two ends on the walls, the segment inside the plan, its
middle off the walls, away from every exit and from the other doors.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry.region import exit_list

__all__ = ["check_doors", "door_segments"]


def door_segments(region: Any) -> np.ndarray:
    """The region's inner doors as an array ``(D, 2, 2)`` of end points (``(0, 2, 2)`` for a region without
    ``doors``: a box, a disk, a plan that names none)."""
    return np.array(getattr(region, "doors", ()), float).reshape(-1, 2, 2)


def check_doors(polygon: Any, doors: Any, exits: Any, tol: float) -> tuple:
    """``doors`` as segments ``((x0, y0), (x1, y1))``, each refused (named ``doors[k]``) unless it crosses the
    shapely ``polygon`` from wall to wall, clear of the ``exits`` and of the doors before it.

    Parameters
    ----------
    polygon : shapely.Polygon or shapely.MultiPolygon
        The plan.
    doors : sequence of segments
    exits : sequence of segments
        The plan's exits.
    tol : float
        How far (m) an end may lie from a wall, and the least distance to an exit or another door.
    """
    import shapely

    out: list[tuple[tuple[float, float], tuple[float, float]]] = []
    lines: list[Any] = []
    exit_lines = [shapely.LineString(e) for e in exits]
    walls = polygon.boundary
    inside = polygon.buffer(tol)
    for k, d in enumerate(exit_list(doors, "doors")):
        try:
            (ax_, ay_), (bx, by) = d
            seg = ((float(ax_), float(ay_)), (float(bx), float(by)))
        except (TypeError, ValueError):
            raise ParameterError(f"doors[{k}]", d, "a segment [[x0, y0], [x1, y1]]") from None
        if seg[0] == seg[1] or not np.isfinite(seg).all():
            raise ParameterError(f"doors[{k}]", d, "a segment of two distinct finite points")
        line = shapely.LineString(seg)
        ends = [shapely.Point(p) for p in seg]
        if any(walls.distance(p) > tol for p in ends):
            raise ParameterError(f"doors[{k}]", d, "a segment whose two ends lie on the plan's walls (its jambs)")
        if not inside.covers(line) or not polygon.contains(line.interpolate(0.5, normalized=True)):
            raise ParameterError(f"doors[{k}]", d, "a segment across the plan from one wall to another")
        for j, e in enumerate(exit_lines):
            if line.distance(e) <= tol:
                raise ParameterError(
                    f"doors[{k}]", d, f"a door clear of exits[{j}] (an exit passes at most its capacity already)"
                )
        for j, other in enumerate(lines):
            if line.distance(other) <= tol:
                raise ParameterError(f"doors[{k}]", d, f"a door clear of doors[{j}]")
        out.append(seg)
        lines.append(line)
    return tuple(out)
