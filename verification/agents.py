"""The paper's agent-based studies (Section V): the MATLAB study and the Unity study.

Section V, first study (MATLAB): humans and robots are mass points moved by eqs. (1)–(2)
with Euler's method, and "the humans perfectly follow the generated navigation velocity
fields and are guided to the target location.  The density convergence error is plotted
in Fig. 4 and verifies the success of the evacuation objective."
:func:`check_agents` runs the scenario's closed loop (:class:`meanfield.ClosedLoop`) over
several seeds and asks for both: most humans in the target region, and a density error
that has decreased.

Section V, second study (Unity): humans with bodies and a limited view radius follow a
robot only when they see one, "and eventually they are also directed to the target
location".  :func:`check_pedestrians` runs the paper's Unity study
(:func:`meanfield.scenarios.scenario.paper_unity_scenario`, whatever the verified scenario) with the
humans as JuPedSim bodies and asks for most humans in the target region with no bodies
overlapping; point-mass runs with and without the view radius are reported for comparison.

The claims, criteria, thresholds and decision rules (:func:`agents_verdict`,
:func:`pedestrians_verdict`) are in :mod:`verification.agents_criteria` and re-exported
here; this module runs the studies (``docs/verification.md``).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from analysis.parallel import map_jobs
from meanfield.crowds.jupedsim_engine import JuPedSimOptions
from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.scenarios.scenario import Scenario, paper_unity_scenario
from verification.agents_criteria import (
    CLAIM,
    CRITERION,
    FRACTION_THRESHOLD,
    KEY,
    OVERLAP_THRESHOLD,
    PEDESTRIANS_CLAIM,
    PEDESTRIANS_CRITERION,
    PEDESTRIANS_FRACTION_THRESHOLD,
    PEDESTRIANS_KEY,
    RATIO_THRESHOLD,
    agents_verdict,
    pedestrians_verdict,
)
from verification.result import CheckResult

__all__ = [
    "KEY",
    "CLAIM",
    "PEDESTRIANS_KEY",
    "PEDESTRIANS_CLAIM",
    "agents_verdict",
    "check_agents",
    "check_pedestrians",
    "pedestrians_verdict",
]

QUICK_SEEDS: tuple[int, ...] = (0, 1, 2)
FULL_SEEDS: tuple[int, ...] = tuple(range(10))

# summary keys and time series ({record key: dataset variable}) every run record carries
_RUN_KEYS = ("seed", "status", "message", "fraction_in_target", "l2_error_ratio", "time_to_90", "time_final",
             "wall_seconds")
_RUN_SERIES = {"time": "time", "fraction_series": "fraction_in_target"}


def _run_record(scenario: Scenario, keys: tuple[str, ...] = (), series: dict[str, str] | None = None) -> dict:
    """Run one closed loop and keep the common summary keys and series, plus ``keys`` and ``series``."""
    from meanfield.simulation.loop import ClosedLoop

    res = ClosedLoop(scenario).run(progress=False)
    s, ds = res.summary, res.dataset
    record = {k: s.get(k) for k in _RUN_KEYS + keys}
    record.update({k: ds[v].values for k, v in {**_RUN_SERIES, **(series or {})}.items()})
    return record


def _run_seed(job: tuple[dict[str, Any], int]) -> dict[str, Any]:
    """One closed-loop run (module level: runs in a worker process)."""
    d, seed = job
    sc = Scenario.from_dict(d).replace(seed=seed)
    return _run_record(sc, ("l2_error_initial", "l2_error_final"), {"error_series": "rho_error_l2"})


def _plot(runs: list[dict[str, Any]], path: Path) -> None:
    from matplotlib.figure import Figure

    from analysis.figures import save_figure

    fig = Figure(figsize=(10.0, 4.0))
    ax, bx = fig.subplots(1, 2)
    for k, r in enumerate(runs):
        style = "-" if r["status"] == "completed" else "--"
        ax.plot(r["time"], r["fraction_series"], style, color=f"C{k % 10}", lw=1.0, label=f"seed {r['seed']}")
        bx.plot(r["time"], r["error_series"], style, color=f"C{k % 10}", lw=1.0, label=f"seed {r['seed']}")
    ax.axhline(FRACTION_THRESHOLD, color="k", ls=":", lw=0.8, label=f"{FRACTION_THRESHOLD:g}")
    ax.set_xlabel("time")
    ax.set_ylabel("fraction of humans in the target region")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title("Humans guided to the target (Section V)", fontsize=10)
    ax.legend(fontsize=6, ncol=2)
    bx.set_xlabel("time")
    bx.set_ylabel("‖ρ̂ − ρ_*‖ (L²)")
    bx.set_title("Density error (the paper's Fig. 4)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def check_agents(
    scenario: Scenario,
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    workers: int | None = None,
) -> CheckResult:
    """Check the MATLAB study of Section V: the humans reach the target, the density error falls.

    Paper, Section V: "the humans perfectly follow the generated navigation velocity
    fields and are guided to the target location.  The density convergence error is
    plotted in Fig. 4 and verifies the success of the evacuation objective."

    The scenario's closed loop (:class:`meanfield.ClosedLoop`) is run for several seeds.
    Decision rule (:func:`agents_verdict`): median fraction in the target region ≥ 0.9
    and median ``l2_error_ratio`` < 1; a diverged seed counts as a failure.

    Parameters
    ----------
    scenario : Scenario
        The closed loop to run; its ``seed`` is replaced by each seed.
    out_dir : Path
        The report's directory; the figure goes to ``out_dir / "figures"``.
    quick : bool
        Seeds 0, 1, 2; otherwise 0–9.
    progress : bool
        Show a progress bar over the runs.
    workers : int, optional
        Worker processes (default: the cores; 1: this process).

    Returns
    -------
    CheckResult
        Key ``"agents"``; one case per seed.
    """
    start = time.perf_counter()
    out_dir = Path(out_dir)
    seeds = QUICK_SEEDS if quick else FULL_SEEDS
    settings = {"seeds": list(seeds), "t_final": scenario.t_final, "crowd": scenario.crowd.n,
                "robots": scenario.robots.n}
    try:
        runs = map_jobs(_run_seed, [(scenario.to_dict(), s) for s in seeds], workers, "agents (seeds)", progress)
    except (ParameterError, SimulationDiverged) as exc:
        reason = f"the scenario's closed loop cannot be run: {exc}"
        return CheckResult.inconclusive(KEY, CLAIM, reason, criterion=CRITERION, measured={"settings": settings},
                                        seconds=time.perf_counter() - start)
    fractions = [r["fraction_in_target"] for r in runs]
    ratios = [r["l2_error_ratio"] for r in runs]
    statuses = [r["status"] for r in runs]
    verdict, med_f, med_r = agents_verdict(fractions, ratios, statuses)
    failed = [r["seed"] for r in runs if r["status"] != "completed"]

    fig_dir = out_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    rel = f"figures/{KEY}_time_series.png"
    _plot(runs, out_dir / rel)

    cases = [
        {
            "seed": r["seed"],
            "status": r["status"],
            "message": r["message"],
            "fraction_in_target": r["fraction_in_target"],
            "l2_error_ratio": r["l2_error_ratio"],
            "time_to_90": r["time_to_90"],
            "time_final": r["time_final"],
            "wall_seconds": r["wall_seconds"],
            "verdict": "holds"
            if r["status"] == "completed"
            and r["fraction_in_target"] >= FRACTION_THRESHOLD
            and r["l2_error_ratio"] is not None
            and r["l2_error_ratio"] < RATIO_THRESHOLD
            else "fails",
        }
        for r in runs
    ]
    measured = {
        "settings": settings,
        "median_fraction_in_target": med_f,
        "median_l2_error_ratio": med_r,
        "fraction_in_target": fractions,
        "l2_error_ratio": ratios,
        "time_to_90": [r["time_to_90"] for r in runs],
        "status": statuses,
        "diverged_seeds": failed,
        "seeds_meeting_both": sum(c["verdict"] == "holds" for c in cases),
    }
    summary = (
        f"median fraction in target {med_f:.3g} (≥ {FRACTION_THRESHOLD}), median error ratio {med_r:.3g} "
        f"(< {RATIO_THRESHOLD:g}) over {len(seeds)} seeds" + (f"; diverged seeds {failed}" if failed else "")
    )
    reasons = []
    if verdict == "fails":
        if med_f < FRACTION_THRESHOLD:
            reasons.append(f"median fraction in target {med_f:.3g} < {FRACTION_THRESHOLD}")
        if not med_r < RATIO_THRESHOLD:
            reasons.append(f"median error ratio {med_r:.3g} ≥ {RATIO_THRESHOLD:g}")
        if failed:
            reasons.append(f"runs of seeds {failed} did not complete")
    return CheckResult(
        KEY,
        CLAIM,
        verdict,  # type: ignore[arg-type]
        summary=summary,
        measured=measured,
        bound={"median_fraction_in_target_min": FRACTION_THRESHOLD, "median_l2_error_ratio_below": RATIO_THRESHOLD},
        reason="; ".join(reasons),
        criterion=CRITERION,
        cases=cases,
        figures=[rel],
        seconds=time.perf_counter() - start,
    )


# ---------------------------------------------------------------------- the Unity study
PEDESTRIANS_QUICK_SEEDS: tuple[int, ...] = (0, 1, 2)
PEDESTRIANS_FULL_SEEDS: tuple[int, ...] = tuple(range(5))

# variant -> (label, crowd.kind, view gating); the first is judged, the others are reported (full mode)
VARIANTS: dict[str, tuple[str, str, bool]] = {
    "jupedsim": ("JuPedSim bodies, 30 m view", "jupedsim", True),
    "point-mass": ("point mass, 30 m view", "point-mass", True),
    "point-mass-no-view": ("point mass, no view gating", "point-mass", False),
}

def unity_scenario(seed: int, variant: str) -> Scenario:
    """The paper's Unity study for ``seed``, with the crowd backend and view gating of ``variant``."""
    _, backend, gated = VARIANTS[variant]
    values: dict[str, Any] = {"crowd.kind": backend}
    if not gated:
        values["view.radius"] = "none"
    return paper_unity_scenario(seed).with_values(values)


