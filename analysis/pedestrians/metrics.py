"""Pedestrian-dynamics measurements of a run with PedPy: N(t) in the target, density maps.

The paper's two studies are judged by how many humans reach the target region.  This
module measures that with `PedPy <https://pedpy.readthedocs.io>`_, the analysis library
of the pedestrian-dynamics community, instead of the toolkit's own counters, so that the
numbers can be compared with experiments and other simulators:

1. the humans' recorded trajectories are written in PedPy's plain-text format
   (:func:`meanfield.io.trajectories.write_pedpy_trajectories`) and loaded back with
   :func:`pedpy.load_trajectory_from_txt`; the walkable area is the room of the run's
   scenario;
2. ``N(t)``, the number of humans in the target region, is PedPy's classic density in
   the measurement area *target disk ∩ room* times its area; it is cross-checked against
   the run's own ``fraction_in_target`` (they differ only for humans between the
   polygonised disk and the true circle, or exactly on a wall: PedPy counts a point
   strictly inside the area);
3. PedPy's density profiles (classic, and Voronoi over a subsample of frames) over the
   last part of the run, beside the toolkit's KDE density ``N · ρ̂`` averaged over the
   same frames;
4. figures of both (:func:`plot_pedestrian_figures`).

PedPy is imported lazily, inside the functions: the rest of :mod:`analysis` works without
it.  ``meanfield pedestrians RUN_DIR... --out DIR`` (:func:`analysis.pedestrians.cli.register`) runs it all
(``docs/pedestrians.md``).

This module holds the measurements; the figures are drawn by
:mod:`analysis.pedestrians.figures` and the command lives in :mod:`analysis.pedestrians.cli`,
(:func:`plot_pedestrian_figures` is re-exported here).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.pedestrians.figures import plot_pedestrian_figures
from analysis.pedestrians.flow import speed_and_flow
from meanfield.errors import ParameterError

__all__ = [
    "PedestrianMetrics",
    "load_run",
    "walkable_area",
    "target_measurement_area",
    "load_pedpy_trajectories",
    "count_in_target",
    "density_maps",
    "pedestrian_metrics",
    "plot_pedestrian_figures",
]

# a grid size a hair above the toolkit's cell, so that PedPy's np.arange(min, max + g, g)
# gives exactly the toolkit's number of cells (1/30 would give 31 cells on the unit square)
_GRID_STRETCH = 1.0 + 1e-9


def _pedpy():
    try:
        import pedpy
    except ImportError as exc:  # pragma: no cover - exercised only without PedPy
        raise ImportError(
            "analysis.pedestrians.metrics needs PedPy (pedestrian-dynamics analysis): pip install pedpy"
        ) from exc
    return pedpy


def _scenario(dataset: Any):
    from meanfield.scenarios.scenario import Scenario

    text = dataset.attrs.get("scenario_toml")
    if not text:
        raise ParameterError("dataset", "no scenario_toml attribute", "a run dataset written by meanfield run")
    return Scenario.from_toml(str(text))


def load_run(run_dir: str | Path) -> Any:
    """The dataset ``RUN_DIR/timeseries.nc`` of ``meanfield run`` (loaded into memory).

    Raises
    ------
    ParameterError
        ``"run_dir"`` if the file does not exist.
    """
    import xarray as xr

    path = Path(run_dir) / "timeseries.nc"
    if not path.is_file():
        raise ParameterError("run_dir", str(run_dir), "a directory written by meanfield run (with timeseries.nc)")
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


def walkable_area(dataset: Any, resolution: int = 256) -> Any:
    """The room of the run as a :class:`pedpy.WalkableArea`.

    The domain is parsed from the dataset's ``scenario_toml`` attribute and polygonised by
    :meth:`meanfield.geometry.domain.Domain.to_shapely` (a disk becomes a ``resolution``-gon).
    """
    pedpy = _pedpy()
    return pedpy.WalkableArea(_scenario(dataset).domain.to_shapely(resolution=resolution))


def target_measurement_area(dataset: Any, segments: int = 1024, resolution: int = 256) -> Any:
    """The target region as a :class:`pedpy.MeasurementArea`: target disk ∩ room.

    The disk (centre ``target_center_x/y``, radius ``target_radius`` from the dataset's
    attributes) is the inscribed ``segments``-gon of the circle (``segments`` a multiple
    of 4), so it misses at most the sagitta ``r (1 − cos(π/segments))`` of the circle.

    Raises
    ------
    ParameterError
        ``"dataset"`` if the attributes are missing or the intersection is empty or not
        one convex polygon (PedPy's measurement areas are convex).
    """
    import shapely

    pedpy = _pedpy()
    try:
        cx, cy = float(dataset.attrs["target_center_x"]), float(dataset.attrs["target_center_y"])
        r = float(dataset.attrs["target_radius"])
    except KeyError as exc:
        missing = f"no attribute {exc.args[0]!r}"
        raise ParameterError("dataset", missing, "a run dataset with the target region") from None
    disk = shapely.Point(cx, cy).buffer(r, quad_segs=max(segments // 4, 2))
    room = _scenario(dataset).domain.to_shapely(resolution=resolution)
    area = shapely.intersection(disk, room)
    if area.is_empty or area.geom_type != "Polygon":
        raise ParameterError("dataset", f"target disk ∩ room is {area.geom_type}", "one polygon")
    try:
        return pedpy.MeasurementArea(area)
    except Exception as exc:  # pedpy.errors.GeometryError (non-convex room)
        raise ParameterError("dataset", f"target disk ∩ room: {exc}", "a convex measurement area") from exc


def load_pedpy_trajectories(dataset: Any, path: str | Path) -> Any:
    """Write the humans' trajectories to ``path`` and load them into a :class:`pedpy.TrajectoryData`.

    See :func:`meanfield.io.trajectories.write_pedpy_trajectories` for the format, the frame
    numbering (frame ``k`` is recorded time ``k``) and the refusals.
    """
    from meanfield.io.trajectories import write_pedpy_trajectories

    pedpy = _pedpy()
    written = write_pedpy_trajectories(dataset, path)
    return pedpy.load_trajectory_from_txt(trajectory_file=written)


def count_in_target(traj: Any, measurement_area: Any) -> np.ndarray:
    """``N(t)``: humans strictly inside ``measurement_area`` per frame, from PedPy's classic density.

    ``N = ρ_classic · A`` with ``ρ_classic`` from :func:`pedpy.compute_classic_density`,
    rounded to the nearest integer (the product is an integer up to rounding error).

    Returns
    -------
    ndarray of int, shape (frames,)
        One count per frame ``0 … max frame`` of ``traj``.
    """
    pedpy = _pedpy()
    dens = pedpy.compute_classic_density(traj_data=traj, measurement_area=measurement_area)
    dens = dens.sort_values("frame")
    return np.rint(dens["density"].to_numpy(dtype=float) * measurement_area.area).astype(np.int64)


def _profile_to_xy(profile: np.ndarray) -> np.ndarray:
    # PedPy's profiles are rows top (max y) → bottom, columns left → right (for imshow);
    # the toolkit's fields are indexed (x, y)
    return np.rot90(np.asarray(profile, dtype=float), k=-1)


def density_maps(
    traj: Any,
    area: Any,
    frames: np.ndarray,
    grid_size: float,
    *,
    voronoi_frames: int = 12,
) -> dict[str, Any]:
    """PedPy's density profiles over ``frames``, averaged, on square cells of ``grid_size``.

    Parameters
    ----------
    traj : pedpy.TrajectoryData
    area : pedpy.WalkableArea
        The room; the grid covers its bounding box from its lower-left corner.
    frames : ndarray of int
        The frames of the window.
    grid_size : float
        Cell side (the toolkit's cell side makes the maps comparable cell by cell).
    voronoi_frames : int
        The Voronoi profile (:func:`pedpy.compute_individual_voronoi_polygons`, then
        :func:`pedpy.compute_density_profile`) costs 0.3–1.2 s per frame for 200 humans
        on 30 × 30 cells (measured on two cores, idle and loaded), so it is averaged over
        at most this many frames evenly spread over the window; ``0`` skips it.

    Returns
    -------
    dict
        ``classic`` and ``voronoi`` (``None`` if skipped or failed, with the reason in
        ``voronoi_error``): mean density, shape (cells_x, cells_y), indexed (x, y);
        ``x_edges``, ``y_edges``; ``voronoi_frames`` used; wall times.
    """
    pedpy = _pedpy()
    frames = np.asarray(frames, dtype=np.int64)
    g = float(grid_size) * _GRID_STRETCH
    data = traj.data[traj.data["frame"].isin(frames)]
    t0 = time.perf_counter()
    classic = pedpy.compute_density_profile(
        data=data, walkable_area=area, grid_size=g, density_method=pedpy.DensityMethod.CLASSIC
    )
    classic_mean = np.mean([_profile_to_xy(p) for p in classic], axis=0)
    out: dict[str, Any] = {"classic": classic_mean, "classic_seconds": time.perf_counter() - t0}
    x0, y0, _, _ = area.bounds
    nx, ny = classic_mean.shape
    out["x_edges"] = x0 + g * np.arange(nx + 1)
    out["y_edges"] = y0 + g * np.arange(ny + 1)
    out["voronoi"], out["voronoi_error"], out["voronoi_frames"] = None, None, []
    if voronoi_frames > 0 and frames.size:
        pick = np.unique(frames[np.linspace(0, frames.size - 1, min(voronoi_frames, frames.size)).round().astype(int)])
        t0 = time.perf_counter()
        try:
            sub = pedpy.TrajectoryData(traj.data[traj.data["frame"].isin(pick)], traj.frame_rate)
            polys = pedpy.compute_individual_voronoi_polygons(traj_data=sub, walkable_area=area)
            vor = pedpy.compute_density_profile(
                data=polys, walkable_area=area, grid_size=g, density_method=pedpy.DensityMethod.VORONOI
            )
            out["voronoi"] = np.mean([_profile_to_xy(p) for p in vor], axis=0)
            out["voronoi_frames"] = pick.tolist()
        except Exception as exc:  # coincident points, degenerate cells: report, keep the rest
            out["voronoi_error"] = f"{type(exc).__name__}: {exc}"
        out["voronoi_seconds"] = time.perf_counter() - t0
    return out


@dataclass
class PedestrianMetrics:
    """What :func:`pedestrian_metrics` measured on one run.

    Counts and fractions are per analysed frame (the recorded frames, without a short last
    one); densities are in humans per unit area of the scenario (m⁻² for ``paper-unity``),
    indexed (x, y) on the toolkit's grid.
    """

    run_dir: str
    scenario: str
    backend: str
    seed: int | None
    n_humans: int
    frame_rate: float
    times: np.ndarray
    target_center: tuple[float, float]
    target_radius: float
    measurement_area: float
    n_in_target: np.ndarray
    fraction_pedpy: np.ndarray
    fraction_toolkit: np.ndarray
    boundary_band: np.ndarray
    window: tuple[float, float]
    window_frames: np.ndarray
    grid_size: float
    x_edges: np.ndarray
    y_edges: np.ndarray
    room_bounds: tuple[float, float, float, float]
    density_classic: np.ndarray
    density_voronoi: np.ndarray | None
    voronoi_frames: list[int]
    voronoi_error: str | None
    density_toolkit: np.ndarray
    trajectory_file: str
    seconds: dict[str, float] = field(default_factory=dict)
    figures: dict[str, str] = field(default_factory=dict)
    speed_and_flow: dict[str, Any] = field(default_factory=dict)  # analysis.pedestrians.flow

    @property
    def count_difference(self) -> np.ndarray:
        """Toolkit count minus PedPy count per frame (humans)."""
        return np.rint(self.fraction_toolkit * self.n_humans).astype(np.int64) - self.n_in_target

    @property
    def max_fraction_difference(self) -> float:
        """``max_t |fraction_in_target − N(t)/N|``."""
        return float(np.max(np.abs(self.fraction_toolkit - self.fraction_pedpy)))

    @property
    def differences_explained(self) -> bool:
        """Whether every frame's ``toolkit − PedPy`` count lies in ``[0, boundary_band]``.

        The toolkit counts a human at distance ``d ≤ r`` from the centre; PedPy counts a
        point strictly inside the inscribed polygon ∩ room.  Only humans in the disk within
        the polygon's sagitta of the circle, or on a wall, can be counted by one and not
        the other (``boundary_band``).
        """
        d = self.count_difference
        return bool(np.all((d >= 0) & (d <= self.boundary_band)))

    def to_dict(self) -> dict[str, Any]:
        """The numbers (no per-frame arrays, no maps), JSON-ready."""
        peak = {
            "classic": float(np.max(self.density_classic)),
            "voronoi": None if self.density_voronoi is None else float(np.max(self.density_voronoi)),
            "toolkit_kde": float(np.max(self.density_toolkit)),
        }
        return {
            "run_dir": self.run_dir,
            "scenario": self.scenario,
            "backend": self.backend,
            "seed": self.seed,
            "n_humans": self.n_humans,
            "frames": int(self.times.size),
            "frame_rate": self.frame_rate,
            "time_final": float(self.times[-1]),
            "target_center": list(self.target_center),
            "target_radius": self.target_radius,
            "measurement_area": self.measurement_area,
            "fraction_final_pedpy": float(self.fraction_pedpy[-1]),
            "fraction_final_toolkit": float(self.fraction_toolkit[-1]),
            "max_fraction_difference": self.max_fraction_difference,
            "max_count_difference": int(np.max(np.abs(self.count_difference))),
            "max_boundary_band": int(np.max(self.boundary_band)),
            "differences_explained": self.differences_explained,
            "window": list(self.window),
            "window_frames": int(self.window_frames.size),
            "grid_size": self.grid_size,
            "density_peak": peak,
            "density_mass": {
                "classic": float(np.sum(self.density_classic) * self.grid_size**2),
                "voronoi": None
                if self.density_voronoi is None
                else float(np.sum(self.density_voronoi) * self.grid_size**2),
                "toolkit_kde": float(np.sum(self.density_toolkit) * self.grid_size**2),
            },
            "voronoi_frames": self.voronoi_frames,
            "voronoi_error": self.voronoi_error,
            "trajectory_file": self.trajectory_file,
            "speed_and_flow": {k: v for k, v in self.speed_and_flow.items() if k not in ("mean_speed", "n_t")},
            "seconds": self.seconds,
            "figures": self.figures,
        }


def _boundary_band(dataset: Any, m: int, segments: int, room: Any) -> np.ndarray:
    """Per frame: humans in the target disk that the inscribed polygon ∩ room may miss."""
    import shapely

    cx, cy = float(dataset.attrs["target_center_x"]), float(dataset.attrs["target_center_y"])
    r = float(dataset.attrs["target_radius"])
    x = np.asarray(dataset["human_x"].values[:m], dtype=float)
    y = np.asarray(dataset["human_y"].values[:m], dtype=float)
    d = np.hypot(x - cx, y - cy)
    inner = r * math.cos(math.pi / segments) * (1 - 1e-12)
    in_disk = d <= r
    on_wall = np.zeros_like(in_disk)
    ok = np.isfinite(x) & np.isfinite(y)
    on_wall[ok] = shapely.distance(room.exterior, shapely.points(x[ok], y[ok])) <= 1e-9 * max(r, 1.0)
    return np.count_nonzero(in_disk & ((d > inner) | on_wall), axis=1)


def pedestrian_metrics(
    run_dir: str | Path,
    out_dir: str | Path | None = None,
    *,
    window_fraction: float = 0.2,
    voronoi_frames: int = 12,
    segments: int = 1024,
    figures: bool = True,
) -> PedestrianMetrics:
    """Measure a run with PedPy: ``N(t)`` in the target region, density maps, speed and flow.

    Speed and flow (:mod:`analysis.pedestrians.flow`): PedPy's individual speeds and their
    mean per frame, and the flow across the target region's entry line.

    Parameters
    ----------
    run_dir : str or Path
        A directory written by ``meanfield run`` (``timeseries.nc``).
    out_dir : str or Path, optional
        Where to write ``trajectories.txt`` and the figures (default ``run_dir``).
    window_fraction : float
        The density maps average the frames of the last ``window_fraction`` of the
        recorded time span, in ``(0, 1]``.
    voronoi_frames : int
        At most this many frames of the window for the Voronoi map (0: skip it).
    segments : int
        Vertices of the polygonised target disk.
    figures : bool
        Also draw ``n_in_target.png`` and ``density_map.png`` (:func:`plot_pedestrian_figures`).

    Returns
    -------
    PedestrianMetrics
    """
    if not (isinstance(window_fraction, int | float) and 0 < window_fraction <= 1):
        raise ParameterError("window_fraction", window_fraction, "a number in (0, 1]")
    if int(voronoi_frames) < 0:
        raise ParameterError("voronoi_frames", voronoi_frames, "an integer >= 0")
    run_dir = Path(run_dir)
    out = Path(out_dir) if out_dir is not None else run_dir
    out.mkdir(parents=True, exist_ok=True)
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    ds = load_run(run_dir)
    n_recorded, total = int(ds.sizes["human"]), int(ds.attrs.get("humans_total", ds.sizes["human"]))
    if n_recorded != total:
        raise ParameterError(
            "run_dir",
            f"{run_dir} recorded {n_recorded} of {total} humans",
            'a run that recorded every human (record_humans = "all" or >= crowd.n)',
        )
    sc = _scenario(ds)
    traj_path = out / "trajectories.txt"
    traj = load_pedpy_trajectories(ds, traj_path)
    seconds["write_and_load"] = time.perf_counter() - t0
    m = int(traj.data["frame"].max()) + 1
    times = np.asarray(ds["time"].values[:m], dtype=float)
    n = int(ds.sizes["human"])

    t0 = time.perf_counter()
    room = walkable_area(ds)
    target = target_measurement_area(ds, segments=segments)
    counts = count_in_target(traj, target)
    seconds["n_in_target"] = time.perf_counter() - t0
    band = _boundary_band(ds, m, segments, room.polygon)

    t_end, t_start = float(times[-1]), float(times[0])
    w0 = t_end - window_fraction * (t_end - t_start)
    win = np.flatnonzero(times >= w0 - 1e-9 * max(abs(t_end), 1.0))
    dx = float(ds["x"].values[1] - ds["x"].values[0])
    t0 = time.perf_counter()
    maps = density_maps(traj, room, win, dx, voronoi_frames=int(voronoi_frames))
    seconds["density_classic"] = maps["classic_seconds"]
    if "voronoi_seconds" in maps:
        seconds["density_voronoi"] = maps["voronoi_seconds"]
    kde = n * np.asarray(ds["density"].values[win], dtype=float).mean(axis=0)
    t0 = time.perf_counter()
    target_center = (float(ds.attrs["target_center_x"]), float(ds.attrs["target_center_y"]))
    flow = speed_and_flow(traj, room, target_center, float(ds.attrs["target_radius"]))
    seconds["speed_and_flow"] = time.perf_counter() - t0

    metrics = PedestrianMetrics(
        run_dir=str(run_dir),
        scenario=sc.name,
        backend=str(ds.attrs.get("backend", "point-mass")),
        seed=int(ds.attrs["seed"]) if "seed" in ds.attrs else None,
        n_humans=n,
        frame_rate=float(traj.frame_rate),
        times=times,
        target_center=target_center,
        target_radius=float(ds.attrs["target_radius"]),
        measurement_area=float(target.area),
        n_in_target=counts,
        fraction_pedpy=counts / n,
        fraction_toolkit=np.asarray(ds["fraction_in_target"].values[:m], dtype=float),
        boundary_band=band,
        window=(float(times[win[0]]), t_end),
        window_frames=win,
        grid_size=dx,
        x_edges=maps["x_edges"],
        y_edges=maps["y_edges"],
        room_bounds=tuple(float(b) for b in sc.domain.bounds),
        density_classic=maps["classic"],
        density_voronoi=maps["voronoi"],
        voronoi_frames=maps["voronoi_frames"],
        voronoi_error=maps["voronoi_error"],
        density_toolkit=kde,
        trajectory_file=str(traj_path),
        seconds=seconds,
        speed_and_flow=flow,
    )
    if figures:
        metrics.figures = {k: str(v) for k, v in plot_pedestrian_figures(metrics, out).items()}
    return metrics
