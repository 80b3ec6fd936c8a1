"""A plan drawn in JuPedSim's web app, as a scenario: what each part of an export becomes.

:func:`scenario_table` turns a JuPedSim web-app export (read by :func:`meanfield.io.webapp.read_export`)
into the tables of a scenario, which :func:`meanfield.scenarios.scenario.load_scenario` builds (so
``meanfield run EXPORT.zip`` and ``meanfield scenario EXPORT.zip`` take an export where they take a
TOML file).  The format is read directly, as ``jupedsim_scenarios.load_scenario`` (jupedsim-scenarios
0.7, the reference for what an export holds) reads it, without that package: it would bring JuPedSim's
full dependency set along, and reading the format is a JSON and a WKT.

* the walkable area (the WKT) is the plan, ``[domain] kind = "plan"``, its holes the obstacles;
* each exit polygon becomes the segments where it meets the walkable area's boundary, ``domain.exits``:
  the walls it is drawn across (a door in a wall), or, drawn inside against walls, the longest of them;
  an exit drawn across an opening (a corridor's end, a door's gap), whose edge inside the area is one
  straight segment from wall to wall, is cut off the plan and that edge is the exit, where the web app
  removes people; an exit polygon inside the area, touching no wall, is cut out of the plan and its
  outline is the exit (people leave on reaching it, as in the web app);
* each distribution becomes a group, ``crowd.initial = "groups"``: its polygon (the part in the
  walkable area) and its count (``distribution_mode = "by_number"``; a percentage is turned into a
  count as jupedsim-scenarios does, from the area its bodies could fill);
* a distribution's journeys (``journey_weights`` onto ``journeys_v2``) give its group's exit, the last
  exit of the journey; a distribution with journeys to several exits is split into one group per exit,
  the people shared by the journeys' weights (largest remainder); without a journey, a group walks to
  its nearest exit (jupedsim-scenarios sends it to the nearest too);
* the model's settings (``config.simulation_settings``) become ``[crowd.options.jupedsim]``: the
  operational model, its parameters that JuPedSim takes from the toolkit (with jupedsim-scenarios'
  defaults where the export has none), its step ``dt`` (``time_step``), the bodies' radius and desired
  speed (``crowd.free_speed``); ``max_simulation_time`` is ``t_final`` and ``baseSeed`` the seed.

The crowd is the web app's: everyone knows the way to its exit (``crowd.guidance = "geodesic"``), the
robots are parked signs nobody follows (``controller.kind = "static-signs"``), as in ``rimea-10``;
``--set crowd.guidance=signs --set controller.kind=guide --set robots.n=8`` hands the crowd to the robots.

What cannot be mapped is listed, one :class:`~meanfield.errors.ScenarioWarning` per item, and left out:
checkpoints (waypoints, waiting areas), speed zones, legacy journeys and transitions, routing tables,
throughput limits on exits, flow spawning, pre-movement times, spreads of radius and speed, a model
parameter the toolkit does not pass to JuPedSim, several simulations, any other table of the export
(train constraints, ...).  Refused, naming the file (:class:`~meanfield.errors.ParameterError`): no
walkable area, no exit, an exit that does not touch the walkable area, a distribution outside it, an
unknown model.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from typing import Any

from meanfield.errors import ParameterError, ScenarioWarning
from meanfield.io.webapp import WebAppExport

__all__ = ["scenario_table", "WEBAPP_MODELS", "MAPPED_KEYS"]

WEBAPP_MODELS: dict[str, str] = {
    "CollisionFreeSpeedModel": "collision-free-speed",
    "CollisionFreeSpeedModelV2": "collision-free-speed-v2",
    "CollisionFreeSpeedModelV3": "collision-free-speed-v3",
    "AnticipationVelocityModel": "anticipation-velocity",
    "GeneralizedCentrifugalForceModel": "generalized-centrifugal-force",
    "SocialForceModel": "social-force",
    "WarpDriverModel": "warp-driver",
}
"""The web app's ``model_type`` and the operational model it is (``crowd.options.jupedsim.model``)."""

