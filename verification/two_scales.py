"""One crowd at two scales: the congested agents against the congested density, and the gap as the room grows.

The toolkit runs a congested crowd at two scales: point masses whose door model is the forward cell
(:class:`meanfield.crowds.forward_cell.ForwardCell`, with exits and doors at their capacity) and the density under
Godunov's supply–demand flux (:mod:`meanfield.fokker_planck.congested`), both with the linear
diagram and the informed crowd on the fastest route (docs page *Congestion*).  They claim to be one
model at two scales; :func:`check_two_scales` measures it where an evacuation engineer reads it, in
the times at which 10 %, 50 % and 90 % of the crowd are out (``t10``, ``t50``, ``t90``) and the
bottleneck's flow ``J`` between them:

* **the bottleneck** (the built-in ``bottleneck``, 200 people starting in its 10 m × 8 m room, the
  corridor ``b`` wide) at every width of :data:`FULL_WIDTHS`: the agents' median over seeds against the
  density's one run (it is deterministic);
* **the plans** ``l-room``, ``office`` and ``hall``, the informed crowd, on cells :data:`PLAN_REFINEMENT` times
  finer than the plans' own at both scales (the density on the office's 0.5 m cells is 1.5 % (t50) and 4.3 % (t90)
  late against its value on 0.25 m cells, which 0.125 m cells move by 0.8 % more; docs page *Congestion*, "The
  doors' capacity");
* **the limit.**  The bottleneck of width 2 m scaled by ``L`` = 1, 2, 3: every length times ``L`` (the
  room, the corridor, the door, the route's cells), ``N = 200 L²`` people, times read as ``t/L``.

**Why the scaled room is the limit.**  The agents interact at a person's scale (a lane of 0.46 m, a
door that passes 1.81 persons/(m·s)), not through a kernel that widens with the room, so their limit
is hydrodynamic, not the mean-field limit at a fixed room of the paper's Section III: with the person
fixed and the room ``L`` times larger, the crowd holds ``L²`` times the people at the same density,
and ``(x/L, t/L)`` turns the LWR law ``∂ₜρ + ∇·(ρ v₀ g(ρ) e) = 0`` into itself (the follow-the-leader
limit of Di Francesco and Rosini, ARMA 217 (2015) 831–871).  What is left over at a finite ``L``, a
door's edges a lane wide and a queue's discreteness, is of order ``d/L`` and ``1/√N``, and the gap
must shrink with ``L``.  The density at each ``L`` runs on ``L`` times coarser cells, so that its
numerical problem in ``(x/L, t/L)`` is the same; only its diffusion, ``σ/L`` there, vanishes, as the
agents' noise does.  The ensemble mean over seeds at a fixed room is not this limit: it converges to
the ``N``-person system's own mean, whose queue is ``N`` persons long, whatever the number of seeds.

The criterion (:func:`two_scales_verdict`) holds when every case's ``t50`` and ``t90`` (and on the
bottleneck its ``J``) agree within :data:`TOLERANCE`, and the limit's gap falls as ``L`` grows.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from analysis.parallel import map_jobs
from meanfield.scenarios.scenario import Scenario, builtin_scenarios
from verification.result import CheckResult

__all__ = [
    "KEY",
    "CLAIM",
    "CRITERION",
    "TOLERANCE",
    "bottleneck",
    "check_two_scales",
    "exit_times",
    "informed",
    "refined",
    "summarise",
    "two_scales_verdict",
]

KEY = "two_scales"
CLAIM = (
    "The congested crowd is one model at two scales: the point masses (forward-cell door model, exits and doors "
    "at their capacity) and the density (Godunov's flux), with the same diagram and the informed crowd on the fastest "
    "route, empty the bottleneck and the plans at the same times, and their gap shrinks as the room grows."
)
TOLERANCE = 0.10
"""Largest relative gap ``|agents/density − 1|`` of ``t50``, ``t90`` and the bottleneck's ``J``."""

