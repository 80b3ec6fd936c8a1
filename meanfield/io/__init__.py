"""Files: atomic output and the run folder (:mod:`~meanfield.io.atomic`), a NetCDF dataset as plain data written
without xarray (:mod:`~meanfield.io.netcdf`), trajectories in the formats
pedestrian-dynamics tools read (:mod:`~meanfield.io.trajectories`), JuPedSim web-app exports read and written
back with a run (:mod:`~meanfield.io.webapp`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "JUPEDSIM_SQLITE_VERSION": "meanfield.io.trajectories",
    "NetCDFDataset": "meanfield.io.netcdf",
    "NetCDFVariable": "meanfield.io.netcdf",
    "atomic_write_json": "meanfield.io.atomic",
    "atomic_write_text": "meanfield.io.atomic",
    "atomic_write_with": "meanfield.io.atomic",
    "check_complete_folder": "meanfield.io.atomic",
    "check_output_dir": "meanfield.io.atomic",
    "check_output_file": "meanfield.io.atomic",
    "folder_lock": "meanfield.io.atomic",
    "frame_spacing": "meanfield.io.trajectories",
    "save_figure": "meanfield.io.atomic",
    "sha256_of": "meanfield.io.atomic",
    "subplots": "meanfield.io.atomic",
    "write_complete_folder": "meanfield.io.atomic",
    "write_jupedsim_sqlite": "meanfield.io.trajectories",
    "write_pedpy_trajectories": "meanfield.io.trajectories",
    "WebAppExport": "meanfield.io.webapp",
    "read_export": "meanfield.io.webapp",
    "write_export_with_trajectory": "meanfield.io.webapp",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