_MODEL_PARAMETERS: dict[str, dict[str, tuple[str, float]]] = {
    # web app's name -> (name in [crowd.options.jupedsim], jupedsim-scenarios' default), by model
    "CollisionFreeSpeedModel": {
        "strength_neighbor_repulsion": ("strength_neighbor_repulsion", 2.6),
        "range_neighbor_repulsion": ("range_neighbor_repulsion", 0.1),
    },
    "CollisionFreeSpeedModelV2": {
        "time_gap": ("time_gap", 1.0),
        "strength_neighbor_repulsion": ("strength_neighbor_repulsion", 2.6),
        "range_neighbor_repulsion": ("range_neighbor_repulsion", 0.1),
    },
    "AnticipationVelocityModel": {"time_gap": ("time_gap", 1.06)},  # (jupedsim-scenarios fixes it at 1.06)
}
_UNMAPPED_MODEL_PARAMETERS: dict[str, tuple[str, ...]] = {
    "AnticipationVelocityModel": ("T", "s0", "anticipation_time", "reaction_time"),
    "GeneralizedCentrifugalForceModel": (
        "gcfm_strength_neighbor_repulsion", "gcfm_strength_geometry_repulsion",
        "gcfm_max_neighbor_interaction_distance", "gcfm_max_geometry_interaction_distance",
        "gcfm_max_neighbor_repulsion_force", "gcfm_max_geometry_repulsion_force",
        "mass", "tau", "a_v", "a_min", "b_min", "b_max",
    ),
    "SocialForceModel": (
        "sfm_body_force", "sfm_friction", "relaxation_time", "agent_strength", "agent_range", "mass",
        "sfm_obstacle_scale",
    ),
    "WarpDriverModel": (
        "wd_time_horizon", "wd_step_size", "wd_sigma", "wd_time_uncertainty", "wd_velocity_uncertainty_x",
        "wd_velocity_uncertainty_y",
    ),
}  # fmt: skip
"""The parameters of each model that the web app sets and the toolkit does not pass to JuPedSim (a warning each)."""

MAPPED_KEYS = ("config", "exits", "distributions", "journeys_v2", "walkable_area_wkt", "obstacles", "project_version")
"""The top-level keys of an export that are read (``obstacles`` holds only their heights: the holes are in the
WKT); every other non-empty one gives a warning per item."""

_UNMAPPED_TABLES = {
    "checkpoints": "checkpoint (a waypoint or waiting area) {key}: people walk straight to their exit",
    "waiting_polygons": "waiting area {key}: people walk straight to their exit",
    "waypoints": "waypoint {key}: people walk straight to their exit",
    "zones": "speed zone {key}: people keep their speed there",
    "journeys": "journey {key} of the legacy stage graph (jupedsim-scenarios reads journeys_v2): people walk to the "
    "exit of their journeys_v2, or the nearest",
    "transitions": "transition {key} of the legacy stage graph: people walk straight to their exit",
    "waypoint_routing": "routing of {key}: people walk straight to their exit",
    "routing": "routing of {key}: people walk straight to their exit",
}

DEFAULT_RADIUS = 0.2
"""m: a body's radius where a distribution gives none (jupedsim-scenarios' default)."""
DEFAULT_SPEED = 1.2
"""m/s: the desired speed where a distribution gives none (jupedsim-scenarios' default)."""
DEFAULT_TIME_STEP = 0.01
"""s: JuPedSim's step where the export gives no ``dt`` (JuPedSim's default)."""
CONTROL_PERIOD = 0.1
"""s: about how often the toolkit steers (``dt``, a whole number of JuPedSim's steps)."""
RECORD_PERIOD = 0.5
"""s: about how often a run records the humans (``record_every`` steps)."""


def _warn(source: Any, message: str) -> None:
    warnings.warn(f"{source.name}: {message}", ScenarioWarning, stacklevel=3)


def _refuse(source: Any, what: str) -> ParameterError:
    return ParameterError("scenario", str(source), f"a JuPedSim web-app export with {what}")


def _polygon(source: Any, coords: Any, what: str) -> Any:
    import shapely

    try:
        poly = shapely.Polygon(coords)
    except (TypeError, ValueError, shapely.errors.GEOSException):
        raise _refuse(source, f"{what} given as a polygon, [[x, y], ...] (it is {str(coords)[:60]})") from None
    if not poly.is_valid:
        poly = shapely.make_valid(poly)
    if poly.is_empty or poly.area <= 0:
        raise _refuse(source, f"{what} given as a polygon with an area (it has none)")
    return poly