DOOR_MODEL = "forward-cell"
PLAN_REFINEMENT = 2
"""The plans' cells (routes, and the density's grid) divided by this at both scales."""
FULL_WIDTHS: tuple[float, ...] = (0.8, 1.0, 2.0, 2.5)
QUICK_WIDTHS: tuple[float, ...] = (2.0,)
FULL_PLANS: tuple[str, ...] = ("l-room", "office", "hall")
QUICK_PLANS: tuple[str, ...] = ()
FULL_SCALES: tuple[int, ...] = (1, 2, 3)
QUICK_SCALES: tuple[int, ...] = (1, 2)
FULL_SEEDS: tuple[int, ...] = tuple(range(10))
QUICK_SEEDS: tuple[int, ...] = (0, 1, 2)
LIMIT_SEEDS: tuple[int, ...] = (0, 1, 2)
"""The seeds of the scaled bottleneck beyond ``L = 1`` (its ``200 L²`` people fluctuate less, and cost ``L³``)."""
LIMIT_WIDTH = 2.0
"""m: the door of the scaled bottleneck at ``L = 1``."""
SHARES: tuple[float, ...] = (0.1, 0.5, 0.9)

CRITERION = (
    f"holds when, on the bottleneck at every width and on every plan, the agents' median over seeds of t50 and "
    f"t90 (and on the bottleneck of J, the flow between the exits of 10 % and 90 %) is within {TOLERANCE:.0%} of "
    f"the density's, and in the bottleneck of width {LIMIT_WIDTH:g} m scaled by L (N = 200 L²) the gap, the "
    f"largest of |t10, t50, t90 of the agents (median) / the density's − 1|, falls strictly as L grows; fails "
    f"otherwise"
)


def bottleneck(b: float, scale: float = 1.0, kind: str = "point-mass", seed: int = 0) -> Scenario:
    """The built-in ``bottleneck`` with a corridor ``b`` wide, every length times ``scale``, and the crowd ``kind``.

    The ``200 scale²`` people start uniform in the room (none in the corridor), on the fastest route, with the
    forward-cell door model for the point masses; the route's cells are ``0.1 scale`` m and the horizon ``400 scale``
    s.

    Parameters
    ----------
    b : float
        The corridor's width at ``scale = 1``, m.
    scale : float
        ``L``: every length (and the horizon) times ``L``, the people times ``L²``.
    kind : {"point-mass", "fokker-planck"}
        The crowd's scale.
    seed : int
        The agents' seed.
    """
    s = float(scale)
    lo, hi = s * (4.0 - b / 2), s * (4.0 + b / 2)
    width, height, end = 10.0 * s, 8.0 * s, 12.0 * s
    room = f"POLYGON ((0 0, {width:g} 0, {width:g} {height:g}, 0 {height:g}, 0 0))"
    n = round(200 * s * s)
    values: dict[str, Any] = {
        "domain.wkt": f"POLYGON ((0 0, {width:g} 0, {width:g} {lo:g}, {end:g} {lo:g}, {end:g} {hi:g}, "
        f"{width:g} {hi:g}, {width:g} {height:g}, 0 {height:g}, 0 0))",
        "domain.exits": [[[end, lo], [end, hi]]],
        "grid.cells": [120, 80],  # 0.1 L m: the same numerical problem in (x/L, t/L)
        "crowd.n": n,
        "crowd.initial": "groups",
        "crowd.groups": [{"region": room, "n": n}],
        "target.center": [end, 4.0 * s],
        "t_final": 400.0 * s,
    }
    return informed(builtin_scenarios()["bottleneck"](seed=seed).with_values(values), kind)


def informed(scenario: Scenario, kind: str) -> Scenario:
    """``scenario`` with the informed crowd on the fastest route at the scale ``kind`` (:data:`DOOR_MODEL` for
    agents)."""
    values: dict[str, Any] = {"crowd.kind": kind, "crowd.guidance": "fastest-route"}
    if kind == "point-mass":
        values["crowd.door_model"] = DOOR_MODEL
    return scenario.with_values(values)


