"""The robot-count study the paper leaves open: success against robot count n and kernel range η.

The paper sizes the team by coverage (its discussion, :func:`analysis.robot_count.coverage_estimate`):
a robot's sign is felt, at level ``ε`` or more, within ``r_ε = √(η ln(c/ε))`` of it, and
those disks should cover Ω.  This module measures what the closed loop actually needs:
the scenario is run for every robot count × kernel range × seed on Dask
(:func:`meanfield.workflows.sweep.run_sweep`, local or remote, resumable) and the outcome is reduced
to medians over seeds of

* the fraction of humans in the target region at ``t_final``, and
* the time at which 90 % of them first are in it, a run that never got there counting
  as later than any that did (the median is ``inf`` when half the seeds never did),

with the coverage estimate ``n_cov(η)`` for a few levels ``ε`` beside them, so the two can
be compared on one figure (:func:`analysis.figures.plot_robot_count_sweep`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.robot_count import coverage_estimate
from meanfield.errors import ParameterError
from meanfield.scenarios.scenario import Scenario

__all__ = ["RobotCountSweep", "run_robot_count_sweep", "summarize_robot_count_sweep", "COUNT_KEY", "ETA_KEY"]

COUNT_KEY = "robots.n"
ETA_KEY = "kernel.eta"


@dataclass
class RobotCountSweep:
    """Medians over seeds of a robot count × η sweep, and the coverage estimates.

    Attributes
    ----------
    counts, etas : list
        The swept robot counts and kernel ranges (sweep order).
    seeds : list of int
    fraction : ndarray, shape (len(counts), len(etas))
        Median final fraction in the target region.
    time_to_90 : ndarray, same shape
        Median time to 90 % in the target region (``inf``: half the seeds or more never).
    reached_90 : ndarray, same shape
        Fraction of seeds that reached 90 %.
    failed : ndarray of int, same shape
        Runs that diverged or errored (excluded from the medians; a cell with no run left is NaN).
    threshold : float
        Success level of the median fraction.
    minimum : dict
        ``{η: smallest n whose median fraction >= threshold}`` (None: no count did).
    coverage : dict
        ``{ε/c: [n_cov(η) for η in etas]}``.
    t_final : float
        The runs' horizon.
    c : float
        The kernel peak (ε levels are fractions of it).
    """

    counts: list[int]
    etas: list[float]
    seeds: list[int]
    fraction: np.ndarray
    time_to_90: np.ndarray
    reached_90: np.ndarray
    failed: np.ndarray
    threshold: float
    minimum: dict[float, int | None]
    coverage: dict[float, list[int]]
    t_final: float
    c: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``inf`` as the string "never")."""

        def clean(a: np.ndarray) -> list:
            return [[("never" if math.isinf(v) else (None if math.isnan(v) else float(v))) for v in row] for row in a]

        return {
            "counts": self.counts,
            "etas": self.etas,
            "seeds": self.seeds,
            "threshold": self.threshold,
            "t_final": self.t_final,
            "kernel_c": self.c,
            "median_fraction_in_target": clean(self.fraction),
            "median_time_to_90": clean(self.time_to_90),
            "seeds_reaching_90": clean(self.reached_90),
            "failed_runs": self.failed.tolist(),
            "minimum_count": {str(k): v for k, v in self.minimum.items()},
            "coverage_estimate": {str(k): v for k, v in self.coverage.items()},
        }


def run_robot_count_sweep(
    scenario: Scenario | str,
    counts: Sequence[int],
    etas: Sequence[float],
    seeds: int | Sequence[int],
    out_dir: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
):
    """Run the closed loop for every robot count × η × seed on Dask; the sweep's Dataset.

    A thin call of :func:`meanfield.workflows.sweep.run_sweep` with ``{"robots.n": counts,
    "kernel.eta": etas}``: same output layout (``OUT/runs/*.json``, ``OUT/sweep.nc``), same
    resuming, same refusal of bad input before any run.
    """
    from meanfield.workflows.sweep import run_sweep

    counts = [int(n) for n in counts]
    if not counts or min(counts) < 1:
        raise ParameterError("counts", counts, "robot counts, each >= 1")
    etas = [float(e) for e in etas]
    if not etas or min(etas) <= 0:
        raise ParameterError("etas", etas, "kernel ranges, each > 0")
    return run_sweep(
        scenario, {COUNT_KEY: counts, ETA_KEY: etas}, seeds, out_dir,
        scheduler=scheduler, workers=workers, progress=progress,
    )


def summarize_robot_count_sweep(
    ds: Any, threshold: float = 0.9, eps_fractions: Sequence[float] = (0.5, 0.2, 0.1)
) -> RobotCountSweep:
    """Medians over seeds, the smallest successful count per η, and the coverage estimates.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep over ``robots.n`` and ``kernel.eta`` (any order) and ``seed``, as written by
        :func:`run_robot_count_sweep` / ``meanfield sweep`` (``OUT/sweep.nc``).
    threshold : float
        Success level of the median final fraction in the target region.
    eps_fractions : sequence of float
        Coverage levels ``ε`` as fractions of the kernel peak ``c`` (each in (0, 1)).
    """
    for key in (COUNT_KEY, ETA_KEY, "seed"):
        if key not in ds.dims:
            raise ParameterError("ds", sorted(ds.dims), f"a sweep with dimensions {COUNT_KEY}, {ETA_KEY} and seed")
    if not 0 < threshold <= 1:
        raise ParameterError("threshold", threshold, "a fraction in (0, 1]")
    if any(not 0 < f < 1 for f in eps_fractions):
        raise ParameterError("eps_fractions", list(eps_fractions), "fractions of c, each in (0, 1)")
    ds = ds.transpose(COUNT_KEY, ETA_KEY, "seed")
    scenario = Scenario.from_toml(ds.attrs["scenario"])
    ok = ds["status"].values == "completed"
    frac = np.where(ok, ds["fraction_in_target"].values, np.nan)
    t90 = ds["time_to_90"].values
    t90 = np.where(ok, np.where(np.isnan(t90), np.inf, t90), np.nan)  # never reached: later than any
    with warnings.catch_warnings():  # a cell whose runs all failed is NaN, silently
        warnings.simplefilter("ignore", RuntimeWarning)
        med_frac = np.nanmedian(frac, axis=-1)
        med_t90 = np.nanmedian(t90, axis=-1)  # inf counts as a value: the median is inf if half never did
        reached = np.nanmean(np.where(ok, np.isfinite(t90), np.nan), axis=-1)
    counts = [int(n) for n in ds[COUNT_KEY].values]
    etas = [float(e) for e in ds[ETA_KEY].values]
    order = np.argsort(counts)
    minimum = {}
    for j, eta in enumerate(etas):
        good = [counts[i] for i in order if med_frac[i, j] >= threshold]
        minimum[eta] = good[0] if good else None
    c = scenario.kernel.c
    coverage = {
        f: [coverage_estimate(scenario.domain, c, eta, f * c).n for eta in etas] for f in eps_fractions
    }
    seeds = [int(s) for s in ds["seed"].values]
    return RobotCountSweep(
        counts=counts,
        etas=etas,
        seeds=seeds,
        fraction=med_frac,
        time_to_90=med_t90,
        reached_90=reached,
        failed=(~ok & (ds["status"].values != "not run")).sum(axis=-1).astype(int),
        threshold=float(threshold),
        minimum=minimum,
        coverage=coverage,
        t_final=scenario.t_final,
        c=c,
    )
