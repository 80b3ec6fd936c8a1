"""The paper's "rough lower estimate" of the robot count, against closed-loop runs.

Paper, Section IV ("Discussion"): "A rough lower estimate for n is that when the robots
are regularly distributed in Ω, we have ∪_i M_ε(v_{r_i}) = Ω for a sufficiently large ε,
i.e., their range of influence can cover the whole workspace", with
``M_ε(v_{r_i}) = {x : ‖v_{r_i}(x)‖ > ε}``, a disk of radius ``r_ε = √(η ln(c/ε))``.

:func:`check_robot_count` computes that estimate (:func:`analysis.robot_count.coverage_estimate`,
the smallest regular square lattice of such disks covering Ω) at ε = c/10, c/4, c/2 and
holds it against the empirical minimum (:func:`analysis.robot_count.empirical_robot_count`:
the smallest robot count tried whose median fraction of humans in the target region,
over seeds, reaches 0.9).  A *lower* estimate holds when it does not exceed the empirical
minimum.  ε = c/2 decides: on the unit square with the paper's kernel it gives the
paper's 4 × 4 = 16 robots.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from analysis.robot_count import RobotCountStudy, coverage_estimate, empirical_robot_count
from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.scenarios.scenario import Scenario
from verification.result import CheckResult

__all__ = ["KEY", "CLAIM", "EPS_FRACTIONS", "DECIDING", "check_robot_count", "robot_count_verdict"]

KEY = "robot_count"
CLAIM = (
    "Section IV (Discussion): a rough lower estimate for the number of robots n is that, regularly "
    "distributed in Ω, their sets M_ε = {‖v_{r_i}‖ > ε} cover Ω for a sufficiently large ε."
)
EPS_FRACTIONS: dict[str, float] = {"c/10": 0.1, "c/4": 0.25, "c/2": 0.5}
"""The field levels ε tried, as fractions of the kernel's peak ``c``."""
DECIDING = "c/2"
"""The level that decides the overall verdict (the paper's 16 robots on the unit square)."""
THRESHOLD = 0.9

QUICK_COUNTS: tuple[int, ...] = (1, 2, 4, 6, 9, 16)
QUICK_SEEDS: tuple[int, ...] = (0, 1)
FULL_COUNTS: tuple[int, ...] = (1, 2, 4, 6, 9, 12, 16, 25)
FULL_SEEDS: tuple[int, ...] = (0, 1, 2, 3, 4)

CRITERION = (
    "the empirical minimum is the smallest robot count tried whose median (over seeds) fraction of humans "
    f"in the target region at t_final is ≥ {THRESHOLD}; at each ε the estimate holds when the coverage "
    "estimate n(ε) ≤ the empirical minimum; the overall verdict is the one at ε = c/2 (the level giving the "
    "paper's 16 robots on the unit square); inconclusive when no tried count succeeds"
)


def robot_count_verdict(
    coverage: Mapping[str, int], minimum: int | None, deciding: str = DECIDING
) -> tuple[str, dict[str, str]]:
    """The decision rule of :func:`check_robot_count`.

    Parameters
    ----------
    coverage : mapping of str to int
        Coverage estimate ``n(ε)`` per level label (``"c/10"``, ``"c/4"``, ``"c/2"``).
    minimum : int or None
        Empirical minimum robot count (None: no tried count succeeded).
    deciding : str
        The label whose verdict is the overall verdict.

    Returns
    -------
    verdict : {"holds", "fails", "inconclusive"}
        The verdict at ``deciding``.
    per_eps : dict
        ``{label: verdict}``: ``"holds"`` when ``n(ε) <= minimum``, else ``"fails"``;
        every level ``"inconclusive"`` when ``minimum`` is None.

    Raises
    ------
    KeyError
        If ``deciding`` is not a key of ``coverage``.
    """
    if minimum is None:
        per = {label: "inconclusive" for label in coverage}
    else:
        per = {label: ("holds" if int(n) <= int(minimum) else "fails") for label, n in coverage.items()}
    return per[deciding], per


def _bracket(counts: list[int], minimum: int | None) -> list[int] | None:
    """``[lo, hi]``: the true minimum (if success were monotone) lies in ``(lo, hi]``."""
    if minimum is None:
        return None
    below = [n for n in counts if n < minimum]
    return [max(below) if below else 0, minimum]


