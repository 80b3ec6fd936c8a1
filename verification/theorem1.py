"""Theorem 1 (paper: Theorem "step I convergence"): with ``v_r ≡ v_d``, ``V₁ = ∫ρ̃²`` decays exponentially.

The claim: ``dV₁/dt = −2∫α|∇ρ̃|² ≤ −k_p V₁`` with ``k_p = 2 α_inf μ₂``, hence
``V₁(t) ≤ V₁(0) e^{−k_p t}``.  The check runs the Fokker–Planck plant under the sampled
Step-I feedback (:func:`~verification.plant.fokker_planck_trajectory`) for the scenario's α
schedule and, when that schedule is density dependent, for a constant ``α = α₀`` too (the
simplest gain the theorem allows, and the only one with a non-vanishing ``α_inf``).  For
constant α it also integrates the controller's exact semi-discrete model
(:func:`~verification.plant.model_trajectory`), a linear heat equation for ρ̃, to see
whether ρ stays positive — the theorem divides by ρ.

Any connected Ω will do, convex or not (a floor plan with re-entrant corners and pillars):
the proof needs the Poincaré–Wirtinger inequality, and μ₂ is computed on the scenario's
own cut-cell grid.  Two hypotheses are checked first (:mod:`verification.hypotheses`):
the grid keeps Ω in one piece, else the verdict is ``inconclusive``; and no exits.  With
exits the mass is not conserved, the claim does not apply (``inconclusive``), and the
plant with the exits' outflow is run and reported, not judged (``docs/verification.md``,
*Floor plans and exits*).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from analysis.poincare import neumann_eigenvalue
from analysis.rates import decay_rate
from meanfield.controllers.alpha_schedules import ConstantAlpha
from meanfield.crowds.density_crowd import initial_density
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.interfaces import AlphaSchedule
from meanfield.io.atomic import save_figure, subplots
from meanfield.scenarios.scenario import Scenario
from meanfield.simulation.assembly import assemble
from verification.hypotheses import disconnected_reason, exits_reason, hypotheses
from verification.plant import Trajectory, exit_sink, fokker_planck_trajectory, model_trajectory
from verification.result import CheckResult, worst

__all__ = ["CLAIM", "alpha_cases", "check_theorem1", "exponential_verdict", "fitted_rate", "feedback_step"]

CLAIM = (
    "Theorem 1: with v_r ≡ v_d (and v_a ≡ 0), V₁ = ∫ρ̃² decays exponentially, "
    "dV₁/dt = −2∫α|∇ρ̃|² ≤ −k_p V₁ with k_p = 2 α_inf μ₂."
)
RTOL = 1e-6
"""Relative slack for round-off in the comparison ``V₁(t) ≤ V₁(0) e^{−k_p t}``."""
VACUOUS = 0.01
"""A bound is called vacuous when ``k_p T`` is below this: it allows ``V₁`` to lose < 1 %."""


def fitted_rate(t: np.ndarray, V: np.ndarray) -> float:
    """Least-squares rate ``k`` of ``V ≈ C e^{−k t}`` over the samples where ``V > 0``."""
    ok = V > 0
    if ok.sum() < 2:
        return float("nan")
    return float(-np.polyfit(t[ok], np.log(V[ok]), 1)[0])


def exponential_verdict(t: np.ndarray, V: np.ndarray, k_p: float, rtol: float = RTOL) -> tuple[str, dict[str, Any]]:
    """Decide ``V(t) ≤ V(0) e^{−k_p t}`` and monotone decrease on a recorded trajectory.

    Returns the verdict (``"holds"`` when both are met, else ``"fails"``) and the figures:
    the worst ratio ``V(t) / (V(0) e^{−k_p t})``, where it occurs, the largest rise of V
    between records, the fitted rate and whether the bound is vacuous (``k_p T < 0.01``).
    """
    bound = V[0] * np.exp(-k_p * (t - t[0]))
    ratio = V / np.maximum(bound, np.finfo(float).tiny)
    i = int(np.argmax(ratio))
    rise = float(np.max(np.diff(V))) if len(V) > 1 else 0.0
    monotone = rise <= rtol * V[0]
    holds = bool(ratio[i] <= 1 + rtol and monotone)
    return ("holds" if holds else "fails"), {
        "worst_ratio_to_bound": float(ratio[i]),
        "worst_ratio_time": float(t[i]),
        "largest_rise": rise,
        "monotone": bool(monotone),
        "fitted_rate": fitted_rate(t, V),
        "k_p": k_p,
        "vacuous": bool(k_p * (t[-1] - t[0]) < VACUOUS),
    }


def feedback_step(h: float, alpha_max: float, dt_max: float) -> float:
    """Step of the sampled Step-I feedback: ``0.9 h²/(4 α_max)``, at most ``dt_max``.

    Holding ``v_d(ρⁿ)`` over a step is an explicit step of the closed-loop diffusion
    ``∇·(α∇ρ̃)``; beyond this step the held feedback overshoots (V₁ grows on the paper's
    grid at ``dt = 0.01``).
    """
    return min(dt_max, 0.9 * h * h / (4.0 * alpha_max))


def alpha_cases(scenario: Scenario, schedule: AlphaSchedule) -> list[tuple[str, AlphaSchedule]]:
    """The α schedules Theorems 1 and 2 are checked with: the scenario's, and constant ``α₀``
    when the scenario's depends on ρ (the one gain with a non-vanishing ``α_inf``)."""
    c = scenario.controller
    cases = [(f"scenario α ({c.alpha_schedule}, α₀={c.alpha:g})", schedule)]
    if c.alpha_schedule != "constant":
        cases.append((f"constant α = {c.alpha:g}", ConstantAlpha(c.alpha)))
    return cases


