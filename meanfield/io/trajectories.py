"""The humans' recorded trajectories in the files pedestrian-dynamics tools read.

:func:`write_jupedsim_sqlite` writes JuPedSim's SQLite trajectory database (geometry
included), which PedPy loads directly and JuPedSim's viewer plays.

:func:`write_pedpy_trajectories` writes the ``human_x``/``human_y`` records of a run's
dataset in the whitespace-separated format of the Pedestrian Dynamics Data Archive, the
format :func:`pedpy.load_trajectory_from_txt` reads: comment lines starting with ``#``
that give the frame rate and the unit, then one line ``id frame x y`` per human and
recorded frame.  Only numpy is needed here: the dataset is an :class:`xarray.Dataset` (a run's
``timeseries.nc`` read back) or a run's frames as they are, a :class:`~meanfield.io.netcdf.NetCDFDataset`
(``result.timeseries``); PedPy itself is used by :mod:`analysis.pedestrians.metrics`.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.errors import ParameterError
from meanfield.io.atomic import atomic_write_text

__all__ = ["frame_spacing", "write_pedpy_trajectories", "write_jupedsim_sqlite", "JUPEDSIM_SQLITE_VERSION"]

# relative tolerance on the spacing of recorded frames (times are sums of float steps)
_SPACING_RTOL = 1e-6


def frame_spacing(times: Any) -> tuple[float, int]:
    """The time between recorded frames, and how many frames are evenly spaced by it.

    The frames ``times[:m]`` are evenly spaced; ``m`` is ``len(times)`` or, when the last
    frame follows the one before it after a shorter interval (a run whose final time is
    not a multiple of the recording period, or an interrupted run), ``len(times) - 1``.

    Parameters
    ----------
    times : array_like, shape (T,)
        Recorded times, ``T >= 2``, strictly increasing.

    Returns
    -------
    spacing : float
        The common time between the first ``m`` frames (their mean spacing).
    m : int
        Number of leading frames that keep it.

    Raises
    ------
    ParameterError
        ``"dataset"`` if there are fewer than two frames, if the times are not finite
        and strictly increasing, or if the spacing is uneven anywhere but at a shorter
        last interval.
    """
    t = np.asarray(times, dtype=float).ravel()
    if t.size < 2:
        raise ParameterError("dataset", f"{t.size} recorded frame(s)", "at least two recorded frames")
    gaps = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(gaps <= 0):
        raise ParameterError("dataset", "time coordinate not strictly increasing", "finite, increasing frame times")
    regular = gaps[:-1] if gaps.size > 1 else gaps
    ref = float(np.median(regular))
    tol = _SPACING_RTOL * ref
    if np.any(np.abs(regular - ref) > tol):
        raise ParameterError(
            "dataset",
            f"frame spacings from {regular.min():.6g} to {regular.max():.6g}",
            "evenly spaced recorded frames (only the last interval may be shorter)",
        )
    m = t.size
    last = float(gaps[-1])
    if gaps.size > 1 and abs(last - ref) > tol:
        if last > ref:
            raise ParameterError(
                "dataset",
                f"last frame spacing {last:.6g} > {ref:.6g}",
                "evenly spaced recorded frames (only the last interval may be shorter)",
            )
        m -= 1
    spacing = float((t[m - 1] - t[0]) / (m - 1))
    return spacing, m


def write_pedpy_trajectories(dataset: Any, path: str | Path) -> Path:
    """Write the humans' trajectories of a run in PedPy's plain-text format, atomically.

    Each recorded frame ``k`` (time ``time[0] + k · Δt``) becomes one line
    ``id frame x y`` per human, with ``id`` the human's index (the ``human`` coordinate
    when it holds integers) and ``frame = k``.  The header gives the frame rate
    ``1 / Δt``, where ``Δt`` is the time between recorded frames, and the unit
    ``m`` for an SI scenario (``paper-unity``, plans); a dimensionless scenario (``paper``:
    room widths) says so in the header instead of claiming metres (PedPy reads the numbers
    alike: the unit square of ``paper`` as a 1 m × 1 m room).
    Positions that are not finite (a human absent from a frame) are left out.

    The file is written to a temporary file in the destination's directory and moved
    over ``path`` (:func:`meanfield.io.atomic.atomic_write_text`): it is complete or absent.

    Parameters
    ----------
    dataset : xarray.Dataset or NetCDFDataset
        A run's ``timeseries.nc`` (or ``result.timeseries``): the variables ``human_x`` and ``human_y`` with dims
        ``(time, human)`` and the coordinate ``time``.
    path : str or Path
        Destination file (its directory is created).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ParameterError
        ``"dataset"`` if it lacks ``human_x``/``human_y`` with dims ``(time, human)``,
        has no recorded frame (or only one: the frame rate is then undefined), has
        frame times that are not strictly increasing, or has unevenly spaced frames.
        One exception is tolerated: **a last frame recorded after a shorter interval
        than the others** (the run ended between two recording instants) **is dropped**,
        since a trajectory file has one frame rate.

    Examples
    --------
    >>> import xarray as xr
    >>> ds = xr.open_dataset("runs/paper/timeseries.nc", engine="h5netcdf")
    >>> write_pedpy_trajectories(ds, "runs/paper/trajectories.txt")
    """
    for name in ("human_x", "human_y"):
        if name not in getattr(dataset, "data_vars", {}):
            raise ParameterError("dataset", f"no variable {name!r}", "a run dataset with human_x and human_y")
        if tuple(dataset[name].dims) != ("time", "human"):
            raise ParameterError("dataset", f"{name} dims {tuple(dataset[name].dims)}", "dims ('time', 'human')")
    if dataset.sizes.get("time", 0) == 0:
        raise ParameterError("dataset", "no recorded frame", "at least two recorded frames")
    times = np.asarray(dataset["time"].values, dtype=float)
    spacing, m = frame_spacing(times)
    frame_rate = float(f"{1.0 / spacing:.12g}")  # 1/0.1 is 10.000000000000002; PedPy parses the header
    x = np.asarray(dataset["human_x"].values, dtype=float)[:m]
    y = np.asarray(dataset["human_y"].values, dtype=float)[:m]
    n = x.shape[1]
    ids = np.arange(n, dtype=np.int64)
    if "human" in dataset.coords and np.issubdtype(dataset["human"].dtype, np.integer):
        ids = np.asarray(dataset["human"].values, dtype=np.int64)
    # rows ordered by human, then frame (the order of PedPy's own examples)
    frame = np.tile(np.arange(m, dtype=np.int64), n)
    pid = np.repeat(ids, m)
    xs = x.T.ravel()
    ys = y.T.ravel()
    keep = np.isfinite(xs) & np.isfinite(ys)
    si = dataset.attrs.get("units_system", "SI") == "SI"
    header = (
        "# trajectories of the humans of a meanfield run (meanfield.io.trajectories)\n"
        f"# framerate: {frame_rate!r}\n"
        f"# frame k is recorded at time {float(times[0])!r} + k / (frame rate); {m} frames, {n} humans\n"
        + (
            "# id frame x/m y/m\n"
            if si
            else "# lengths and times in the scenario's dimensionless units (room widths), not metres and seconds\n"
            "# id frame x y\n"
        )
    )
    buf = io.StringIO()
    buf.write(header)
    if keep.any():
        table = np.empty(int(keep.sum()), dtype=[("id", np.int64), ("frame", np.int64), ("x", float), ("y", float)])
        table["id"], table["frame"], table["x"], table["y"] = pid[keep], frame[keep], xs[keep], ys[keep]
        np.savetxt(buf, table, fmt=["%d", "%d", "%.17g", "%.17g"])
    return atomic_write_text(Path(path), buf.getvalue())


JUPEDSIM_SQLITE_VERSION = 2
"""The version of JuPedSim's trajectory database this module writes (JuPedSim 1.x)."""