def check_robot_count(
    scenario: Scenario,
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    workers: int | None = None,
) -> CheckResult:
    """Hold the paper's coverage estimate of the robot count against closed-loop runs.

    Paper, Section IV ("Discussion"): "A rough lower estimate for n is that when the
    robots are regularly distributed in Ω, we have ∪_{i=1}^n M_ε(v_{r_i}) = Ω for a
    sufficiently large ε".  The estimate :func:`analysis.robot_count.coverage_estimate`
    at ε = c/10, c/4 and c/2 (``c``, ``η`` from ``scenario.kernel``) is a lower estimate
    when it does not exceed the empirical minimum from
    :func:`analysis.robot_count.empirical_robot_count` (median fraction in the target
    ≥ 0.9 over seeds, the scenario's robot layout rule).  ε = c/2 decides
    (:func:`robot_count_verdict`).

    Parameters
    ----------
    scenario : Scenario
        Its ``robots.n`` is replaced by each count tried; the layout must not be explicit.
    out_dir : Path
        The report's directory; the figure goes to ``out_dir / "figures"``.
    quick : bool
        Counts (1, 2, 4, 6, 9, 16), seeds (0, 1); otherwise counts
        (1, 2, 4, 6, 9, 12, 16, 25), seeds 0–4.  The scenario's ``t_final`` either way.
    progress : bool
        Show a progress bar.
    workers : int, optional
        Worker processes for the closed-loop runs (default: the cores).

    Returns
    -------
    CheckResult
        Key ``"robot_count"``; one case per ε.
    """
    start = time.perf_counter()
    out_dir = Path(out_dir)
    counts = QUICK_COUNTS if quick else FULL_COUNTS
    seeds = QUICK_SEEDS if quick else FULL_SEEDS
    c, eta = scenario.kernel.c, scenario.kernel.eta
    settings = {"counts": list(counts), "seeds": list(seeds), "threshold": THRESHOLD, "t_final": scenario.t_final,
                "t_final_shortened": False, "layout": scenario.robots.layout}

    def inconclusive(reason: str, **extra: Any) -> CheckResult:
        measured = {"settings": settings, **extra}
        return CheckResult.inconclusive(
            KEY, CLAIM, reason, criterion=CRITERION, measured=measured, seconds=time.perf_counter() - start
        )

    if scenario.robots.layout == "explicit":
        return inconclusive("the scenario places its robots explicitly: the robot count cannot be varied")
    try:
        layouts = {label: coverage_estimate(scenario.domain, c, eta, f * c) for label, f in EPS_FRACTIONS.items()}
    except ParameterError as exc:
        return inconclusive(f"the coverage estimate cannot be computed for this scenario: {exc}")
    coverage = {label: lay.n for label, lay in layouts.items()}
    coverage_info = {
        label: {"eps": EPS_FRACTIONS[label] * c, "radius": lay.radius, "n": lay.n, "cols": lay.cols, "rows": lay.rows}
        for label, lay in layouts.items()
    }
    try:
        study: RobotCountStudy = empirical_robot_count(
            scenario, counts, seeds, threshold=THRESHOLD, workers=workers, progress=progress
        )
    except (ParameterError, SimulationDiverged) as exc:
        return inconclusive(f"the closed-loop runs could not be made: {exc}", coverage=coverage_info)

    verdict, per_eps = robot_count_verdict(coverage, study.minimum)
    medians = study.medians()
    measured: dict[str, Any] = {
        "settings": settings,
        "coverage": coverage_info,
        "empirical_minimum": study.minimum,
        "minimum_bracket": _bracket(study.counts, study.minimum),
        "median_fraction_in_target": {str(n): v for n, v in medians.items()},
        "fraction_in_target": {str(n): v for n, v in study.values.items()},
        "l2_error_ratio": {str(n): v for n, v in study.l2_ratio.items()},
        "scenario_robots": scenario.robots.n,
        "deciding_eps_matches_scenario_robots": coverage[DECIDING] == scenario.robots.n,
    }

    fig_dir = out_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    rel = f"figures/{KEY}_fraction_vs_n.png"
    from analysis.figures import plot_robot_count, save_figure

    fig = plot_robot_count(study, {EPS_FRACTIONS[k] * c: n for k, n in coverage.items()}, c)
    save_figure(fig, out_dir / rel)

    cases = [
        {
            "eps": label,
            "eps_value": EPS_FRACTIONS[label] * c,
            "radius": layouts[label].radius,
            "coverage_n": coverage[label],
            "empirical_minimum": study.minimum,
            "verdict": per_eps[label],
        }
        for label in EPS_FRACTIONS
    ]
    cov_text = ", ".join(f"n({k}) = {n}" for k, n in coverage.items())
    if study.minimum is None:
        best = max(medians.items(), key=lambda kv: kv[1])
        reason = (
            f"no robot count tried reached a median fraction in target ≥ {THRESHOLD} (best: {best[1]:.3g} at n = "
            f"{best[0]}), so the empirical minimum is unknown"
        )
        res = CheckResult(
            KEY, CLAIM, "inconclusive", summary=f"no count succeeded; {cov_text}", measured=measured,
            bound={"coverage": coverage}, reason=reason, criterion=CRITERION, cases=cases, figures=[rel],
        )
        res.seconds = time.perf_counter() - start
        return res
    summary = f"empirical minimum n = {study.minimum} (median fraction ≥ {THRESHOLD}); coverage {cov_text}"
    reason = (
        ""
        if verdict == "holds"
        else f"the coverage estimate at ε = {DECIDING} asks for {coverage[DECIDING]} robots, more than the "
        f"{study.minimum} that already reach the target in closed loop: it is not a lower estimate there"
    )
    return CheckResult(
        KEY,
        CLAIM,
        verdict,  # type: ignore[arg-type]
        summary=summary,
        measured=measured,
        bound={"coverage": coverage, "deciding_eps": DECIDING},
        reason=reason,
        criterion=CRITERION,
        cases=cases,
        figures=[rel],
        seconds=time.perf_counter() - start,
    )
