"""The outcome of a closed-loop run: its recorded frames, its summary, and how it is saved.

:class:`SimulationResult` holds data only; figures are drawn by :mod:`meanfield.plotting.figures`,
which a caller hands to :meth:`SimulationResult.save` as ``artifacts`` (the command line
does), so that results never import the plotting code.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from meanfield.io.netcdf import NetCDFDataset
from meanfield.scenarios.scenario import Scenario
from meanfield.signs.kernels import NavigationKernel

__all__ = ["SimulationResult", "ArtifactWriter"]

ArtifactWriter = Callable[["SimulationResult", Path], dict[str, Path]]
"""Writes files derived from a result into a folder (e.g. figures) and returns their paths by name."""


@dataclass
class SimulationResult:
    """Outcome of a closed-loop run.

    Attributes
    ----------
    scenario : Scenario
    timeseries : NetCDFDataset
        Recorded frames (robot states, humans, density estimates, V₁, V₂, errors, speeds): the contents of
        ``timeseries.nc`` as plain numpy arrays and attributes (:mod:`meanfield.io.netcdf`), without xarray.
    summary : dict
        ``fraction_in_target``, ``l2_error_initial``, ``l2_error_final``,
        ``w2_to_target_final``, ``time_to_90``, ``max_robot_speed``, ``speed_limit``,
        ``steps``, ``wall_seconds``, ``seed``, ``status``, the scenario, and more.
    kernel : NavigationKernel, optional
        The navigation kernel the run used (figures draw it).
    """

    scenario: Scenario
    timeseries: NetCDFDataset
    summary: dict[str, Any]
    kernel: NavigationKernel | None = None

    @cached_property
    def dataset(self) -> Any:
        """The recorded frames as an :class:`xarray.Dataset`, built from :attr:`timeseries` on first use
        (importing xarray and pandas, which a run and its :meth:`save` never do).

        The dataset ``xr.open_dataset(folder / "timeseries.nc", engine="h5netcdf")`` reads back; its arrays
        are :attr:`timeseries`' own, its attributes copies (:meth:`~meanfield.io.netcdf.NetCDFDataset.to_xarray`).
        """
        return self.timeseries.to_xarray()

    FILE_NAMES = (
        "timeseries.nc", "scenario.toml", "summary.json", "trajectories.sqlite",
        "target_and_error.png", "snapshots.png", "evacuation.png", "animation.gif",
    )  # fmt: skip
    """Every name :meth:`save` may write into a run's folder (with the artifacts of ``meanfield run``), so that a
    folder can be checked before the run (:func:`meanfield.io.atomic.check_output_names`)."""

    def save(self, out_dir: str | Path, artifacts: Iterable[ArtifactWriter] = ()) -> dict[str, Path]:
        """Write ``timeseries.nc``, ``scenario.toml``, the ``artifacts`` and (last) ``summary.json``.

        ``timeseries.nc`` is :attr:`timeseries`, written with h5netcdf directly
        (:meth:`~meanfield.io.netcdf.NetCDFDataset.write_netcdf`: no xarray import; xarray reads the file as
        :attr:`dataset`).

        Every file is written atomically and carries the run's id (``run_id``: the NetCDF
        attribute, a comment in ``scenario.toml``, the figures' PNG metadata); an earlier
        run's ``summary.json`` in the folder is removed first, with the files it listed, and
        the new one, written last, lists every file with its SHA-256
        (:func:`meanfield.io.atomic.write_complete_folder`).  So a folder with a ``summary.json``
        holds one complete run and nothing else, which
        :func:`meanfield.io.atomic.check_complete_folder` checks.

        Parameters
        ----------
        out_dir : str or Path
        artifacts : iterable of callables
            ``writer(result, out_dir) -> {name: path}``, e.g. :func:`meanfield.plotting.figures.save_run_figures`.
        """
        from meanfield.io.atomic import atomic_write_text, atomic_write_with, write_complete_folder

        rid = self.summary.get("run_id", "")

        def write_files(out: Path) -> dict[str, Path]:
            paths: dict[str, Path] = {}
            paths["timeseries"] = atomic_write_with(out / "timeseries.nc", self.timeseries.write_netcdf)
            header = f"# meanfield run {rid}: the scenario of this run (re-runnable as is)\n" if rid else ""
            paths["scenario"] = atomic_write_text(out / "scenario.toml", header + self.scenario.to_toml())
            for writer in artifacts:
                paths.update(writer(self, out))
            return paths

        return write_complete_folder(out_dir, write_files, self.summary)
