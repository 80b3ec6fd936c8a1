"""The claims of the paper's agent-based studies (Section V) and their decision rules.

What :mod:`verification.agents` checks, and how it decides (``docs/verification.md``): the
claim quoted from the paper, the criterion in words, the thresholds, and the verdict
functions that turn per-seed measurements into ``"holds"``, ``"fails"`` or
``"inconclusive"`` -- :func:`agents_verdict` for the MATLAB study, :func:`pedestrians_verdict`
for the Unity study.  No simulation runs here: the runs are in :mod:`verification.agents`,
which re-exports every name of this module.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "KEY",
    "CLAIM",
    "CRITERION",
    "FRACTION_THRESHOLD",
    "RATIO_THRESHOLD",
    "PEDESTRIANS_KEY",
    "PEDESTRIANS_CLAIM",
    "PEDESTRIANS_CRITERION",
    "PEDESTRIANS_FRACTION_THRESHOLD",
    "OVERLAP_THRESHOLD",
    "agents_verdict",
    "pedestrians_verdict",
]

# ---------------------------------------------------------------------- the MATLAB study
KEY = "agents"
CLAIM = (
    "Section V (MATLAB study): with the feedback laws the humans, moved by eq. (1), \"are guided to the target "
    "location\", and the density convergence error (Fig. 4) \"verifies the success of the evacuation objective\"."
)
FRACTION_THRESHOLD = 0.9
RATIO_THRESHOLD = 1.0

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


# ---------------------------------------------------------------------- the Unity study
PEDESTRIANS_KEY = "pedestrians"
PEDESTRIANS_CLAIM = (
    "Section V (Unity study): humans with bodies who follow a robot only when it is within their 30 m view "
    "radius (150 m × 150 m map) \"eventually ... are also directed to the target location\", so the algorithm "
    "is robust to scenarios that are not precisely modeled."
)
PEDESTRIANS_FRACTION_THRESHOLD = 0.8
OVERLAP_THRESHOLD = 0.01  # deepest body overlap, as a fraction of a body's diameter

PEDESTRIANS_CRITERION = (
    "always on the paper's Unity study (meanfield.scenarios.scenario.paper_unity_scenario: 150 × 150 m, 200 humans, "
    "16 robots, 30 m view radius, target at the corner (150, 150), t_final 1000 s), whatever the verified "
    "scenario, with the humans as JuPedSim bodies (collision-free speed model, radius 0.2 m); holds when, over "
    f"seeds, the median fraction of humans in the target region at t_final is ≥ {PEDESTRIANS_FRACTION_THRESHOLD} "
    "AND every run completed (a diverged run fails the check) AND the deepest overlap of two bodies over all runs "
    f"and control steps is ≤ {OVERLAP_THRESHOLD:g} of a body diameter (the collision-free model should keep "
    "bodies apart); fails otherwise; inconclusive when JuPedSim is not installed. The full variant also runs "
    "point-mass humans with and without the view radius on the same seeds: reported, not judged"
)


def pedestrians_verdict(
    fractions: list[float | None],
    statuses: list[str],
    overlaps: list[float | None],
    fraction_threshold: float = PEDESTRIANS_FRACTION_THRESHOLD,
    overlap_threshold: float = OVERLAP_THRESHOLD,
) -> tuple[str, float, float]:
    """The decision rule of :func:`check_pedestrians` (the JuPedSim runs only).

    Parameters
    ----------
    fractions : list of float
        Fraction of humans in the target region at ``t_final``, per seed; a run that did
        not complete counts as 0.
    statuses : list of str
        Run status per seed; anything but ``"completed"`` (a diverged run) fails the check.
    overlaps : list of float or None
        ``body_overlap_max_relative`` per seed (deepest overlap / body diameter); None or
        NaN for a completed run counts as +inf (not shown to be collision-free).
    fraction_threshold, overlap_threshold : float
        Success needs ``median fraction >= fraction_threshold``, every run completed and
        ``max overlap <= overlap_threshold``.

    Returns
    -------
    verdict : {"holds", "fails", "inconclusive"}
        ``"inconclusive"`` only when there is no seed or the lists differ in length.
    median_fraction, worst_overlap : float
        The median judged and the deepest relative overlap over the runs.
    """
    if not statuses or not (len(fractions) == len(statuses) == len(overlaps)):
        return "inconclusive", math.nan, math.nan
    fr, ov = [], []
    for f, s, o in zip(fractions, statuses, overlaps, strict=True):
        done = s == "completed"
        fr.append(float(f) if done and f is not None and math.isfinite(float(f)) else 0.0)
        if o is not None and math.isfinite(float(o)):
            ov.append(float(o))
        elif done:
            ov.append(math.inf)
    med_f = float(np.median(fr))
    worst_o = max(ov) if ov else math.nan
    ok = med_f >= fraction_threshold and all(s == "completed" for s in statuses) and worst_o <= overlap_threshold
    return ("holds" if ok else "fails"), med_f, worst_o
