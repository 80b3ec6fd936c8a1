"""Mean-field equivalence: the agents' density approaches the Fokker–Planck solution as N grows.

The paper (Section III, "Problem formulation") replaces the ``N`` humans of the SDE
(eq. (1)) by their density, "considering the mean-field limit as N → ∞", which
satisfies the Fokker–Planck equation (eq. (4)).  Every guarantee of Section IV is proved
on the PDE, every simulation of Section V runs agents: the two must agree for large ``N``.

:func:`check_mean_field` runs :func:`meanfield.workflows.mean_field_limit.compare_agents_pde`: the scenario's
closed loop is run once and its robot trajectory is replayed to crowds of ``N`` agents
and to the PDE, from the same initial density.  The distance that decides is
``error_to_expected`` = ‖ρ̂_N − E[ρ̂ under ρ_PDE]‖ (the kernel density estimate against the
estimator's own mean under the PDE law), because the raw distance ‖ρ̂_N − ρ_PDE‖ carries
the estimator's smoothing bias, a floor independent of ``N`` (see ``docs/fokker_planck.md``,
"Agents beside the PDE").  Independent agents give a Monte-Carlo error ∝ ``N^(-1/2)``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.scenarios.scenario import Scenario
from meanfield.signs.interaction import GaussianPotential
from meanfield.workflows.mean_field_limit import compare_agents_pde, fit_slope
from verification.result import CheckResult

__all__ = ["KEY", "CLAIM", "SLOPE_RANGE", "check_mean_field", "mean_field_verdict"]

KEY = "mean_field"
CLAIM = (
    "Section III: in the mean-field limit N → ∞ the density of the N humans of the SDE (1), "
    "ρ ≈ (1/N) Σ_j δ_{X_j}, satisfies the Fokker–Planck equation (4)."
)
SLOPE_RANGE: tuple[float, float] = (-0.75, -0.25)
"""Admissible log-log slope of the error against ``N`` (the Monte-Carlo rate is −1/2)."""

QUICK_SIZES: tuple[int, ...] = (100, 1_000, 10_000)
FULL_SIZES: tuple[int, ...] = (100, 1_000, 10_000, 100_000)
QUICK_T_FINAL = 10.0
FULL_CELLS: tuple[int, int] = (64, 64)

CRITERION = (
    "holds when the time-mean of ‖KDE_N − E[KDE under ρ_PDE]‖ decreases strictly with N and the "
    f"least-squares slope of log(error) against log(N) over all N tried lies in [{SLOPE_RANGE[0]}, "
    f"{SLOPE_RANGE[1]}] (Monte-Carlo rate −1/2); fails otherwise"
)


def mean_field_verdict(
    n: list[int] | tuple[int, ...] | np.ndarray,
    errors: list[float] | tuple[float, ...] | np.ndarray,
    slope_range: tuple[float, float] = SLOPE_RANGE,
) -> tuple[str, float]:
    """The decision rule of :func:`check_mean_field`, on the time-mean errors per crowd size.

    Parameters
    ----------
    n : sequence of int
        Crowd sizes ``N``, increasing.
    errors : sequence of float
        Time-mean ``error_to_expected`` for each ``N``.
    slope_range : (float, float)
        Admissible slope of ``log error`` against ``log N`` (inclusive).

    Returns
    -------
    verdict : {"holds", "fails", "inconclusive"}
        ``"holds"`` when the errors decrease strictly with ``N`` and the fitted slope lies
        in ``slope_range``; ``"fails"`` otherwise; ``"inconclusive"`` when fewer than two
        sizes, sizes not increasing, or an error that is not finite and positive (no slope
        can be fitted).
    slope : float
        The fitted slope (:func:`meanfield.workflows.mean_field_limit.fit_slope`; NaN when inconclusive).
    """
    ns = np.asarray(n, float)
    err = np.asarray(errors, float)
    if (
        ns.ndim != 1
        or ns.shape != err.shape
        or len(ns) < 2
        or np.any(np.diff(ns) <= 0)
        or not np.all(np.isfinite(err))
        or np.any(err <= 0)
    ):
        return "inconclusive", math.nan
    slope = fit_slope(ns, err)
    decreasing = bool(np.all(np.diff(err) < 0))
    lo, hi = slope_range
    ok = decreasing and lo <= slope <= hi
    return ("holds" if ok else "fails"), slope


def _interaction(scenario: Scenario) -> GaussianPotential | None:
    w = scenario.interaction
    if w.kind == "gaussian":
        return GaussianPotential(w.strength, w.length)
    return None


def _plot(ds: Any, sizes: list[int], mean_exp: np.ndarray, mean_pde: np.ndarray, slope: float, path: Path) -> None:
    from matplotlib.figure import Figure

    from analysis.figures import save_figure

    fig = Figure(figsize=(10.0, 4.0))
    ax, bx = fig.subplots(1, 2)
    ns = np.asarray(sizes, float)
    ax.loglog(ns, mean_exp, "o-", color="C0", label=f"‖KDE − E[KDE | ρ_PDE]‖ (slope {slope:.3f})")
    ax.loglog(ns, mean_pde, "s--", color="0.5", label="‖KDE − ρ_PDE‖ (incl. KDE bias)")
    ref = mean_exp[0] * (ns / ns[0]) ** -0.5
    ax.loglog(ns, ref, ":", color="C3", label="N^(−1/2) reference")
    ax.set_xlabel("agents N")
    ax.set_ylabel("time-mean L² distance")
    ax.set_title("Agents (SDE (1)) vs Fokker–Planck (4)", fontsize=10)
    ax.legend(fontsize=7)
    t = ds["time"].values
    for k, n in enumerate(sizes):
        bx.semilogy(t, ds["error_to_expected"].values[k], color=f"C{k}", label=f"N = {n}")
    bx.set_xlabel("time")
    bx.set_ylabel("‖KDE − E[KDE | ρ_PDE]‖")
    bx.set_title("Distance over time", fontsize=10)
    bx.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def check_mean_field(
    scenario: Scenario,
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    workers: int | None = None,
) -> CheckResult:
    """Check the mean-field equivalence of the SDE crowd (eq. (1)) and the PDE (eq. (4)).

    Paper, Section III: "To address the challenge of the large human population, we
    consider the mean-field limit as N → ∞", where the crowd density satisfies (4).

    The robot trajectory of the scenario's closed loop is replayed to crowds of ``N``
    agents and to the Fokker–Planck solver (:func:`meanfield.workflows.mean_field_limit.compare_agents_pde`,
    with the scenario's interaction ``W`` if it has one).  Decision rule
    (:func:`mean_field_verdict`): the time-mean of ``error_to_expected`` must decrease
    strictly with ``N``, with a fitted log-log slope in ``[-0.75, -0.25]`` (theory: −1/2).

    Parameters
    ----------
    scenario : Scenario
        Domain, σ, kernel, interaction, disturbance, initial density, ``dt``, robots.
    out_dir : Path
        The report's directory; the figure goes to ``out_dir / "figures"``.
    quick : bool
        ``N ∈ (100, 1000, 10000)``, horizon ``min(10, t_final)``, the scenario's grid.
        Otherwise ``N`` up to 100 000, the scenario's ``t_final``, a 64² grid.
    progress : bool
        Show progress bars.
    workers : int, optional
        Unused (the comparison runs in this process); accepted for a uniform signature.

    Returns
    -------
    CheckResult
        Key ``"mean_field"``; ``measured`` holds the errors per ``N`` (time means), the
        slope, and the raw distance to the PDE for information.
    """
    start = time.perf_counter()
    out_dir = Path(out_dir)
    sizes = QUICK_SIZES if quick else FULL_SIZES
    horizon = min(QUICK_T_FINAL, scenario.t_final) if quick else scenario.t_final
    cells = tuple(scenario.grid.cells) if quick else FULL_CELLS
    record_interval = min(1.0, horizon / 10)
    interaction = _interaction(scenario)
    settings = {
        "n_agents": list(sizes),
        "t_final": horizon,
        "cells": list(cells),
        "record_interval": record_interval,
        "seed": scenario.seed,
        "interaction": None
        if interaction is None
        else {"strength": interaction.strength, "length": interaction.length},
    }

    def inconclusive(reason: str, **extra: Any) -> CheckResult:
        measured = {"settings": settings, **extra}
        return CheckResult.inconclusive(
            KEY, CLAIM, reason, criterion=CRITERION, measured=measured, seconds=time.perf_counter() - start
        )

    try:
        cmp = compare_agents_pde(
            scenario,
            sizes,
            interaction=interaction,
            t_final=horizon,
            cells=cells,
            record_interval=record_interval,
            progress=progress,
            label="scenario W" if interaction is not None else "W = 0",
        )
    except SimulationDiverged as exc:
        return inconclusive(f"the scenario's closed loop diverged while recording the robot trajectory: {exc}")
    except ParameterError as exc:
        return inconclusive(f"the scenario cannot be used for the agents-vs-PDE comparison: {exc}")
    summary = cmp.summary
    if summary["status"] != "completed":
        return inconclusive(f"the comparison did not complete ({summary['status']}): {summary['message']}")

    mean_exp = cmp.mean_errors("error_to_expected")
    mean_pde = cmp.mean_errors("error_to_pde")
    verdict, slope = mean_field_verdict(sizes, mean_exp)
    measured: dict[str, Any] = {
        "settings": settings,
        "n_agents": list(sizes),
        "error_to_expected_mean": [float(v) for v in mean_exp],
        "error_to_expected_final": [float(v) for v in cmp.dataset["error_to_expected"].values[:, -1]],
        "slope": slope,
        "slope_1e2_1e4": summary.get("error_to_expected_slope_1e2_1e4"),
        "decreasing": bool(np.all(np.diff(mean_exp) < 0)),
        "error_to_pde_mean": [float(v) for v in mean_pde],
        "error_to_pde_slope": summary.get("error_to_pde_slope_all"),
        "pde_mass_drift": summary["pde_mass_drift"],
        "pde_min": summary["pde_min"],
        "measurements": int(cmp.dataset.sizes["time"]),
        "bandwidth": summary["bandwidth"],
        "pde_method": summary["pde_method"],
        "comparison_wall_seconds": summary["wall_seconds"],
    }
    if "error_to_expected_paper_sign_mean" in summary:
        measured["error_to_expected_paper_sign_mean"] = list(summary["error_to_expected_paper_sign_mean"].values())
    if verdict == "inconclusive":
        return inconclusive("the time-mean errors are not finite and positive: no slope can be fitted", **measured)

    fig_dir = out_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    rel = f"figures/{KEY}_error_vs_n.png"
    _plot(cmp.dataset, list(sizes), mean_exp, mean_pde, slope, out_dir / rel)

    cases = [
        {
            "n_agents": n,
            "error_to_expected_mean": float(e),
            "error_to_pde_mean": float(p),
            "verdict": "holds" if k == 0 or e < mean_exp[k - 1] else "fails",
            "note": "first size"
            if k == 0
            else ("below the previous N" if e < mean_exp[k - 1] else "not below the previous N"),
        }
        for k, (n, e, p) in enumerate(zip(sizes, mean_exp, mean_pde, strict=True))
    ]
    errs = ", ".join(f"N={n}: {e:.3g}" for n, e in zip(sizes, mean_exp, strict=True))
    summary_line = (
        f"slope {slope:.3f} (range [{SLOPE_RANGE[0]}, {SLOPE_RANGE[1]}]); time-mean ‖KDE − E[KDE]‖ {errs}; "
        f"{'strictly decreasing' if measured['decreasing'] else 'not strictly decreasing'}"
    )
    reason = "" if verdict == "holds" else (
        "the error does not decrease strictly with N" if not measured["decreasing"]
        else f"the fitted slope {slope:.3f} is outside [{SLOPE_RANGE[0]}, {SLOPE_RANGE[1]}]"
    )
    return CheckResult(
        KEY,
        CLAIM,
        verdict,  # type: ignore[arg-type]
        summary=summary_line,
        measured=measured,
        bound={"slope_range": list(SLOPE_RANGE), "theoretical_slope": -0.5, "strictly_decreasing": True},
        reason=reason,
        criterion=CRITERION,
        cases=cases,
        figures=[rel],
        seconds=time.perf_counter() - start,
    )