def _run_unity(job: tuple[str, dict[str, Any]]) -> dict[str, Any]:
    """One Unity-study closed loop (module level: runs in a worker process)."""
    variant, d = job
    keys = ("seen_fraction_final", "body_overlap_max", "body_overlap_max_relative")
    return {"variant": variant, **_run_record(Scenario.from_dict(d), keys, {"seen_series": "seen_fraction"})}


def _plot_unity(runs: list[dict[str, Any]], path: Path) -> None:
    from matplotlib.figure import Figure

    from analysis.figures import save_figure

    styles = {"jupedsim": "-", "point-mass": "--", "point-mass-no-view": ":"}
    seeds = sorted({r["seed"] for r in runs})
    fig = Figure(figsize=(10.0, 3.8))
    ax, bx = fig.subplots(1, 2)
    for r in runs:
        color = f"C{seeds.index(r['seed']) % 10}"
        label = f"{VARIANTS[r['variant']][0]}, seed {r['seed']}"
        ax.plot(r["time"], r["fraction_series"], styles[r["variant"]], color=color, lw=1.0, label=label)
        if r["variant"] == "jupedsim":
            bx.plot(r["time"], r["seen_series"], "-", color=color, lw=1.0, label=f"seed {r['seed']}")
    ax.axhline(PEDESTRIANS_FRACTION_THRESHOLD, color="k", ls=":", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fraction of humans in the target region")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title("Unity study: humans guided to the target", fontsize=10)
    ax.legend(fontsize=5.5, ncol=1 + (len(runs) > 5))
    bx.set_xlabel("time (s)")
    bx.set_ylabel("fraction of humans who see a robot")
    bx.set_ylim(-0.02, 1.02)
    bx.set_title("JuPedSim runs: humans within 30 m of a robot", fontsize=10)
    bx.legend(fontsize=6)
    fig.tight_layout()
    save_figure(fig, path)


def _median(values: list[float | None]) -> float:
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.median(v)) if v else math.nan


