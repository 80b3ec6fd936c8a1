"""What speed limits cost: closed-loop runs over ``u_max`` for β/γ strategies.

Two ways to respect a robot's speed limit: the paper's minimum-norm inputs clipped after
the fact (``"min-norm"``: the robot moves along the commanded direction at ``u_max``,
``dV₂/dt`` loses whatever the clipping removed, unaccounted), or the bounded program of
:mod:`analysis.bounded` (``"bounded"``: inputs chosen within the limits, the uncancelled
part of ``A`` reported as the shortfall, the ISS input of Theorem 2).
:func:`limits_study` runs both over a list of limits and seeds and keeps, per run, the
summary and the time series that show how often the limits bind.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.parallel import map_jobs
from meanfield.errors import ParameterError
from meanfield.scenarios.scenario import Scenario

__all__ = ["LimitRun", "LimitsStudy", "limits_study"]

SUMMARY_KEYS = (
    "status",
    "fraction_in_target",
    "l2_error_ratio",
    "time_to_90",
    "max_robot_speed",
    "saturated_fraction",
    "limits_binding_fraction",
    "shortfall_mean",
    "shortfall_max",
    "shortfall_applied_mean",
    "steps_per_second",
)


@dataclass
class LimitRun:
    """One closed-loop run of the study: its settings, summary and recorded series."""

    strategy: str
    u_max: float
    seed: int
    summary: dict[str, Any]
    time: np.ndarray
    rho_error: np.ndarray
    robots_at_limit: np.ndarray
    shortfall_applied: np.ndarray

    def to_dict(self, series: bool = False) -> dict[str, Any]:
        d = {"strategy": self.strategy, "u_max": self.u_max, "seed": self.seed, **self.summary}
        if series:
            d.update(
                time=self.time.tolist(),
                rho_error=self.rho_error.tolist(),
                robots_at_limit=self.robots_at_limit.tolist(),
                shortfall_applied=self.shortfall_applied.tolist(),
            )
        return d


@dataclass
class LimitsStudy:
    """All runs of :func:`limits_study`, with per-setting medians."""

    scenario_name: str
    robots: int
    runs: list[LimitRun]

    def settings(self) -> list[tuple[str, float]]:
        """The (strategy, u_max) pairs, in the order they were asked for."""
        return list(dict.fromkeys((r.strategy, r.u_max) for r in self.runs))

    def median(self, strategy: str, u_max: float, key: str) -> float:
        """Median of a summary entry over the seeds of one setting (NaN for missing values)."""
        v = [r.summary[key] for r in self.runs if r.strategy == strategy and r.u_max == u_max]
        v = [np.nan if x is None else float(x) for x in v]
        return float(np.nanmedian(v)) if v and not np.all(np.isnan(v)) else float("nan")

    def table(self) -> list[dict[str, Any]]:
        """One row per setting: medians over seeds."""
        keys = ("fraction_in_target", "l2_error_ratio", "limits_binding_fraction", "shortfall_applied_mean",
                "saturated_fraction", "max_robot_speed")
        return [
            {"strategy": s, "u_max": u, **{k: self.median(s, u, k) for k in keys}} for s, u in self.settings()
        ]

    def to_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario_name,
            "robots": self.robots,
            "table": self.table(),
            "runs": [r.to_dict() for r in self.runs],
        }


def _run_one(args: tuple[dict, str, float, int]) -> LimitRun:
    from meanfield.simulation.loop import ClosedLoop

    d, strategy, u_max, seed = args
    sc = Scenario.from_dict(d).with_values({"robots.u_max": u_max, "controller.beta_gamma": strategy, "seed": seed})
    res = ClosedLoop(sc).run(progress=False)
    ds = res.dataset
    return LimitRun(
        strategy,
        u_max,
        seed,
        {k: res.summary[k] for k in SUMMARY_KEYS},
        np.asarray(ds["time"].values, float),
        np.asarray(ds["rho_error_l2"].values, float),
        np.asarray(ds["robots_at_limit"].values, float),
        np.asarray(ds["shortfall_applied"].values, float),
    )


def limits_study(
    scenario: Scenario,
    u_max_values: Sequence[float],
    strategies: Sequence[str] = ("min-norm", "bounded"),
    seeds: Sequence[int] = (0,),
    workers: int | None = None,
    progress: bool = True,
) -> LimitsStudy:
    """Run ``scenario`` for every strategy, speed limit and seed.

    Parameters
    ----------
    scenario : Scenario
    u_max_values : sequence of float
        Speed limits ``u_max`` (each > 0).
    strategies : sequence of {"min-norm", "bounded"}
        β/γ strategies (min-norm is clipped by the robots' saturation).
    seeds : sequence of int
    workers : int, optional
        Worker processes (default: the number of cores; 1 runs in this process).
    progress : bool
        Show a progress bar.
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError("scenario", type(scenario).__name__, "a Scenario")
    u_max_values = [float(u) for u in u_max_values]
    if not u_max_values or not all(np.isfinite(u) and u > 0 for u in u_max_values):
        raise ParameterError("u_max_values", u_max_values, "speed limits, each a finite number > 0")
    for s in strategies:
        if s not in ("min-norm", "bounded"):
            raise ParameterError("strategies", s, "'min-norm' or 'bounded'")
    seeds = [int(s) for s in seeds]
    if not seeds or min(seeds) < 0:
        raise ParameterError("seeds", seeds, "at least one seed >= 0")
    d = scenario.to_dict()
    jobs = [(d, s, u, seed) for s in strategies for u in u_max_values for seed in seeds]
    runs = map_jobs(_run_one, jobs, workers, "speed limits", progress)
    return LimitsStudy(scenario.name, scenario.robots.n, runs)