def refined(scenario: Scenario, factor: int = PLAN_REFINEMENT) -> Scenario:
    """``scenario`` on cells ``factor`` times finer in each direction (its routes' and the density's)."""
    nx, ny = scenario.to_dict()["grid"]["cells"]
    return scenario.with_values({"grid.cells": [factor * int(nx), factor * int(ny)]})


def exit_times(scenario: Scenario, shares: tuple[float, ...] = SHARES) -> dict[str, Any]:
    """Run ``scenario``'s closed loop until ``max(shares)`` of the crowd is out; the time each share was out.

    Both scales report the share still in the plan (``remaining_fraction``); a share's time is the first step's
    end at which at most ``1 − share`` remains (NaN if the horizon came first).
    """
    from meanfield.simulation.loop import ClosedLoop

    start = time.perf_counter()
    loop = ClosedLoop(scenario)
    last = max(shares)
    times, left = [0.0], [1.0]
    while loop.t < scenario.t_final - 1e-9 and left[-1] > 1.0 - last:
        loop.step()
        times.append(loop.t)
        left.append(float(loop.crowd.remaining_fraction()))
    t, r = np.asarray(times), np.asarray(left)
    out = {}
    for q in shares:
        k = np.flatnonzero(r <= 1.0 - q + 1e-12)
        out[f"t{round(100 * q)}"] = float(t[k[0]]) if len(k) else math.nan
    return {**out, "people": scenario.crowd.n, "wall_seconds": time.perf_counter() - start}


def _run(job: tuple[dict[str, Any], dict[str, Any]]) -> dict[str, Any]:
    """One run (module level: runs in a worker process)."""
    scenario, labels = job
    return {**labels, **exit_times(Scenario.from_dict(scenario))}


def _flow(row: dict[str, Any]) -> float:
    """Persons/s between the exits of 10 % and 90 % of the crowd."""
    return 0.8 * row["people"] / (row["t90"] - row["t10"])


def _median(rows: list[dict[str, Any]], key: str) -> float:
    values = [_flow(r) if key == "J" else r[key] for r in rows]
    return float(np.median(values)) if values and all(np.isfinite(values)) else math.nan


def _gaps(agents: list[dict[str, Any]], density: dict[str, Any], keys: tuple[str, ...]) -> dict[str, float]:
    """``agents' median / density − 1`` for each of ``keys`` (``"J"`` the flow, else a time)."""
    out = {}
    for key in keys:
        d = _flow(density) if key == "J" else density[key]
        out[key] = _median(agents, key) / d - 1.0 if np.isfinite(d) and d > 0 else math.nan
    return out


def _limit_case(scale: float, cases: Any) -> str:
    """The case the limit reads at ``scale``: the judged bottleneck of :data:`LIMIT_WIDTH` at ``L = 1``."""
    at_one = f"bottleneck {LIMIT_WIDTH:g} m"
    return at_one if scale == 1 and at_one in cases else f"limit L={scale:g}"


