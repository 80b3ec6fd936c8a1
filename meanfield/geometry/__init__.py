"""The region Ω and everything drawn on it.

Regions (:mod:`~meanfield.geometry.region`: the :class:`Region` interface; :mod:`~meanfield.geometry.domain`:
box, disk, polygon; :mod:`~meanfield.geometry.plan`: floor plans with holes, from WKT, GeoJSON or
DXF (:mod:`~meanfield.geometry.dxf`)), the finite-volume grid with its cut cells
(:mod:`~meanfield.geometry.grid`, :mod:`~meanfield.geometry.cut_cells`), walls
(:mod:`~meanfield.geometry.walls`), exits (:mod:`~meanfield.geometry.exits`), geodesic routes
(:mod:`~meanfield.geometry.geodesic`), line of sight (:mod:`~meanfield.geometry.sight`), the target
density (:mod:`~meanfield.geometry.target`), the share of a disk inside Ω
(:mod:`~meanfield.geometry.disk_share`) and a region that becomes wall during a run
(:mod:`~meanfield.geometry.blocking`). The private ``_*_loops`` modules are their compiled loops.

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "BoundaryPart": "meanfield.geometry.region",
    "CONVEX_RTOL": "meanfield.geometry.region",
    "DiskShare": "meanfield.geometry.disk_share",
    "Domain": "meanfield.geometry.domain",
    "ExitRoutes": "meanfield.geometry.geodesic",
    "ExitSink": "meanfield.geometry.exits",
    "FULL_TEST_BELOW": "meanfield.geometry.walls",
    "FaceField": "meanfield.geometry.grid",
    "Grid": "meanfield.geometry.grid",
    "LOOK_AHEAD": "meanfield.geometry.geodesic",
    "Plan": "meanfield.geometry.plan",
    "Region": "meanfield.geometry.region",
    "SLIVER": "meanfield.geometry.cut_cells",
    "Segment": "meanfield.geometry.dxf",
    "SightLines": "meanfield.geometry.sight",
    "UNITS": "meanfield.geometry.dxf",
    "WallsChange": "meanfield.geometry.blocking",
    "WallIndex": "meanfield.geometry.walls",
    "blocked_region": "meanfield.geometry.blocking",
    "blocking_walls": "meanfield.geometry.sight",
    "convex_polygon": "meanfield.geometry.region",
    "convex_polygon_cut_cells": "meanfield.geometry.cut_cells",
    "disk_cut_cells": "meanfield.geometry.cut_cells",
    "disk_share": "meanfield.geometry.disk_share",
    "distance_to_segments": "meanfield.geometry.exits",
    "exit_distance": "meanfield.geometry.geodesic",
    "exit_segments": "meanfield.geometry.exits",
    "fraction_in_disk": "meanfield.geometry.target",
    "gaussian_target": "meanfield.geometry.target",
    "leaving": "meanfield.geometry.exits",
    "linear_binning": "meanfield.geometry.grid",
    "plan_from_table": "meanfield.geometry.plan",
    "read_dxf": "meanfield.geometry.dxf",
    "region_from_table": "meanfield.geometry.region",
    "region_keywords": "meanfield.geometry.region",
    "routes_for": "meanfield.geometry.geodesic",
    "sample_by_rejection": "meanfield.geometry.region",
    "segment_hits": "meanfield.geometry.walls",
    "square_lattice": "meanfield.geometry.region",
    "target_region_radius": "meanfield.geometry.target",
    "tell_exits_closed": "meanfield.geometry.exits",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