def _walkable_area(export: WebAppExport) -> Any:
    import shapely

    source = export.source
    if not export.walkable_wkt:
        raise _refuse(source, f"a walkable area ({export.wkt_name} is empty)")
    try:
        geom = shapely.from_wkt(export.walkable_wkt)
    except shapely.errors.GEOSException as exc:
        raise _refuse(source, f"a walkable area in WKT ({export.wkt_name}: {exc})") from None
    parts = [g for g in shapely.get_parts(geom) if isinstance(g, shapely.Polygon | shapely.MultiPolygon)]
    area = shapely.union_all(parts) if parts else shapely.Polygon()
    if area.is_empty or area.area <= 0:
        raise _refuse(source, f"a walkable area ({export.wkt_name} holds no polygon: {export.walkable_wkt[:60]})")
    if not area.is_valid:
        raise _refuse(source, f"a valid walkable area ({shapely.is_valid_reason(area)})")
    if not isinstance(area, shapely.Polygon):
        raise _refuse(source, f"a walkable area in one piece ({export.wkt_name} holds {len(area.geoms)} pieces)")
    return area


def _exit_segments(poly: Any, area: Any, tol: float) -> tuple[list, list]:
    """The pieces of the area's boundary inside the exit polygon ``poly``, as segments (collinear pieces joined):
    those ``poly`` also covers outside the area (a door drawn across the wall), and the others (flush with the wall,
    inside)."""
    import shapely

    meets = shapely.intersection(area.boundary, poly)
    lines = [g for g in shapely.get_parts(meets) if isinstance(g, shapely.LineString) and g.length > tol]
    across, flush = [], []
    if not lines:
        return across, flush
    merged = shapely.line_merge(shapely.MultiLineString(lines))
    step = 1e-6 * math.dist(area.bounds[:2], area.bounds[2:])
    for line in shapely.get_parts(merged):
        pts = list(line.simplify(tol).coords)
        for a, b in zip(pts, pts[1:], strict=False):
            if math.dist(a, b) <= tol:
                continue
            mid = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
            nx, ny = (b[1] - a[1]) / math.dist(a, b), (a[0] - b[0]) / math.dist(a, b)
            sides = [shapely.Point(mid[0] + s * step * nx, mid[1] + s * step * ny) for s in (1.0, -1.0)]
            outside = sides[0] if not area.contains(sides[0]) else sides[1]
            segment = (tuple(map(float, a)), tuple(map(float, b)))
            (across if poly.contains(outside) else flush).append(segment)
    return across, flush


def _across_an_opening(poly: Any, area: Any, tol: float) -> Any:
    """For an exit polygon drawn across an opening (a corridor's end, a door's gap): its part inside the area and the
    straight segment where it meets the rest of the area, if that is all of its edge inside the area (None
    otherwise)."""
    import shapely

    part = shapely.intersection(poly, area)
    if not isinstance(part, shapely.Polygon) or part.area <= 0:
        return None
    inside = shapely.difference(part.boundary, area.boundary.buffer(tol, cap_style="flat"))
    lines = [g for g in shapely.get_parts(inside) if isinstance(g, shapely.LineString) and g.length > 2 * tol]
    if len(lines) != 1:
        return None
    pts = list(lines[0].simplify(2 * tol).coords)
    if len(pts) != 2:
        return None
    # the segment ends on the walls (up to the buffer's trim): snap each end onto the boundary
    ends = [shapely.get_coordinates(shapely.shortest_line(shapely.Point(p), area.boundary))[1] for p in pts]
    return part, (tuple(map(float, ends[0])), tuple(map(float, ends[1])))


