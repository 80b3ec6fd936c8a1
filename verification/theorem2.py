"""Theorem 2 (paper: Theorem "step I ISS"): ``‖ρ̃‖`` is input-to-state stable to ``‖ṽ + v_a‖``.

With ``v_r = v_d + ṽ`` and a disturbance ``v_a`` (``w = ṽ + v_a``), the proof (see
:mod:`analysis.rates`) gives, for every ``c₁ ∈ (0, 1)``,

    ‖ρ̃(t)‖ ≤ max( ‖ρ̃₀‖ e^{−(1−c₁) α_inf μ₂ t},  sup ρ · sup‖w‖ / (c₁ √μ₂ α_inf) ),

so the bound held against the run is the smallest of these over a grid of ``c₁`` — a
valid ``β(‖ρ̃₀‖, t) + γ sup‖w‖`` at every ``t``.  ``α_inf`` and ``sup ρ`` are taken along
the run, as the theorem's constants are.  The plant is the Fokker–Planck solver under
the sampled feedback ``v_d(ρⁿ) + w``; the default ``ṽ`` is a persistent uniform drift
pointing away from the target (it fights the controller everywhere), plus the
scenario's own ``v_a``.

Any connected Ω will do, convex or not (μ₂ of the scenario's cut-cell grid; a grid that
splits Ω into pieces gives ``inconclusive``).  **With exits** the claim does not apply as
stated: mass leaves, the Poincaré–Wirtinger step needs ``∫ρ̃ = 0``, and even ``w = 0``,
``ρ₀ = ρ_*`` leaves ``ρ_*`` when ρ_* does not vanish on the exits.  What the same proof
still gives, and what is then judged, treats the outflow as an input: with ``E = −kρ``
the exits' outflow (:class:`~meanfield.geometry.exits.ExitSink`),
``½ d‖ρ̃‖²/dt ≤ −α_inf‖∇ρ̃‖² − ⟨ρ̃, kρ̃⟩ + sup ρ ‖w‖ ‖∇ρ̃‖ + ‖kρ_*‖ ‖ρ̃‖``, and the
exits' outflow makes ``α_inf‖∇u‖² + ⟨u, ku⟩ ≥ λ_E‖u‖²`` with no mean-zero condition
(:func:`analysis.rates.exit_eigenvalue`).  Hence, for every ``c₁ ∈ (0, 1)``,

    ‖ρ̃(t)‖ ≤ max( ‖ρ̃₀‖ e^{−(1−c₁) λ_E t},  (sup ρ sup‖w‖/√α_inf + ‖kρ_*‖/√λ_E) / (c₁ √λ_E) ),

the paper's bound with ``α_inf μ₂ → λ_E`` and the target's own outflow ``‖kρ_*‖`` as a
second input (:func:`iss_bound_with_exits`; ``docs/verification.md``, *Floor plans and
exits*).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from analysis.poincare import neumann_eigenvalue
from analysis.rates import exit_eigenvalue
from meanfield.crowds.density_crowd import initial_density
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.grid import FaceField, Grid
from meanfield.io.atomic import save_figure, subplots
from meanfield.scenarios.scenario import Scenario
from meanfield.simulation.assembly import assemble, disturbance_for
from verification.hypotheses import disconnected_reason, exits_reason, hypotheses
from verification.plant import Trajectory, exit_sink, fokker_planck_trajectory
from verification.result import CheckResult, worst
from verification.theorem1 import alpha_cases, feedback_step

__all__ = ["CLAIM", "DEFAULT_SPEED", "check_theorem2", "iss_bound", "iss_bound_with_exits", "away_from_target"]

CLAIM = "Theorem 2: with v_r = v_d + ṽ and a disturbance v_a, ‖ρ̃‖ is ISS to ‖ṽ + v_a‖ (given sup ρ < ∞)."
DEFAULT_SPEED = 0.05
"""Speed of the default persistent ``ṽ`` (a quarter of the paper scenario's kernel strength)."""
C1_GRID = np.linspace(0.02, 0.98, 49)


def iss_bound(
    t: np.ndarray, rho0_error: float, sup_w: float, sup_rho: float, alpha_inf: float, mu2: float
) -> np.ndarray:
    """Theorem 2's bound ``min_{c₁} max(‖ρ̃₀‖e^{−(1−c₁)α_inf μ₂ t}, sup ρ sup‖w‖/(c₁√μ₂ α_inf))``.

    Each ``c₁`` gives a valid bound, so their minimum is one; ``inf`` when ``α_inf = 0``.
    """
    t = np.asarray(t, float)
    if alpha_inf <= 0:
        return np.full(t.shape, math.inf)
    c1 = C1_GRID[:, None]
    transient = rho0_error * np.exp(-(1 - c1) * alpha_inf * mu2 * t[None, :])
    ultimate = sup_rho * sup_w / (c1 * math.sqrt(mu2) * alpha_inf)
    return np.maximum(transient, ultimate).min(axis=0)


def iss_bound_with_exits(
    t: np.ndarray,
    rho0_error: float,
    sup_w: float,
    sup_rho: float,
    alpha_inf: float,
    lam: float,
    target_outflow: float,
) -> np.ndarray:
    """With exits: ``min_{c₁} max(‖ρ̃₀‖e^{−(1−c₁)λ_E t}, (sup ρ sup‖w‖/√α_inf + ‖kρ_*‖/√λ_E)/(c₁√λ_E))``.

    ``lam`` is ``λ_E`` (:func:`analysis.rates.exit_eigenvalue` at ``α_inf``) and
    ``target_outflow`` is ``‖kρ_*‖``; with ``target_outflow = 0`` and ``λ_E = α_inf μ₂`` it
    is :func:`iss_bound`.  ``inf`` when ``α_inf = 0`` or ``λ_E = 0``.
    """
    t = np.asarray(t, float)
    if alpha_inf <= 0 or lam <= 0:
        return np.full(t.shape, math.inf)
    c1 = C1_GRID[:, None]
    transient = rho0_error * np.exp(-(1 - c1) * lam * t[None, :])
    ultimate = (sup_rho * sup_w / math.sqrt(alpha_inf) + target_outflow / math.sqrt(lam)) / (c1 * math.sqrt(lam))
    return np.maximum(transient, ultimate).min(axis=0)


def away_from_target(grid: Grid, target_center: tuple[float, float], speed: float) -> Callable[[float], FaceField]:
    """A uniform drift of the given speed from ρ_*'s centre towards Ω's centre, on the faces."""
    x0, x1, y0, y1 = grid.domain.bounds
    d = np.array([(x0 + x1) / 2 - target_center[0], (y0 + y1) / 2 - target_center[1]])
    n = float(np.hypot(*d))
    d = d / n if n > 0 else np.array([-1.0, 0.0])
    fx = np.full((grid.shape[0] - 1, grid.shape[1]), speed * d[0])
    fy = np.full((grid.shape[0], grid.shape[1] - 1), speed * d[1])
    return lambda t: (fx, fy)


def _faces(grid: Grid, v_a: Callable, t: float) -> FaceField:
    (xx, xy), (yx, yy) = grid.face_points_x, grid.face_points_y
    return np.asarray(v_a(xx, xy, t)[0], float), np.asarray(v_a(yx, yy, t)[1], float)


def _figure(path: Path, series: list[tuple[str, Trajectory, np.ndarray]]) -> None:
    fig, ax = subplots(figsize=(6.5, 3.8))
    for label, tr, bound in series:
        (line,) = ax.semilogy(tr.t, tr.rho_error, label=f"{label}: ‖ρ̃‖")
        if np.isfinite(bound).all():
            ax.semilogy(tr.t, bound, "--", color=line.get_color(), label="ISS bound")
    ax.set_xlabel("t (scenario time unit)")
    ax.set_title("‖ρ̃(t)‖ against β(‖ρ̃₀‖, t) + γ sup‖ṽ + v_a‖")
    ax.set_ylabel("‖ρ̃‖ (L², log scale)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def check_theorem2(
    scenario: Scenario,
    out_dir: Path,
    *,
    quick: bool = False,
    progress: bool = False,
    workers: int | None = None,
    v_tilde: Callable[[float], FaceField] | None = None,
    speed: float = DEFAULT_SPEED,
) -> CheckResult:
    """Check Theorem 2 under a persistent ``ṽ`` and the scenario's ``v_a``.

    Parameters
    ----------
    scenario : Scenario
    out_dir : Path
        Report directory (figure ``figures/theorem2.png``).
    quick : bool
        Horizon 1.5 (else 4).
    v_tilde : callable, optional
        ``ṽ(t)`` on the grid's faces; default :func:`away_from_target` at ``speed``.
    speed : float
        Speed of the default ``ṽ``.
    """
    start = time.perf_counter()
    parts = assemble(scenario, crowd="fokker-planck", controller="backstepping")  # the PDE plant's parts
    grid, ctrl = parts.grid, parts.controller
    hyp = hypotheses(grid)
    split = disconnected_reason(hyp, grid.cells)
    if split is not None:
        return CheckResult.inconclusive(
            "theorem2", CLAIM, split, measured={"hypotheses": hyp.to_dict()}, seconds=time.perf_counter() - start
        )
    mu2 = neumann_eigenvalue(grid)
    sink = exit_sink(grid, ctrl.sigma)
    target_outflow = 0.0 if sink is None else grid.norm(sink.total_rate * ctrl.target)
    rho0 = initial_density(scenario, grid)
    t_final = 1.5 if quick else 4.0
    vt = v_tilde if v_tilde is not None else away_from_target(grid, scenario.target.center, speed)
    v_a = disturbance_for(scenario)

    def w(t: float) -> FaceField:
        a = vt(t)
        if v_a is None:
            return a
        b = _faces(grid, v_a, t)
        return a[0] + b[0], a[1] + b[1]

    c = scenario.controller
    schedules = alpha_cases(scenario, ctrl.alpha)
    cases: list[dict[str, Any]] = []
    series = []
    for label, schedule in schedules:
        ctrl.alpha = schedule
        dt = feedback_step(min(grid.dx, grid.dy), c.alpha, scenario.dt)
        fp = FokkerPlanck(grid, ctrl.sigma, method="split", interaction=ctrl.interaction, exits=False)  # the sink below
        every = max(1, int(round(0.02 / dt)))
        traj = fokker_planck_trajectory(ctrl, fp, rho0, t_final, dt, w=w, record_every=every, sink=sink)
        alpha_inf = float(traj.alpha_min.min())
        sup_rho = float(traj.rho_max.max())
        sup_w = float(traj.w_norm.max())
        err = traj.rho_error
        extra: dict[str, Any] = {}
        if sink is None:
            bound = iss_bound(traj.t, float(err[0]), sup_w, sup_rho, alpha_inf, mu2)
            gain = sup_rho / (math.sqrt(mu2) * alpha_inf) if alpha_inf > 0 else math.inf
            ultimate = gain * sup_w
        else:  # the outflow as a second input, λ_E in place of α_inf μ₂
            lam = exit_eigenvalue(grid, alpha_inf, sink.total_rate) if alpha_inf > 0 else 0.0
            bound = iss_bound_with_exits(traj.t, float(err[0]), sup_w, sup_rho, alpha_inf, lam, target_outflow)
            gain = sup_rho / math.sqrt(lam * alpha_inf) if lam > 0 else math.inf
            ultimate = gain * sup_w + (target_outflow / lam if lam > 0 else math.inf)
            extra = {
                "lambda_E": lam,
                "alpha_inf_mu2": alpha_inf * mu2,
                "target_outflow": target_outflow,
                "mass_out": float(1.0 - traj.mass[-1] / traj.mass[0]),
                "rho_error_floor_final": float((traj.mass[0] - traj.mass[-1]) / math.sqrt(grid.area)),
            }
        ratio = err / bound
        i = int(np.argmax(ratio))
        verdict = "holds" if ratio[i] <= 1 + 1e-9 else "fails"
        stopped = traj.info.get("stopped")
        if stopped:  # the theorem assumes ρ > 0
            extra["stopped"] = stopped
            if verdict == "holds":
                verdict, extra["reason"] = "inconclusive", f"{stopped}; the bound held until then"
        cases.append(
            {
                "case": label,
                "verdict": verdict,
                "worst_ratio_to_bound": float(ratio[i]),
                "worst_ratio_time": float(traj.t[i]),
                "rho_error_initial": float(err[0]),
                "rho_error_final": float(err[-1]),
                "rho_error_max": float(err.max()),
                "sup_w": sup_w,
                "sup_rho": sup_rho,
                "alpha_inf": alpha_inf,
                "iss_gain_c1_to_1": gain,
                "ultimate_bound_c1_to_1": ultimate,
                "vacuous": bool(bound[-1] >= err[0]),  # the bound allows no decrease at all over the run
                "dt": dt,
                "t_final": t_final,
                **extra,
            }
        )
        series.append((label, traj, bound))
    ctrl.alpha = schedules[0][1]
    figdir = out_dir / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    _figure(figdir / "theorem2.png", series)
    first = cases[0]
    summary = "; ".join(
        f"{k['case']}: {k['verdict']}{' (vacuous bound)' if k['vacuous'] else ''}, worst ‖ρ̃‖/bound "
        f"{k['worst_ratio_to_bound']:.3g}, final ‖ρ̃‖ {k['rho_error_final']:.3g} vs ultimate "
        f"{k['ultimate_bound_c1_to_1']:.3g}"
        + (f", λ_E {k['lambda_E']:.3g}, mass out {k['mass_out']:.2%}" if sink else "")
        for k in cases
    )
    verdict = worst([k["verdict"] for k in cases])
    reason = "; ".join(dict.fromkeys(k["reason"] for k in cases if k["verdict"] == "inconclusive"))
    if sink is not None:  # the paper's claim does not apply; its corollary with the outflow as an input was judged
        reason = exits_reason(first["mass_out"], float(series[0][1].t[-1])) + (f"; {reason}" if reason else "")
        vacuous = all(k["vacuous"] for k in cases)
        vacuous = " — vacuous in every α case: on this run it could not fail" if vacuous else ""
        summary = (
            f"not applicable as stated: {reason}. Judged instead, ISS to (‖ṽ + v_a‖, the target's outflow "
            f"‖kρ_*‖ = {target_outflow:.3g}) with rate λ_E: {verdict}{vacuous}; " + summary
        )
        verdict = worst([verdict, "inconclusive"])
    elif not hyp.convex:
        summary = f"Ω not convex ({hyp.region}): μ₂ = {mu2:.4g} of its cut-cell grid; " + summary
    return CheckResult(
        key="theorem2",
        claim=CLAIM,
        verdict=verdict,
        summary=summary,
        reason=reason,
        measured={
            "worst_ratio_to_bound": first["worst_ratio_to_bound"],
            "rho_error_final": first["rho_error_final"],
            "hypotheses": hyp.to_dict(),
        },
        bound={
            "iss_gain": first["iss_gain_c1_to_1"],
            "sup_w": first["sup_w"],
            "ultimate_bound": first["ultimate_bound_c1_to_1"],
            "v_tilde": "user" if v_tilde is not None else f"uniform drift away from the target, speed {speed:g}",
            "v_a": "scenario" if v_a is not None else "none",
            **({"lambda_E": first["lambda_E"], "target_outflow": target_outflow} if sink is not None else {}),
        },
        criterion=(
            "On the Fokker–Planck plant under v_r = v_d(ρⁿ) + ṽ + v_a: holds when ‖ρ̃(t)‖ stays below "
            "min over c₁ ∈ [0.02, 0.98] of max(‖ρ̃₀‖e^{−(1−c₁)α_inf μ₂ t}, sup ρ sup‖ṽ+v_a‖/(c₁√μ₂ α_inf)) at "
            "every record (α_inf, sup ρ along the run, μ₂ discrete, any connected Ω); worst over the α cases. "
            "With exits the claim is inconclusive (mass not conserved) and its corollary is judged on the plant with "
            "the exits' outflow: α_inf μ₂ → λ_E (α_inf‖∇u‖² + ⟨u, ku⟩ ≥ λ_E‖u‖²) and sup ρ sup‖w‖/√α_inf + "
            "‖kρ_*‖/√λ_E in place of sup ρ sup‖w‖/√α_inf; a failure of the corollary makes the verdict fails."
        ),
        cases=cases,
        figures=["figures/theorem2.png"],
        seconds=time.perf_counter() - start,
    )
