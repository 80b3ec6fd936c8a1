"""The paper's agent-based studies (Section V): the MATLAB study and the Unity study.

Section V, first study (MATLAB): humans and robots are mass points moved by eqs. (1)–(2)
with Euler's method, and "the humans perfectly follow the generated navigation velocity
fields and are guided to the target location.  The density convergence error is plotted
in Fig. 4 and verifies the success of the evacuation objective."
:func:`check_agents` runs the scenario's closed loop (:class:`meanfield.ClosedLoop`) over
several seeds and asks for both: most humans in the target region, and a density error
that has decreased.

Section V, second study (Unity): humans with bodies and a limited view radius follow a
robot only when they see one.  That needs a pedestrian backend (JuPedSim in this
toolkit's design), which this version does not have: :func:`check_pedestrians` says so.
"""

from __future__ import annotations

import importlib.util
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from analysis.parallel import map_jobs
from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.scenario import Scenario
from verification.result import CheckResult

__all__ = [
    "KEY",
    "CLAIM",
    "PEDESTRIANS_KEY",
    "PEDESTRIANS_CLAIM",
    "agents_verdict",
    "check_agents",
    "check_pedestrians",
    "pedestrian_backends",
]

KEY = "agents"
CLAIM = (
    "Section V (MATLAB study): with the feedback laws the humans, moved by eq. (1), \"are guided to the target "
    "location\", and the density convergence error (Fig. 4) \"verifies the success of the evacuation objective\"."
)
FRACTION_THRESHOLD = 0.9
RATIO_THRESHOLD = 1.0
QUICK_SEEDS: tuple[int, ...] = (0, 1, 2)
FULL_SEEDS: tuple[int, ...] = tuple(range(10))

CRITERION = (
    f"holds when, over seeds, the median fraction of humans in the target region at t_final is ≥ "
    f"{FRACTION_THRESHOLD} (the toolkit's target-region convention, as for time_to_90) AND the median "
    f"ratio ‖ρ̂ − ρ_*‖(t_final) / ‖ρ̂ − ρ_*‖(0) is < {RATIO_THRESHOLD:g}; fails otherwise; a seed whose "
    "run did not complete (diverged) counts as a failure of that seed (fraction 0, ratio +inf)"
)


def agents_verdict(
    fractions: list[float | None],
    ratios: list[float | None],
    statuses: list[str],
    fraction_threshold: float = FRACTION_THRESHOLD,
    ratio_threshold: float = RATIO_THRESHOLD,
) -> tuple[str, float, float]:
    """The decision rule of :func:`check_agents`.

    Parameters
    ----------
    fractions : list of float
        Fraction of humans in the target region at ``t_final``, per seed.
    ratios : list of float or None
        ``l2_error_ratio`` (final / initial density error) per seed; None or NaN (no
        initial error to compare with) counts as not decreased (+inf).
    statuses : list of str
        Run status per seed; anything but ``"completed"`` (a diverged run) makes that
        seed a failure: fraction 0, ratio +inf.
    fraction_threshold, ratio_threshold : float
        Success needs ``median fraction >= fraction_threshold`` and ``median ratio <
        ratio_threshold``.

    Returns
    -------
    verdict : {"holds", "fails", "inconclusive"}
        ``"inconclusive"`` only when there is no seed or the lists differ in length.
    median_fraction, median_ratio : float
        The medians judged (failed seeds included as described).
    """
    if not statuses or not (len(fractions) == len(ratios) == len(statuses)):
        return "inconclusive", math.nan, math.nan
    fr, rr = [], []
    for f, r, s in zip(fractions, ratios, statuses, strict=True):
        ok = s == "completed"
        f = float(f) if ok and f is not None and math.isfinite(float(f)) else 0.0
        r = float(r) if ok and r is not None and math.isfinite(float(r)) else math.inf
        fr.append(f)
        rr.append(r)
    med_f = float(np.median(fr))
    med_r = float(np.median(rr))
    ok = med_f >= fraction_threshold and med_r < ratio_threshold
    return ("holds" if ok else "fails"), med_f, med_r


def _run_seed(job: tuple[dict[str, Any], int]) -> dict[str, Any]:
    """One closed-loop run (module level: runs in a worker process)."""
    from meanfield.simulate import ClosedLoop

    d, seed = job
    sc = Scenario.from_dict(d).replace(seed=seed)
    res = ClosedLoop(sc).run(progress=False)
    s, ds = res.summary, res.dataset
    return {
        "seed": seed,
        "status": s["status"],
        "message": s["message"],
        "fraction_in_target": s["fraction_in_target"],
        "l2_error_ratio": s["l2_error_ratio"],
        "l2_error_initial": s["l2_error_initial"],
        "l2_error_final": s["l2_error_final"],
        "time_to_90": s["time_to_90"],
        "time_final": s["time_final"],
        "wall_seconds": s["wall_seconds"],
        "time": ds["time"].values,
        "fraction_series": ds["fraction_in_target"].values,
        "error_series": ds["rho_error_l2"].values,
    }


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
PEDESTRIANS_KEY = "pedestrians"
PEDESTRIANS_CLAIM = (
    "Section V (Unity study): humans with bodies who follow a robot only when it is within their 30 m view "
    "radius (150 m × 150 m map) \"eventually ... are also directed to the target location\", so the algorithm "
    "is robust to scenarios that are not precisely modeled."
)
NOT_AVAILABLE = (
    "the pedestrian backend (JuPedSim, the paper's Unity study) is not available in this version of the toolkit"
)
NOT_WIRED = "a pedestrian backend is installed but not wired into verification yet"


def pedestrian_backends() -> tuple[str, ...]:
    """Installed pedestrian backends (plugin kind ``"backend"``), or ``()`` if that kind is unknown."""
    from meanfield import plugins

    try:
        return tuple(plugins.available("backend"))
    except (ValueError, KeyError):  # ParameterError (an unknown plugin kind) is a ValueError
        return ()


def check_pedestrians(
    scenario: Scenario,
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    workers: int | None = None,
) -> CheckResult:
    """The Unity study of Section V (view radius, bodies): inconclusive in this version.

    Paper, Section V: "In the Unity simulation, the humans are guided only when they see
    a robot near them and eventually they are also directed to the target location,
    which suggests that the evacuation algorithm is robust to scenarios that are not
    precisely modeled."  Checking it needs a pedestrian simulator with bodies and local
    views (JuPedSim in this toolkit's design).  No such backend exists in this version;
    if one is found (plugin kind ``"backend"`` and the ``jupedsim`` package) it is not
    wired into the check yet.  Either way the verdict is ``"inconclusive"``.

    Parameters
    ----------
    scenario : Scenario
        Unused.
    out_dir : Path
        Unused (no figure).
    quick, progress : bool
        Unused.
    workers : int, optional
        Unused.

    Returns
    -------
    CheckResult
        Key ``"pedestrians"``, verdict ``"inconclusive"`` with the reason.
    """
    start = time.perf_counter()
    backends = pedestrian_backends()
    installed = importlib.util.find_spec("jupedsim") is not None
    reason = NOT_WIRED if (installed and backends) else NOT_AVAILABLE
    return CheckResult.inconclusive(
        PEDESTRIANS_KEY,
        PEDESTRIANS_CLAIM,
        reason,
        measured={"jupedsim_installed": installed, "backends": list(backends)},
        criterion="needs a pedestrian backend with bodies and view radii; without one the check cannot decide",
        seconds=time.perf_counter() - start,
    )