def _exits(export: WebAppExport, area: Any) -> tuple[Any, list, dict[str, list[int]]]:
    """The plan (the area, inner exits cut out), the exit segments, and each exit's segment indices."""
    import shapely

    source, data = export.source, export.data
    exits = data.get("exits")
    if not isinstance(exits, dict) or not exits:
        raise _refuse(source, "an exit (its 'exits' table is missing or empty)")
    tol = 1e-9 * max(1.0, math.dist(area.bounds[:2], area.bounds[2:]))
    segments: list = []
    of_exit: dict[str, list[int]] = {}
    inner: list[tuple[str, Any]] = []
    cut: list[Any] = []
    for key, entry in exits.items():
        coords = entry.get("coordinates") if isinstance(entry, dict) else None
        poly = _polygon(source, coords, f"exit {key}")
        across, flush = _exit_segments(poly, area, tol)
        opening = _across_an_opening(poly, area, tol) if across else None
        if opening is not None:  # the area ends where the web app removes people: the exit's inner edge
            cut.append(opening[0])
            across = [opening[1]]
        if not across and flush:  # drawn inside, against the walls: the door is the longest wall it touches
            flush.sort(key=lambda seg: -math.dist(*seg))
            if len(flush) > 1:
                _warn(source, f"exit {key} lies against {len(flush)} walls: the longest is its door, the others "
                              "stay walls")  # fmt: skip
            across = flush[:1]
        found = across
        if found:
            of_exit[key] = list(range(len(segments), len(segments) + len(found)))
            segments += found
            if len(found) > 1:
                _warn(source, f"exit {key} crosses the walls along {len(found)} segments: each is an exit of the plan "
                              "(domain.exits), and its people walk to the longest")  # fmt: skip
        elif area.contains(poly):
            inner.append((key, poly))
        else:
            raise _refuse(source, f"exits that touch the walkable area (exit {key}, {poly.wkt[:80]}, does not)")
        if isinstance(entry, dict) and entry.get("enable_throughput_throttling") in (True, "true", 1):
            rate = entry.get("max_throughput", 0)
            _warn(source, f"exit {key}: its throughput limit ({rate} persons/s) is not mapped: it lets people "
                          "through as fast as they come")  # fmt: skip
    plan = area
    for part in cut:
        plan = shapely.difference(plan, part)
    for key, poly in inner:  # an exit inside the room: a hole whose outline is the exit
        plan = shapely.difference(plan, poly)
        ring = list(shapely.normalize(poly).exterior.coords)
        found = [(tuple(map(float, a)), tuple(map(float, b))) for a, b in zip(ring, ring[1:], strict=False)
                 if math.dist(a, b) > tol]  # fmt: skip
        of_exit[key] = list(range(len(segments), len(segments) + len(found)))
        segments += found
    return plan, segments, {k: of_exit[k] for k in exits}


def _parameters(source: Any, key: str, entry: dict[str, Any]) -> dict[str, Any]:
    params = entry.get("parameters", {})
    if isinstance(params, str):
        try:
            params = json.loads(params)
        except json.JSONDecodeError:
            raise _refuse(source, f"distribution {key}'s parameters as a table (they are {params[:60]!r})") from None
    if not isinstance(params, dict):
        raise _refuse(source, f"distribution {key}'s parameters as a table (they are {params!r})")
    return params


def _speed(params: dict[str, Any], canonical: str, legacy: str, default: Any) -> Any:
    value = params.get(canonical)
    if value is None:
        value = params.get(legacy)
    return default if value is None else value