def _human_frames(dataset: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """``(ids, x, y, times, spacing)`` of the evenly spaced recorded frames (see :func:`frame_spacing`)."""
    for name in ("human_x", "human_y"):
        if name not in getattr(dataset, "data_vars", {}):
            raise ParameterError("dataset", f"no variable {name!r}", "a run dataset with human_x and human_y")
    times = np.asarray(dataset["time"].values, dtype=float)
    spacing, m = frame_spacing(times)
    x = np.asarray(dataset["human_x"].values, dtype=float)[:m]
    y = np.asarray(dataset["human_y"].values, dtype=float)[:m]
    ids = np.arange(x.shape[1], dtype=np.int64)
    if "human" in dataset.coords and np.issubdtype(dataset["human"].dtype, np.integer):
        ids = np.asarray(dataset["human"].values, dtype=np.int64)
    return ids, x, y, times[:m], spacing


def write_jupedsim_sqlite(dataset: Any, walkable_area: Any, path: str | Path) -> Path:
    """Write the humans' trajectories in JuPedSim's SQLite trajectory format (version 2), atomically.

    The tables JuPedSim's ``SqliteTrajectoryWriter`` writes: ``trajectory_data`` (``frame``,
    ``id``, ``pos_x``, ``pos_y``, ``ori_x``, ``ori_y``; the orientation is the direction of
    the step to the next frame, kept through stops), ``metadata`` (``version``, ``fps``, the
    bounds), ``geometry`` (the walkable area as WKT) and ``frame_data`` (each frame's
    geometry).  PedPy reads it with :func:`pedpy.load_trajectory_from_jupedsim_sqlite` and
    :func:`pedpy.load_walkable_area_from_jupedsim_sqlite`; JuPedSim's viewer plays it.
    Coordinates are in the scenario's units (metres for an SI scenario).

    Parameters
    ----------
    dataset : xarray.Dataset or NetCDFDataset
        A run's ``timeseries.nc`` or ``result.timeseries`` (``human_x``, ``human_y`` on ``(time, human)``).
    walkable_area : shapely geometry
        Ω (e.g. ``scenario.domain.to_shapely()``).
    path : str or Path
    """
    import sqlite3

    import shapely

    from meanfield.io.atomic import atomic_write_with

    ids, x, y, _, spacing = _human_frames(dataset)
    m, n = x.shape
    dx = np.diff(x, axis=0, append=x[-1:])
    dy = np.diff(y, axis=0, append=y[-1:])
    norm = np.hypot(dx, dy)
    moving = norm > 0
    ox = np.where(moving, dx / np.where(moving, norm, 1.0), np.nan)
    oy = np.where(moving, dy / np.where(moving, norm, 1.0), np.nan)
    for k in range(m):  # a stop keeps the last heading; (1, 0) before the first move
        prev_x = ox[k - 1] if k else np.ones(n)
        prev_y = oy[k - 1] if k else np.zeros(n)
        ox[k] = np.where(np.isnan(ox[k]), prev_x, ox[k])
        oy[k] = np.where(np.isnan(oy[k]), prev_y, oy[k])
    frame = np.repeat(np.arange(m, dtype=np.int64), n)
    pid = np.tile(ids, m)
    keep = np.isfinite(x.ravel()) & np.isfinite(y.ravel())
    rows = zip(
        frame[keep].tolist(),
        pid[keep].tolist(),
        x.ravel()[keep].tolist(),
        y.ravel()[keep].tolist(),
        ox.ravel()[keep].tolist(),
        oy.ravel()[keep].tolist(),
        strict=True,
    )
    wkt = shapely.to_wkt(walkable_area, rounding_precision=-1)
    geo_hash = int.from_bytes(hashlib.sha256(wkt.encode()).digest()[:7], "big")
    xmin, ymin, xmax, ymax = walkable_area.bounds

    def write(tmp: Path) -> None:
        tmp.unlink(missing_ok=True)
        con = sqlite3.connect(tmp)
        try:
            cur = con.cursor()
            cur.execute(
                "CREATE TABLE trajectory_data (frame INTEGER NOT NULL, id INTEGER NOT NULL, "
                "pos_x REAL NOT NULL, pos_y REAL NOT NULL, ori_x REAL NOT NULL, ori_y REAL NOT NULL)"
            )
            cur.execute("CREATE TABLE metadata(key TEXT NOT NULL UNIQUE PRIMARY KEY, value TEXT NOT NULL)")
            meta = {
                "version": JUPEDSIM_SQLITE_VERSION,
                "fps": 1.0 / spacing,
                "xmin": xmin,
                "xmax": xmax,
                "ymin": ymin,
                "ymax": ymax,
                "units": dataset.attrs.get("units_system", "SI"),
                "run_id": dataset.attrs.get("run_id", ""),
            }
            cur.executemany("INSERT INTO metadata VALUES(?, ?)", [(k, str(v)) for k, v in meta.items()])
            cur.execute("CREATE TABLE geometry(hash INTEGER NOT NULL, wkt TEXT NOT NULL)")
            cur.execute("CREATE UNIQUE INDEX geometry_hash on geometry(hash)")
            cur.execute("INSERT INTO geometry VALUES(?, ?)", (geo_hash, wkt))
            cur.execute("CREATE TABLE frame_data(frame INTEGER NOT NULL, geometry_hash INTEGER NOT NULL)")
            cur.executemany("INSERT INTO frame_data VALUES(?, ?)", [(k, geo_hash) for k in range(m)])
            cur.executemany("INSERT INTO trajectory_data VALUES(?, ?, ?, ?, ?, ?)", rows)
            cur.execute("CREATE INDEX frame_id_idx ON trajectory_data(frame, id)")
            con.commit()
        finally:
            con.close()

    return atomic_write_with(Path(path), write)
