"""The outcome of a closed-loop run: its recorded frames, its summary, and how it is saved.

:class:`SimulationResult` holds data only; figures are drawn by :mod:`meanfield.plotting`,
which a caller hands to :meth:`SimulationResult.save` as ``artifacts`` (the command line
does), so that results never import the plotting code.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from meanfield.kernels import NavigationKernel
from meanfield.scenario import Scenario

__all__ = ["SimulationResult", "ArtifactWriter"]

ArtifactWriter = Callable[["SimulationResult", Path], dict[str, Path]]
"""Writes files derived from a result into a folder (e.g. figures) and returns their paths by name."""


@dataclass
class SimulationResult:
    """Outcome of a closed-loop run.

    Attributes
    ----------
    scenario : Scenario
    dataset : xarray.Dataset
        Recorded frames (robot states, humans, density estimates, V₁, V₂, errors, speeds).
    summary : dict
        ``fraction_in_target``, ``l2_error_initial``, ``l2_error_final``,
        ``w2_to_target_final``, ``time_to_90``, ``max_robot_speed``, ``speed_limit``,
        ``steps``, ``wall_seconds``, ``seed``, ``status``, the scenario, and more.
    kernel : NavigationKernel, optional
        The navigation kernel the run used (figures draw it).
    """

    scenario: Scenario
    dataset: Any
    summary: dict[str, Any]
    kernel: NavigationKernel | None = None

    def save(self, out_dir: str | Path, artifacts: Iterable[ArtifactWriter] = ()) -> dict[str, Path]:
        """Write ``timeseries.nc``, ``scenario.toml``, the ``artifacts`` and (last) ``summary.json``.

        Every file is written atomically, and ``summary.json`` only once everything else
        is in place, so a directory with a ``summary.json`` is complete.

        Parameters
        ----------
        out_dir : str or Path
        artifacts : iterable of callables
            ``writer(result, out_dir) -> {name: path}``, e.g. :func:`meanfield.plotting.run_figures`.
        """
        from meanfield.io import atomic_write_json, atomic_write_text, atomic_write_with

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths: dict[str, Path] = {}
        paths["timeseries"] = atomic_write_with(
            out / "timeseries.nc", lambda p: self.dataset.to_netcdf(p, engine="h5netcdf")
        )
        paths["scenario"] = atomic_write_text(out / "scenario.toml", self.scenario.to_toml())
        for writer in artifacts:
            paths.update(writer(self, out))
        paths["summary"] = atomic_write_json(out / "summary.json", self.summary)
        return paths