def _count(source: Any, key: str, params: dict[str, Any], region: Any, radius: float) -> int:
    """People in a distribution: its ``number``, or its percentage of the bodies its area holds (as
    jupedsim-scenarios counts them: half the area over a body's disk, at least a 0.1 m radius)."""
    mode = params.get("distribution_mode", "by_number")
    if mode in ("by_percentage", "fill_area", "until_full"):
        default = 100 if mode in ("fill_area", "until_full") else 50
        try:
            percentage = max(1, min(100, int(float(params.get("percentage", default)))))
        except (TypeError, ValueError):
            percentage = default
        r = max(radius, 0.1)
        capacity = max(1, math.floor(0.5 * region.area / (math.pi * r * r)))
        return max(1, capacity * percentage // 100)
    try:
        return max(0, int(params.get("number", 10)))
    except (TypeError, ValueError):
        raise _refuse(source, f"distribution {key}'s number as an integer (it is {params.get('number')!r})") from None


def _journey_exits(export: WebAppExport, exit_keys: set[str]) -> dict[str, str | None]:
    """Each journey (``journeys_v2``) and the exit it ends at (None: no exit in its sequence)."""
    out: dict[str, str | None] = {}
    for j in export.data.get("journeys_v2") or []:
        if not isinstance(j, dict) or "id" not in j:
            continue
        sequence = [s for s in (j.get("sequence") or []) if isinstance(s, str)]
        ends = [s for s in sequence if s in exit_keys]
        out[str(j["id"])] = ends[-1] if ends else None
        if not ends:
            _warn(export.source, f"journey {j['id']} leads to no exit ({' -> '.join(sequence) or 'empty'}): its "
                                 "people walk to their nearest exit")  # fmt: skip
    return out


def _shares(n: int, weights: list[float]) -> list[int]:
    """``n`` shared in proportion to ``weights`` (largest remainder; ties to the first)."""
    total = sum(weights)
    exact = [n * w / total for w in weights]
    out = [math.floor(x) for x in exact]
    for k in sorted(range(len(exact)), key=lambda k: (out[k] - exact[k], k))[: n - sum(out)]:
        out[k] += 1
    return out


def _wkt(geom: Any) -> str:
    import shapely

    return shapely.to_wkt(geom, rounding_precision=-1, trim=True)


def _groups(export: WebAppExport, plan: Any, segments: list, of_exit: dict[str, list[int]]) -> tuple[list, list]:
    """The groups (region, n, exit) and each distribution's (radius, speed, n) for the crowd's values."""
    import shapely

    source, data = export.source, export.data
    dists = data.get("distributions")
    if not isinstance(dists, dict):
        return [], []
    longest = {k: max(idx, key=lambda i: math.dist(*segments[i])) for k, idx in of_exit.items()}
    journeys = _journey_exits(export, set(of_exit))
    groups, bodies = [], []
    for key, entry in dists.items():
        if not isinstance(entry, dict):
            raise _refuse(source, f"distribution {key} as a table with coordinates and parameters")
        poly = _polygon(source, entry.get("coordinates"), f"distribution {key}")
        region = shapely.intersection(poly, plan)
        if region.area <= 1e-9 * poly.area:
            raise _refuse(source, f"distributions inside the walkable area (distribution {key}, {poly.wkt[:80]}, "
                                  "lies outside it)")  # fmt: skip
        if region.area < (1 - 1e-6) * poly.area:
            _warn(source, f"distribution {key}: {1 - region.area / poly.area:.0%} of it lies outside the walkable "
                          "area (or on an obstacle or exit): its people stand in the rest")  # fmt: skip
        region = shapely.normalize(
            shapely.MultiPolygon([g for g in shapely.get_parts(region) if isinstance(g, shapely.Polygon)])
        )
        if len(region.geoms) == 1:
            region = region.geoms[0]
        params = _parameters(source, key, entry)
        radius = float(params.get("radius", DEFAULT_RADIUS))
        speed = float(_speed(params, "desired_speed", "v0", DEFAULT_SPEED))
        n = _count(source, key, params, region, radius)
        _unmapped_parameters(source, key, params, n)
        if n == 0:
            _warn(source, f"distribution {key} holds nobody: left out")
            continue
        bodies.append((key, radius, speed, n))
        weights = [(w.get("journey_id"), float(w.get("weight", 0) or 0)) for w in entry.get("journey_weights") or []
                   if isinstance(w, dict) and str(w.get("journey_id")) in journeys]  # fmt: skip
        weights = [(j, w) for j, w in weights if w > 0]
        if not weights:
            groups.append({"region": _wkt(region), "n": n, "_from": key})
            continue
        by_exit: dict[str | None, float] = {}
        for j, w in weights:
            by_exit[journeys[str(j)]] = by_exit.get(journeys[str(j)], 0.0) + w
        for (exit_key, _), share in zip(by_exit.items(), _shares(n, list(by_exit.values())), strict=True):
            if share:
                group = {"region": _wkt(region), "n": share, "_from": key}
                if exit_key is not None:
                    group["exit"] = longest[exit_key]
                groups.append(group)
    return groups, bodies


def _unmapped_parameters(source: Any, key: str, params: dict[str, Any], n: int) -> None:
    truthy = (True, "true", "True", 1)
    if params.get("use_flow_spawning") in truthy or params.get("flow_schedule"):
        _warn(source, f"distribution {key}: its flow spawning (people arriving from "
                      f"{params.get('flow_start_time', 0)} s to {params.get('flow_end_time', 10)} s) is not mapped: "
                      f"its {n} people stand there from the start")  # fmt: skip
    if params.get("use_premovement") in truthy:
        _warn(source, f"distribution {key}: its pre-movement times ({params.get('premovement_distribution', 'gamma')}) "
                      "are not mapped: everyone walks from the start (crowd.premovement takes uniform or lognormal "
                      "laws)")  # fmt: skip
    if params.get("radius_distribution") == "gaussian" and params.get("radius_std"):
        _warn(source, f"distribution {key}: the spread of its radii (std {params['radius_std']} m) is not mapped: "
                      "every body has the same radius")  # fmt: skip
    std = _speed(params, "desired_speed_std", "v0_std", None)
    if _speed(params, "desired_speed_distribution", "v0_distribution", "constant") == "gaussian" and std:
        _warn(source, f"distribution {key}: the spread of its desired speeds (std {std} m/s) is not mapped: "
                      "everyone has the same free speed")  # fmt: skip


def _crowd_values(source: Any, bodies: list) -> tuple[float, float]:
    """One radius and one free speed for the crowd (the people's mean), with a warning for each distribution that
    differs from it."""
    total = sum(n for *_, n in bodies)
    radius = sum(r * n for _, r, _, n in bodies) / total
    speed = sum(v * n for _, _, v, n in bodies) / total
    for key, r, v, _ in bodies:
        if not math.isclose(r, radius, rel_tol=1e-9):
            _warn(source, f"distribution {key}: its radius {r:g} m is not kept: every body has the crowd's mean, "
                          f"{radius:.4g} m")  # fmt: skip
        if not math.isclose(v, speed, rel_tol=1e-9):
            _warn(source, f"distribution {key}: its desired speed {v:g} m/s is not kept: everyone walks at the "
                          f"crowd's mean, {speed:.4g} m/s")  # fmt: skip
    return radius, speed


def _model(export: WebAppExport) -> tuple[dict[str, Any], dict[str, Any], int, float]:
    """``[crowd.options.jupedsim]`` (model, parameters, step), the rest of the simulation settings, the seed and
    ``t_final``."""
    source = export.source
    config = export.data.get("config") or {}
    settings = config.get("simulation_settings") or {} if isinstance(config, dict) else {}
    params = settings.get("simulationParams") or {}
    if not isinstance(params, dict):
        raise _refuse(source, f"simulationParams as a table (they are {params!r})")
    model_type = params.get("model_type", export.data.get("model_type", "CollisionFreeSpeedModel"))
    if model_type not in WEBAPP_MODELS:
        raise _refuse(source, f"a model_type among {', '.join(WEBAPP_MODELS)} (it is {model_type!r})")
    options: dict[str, Any] = {"model": WEBAPP_MODELS[model_type]}
    for name, (ours, default) in _MODEL_PARAMETERS.get(model_type, {}).items():
        options[ours] = float(params.get(name, default)) if model_type != "AnticipationVelocityModel" else default
    for name in _UNMAPPED_MODEL_PARAMETERS.get(model_type, ()):
        if name in params:
            _warn(source, f"the {model_type}'s parameter {name} = {params[name]!r} is not mapped: JuPedSim's "
                          "default is used")  # fmt: skip
    options["time_step"] = float(params.get("dt") or DEFAULT_TIME_STEP)
    runs = settings.get("numberOfSimulations", 1)
    if isinstance(runs, int | float) and runs > 1:
        _warn(source, f"its {runs:g} simulations (seeds from baseSeed on) are not mapped: one run; "
                      "`meanfield sweep` or --seed runs more")  # fmt: skip
    seed = export.data.get("seed", settings.get("baseSeed", 42))
    t_final = float(params.get("max_simulation_time", 300))
    return options, params, int(seed), t_final


def _other_tables(export: WebAppExport) -> None:
    """One warning per item of every table that is not mapped."""
    source = export.source
    for name, value in export.data.items():
        if name in MAPPED_KEYS or not value:
            continue
        items = list(value) if isinstance(value, dict) else list(range(len(value))) if isinstance(value, list) else []
        template = _UNMAPPED_TABLES.get(name, f"{name}[{{key}}] is not read by the toolkit")
        for item in items or [name]:
            label = item
            if isinstance(value, list) and isinstance(value[item], dict):
                label = value[item].get("id", item)
            text = template.format(key=label)
            if name in _UNMAPPED_TABLES:
                text += " (not mapped)"
            _warn(source, text)


def _grid_cells(plan: Any, segments: list) -> list[int]:
    """Cells about a quarter of the narrowest exit (at most 0.5 m), and at most 300 along a side."""
    x0, y0, x1, y1 = plan.bounds
    narrowest = min(math.dist(*s) for s in segments)
    cell = max(min(0.5, narrowest / 4), max(x1 - x0, y1 - y0) / 300)
    return [max(2, math.ceil((x1 - x0) / cell)), max(2, math.ceil((y1 - y0) / cell))]


def scenario_table(export: WebAppExport) -> dict[str, Any]:
    """The tables of the scenario an export stands for (the module docstring says what maps to what).

    Parameters
    ----------
    export : WebAppExport
        As :func:`meanfield.io.webapp.read_export` reads it.

    Returns
    -------
    dict
        The scenario's tables, as a TOML file holds them (:meth:`Scenario.from_dict
        <meanfield.scenarios.scenario.Scenario.from_dict>` builds and checks the scenario).

    Raises
    ------
    ParameterError
        Named ``scenario``, its value the export's file: no walkable area, no exit, an exit that does not touch
        the walkable area, a distribution outside it, an unknown model, a part that is not a polygon.

    Warns
    -----
    ScenarioWarning
        One per item that is not mapped (checkpoints, zones, flow spawning, ...), naming it.
    """
    source = export.source
    area = _walkable_area(export)
    plan, segments, of_exit = _exits(export, area)
    options, _, seed, t_final = _model(export)
    groups, bodies = _groups(export, plan, segments, of_exit)
    _other_tables(export)
    if groups:
        radius, speed = _crowd_values(source, bodies)
        crowd: dict[str, Any] = {"n": sum(g["n"] for g in groups), "initial": "groups",
                                 "groups": [{k: v for k, v in g.items() if k != "_from"} for g in groups]}  # fmt: skip
    else:
        radius, speed = DEFAULT_RADIUS, DEFAULT_SPEED
        crowd = {"n": 100, "initial": "uniform"}
        _warn(source, "no distribution of people: 100 people, uniform over the walkable area (as jupedsim-scenarios "
                      "places them)")  # fmt: skip
    time_step = options["time_step"]
    dt = time_step * max(1, round(CONTROL_PERIOD / time_step))
    options.update({"radius": radius, "max_speed": speed})
    first = segments[0]
    name = re.sub(r"[^A-Za-z0-9_.-]+", "-", source.stem if source.is_file() else source.name).strip("-") or "webapp"
    return {
        "name": name,
        "seed": seed,
        "dt": dt,
        "t_final": t_final,
        "record_every": max(1, round(RECORD_PERIOD / dt)),
        "units": "SI",
        "domain": {"kind": "plan", "wkt": _wkt(plan), "exits": [[list(a), list(b)] for a, b in segments]},
        "grid": {"cells": _grid_cells(plan, segments)},
        "crowd": {**crowd, "sigma": 0.05, "guidance": "geodesic", "free_speed": speed,
                  "options": {"jupedsim": options}},  # fmt: skip
        "robots": {"n": 4, "layout": "grid", "headings": "random", "u_max": 1.5, "omega_max": 1.5},
        "kernel": {"c": speed, "eta": 9.0},
        "target": {"center": [(first[0][0] + first[1][0]) / 2, (first[0][1] + first[1][1]) / 2], "std": 2.0},
        "density": {"bandwidth": 1.0},
        "controller": {"kind": "static-signs"},
        "view": {"radius": 10.0, "walk_speed": 0.7, "turning_rate": 0.1},
    }