def _case(label: str, traj: Trajectory, mu2: float, plant: str, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    alpha_inf = float(traj.alpha_min.min())
    k_p = decay_rate(alpha_inf, mu2) if alpha_inf > 0 else 0.0
    verdict, figures = exponential_verdict(traj.t, traj.V1, k_p)
    identity = np.abs(traj.dV1_dt + 2 * traj.dissipation)
    out = {
        "case": label,
        "plant": plant,
        "verdict": verdict,
        "alpha_inf": alpha_inf,
        "mu2_discrete": mu2,
        **figures,
        "V1_initial": float(traj.V1[0]),
        "V1_final": float(traj.V1[-1]),
        "rho_min": float(traj.rho_min.min()),
        "identity_mismatch": float(identity.max() / max(2 * traj.dissipation.max(), 1e-300)),
        "t_final": float(traj.t[-1]),
    }
    stopped = traj.info.get("stopped")
    if stopped:  # the theorem assumes ρ > 0: judged only up to there, and a bound kept there is no proof
        out["stopped"] = stopped
        if verdict == "holds":
            out["verdict"], out["reason"] = "inconclusive", f"{stopped}; the bound held until then"
    out.update(extra or {})
    return out


def _figure(path: Path, series: list[tuple[str, Trajectory, float]]) -> None:
    fig, ax = subplots(1, 2, figsize=(10, 3.8))
    for label, tr, k_p in series:
        (line,) = ax[0].semilogy(tr.t, tr.V1, label=f"{label}: V₁")
        bound = tr.V1[0] * np.exp(-k_p * tr.t)
        ax[0].semilogy(tr.t, bound, "--", color=line.get_color(), label=f"bound, k_p={k_p:.3g}")
        ax[1].plot(tr.t, -tr.dV1_dt, color=line.get_color(), label=f"{label}: −dV₁/dt")
        ax[1].plot(tr.t, 2 * tr.dissipation, ":", color=line.get_color(), label="2∫α|∇ρ̃|²")
    ax[0].set_xlabel("t (scenario time unit)")
    ax[0].set_title("V₁ = ∫ρ̃² against V₁(0)e^{−k_p t}")
    ax[0].set_ylabel("V₁ (log scale)")
    ax[0].legend(fontsize=7)
    ax[1].set_xlabel("t (scenario time unit)")
    ax[1].set_yscale("log")
    ax[1].set_title("dissipation identity")
    ax[1].set_ylabel("−dV₁/dt and 2∫α|∇ρ̃|²")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def check_theorem1(
    scenario: Scenario, out_dir: Path, *, quick: bool = False, progress: bool = False, workers: int | None = None
) -> CheckResult:
    """Check Theorem 1 on the scenario's domain, grid, σ, target and α schedule.

    Parameters
    ----------
    scenario : Scenario
    out_dir : Path
        The report directory; the figure goes to ``out_dir/figures/theorem1.png``.
    quick : bool
        Horizon 1.5 (else 4) time units.
    progress, workers
        Unused (the check is one process and a few seconds).
    """
    start = time.perf_counter()
    parts = assemble(scenario, crowd="fokker-planck", controller="backstepping")  # the PDE plant's parts
    grid, ctrl = parts.grid, parts.controller
    hyp = hypotheses(grid)
    split = disconnected_reason(hyp, grid.cells)
    if split is not None:
        return CheckResult.inconclusive(
            "theorem1", CLAIM, split, measured={"hypotheses": hyp.to_dict()}, seconds=time.perf_counter() - start
        )
    mu2 = neumann_eigenvalue(grid)
    rho0 = initial_density(scenario, grid)
    t_final = 1.5 if quick else 4.0
    h = min(grid.dx, grid.dy)
    c = scenario.controller
    sink = exit_sink(grid, ctrl.sigma)
    plant = "Fokker–Planck (Scharfetter–Gummel, sampled v_d" + (", exits' outflow)" if sink else ")")
    schedules = alpha_cases(scenario, ctrl.alpha)
    cases, series = [], []
    for label, schedule in schedules:
        ctrl.alpha = schedule
        dt = feedback_step(h, c.alpha, scenario.dt)
        fp = FokkerPlanck(grid, ctrl.sigma, method="split", interaction=ctrl.interaction, exits=False)  # the sink below
        every = max(1, int(round(0.02 / dt)))
        traj = fokker_planck_trajectory(ctrl, fp, rho0, t_final, dt, record_every=every, sink=sink)
        case = _case(label, traj, mu2, plant, {"dt": dt})
        if sink is not None:
            out = float(1.0 - traj.mass[-1] / traj.mass[0])
            case.update(
                verdict="inconclusive",
                reason=f"mass not conserved: {out:.2%} of the crowd left through the exits",
                mass_out=out,
                V1_floor_final=float((traj.mass[0] - traj.mass[-1]) ** 2 / grid.area),
            )
        cases.append(case)
        series.append((label, traj, case["k_p"]))
        if isinstance(schedule, ConstantAlpha) and sink is None and len(traj.t) > 1:  # the model has no exits
            model = model_trajectory(ctrl, rho0, traj.t)
            m = _case(label, model, mu2, "semi-discrete model (central fluxes, exact substitution)")
            m["positive"] = bool(m["rho_min"] > 0)
            if not m["positive"]:
                m["note"] = "ρ leaves the positive cone: v_d = −(α∇ρ̃ − ∇(σρ))/ρ is undefined on the way"
            cases.append(m)
    ctrl.alpha = schedules[0][1]
    figdir = out_dir / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    _figure(figdir / "theorem1.png", series)
    verdict = worst([k["verdict"] for k in cases if k["plant"].startswith("Fokker")])
    first = cases[0]
    reason = "; ".join(dict.fromkeys(k["reason"] for k in cases if k["verdict"] == "inconclusive"))
    parts = []
    if sink is not None:
        reason = exits_reason(first["mass_out"], float(series[0][1].t[-1]))
        parts.append(f"not applicable: {reason}; reported, not judged")
    elif not hyp.convex:
        parts.append(f"Ω not convex ({hyp.region}): μ₂ = {mu2:.4g} of its cut-cell grid")
    for k in cases:
        vac = " (vacuous bound)" if k["vacuous"] else ""
        gone = f", mass out {k['mass_out']:.2%}" if "mass_out" in k else ""
        parts.append(
            f"{k['case']}, {k['plant'].split(' (')[0]}: {k['verdict']}{vac}, fitted rate {k['fitted_rate']:.3g} "
            f"vs k_p {k['k_p']:.3g}, worst V₁/bound {k['worst_ratio_to_bound']:.3g}, min ρ {k['rho_min']:.2g}{gone}"
        )
    return CheckResult(
        key="theorem1",
        claim=CLAIM,
        verdict=verdict,
        summary="; ".join(parts),
        reason=reason,
        measured={
            "fitted_rate": first["fitted_rate"],
            "worst_ratio_to_bound": first["worst_ratio_to_bound"],
            "cases": len(cases),
            "hypotheses": hyp.to_dict(),
            **({"mass_out": first["mass_out"]} if sink is not None else {}),
        },
        bound={"k_p": first["k_p"], "alpha_inf": first["alpha_inf"], "mu2_discrete": mu2},
        criterion=(
            "On the Fokker–Planck plant under the sampled feedback v_r = v_d(ρⁿ): holds when "
            f"V₁(t) ≤ V₁(0)e^{{−k_p t}}(1 + {RTOL:g}) at every record and V₁ never rises, with k_p = 2 α_inf μ₂ "
            "(α_inf the smallest face gain along the run, μ₂ the discrete Neumann eigenvalue of the grid, on any "
            "connected Ω, convex or not); the verdict is the worst over the α cases. The semi-discrete model is "
            "reported, not judged. Inconclusive when the grid splits Ω into pieces, or when Ω has exits (mass is "
            "not conserved; the plant with the exits' outflow is then reported, not judged)."
        ),
        cases=cases,
        figures=["figures/theorem1.png"],
        seconds=time.perf_counter() - start,
    )