def check_pedestrians(
    scenario: Scenario,
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    workers: int | None = None,
) -> CheckResult:
    """Check the Unity study of Section V: humans with bodies and a 30 m view reach the target.

    Paper, Section V: "In the Unity simulation, the humans are guided only when they see
    a robot near them and eventually they are also directed to the target location,
    which suggests that the evacuation algorithm is robust to scenarios that are not
    precisely modeled."

    The claim is about the paper's Unity study, so the check **does not use the
    ``scenario`` argument's parameters**: it always runs
    :func:`meanfield.scenarios.scenario.paper_unity_scenario` (150 × 150 m, 200 humans, 16 robots,
    30 m view radius, t_final 1000 s) with ``crowd.kind = "jupedsim"``, over
    several seeds (``measured["settings"]`` says so).  Decision rule
    (:func:`pedestrians_verdict`): median fraction in the target region at t_final ≥ 0.8,
    every run completed, and the deepest body overlap ≤ 1 % of a diameter.  The full
    variant also runs point-mass humans with and without the view radius on the same
    seeds, reported but not judged.  Without JuPedSim the verdict is ``"inconclusive"``
    with the install command.

    Parameters
    ----------
    scenario : Scenario
        Not used (see above).
    out_dir : Path
        The report's directory; the figure goes to ``out_dir / "figures"``.
    quick : bool
        JuPedSim seeds 0, 1, 2 only; otherwise seeds 0–4 and the point-mass comparisons.
    progress : bool
        Show a progress bar over the runs.
    workers : int, optional
        Worker processes (default: the cores; 1: this process).

    Returns
    -------
    CheckResult
        Key ``"pedestrians"``; one case per run (the point-mass ones marked ``"comparison"``).
    """
    from meanfield.crowds._jupedsim_api import JuPedSimUnavailable, jupedsim_version, load_jupedsim

    del scenario  # the claim is about the paper's Unity study, not the verified scenario
    start = time.perf_counter()
    out_dir = Path(out_dir)
    seeds = PEDESTRIANS_QUICK_SEEDS if quick else PEDESTRIANS_FULL_SEEDS
    variants = ["jupedsim"] if quick else list(VARIANTS)
    ref = unity_scenario(seeds[0], "jupedsim")
    settings = {
        "scenario": f"{ref.name} (meanfield.scenarios.paper_unity_scenario), independent of the verified scenario",
        "seeds": list(seeds),
        "judged": VARIANTS["jupedsim"][0],
        "comparisons": [VARIANTS[v][0] for v in variants[1:]],
        "domain_m": [ref.domain.bounds[1] - ref.domain.bounds[0], ref.domain.bounds[3] - ref.domain.bounds[2]],
        "humans": ref.crowd.n,
        "robots": ref.robots.n,
        "view_radius_m": ref.view.radius,
        "target_center": list(ref.target.center),
        "t_final_s": ref.t_final,
        "dt_s": ref.dt,
        "pedestrian_model": JuPedSimOptions.of(ref).model,
        "body_radius_m": JuPedSimOptions.of(ref).radius,
        "jupedsim_version": jupedsim_version(),
    }
    try:
        load_jupedsim()
    except JuPedSimUnavailable as exc:
        reason = f"JuPedSim, the pedestrian backend of the Unity study, is not installed: {exc}"
        return CheckResult.inconclusive(PEDESTRIANS_KEY, PEDESTRIANS_CLAIM, reason, criterion=PEDESTRIANS_CRITERION,
                                        measured={"settings": settings}, seconds=time.perf_counter() - start)
    jobs = [(v, unity_scenario(s, v).to_dict()) for v in variants for s in seeds]
    try:
        runs = map_jobs(_run_unity, jobs, workers, "pedestrians (runs)", progress)
    except (ParameterError, SimulationDiverged) as exc:
        reason = f"the Unity study's closed loop cannot be run: {exc}"
        return CheckResult.inconclusive(PEDESTRIANS_KEY, PEDESTRIANS_CLAIM, reason, criterion=PEDESTRIANS_CRITERION,
                                        measured={"settings": settings}, seconds=time.perf_counter() - start)
    judged = [r for r in runs if r["variant"] == "jupedsim"]
    fractions = [r["fraction_in_target"] for r in judged]
    statuses = [r["status"] for r in judged]
    overlaps = [r["body_overlap_max_relative"] for r in judged]
    verdict, med_f, worst_o = pedestrians_verdict(fractions, statuses, overlaps)
    failed = [r["seed"] for r in judged if r["status"] != "completed"]

    (out_dir / "figures").mkdir(parents=True, exist_ok=True)
    rel = f"figures/{PEDESTRIANS_KEY}_fraction_in_target.png"
    _plot_unity(runs, out_dir / rel)

    cases = []
    for r in runs:
        role = "judged" if r["variant"] == "jupedsim" else "comparison"
        if role == "comparison":
            case_verdict = "not judged"
        else:
            case_verdict = pedestrians_verdict([r["fraction_in_target"]], [r["status"]],
                                               [r["body_overlap_max_relative"]])[0]
        cases.append({
            "run": VARIANTS[r["variant"]][0],
            "role": role,
            "seed": r["seed"],
            "status": r["status"],
            "message": r["message"],
            "fraction_in_target": r["fraction_in_target"],
            "time_to_90": r["time_to_90"],
            "l2_error_ratio": r["l2_error_ratio"],
            "seen_fraction_final": r["seen_fraction_final"],
            "body_overlap_max_relative": r["body_overlap_max_relative"],
            "time_final": r["time_final"],
            "wall_seconds": r["wall_seconds"],
            "verdict": case_verdict,
        })
    comparison = {
        VARIANTS[v][0]: {
            "median_fraction_in_target": _median([r["fraction_in_target"] for r in runs if r["variant"] == v]),
            "fraction_in_target": [r["fraction_in_target"] for r in runs if r["variant"] == v],
            "time_to_90": [r["time_to_90"] for r in runs if r["variant"] == v],
        }
        for v in variants[1:]
    }
    measured: dict[str, Any] = {
        "settings": settings,
        "median_fraction_in_target": med_f,
        "fraction_in_target": fractions,
        "time_to_90": [r["time_to_90"] for r in judged],
        "seen_fraction_final": [r["seen_fraction_final"] for r in judged],
        "body_overlap_max_relative_worst": worst_o,
        "body_overlap_max_m": [r["body_overlap_max"] for r in judged],
        "status": statuses,
        "diverged_seeds": failed,
    }
    if comparison:
        measured["comparison"] = comparison
    summary = (
        f"JuPedSim bodies, 30 m view: median fraction in target {med_f:.3g} (≥ {PEDESTRIANS_FRACTION_THRESHOLD}), "
        f"deepest body overlap {worst_o:.3g} of a diameter (≤ {OVERLAP_THRESHOLD:g}) over seeds {list(seeds)}"
        + (f"; diverged seeds {failed}" if failed else "")
        + "".join(f"; {k}: median {c['median_fraction_in_target']:.3g}" for k, c in comparison.items())
    )
    reasons = []
    if verdict == "fails":
        if med_f < PEDESTRIANS_FRACTION_THRESHOLD:
            reasons.append(f"median fraction in target {med_f:.3g} < {PEDESTRIANS_FRACTION_THRESHOLD}")
        if not worst_o <= OVERLAP_THRESHOLD:
            reasons.append(f"bodies overlap by {worst_o:.3g} of a diameter > {OVERLAP_THRESHOLD:g}")
        if failed:
            reasons.append(f"runs of seeds {failed} did not complete")
    return CheckResult(
        PEDESTRIANS_KEY,
        PEDESTRIANS_CLAIM,
        verdict,  # type: ignore[arg-type]
        summary=summary,
        measured=measured,
        bound={
            "median_fraction_in_target_min": PEDESTRIANS_FRACTION_THRESHOLD,
            "body_overlap_max_relative_max": OVERLAP_THRESHOLD,
            "runs_completed": "all",
        },
        reason="; ".join(reasons),
        criterion=PEDESTRIANS_CRITERION,
        cases=cases,
        figures=[rel],
        seconds=time.perf_counter() - start,
    )
