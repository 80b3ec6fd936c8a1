"""Speed and flow of a measured run, with PedPy's measures (``meanfield pedestrians``).

* **Speed**: each human's speed from PedPy (:func:`pedpy.compute_individual_speed`,
  border-single-sided differences over ``frame_step`` frames), and its mean per frame over
  the whole room (:func:`pedpy.compute_mean_speed_per_frame`).
* **Flow into the target region**: PedPy's ``N(t)`` and flow
  (:func:`pedpy.compute_n_t`, :func:`pedpy.compute_flow`) across the *entry line* of the
  target region: the line perpendicular to the direction from the room's centre to the
  target's centre, at the target radius from the target's centre on the room's side,
  clipped to the room.  A human entering the target region from the room crosses it.

Docs page *Pedestrians*; numbers in the scenario's units (m and s for ``paper-unity``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["entry_line", "speed_and_flow"]


def entry_line(room: Any, target_center: tuple[float, float], target_radius: float) -> Any:
    """The target region's entry line (a shapely LineString), clipped to ``room``; None if degenerate."""
    import shapely

    cx, cy = room.centroid.x, room.centroid.y
    tx, ty = target_center
    d = math.hypot(tx - cx, ty - cy)
    if d == 0:
        return None
    ux, uy = (cx - tx) / d, (cy - ty) / d  # from the target towards the room
    px, py = tx + target_radius * ux, ty + target_radius * uy
    span = 2.0 * math.hypot(*(np.subtract(room.bounds[2:], room.bounds[:2])))
    line = shapely.LineString([(px - span * uy, py + span * ux), (px + span * uy, py - span * ux)])
    clipped = line.intersection(room)
    if clipped.is_empty or clipped.length == 0:
        return None
    if clipped.geom_type != "LineString":  # a non-convex room: the piece nearest the target
        clipped = min(clipped.geoms, key=lambda g: g.distance(shapely.Point(tx, ty)))
    return clipped


def speed_and_flow(
    traj: Any, room: Any, target_center: tuple[float, float], target_radius: float, frame_step: int = 1
) -> dict[str, Any]:
    """PedPy's speed and flow of a run (see the module docstring).

    Parameters
    ----------
    traj : pedpy.TrajectoryData
    room : pedpy.WalkableArea
    target_center, target_radius
        The target region.
    frame_step : int
        Frames on each side of a speed difference.

    Returns
    -------
    dict
        ``mean_speed`` (per frame, the whole room), ``speed_median``, ``speed_max`` (over
        every human and frame), and, with an entry line, ``crossings`` (humans who crossed
        it), ``n_t`` (cumulative crossings per frame), ``flow_mean`` (humans per unit time
        over the crossings, PedPy's flow; None with fewer than two crossings or too few
        frames for its windows of one second), ``entry_line`` (its end points and length).
    """
    import pedpy

    speeds = pedpy.compute_individual_speed(
        traj_data=traj, frame_step=frame_step, speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED
    )
    whole_room = pedpy.MeasurementArea(room.polygon)
    mean = pedpy.compute_mean_speed_per_frame(traj_data=traj, individual_speed=speeds, measurement_area=whole_room)
    out: dict[str, Any] = {
        "mean_speed": mean["speed"].to_numpy(dtype=float) if "speed" in mean else mean.to_numpy(dtype=float),
        "speed_median": float(np.median(speeds["speed"])),
        "speed_max": float(np.max(speeds["speed"])),
    }
    line = entry_line(room.polygon, target_center, target_radius)
    if line is None:
        return out
    ml = pedpy.MeasurementLine(line)
    n_t, crossing = pedpy.compute_n_t(traj_data=traj, measurement_line=ml)
    out["entry_line"] = {"points": [list(p) for p in line.coords], "length": float(line.length)}
    out["n_t"] = n_t["cumulative_pedestrians"].to_numpy(dtype=float)
    out["crossings"] = int(len(crossing))
    if len(crossing) >= 2:
        delta = max(int(traj.frame_rate), 1)
        flow = pedpy.compute_flow(
            nt=n_t, crossing_frames=crossing, individual_speed=speeds, delta_frame=delta, frame_rate=traj.frame_rate
        )
        values = flow["flow"].to_numpy(dtype=float) if "flow" in flow.columns else np.empty(0)
        out["flow_mean"] = float(np.nanmean(values)) if values.size else None  # None: too few frames per window
    else:
        out["flow_mean"] = None
    return out