def summarise(
    rows: list[dict[str, Any]], judged: dict[str, tuple[str, ...]], scales: tuple[float, ...]
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The judged cases and the limit from the runs' rows.

    Parameters
    ----------
    rows : list of dict
        One per run: ``case``, ``kind`` (``"agents"`` or ``"density"``), ``seed``, ``people`` and the times
        ``t10``, ``t50``, ``t90`` (s).
    judged : dict
        Case name → the figures judged there (``"t50"``, ``"t90"``, ``"J"``).
    scales : tuple of float
        The limit's ``L``, increasing (the case ``limit L=…``, or the judged bottleneck at ``L = 1``).

    Returns
    -------
    cases : list of dict
        Per judged case its ``gaps`` (``agents' median / density − 1`` per figure), the agents' median and
        worst seed, the density's figure and its verdict.
    limit : list of dict
        Per ``L`` the gaps of ``t10``, ``t50``, ``t90`` and the largest of them (``gap``), and both curves'
        times over ``L``.
    """

    def runs(case: str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
        mine = [r for r in rows if r["case"] == case]
        return [r for r in mine if r["kind"] == "agents"], next(r for r in mine if r["kind"] == "density")

    cases = []
    for case, keys in judged.items():
        agents, density = runs(case)
        gaps = _gaps(agents, density, keys)
        ok = all(abs(g) <= TOLERANCE for g in gaps.values())
        cases.append({"case": case, "verdict": "holds" if ok else "fails", "gaps": gaps,
                      "agents_median": {k: _median(agents, k) for k in keys},
                      "agents_worst_seed": {k: float(max(r[k] for r in agents)) for k in keys if k != "J"},
                      "density": {k: (_flow(density) if k == "J" else density[k]) for k in keys}})  # fmt: skip
    limit = []
    for scale in scales:
        agents, density = runs(_limit_case(scale, judged))
        gaps = _gaps(agents, density, tuple(f"t{round(100 * q)}" for q in SHARES))
        limit.append({"scale": scale, "people": density["people"], "gaps": gaps,
                      "gap": max(abs(g) for g in gaps.values()),
                      "agents_median_over_L": {k: _median(agents, k) / scale for k in gaps},
                      "density_over_L": {k: density[k] / scale for k in gaps}})  # fmt: skip
    return cases, limit


def two_scales_verdict(
    case_gaps: list[dict[str, float]], limit_gaps: list[float], tolerance: float = TOLERANCE
) -> tuple[str, str]:
    """The decision rule of :func:`check_two_scales`.

    Parameters
    ----------
    case_gaps : list of dict
        Per case (a width, a plan), its relative gaps ``agents/density − 1`` by figure.
    limit_gaps : list of float
        The limit's gap at each scale ``L``, in increasing ``L``.
    tolerance : float
        The largest ``|gap|`` a case may have.

    Returns
    -------
    verdict : {"holds", "fails", "inconclusive"}
        ``"inconclusive"`` when a figure is missing (a run that did not get its crowd out in its horizon) or fewer
        than two scales were run.
    reason : str
        Which figure decided.
    """
    values = [g for case in case_gaps for g in case.values()]
    if not all(np.isfinite(values)) or not all(np.isfinite(limit_gaps)):
        return "inconclusive", "a run did not get the share it was timed at out before its horizon"
    if len(limit_gaps) < 2:
        return "inconclusive", "the limit needs at least two scales"
    worst = max((abs(g) for g in values), default=0.0)
    falls = bool(np.all(np.diff(limit_gaps) < 0))
    if worst <= tolerance and falls:
        return "holds", ""
    reasons = []
    if worst > tolerance:
        reasons.append(f"a gap of {worst:.1%} beyond {tolerance:.0%}")
    if not falls:
        reasons.append("the gap does not fall as L grows: " + ", ".join(f"{g:.1%}" for g in limit_gaps))
    return "fails", "; ".join(reasons)


def _plot(limit: list[dict[str, Any]], cases: list[dict[str, Any]], path: Path) -> None:
    from matplotlib.figure import Figure

    from analysis.figures import save_figure

    fig = Figure(figsize=(11.0, 4.0))
    ax, bx = fig.subplots(1, 2)
    names = [c["case"] for c in cases]
    x = np.arange(len(cases))
    for k, key in enumerate(("t50", "t90", "J")):
        values = [100 * c["gaps"].get(key, math.nan) for c in cases]
        ax.bar(x + (k - 1) * 0.27, values, width=0.27, label=key)
    ax.axhspan(-100 * TOLERANCE, 100 * TOLERANCE, color="0.9", zorder=0, label=f"±{TOLERANCE:.0%}")
    ax.set_xticks(x, names, rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("agents (median) / density − 1 (%)")
    ax.set_title("Agents against the density", fontsize=10)
    ax.legend(fontsize=7)
    scales = [r["scale"] for r in limit]
    bx.plot(scales, [100 * r["gap"] for r in limit], "o-")
    bx.set_xscale("log", base=2)
    bx.set_xlabel("L (the room's lengths × L, N = 200 L²)")
    bx.set_ylabel("largest |t_q agents / t_q density − 1| (%)")
    bx.set_title(f"The limit: the bottleneck of {LIMIT_WIDTH:g} m scaled", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def check_two_scales(
    scenario: Scenario, out_dir: Path, *, quick: bool = False, progress: bool = False, workers: int | None = None
) -> CheckResult:
    """Run the bottleneck, the plans and the scaled bottleneck at both scales; judge (module docstring).

    Parameters
    ----------
    scenario : Scenario
        Unused: the claim is about the toolkit's congested crowd on its own plans (``measured.settings``).
    out_dir : Path
        Report directory (figure ``figures/two_scales.png``).
    quick : bool
        The bottleneck at :data:`QUICK_WIDTHS`, no plan, the limit at :data:`QUICK_SCALES`, seeds
        :data:`QUICK_SEEDS` (else :data:`FULL_WIDTHS`, :data:`FULL_PLANS`, :data:`FULL_SCALES`, :data:`FULL_SEEDS`);
        the limit beyond ``L = 1`` on :data:`LIMIT_SEEDS`.
    progress : bool
        A progress bar over the runs.
    workers : int or None
        Processes for the runs (None: one per core).
    """
    start = time.perf_counter()
    widths, plans = (QUICK_WIDTHS, QUICK_PLANS) if quick else (FULL_WIDTHS, FULL_PLANS)
    scales, seeds = (QUICK_SCALES, QUICK_SEEDS) if quick else (FULL_SCALES, FULL_SEEDS)
    setups: dict[str, tuple[Any, tuple[str, ...]]] = {}  # case -> (scenario at a seed, figures judged)
    for b in widths:
        setups[f"bottleneck {b:g} m"] = ((lambda kind, s, b=b: bottleneck(b, 1, kind, s)), ("t50", "t90", "J"))
    for name in plans:
        setups[name] = ((lambda kind, s, name=name: refined(informed(builtin_scenarios()[name](seed=s), kind))),
                        ("t50", "t90"))  # fmt: skip
    for scale in scales:
        if _limit_case(scale, setups) not in setups:
            setups[_limit_case(scale, setups)] = ((lambda kind, s, L=scale: bottleneck(LIMIT_WIDTH, L, kind, s)), ())
    jobs = []
    for case, (make, _) in setups.items():
        jobs.append((make("fokker-planck", 0).to_dict(), {"case": case, "kind": "density", "seed": 0}))
        mine = LIMIT_SEEDS if case.startswith("limit") else seeds
        jobs += [(make("point-mass", s).to_dict(), {"case": case, "kind": "agents", "seed": s}) for s in mine]
    rows = map_jobs(_run, jobs, workers, "two scales (runs)", progress)
    cases, limit = summarise(rows, {case: keys for case, (_, keys) in setups.items() if keys}, scales)
    verdict, reason = two_scales_verdict([c["gaps"] for c in cases], [r["gap"] for r in limit])
    figdir = out_dir / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    _plot(limit, cases, figdir / "two_scales.png")
    worst = max(cases, key=lambda c: max(abs(g) for g in c["gaps"].values()))
    worst_key = max(worst["gaps"], key=lambda k: abs(worst["gaps"][k]))
    summary = (
        f"largest gap {worst['gaps'][worst_key]:+.1%} ({worst['case']}, {worst_key}); the limit's gap "
        + " → ".join(f"{r['gap']:.1%}" for r in limit)
        + " at L = "
        + ", ".join(f"{r['scale']:g}" for r in limit)
    )
    return CheckResult(
        key=KEY,
        claim=CLAIM,
        verdict=verdict,  # type: ignore[arg-type]
        reason=reason,
        summary=summary,
        measured={
            "limit": limit,
            "settings": {
                "door_model": DOOR_MODEL,
                "plan_refinement": PLAN_REFINEMENT,
                "guidance": "fastest-route",
                "seeds": list(seeds),
                "widths": list(widths),
                "plans": list(plans),
                "scales": list(scales),
                "limit_width": LIMIT_WIDTH,
            },
        },
        bound={"tolerance": TOLERANCE},
        criterion=CRITERION,
        cases=cases,
        figures=["figures/two_scales.png"],
        seconds=time.perf_counter() - start,
    )
