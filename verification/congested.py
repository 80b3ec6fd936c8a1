"""Steps I and II on the congested plant: the law that tracks ``v_d/g`` against the paper's law.

A congested crowd walks at ``g(Nρ)`` times the robots' field (docs page *Congestion*)::

    ∂_t ρ = −∇·(ρ g(Nρ) v_r + ρ u_W) + Δ(σρ).

Step I is unchanged; the robots must make the crowd *walk* at ``v_d``, so Step II tracks
``v_d/ĝ``, ``ĝ = max(g, g_min)`` (:class:`~meanfield.controllers.backstepping.CongestedPlant`,
``controller.congestion = "compensate"``).  On the law's semi-discrete model (central fluxes)::

    v_r = v_d/ĝ:   dV₁/dt = −2(∫α|∇ρ̃|² − J)                                          (I)
    robot law:     dV₂/dt = −(∫α|∇ρ̃|² − J) − Σk_u|b_i|² − Σk_ω g_i²                    (II)

with ``J = ⟨∇ρ̃, ρ_f (g/ĝ − 1) v_d⟩``, zero wherever ``g ≥ g_min`` (docs page *Verification*,
"Steps I and II on the congested plant").  The paper's law (``"ignore"``) claims (I) and (II)
with ``J = 0`` and ``ĝ = 1``; on this plant it misses ``⟨∇ρ̃, ρ_f (g − 1) v_r⟩`` in both.

The check runs, for each law, the closed loop of the robot law on the toolkit's congested
Fokker–Planck solver (Godunov's LWR flux, :mod:`meanfield.fokker_planck.congested`; one step per
control period, robots without limits: the theorems' hypothesis) on a reference plant, and at
every recorded state it evaluates

* (I) and (II) along the law's own model (central congested fluxes, the applied inputs), held
  to round-off (:data:`IDENTITY_RTOL`): the derivation, at the states a real run visits (the
  compensating law's claims carry ``J``; the paper's law claims ``−∫α|∇ρ̃|²``);
* ``dV₂/dt`` along the solver's own ``ρ̇`` (Godunov's fluxes, not the law's model): V₂ is
  *monotone* when it is never positive beyond :data:`PLANT_TOL` of its scale; the time-discrete
  rises of V₂ between records are reported (the sampled loop at ``dt``), not judged;
* the share of the mass on faces where ``g < g_min`` (the guarantee's hypothesis).

It also runs Step I alone: the crowd under the tracked field itself (``v_r = v_d/ĝ``, or ``v_d``
for the paper's law, sampled every ``0.9 h²/(4α₀)`` as the Theorem-1 check does, on the same
solver), where ``V₁ = ∫ρ̃²`` must never rise (:data:`V1_RTOL`).

**The reference plant** does not come from the verified scenario (as the ``pedestrians``
check, it is about one plant, in metres and seconds, and the paper's scenarios have no
congestion): the paper's Unity room (``paper_unity_scenario``: 150 m × 150 m, 16 robots, its
kernel, gains, σ and target) with the density crowd, the linear diagram (the SI default,
``ρ_max`` = 5.4 persons/m², ``g_min`` = 0.1 at 4.86 persons/m²) and a crowd that starts as a
Gaussian of 15 m in the room's middle: :data:`CROWDS` ``dense`` (3000 people, 2.1 persons/m² at
its peak: ``g`` down to about 0.6, never below ``g_min``), judged; and ``jammed`` (8000 people,
5.7 persons/m² at its peak: the core is at the jam density, where ``g = 0``), reported.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.controllers.backstepping import BacksteppingController
from meanfield.controllers.congested_plant import G_MIN, CongestedPlant
from meanfield.errors import SimulationDiverged
from meanfield.io.atomic import save_figure, subplots
from meanfield.scenarios.scenario import Scenario, paper_unity_scenario
from verification.result import CheckResult

__all__ = [
    "CLAIM",
    "CROWDS",
    "IDENTITY_RTOL",
    "PLANT_TOL",
    "V1_RTOL",
    "CongestedRun",
    "TrackingRun",
    "check_congested",
    "congested_run",
    "congested_verdict",
    "reference_plant",
    "tracking_run",
]

CLAIM = (
    "Steps I and II on the congested plant ∂ₜρ = −∇·(ρ g(Nρ) v_r) + Δ(σρ): the law that tracks v_d/g keeps "
    "dV₁/dt = −2∫α|∇ρ̃|² (v_r = v_d/g) and dV₂/dt = −∫α|∇ρ̃|² − Σk_u|b_i|² − Σk_ω g_i² wherever g(Nρ) ≥ g_min; "
    "the paper's law, which tracks v_d, does not."
)
CROWDS: dict[str, int] = {"dense": 3000, "jammed": 8000}
"""The reference plant's crowd sizes: ``dense`` (judged: ``g ≥ g_min`` everywhere) and ``jammed`` (reported)."""
LAWS = ("compensate", "ignore")
"""``controller.congestion`` of the two laws: tracking ``v_d/ĝ``, and the paper's ``v_d``."""
IDENTITY_RTOL = 1e-9
"""(I) and (II) along the law's own model hold to round-off: relative slack of their scale."""
PLANT_TOL = 1e-2
"""``dV₂/dt`` along the solver's Godunov fluxes (not the law's central model) may exceed 0 by this share
of its scale before V₂ is called not monotone (Theorem 3's slack, :data:`verification.theorem3.IDENTITY_TOL`)."""
V1_RTOL = 1e-6
"""Step I alone: ``V₁`` may rise between records by this share of ``V₁(0)`` (:data:`verification.theorem1.RTOL`)."""
DT = 0.025
"""The control period, s: the Theorem-3 check's unlimited step 1e-3 in the paper's unit (T = 25 s)."""
CENTER, SPREAD = (75.0, 75.0), 15.0
"""The initial crowd: a Gaussian of 15 m (persons/m² ≈ N/(2π 15²) at its centre) in the room's middle."""


def reference_plant(law: str, people: int, t_final: float, dt: float = DT) -> Scenario:
    """The reference congested plant (module docstring) with ``controller.congestion = law``.

    Parameters
    ----------
    law : {"compensate", "ignore"}
    people : int
        ``crowd.n``.
    t_final, dt : float
        Horizon and control period, s.
    """
    values = {
        "crowd.kind": "fokker-planck",
        "crowd.n": int(people),
        "crowd.congestion": "linear",
        "crowd.initial": "gaussian",
        "crowd.initial_center": list(CENTER),
        "crowd.initial_std": SPREAD,
        "view.radius": "none",
        "view.walk_speed": 0.0,
        "view.turning_rate": 0.0,
        "robots.u_max": "none",
        "robots.omega_max": "none",
        "controller.kind": "backstepping",
        "controller.dvd_dt": "model",
        "controller.beta_gamma": "min-norm",
        "controller.scaling": "paper",
        "controller.congestion": law,
        "dt": dt,
        "t_final": t_final,
    }
    return paper_unity_scenario(seed=0).with_values(values)


@dataclass
class CongestedRun:
    """One law's closed loop on the congested plant, measured at every record.

    Attributes
    ----------
    t, V2 : ndarray
        Times and ``V₂ = ½‖ρ̃‖² + ½‖ṽ‖²`` (the law's own ``ṽ``: ``v_r − v_d/ĝ`` or ``v_r − v_d``).
    step1_excess : ndarray
        (I): ``(2⟨ρ̃, ρ̇⟩ − claim) / (2∫α|∇ρ̃|² + 2|J|)`` along the law's model under ``v_r`` = the tracked field.
    step2_excess : ndarray
        (II): ``(dV₂/dt − claim) / scale`` along the law's model and the applied inputs,
        ``scale = ∫α|∇ρ̃|² + |J| + Σk_u|b_i|² + Σk_ω g_i² + |shortfall| + |dV₂/dt|``.
    plant_rate : ndarray
        ``dV₂/dt / scale`` along the solver's own ``ρ̇`` (V₂ monotone: never above :data:`PLANT_TOL`).
    plant_excess : ndarray
        ``(dV₂/dt − claim) / scale`` along the solver's ``ρ̇``: the plant's fluxes against the law's model.
    capped_mass : ndarray
        The share of the mass on faces where ``g < g_min``.
    residual_share : ndarray
        ``J / ∫α|∇ρ̃|²``: what the capped faces add to the Step-I term (0 where none is capped).
    g_least, peak : ndarray
        The smallest ``g`` on the faces and the largest density, persons/m².
    speed : ndarray
        The largest robot speed, m/s.
    info : dict
        ``dt``, ``steps``, and ``stopped`` if the run diverged.
    """

    t: np.ndarray
    V2: np.ndarray
    step1_excess: np.ndarray
    step2_excess: np.ndarray
    plant_rate: np.ndarray
    plant_excess: np.ndarray
    capped_mass: np.ndarray
    residual_share: np.ndarray
    g_least: np.ndarray
    peak: np.ndarray
    speed: np.ndarray
    info: dict = field(default_factory=dict)


class _Rates:
    """Observer: (I), (II) along the law's model, ``dV₂/dt`` along the solver, and the capped share."""

    def __init__(self, model: BacksteppingController, record_every: int):
        self.model = model  # the law with the plant's congestion: its model of ρ̇ and the capped share
        self.record_every = record_every
        self.rows: list[tuple] = []

    def start(self, loop: Any) -> None:
        pass

    def step(self, loop: Any, record: Any) -> None:
        if record.index % self.record_every:
            return
        g, law, fp, model = loop.grid, loop.controller, loop.crowd.fp, self.model
        obs, st = record.observation, record.command.state
        rho, t = obs.density, obs.t
        people = model.congestion.people
        v_r = obs.field.velocity()
        dvr = obs.field.velocity_rate(record.u, record.omega)
        report = model.congestion_at(rho, t)
        diss = model.dissipation(rho)  # ∫α|∇ρ̃|²; the compensating law reports ∫α|∇ρ̃|² − J
        scale1 = 2 * diss + 2 * abs(report.residual)
        # (I): the crowd under the tracked field, along the law's model
        tracked = law.tracked_velocity(rho, t)
        step1 = 2 * g.inner(st.rho_tilde, model.congested_density_rate(rho, tracked, t))
        step1_excess = (step1 + 2 * st.dissipation) / scale1

        def rate(rho_dot: np.ndarray) -> float:
            dw = law.tracked_velocity_rate(rho, rho_dot, t)
            return g.inner(st.rho_tilde, rho_dot) + g.face_inner(st.v_tilde, (dvr[0] - dw[0], dvr[1] - dw[1]))

        k_u = np.broadcast_to(law.k_u, (loop.robots.n,))
        k_w = np.broadcast_to(law.k_omega, (loop.robots.n,))
        action = float((k_u * (st.b**2).sum(1)).sum() + (k_w * st.g**2).sum())
        short = record.shortfall_applied
        claim = -st.dissipation - action + short
        model_rate = rate(model.congested_density_rate(rho, v_r, t))
        plant_rate = rate(fp.rhs(rho, t, face_velocity=v_r))
        scale = diss + abs(report.residual) + action + abs(short)
        re, ve = g.norm(st.rho_tilde), g.face_norm(st.v_tilde)
        self.rows.append(
            (
                t,
                0.5 * re * re + 0.5 * ve * ve,
                step1_excess,
                (model_rate - claim) / (scale + abs(model_rate)),
                plant_rate / (scale + abs(plant_rate)),
                (plant_rate - claim) / (scale + abs(plant_rate)),
                report.capped_mass,
                report.residual / diss if diss > 0 else 0.0,
                report.g_least,
                people * float(rho.max()),
                float(np.hypot(record.u[:, 0], record.u[:, 1]).max()),
            )
        )


def congested_run(law: str, people: int, t_final: float, dt: float = DT, record_every: int = 1) -> CongestedRun:
    """The closed loop of one law on the reference congested plant (:func:`reference_plant`), measured.

    Parameters
    ----------
    law : {"compensate", "ignore"}
        ``controller.congestion``.
    people : int
        The crowd's size.
    t_final, dt : float
        Horizon and control period, s.
    record_every : int
        Measure every so many steps.
    """
    from meanfield.crowds.density_crowd import DensityCrowd
    from meanfield.simulation.assembly import assemble
    from meanfield.simulation.loop import ClosedLoop

    sc = reference_plant(law, people, t_final, dt)
    parts = assemble(sc)
    fp = parts.crowd.fp  # the congested solver the density crowd built (Godunov's flux, split stepping)
    crowd = DensityCrowd(fp, parts.crowd.density(), parts.kernel, substeps=False)  # one step per period
    rates = _Rates(_model(parts, people), record_every)
    loop = ClosedLoop(dataclasses.replace(parts, crowd=crowd), observers=[rates])
    steps = int(round(t_final / dt))
    info: dict[str, Any] = {"dt": dt, "steps": steps}
    try:
        for _ in range(steps):
            loop.step()
    except SimulationDiverged as exc:
        info["stopped"] = f"the run diverged at t = {loop.t:.4g} s: {exc}"
    cols = [np.array(c, float) for c in zip(*rates.rows, strict=True)]
    return CongestedRun(*cols, info=info)


@dataclass
class TrackingRun:
    """Step I alone: the crowd under the tracked field itself, on the congested solver.

    Attributes
    ----------
    t, V1 : ndarray
        Times and ``V₁ = ∫ρ̃²``.
    capped_mass : ndarray
        The share of the mass on faces where ``g < g_min``.
    dt : float
        The sampling step ``min(0.9 h²/(4α₀), scenario dt)``.
    """

    t: np.ndarray
    V1: np.ndarray
    capped_mass: np.ndarray
    dt: float


def tracking_run(law: str, people: int, t_final: float) -> TrackingRun:
    """The crowd of the reference plant under ``v_r`` = the law's tracked field at ``ρⁿ`` (``v_d/ĝ`` or ``v_d``),
    held over steps of ``0.9 h²/(4α₀)`` (:func:`verification.theorem1.feedback_step`) of the congested solver
    (:meth:`~meanfield.fokker_planck.solver.FokkerPlanck.solve`, its own stable sub-steps)."""
    from meanfield.simulation.assembly import assemble
    from verification.theorem1 import feedback_step

    sc = reference_plant(law, people, t_final)
    parts = assemble(sc)
    grid, law_, fp = parts.grid, parts.controller, parts.crowd.fp
    model = law_ if law_.congestion is not None else _model(parts, people)
    dt = feedback_step(min(grid.dx, grid.dy), sc.controller.alpha, DT * 10)
    rho, t = parts.crowd.density().copy(), 0.0
    times, V1, capped = [], [], []
    steps = int(round(t_final / dt))
    for k in range(steps + 1):
        rt = rho - parts.target
        times.append(t)
        V1.append(grid.inner(rt, rt))
        capped.append(model.congestion_at(rho, t).capped_mass)
        if k == steps:
            break
        rho = fp.solve(rho, t + dt, t0=t, face_velocity=law_.tracked_velocity(rho, t))
        t = (k + 1) * dt
    return TrackingRun(np.array(times), np.array(V1), np.array(capped), dt)


def _model(parts: Any, people: int) -> BacksteppingController:
    """The law of ``parts`` with the plant's congestion (its model of ``ρ̇``, the capped share)."""
    ctrl, fp = parts.controller, parts.crowd.fp
    return BacksteppingController(
        parts.grid, parts.target, parts.sigma, ctrl.alpha, ctrl.k_u, ctrl.k_omega, ctrl.strategy, ctrl.interaction,
        "model", congestion=CongestedPlant(fp.congestion.diagram, people, G_MIN),
    )  # fmt: skip


def congested_verdict(run: CongestedRun, tracking: TrackingRun, law: str) -> tuple[str, dict[str, Any]]:
    """Judge one law on one crowd: (I) and (II) to round-off; V₂ monotone along the solver and V₁ monotone
    under the tracked field alone, where the law's hypothesis holds.

    (I) and (II) are identities (with ``J`` in the compensating law's Step-I term): they are held at
    every record.  The sign they give is the guarantee: the compensating law's (``"compensate"``) holds
    where no mass sits on a face with ``g < g_min``, the paper's (``"ignore"``) nowhere on this plant
    (its hypothesis ``g ≡ 1`` holds nowhere), so the monotonicity is judged at the compensating law's
    records with no such mass and at every record of the paper's law.  ``fails`` when (I) or (II) misses
    its claim by more than :data:`IDENTITY_RTOL` of its scale, ``dV₂/dt`` along the solver exceeds
    :data:`PLANT_TOL` of its scale at a judged record, or ``V₁`` alone rises by more than
    :data:`V1_RTOL` of ``V₁(0)`` between judged records; otherwise ``inconclusive`` when some record of
    the compensating law has mass where ``g < g_min``, with the reason; ``holds`` else.
    """
    judged = np.ones(run.t.shape, bool) if law == "ignore" else run.capped_mass == 0
    alone = np.ones(tracking.t.shape, bool) if law == "ignore" else tracking.capped_mass == 0
    step1 = float(np.abs(run.step1_excess).max())
    step2 = float(np.abs(run.step2_excess).max())
    rising = float(run.plant_rate[judged].max()) if judged.any() else -1.0
    rises = np.diff(tracking.V1) > V1_RTOL * tracking.V1[0]
    v1_rise = bool((rises & alone[1:] & alone[:-1]).any())
    capped = law == "compensate" and bool(run.capped_mass.max() > 0 or tracking.capped_mass.max() > 0)
    figures = {
        "step1_identity_excess": step1,
        "step2_identity_excess": step2,
        "V2_monotone": bool(run.plant_rate.max() <= PLANT_TOL),
        "plant_rate_max": float(run.plant_rate.max()),
        "plant_excess_max": float(run.plant_excess.max()),
        "time_discrete_V2_rises": float((np.diff(run.V2) > 1e-9 * run.V2[0]).mean()) if len(run.V2) > 1 else 0.0,
        "V2_ratio": float(run.V2[-1] / run.V2[0]),
        "V1_monotone_alone": not bool(rises.any()),
        "V1_ratio_alone": float(tracking.V1[-1] / tracking.V1[0]),
        "capped_mass_max": float(max(run.capped_mass.max(), tracking.capped_mass.max())),
        "capped_records": float((run.capped_mass > 0).mean()),
        "residual_share_max": float(np.abs(run.residual_share).max()),
        "g_least": float(run.g_least.min()),
        "peak_persons_per_m2": float(run.peak.max()),
        "max_speed": float(run.speed.max()),
        "t_final": float(run.t[-1]),
    }
    what = []
    if step1 > IDENTITY_RTOL:
        what.append(f"dV₁/dt under its tracked field misses its claim by {step1:.2g} of its scale")
    if step2 > IDENTITY_RTOL:
        what.append(f"dV₂/dt misses its claim by {step2:.2g} of its scale")
    if rising > PLANT_TOL:
        what.append(f"dV₂/dt along the solver reaches +{rising:.2g} of its scale")
    if v1_rise:
        what.append("V₁ rose under the tracked field alone")
    if what:
        where = f"the crowd walks at g v_r, g down to {figures['g_least']:.2g}" if law == "ignore" else "g ≥ g_min"
        return "fails", {**figures, "reason": "; ".join(what) + f" ({where})"}
    if capped:
        v2 = "V₂ still decreased along the solver" if figures["V2_monotone"] else "V₂ rose along the solver"
        reason = (
            f"the crowd jams on up to {figures['capped_mass_max']:.0%} of the mass (g < g_min = {G_MIN:g}; least g "
            f"{figures['g_least']:.2g}), where no robot field moves it as Step I asks: there the Step-I term "
            f"∫α|∇ρ̃|² − J has no sign (|J| up to {figures['residual_share_max']:.2g} × ∫α|∇ρ̃|²); {v2}"
        )
        return "inconclusive", {**figures, "reason": reason}
    return "holds", figures


def _figure(path: Path, runs: list[tuple[str, CongestedRun]]) -> None:
    fig, ax = subplots(1, 3, figsize=(13, 3.6))
    for label, run in runs:
        style = "-" if "compensate" in label else "--"
        (line,) = ax[0].semilogy(run.t, run.V2, style, label=label)
        ax[1].semilogy(run.t, np.maximum(np.abs(run.step1_excess), 1e-17), style, color=line.get_color())
        ax[2].plot(run.t, run.capped_mass, style, color=line.get_color())
    ax[0].set_title("V₂ (the law's own ṽ)", fontsize=9)
    ax[1].set_title("Step I: |dV₁/dt + 2(∫α|∇ρ̃|² − J)| / scale", fontsize=9)
    ax[2].set_title("share of the mass where g < g_min", fontsize=9)
    for a in ax:
        a.set_xlabel("t (s)")
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def check_congested(
    scenario: Scenario, out_dir: Path, *, quick: bool = False, progress: bool = False, workers: int | None = None
) -> CheckResult:
    """Check Steps I and II on the reference congested plant, for both laws (module docstring).

    Parameters
    ----------
    scenario : Scenario
        Unused: the claim is about the reference plant (``measured.settings`` says which).
    out_dir : Path
        Report directory (figure ``figures/congested.png``).
    quick : bool
        Horizon 5 s (200 control periods; else 60 s), every state recorded.
    progress, workers
        Unused.
    """
    start = time.perf_counter()
    t_final = 5.0 if quick else 60.0
    cases: list[dict[str, Any]] = []
    runs = []
    for crowd, people in CROWDS.items():
        for law in LAWS:
            run = congested_run(law, people, t_final)
            verdict, figures = congested_verdict(run, tracking_run(law, people, t_final), law)
            if "stopped" in run.info:
                figures["stopped"] = run.info["stopped"]
                if verdict == "holds":
                    verdict, figures["reason"] = "inconclusive", run.info["stopped"]
            name = "v_d/g (compensate)" if law == "compensate" else "paper's v_d (ignore)"
            cases.append({"case": f"{crowd} N={people}, {name}", "crowd": crowd, "people": people, "law": law,
                          "verdict": verdict, **figures})  # fmt: skip
            runs.append((f"{crowd} N={people}, {law}", run))
    figdir = out_dir / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    _figure(figdir / "congested.png", runs)
    by = {(k["crowd"], k["law"]): k for k in cases}
    aware, paper = by[("dense", "compensate")], by[("dense", "ignore")]
    verdict, reason = aware["verdict"], aware.get("reason", "")
    if verdict == "holds" and paper["verdict"] != "fails":  # the claim's contrast: the paper's law misses g
        verdict = "fails"
        reason = "the paper's law met the identities on the congested plant, which the derivation says it cannot"
    parts = [
        f"{k['case']}: {k['verdict']} (identities I/II off by {k['step1_identity_excess']:.2g}/"
        f"{k['step2_identity_excess']:.2g}; V₂ monotone {'yes' if k['V2_monotone'] else 'no'}, V₁ alone monotone "
        f"{'yes' if k['V1_monotone_alone'] else 'no'}; g ≥ {k['g_least']:.2g}; mass where g < g_min "
        f"{k['capped_mass_max']:.0%})"
        for k in cases
    ]
    jammed = by[("jammed", "compensate")]
    headline = (
        f"dense crowd (g ≥ {aware['g_least']:.2f}): v_d/g {aware['verdict']}, the paper's v_d {paper['verdict']} "
        f"(Step I off by {paper['step1_identity_excess']:.0%}); jammed crowd: v_d/g {jammed['verdict']}, "
        f"{jammed['capped_mass_max']:.0%} of the mass where g < g_min"
    )
    keys = ("step1_identity_excess", "step2_identity_excess", "V2_monotone", "V1_monotone_alone")
    return CheckResult(
        key="congested",
        claim=CLAIM,
        verdict=verdict,
        reason=reason,
        summary=headline + ". " + "; ".join(parts),
        measured={
            "dense_compensate": {k: aware[k] for k in keys},
            "dense_paper_law": {k: paper[k] for k in keys},
            "jammed_compensate": {"verdict": jammed["verdict"], "capped_mass_max": jammed["capped_mass_max"]},
            "settings": {
                "scenario": "paper-unity, crowd.kind = fokker-planck, crowd.congestion = linear, robots without limits",
                "crowd": f"Gaussian of {SPREAD:g} m at {CENTER}, N = {dict(CROWDS)}",
                "dt": DT,
                "t_final": t_final,
                "g_min": G_MIN,
            },
        },
        bound={"identity_rtol": IDENTITY_RTOL, "plant_tol": PLANT_TOL, "V1_rtol": V1_RTOL, "g_min": G_MIN},
        criterion=(
            "Per law and crowd, at every recorded state of the closed loop on the congested solver (robots without "
            "limits, model-based ∂ₜ of the tracked field, min-norm β/γ, one solver step per period of "
            f"{DT:g} s): (I) 2⟨ρ̃, ρ̇⟩ under v_r = the tracked field and (II) dV₂/dt under the applied inputs, both "
            f"along the law's central congested model, equal their claims to {IDENTITY_RTOL:g} of their scale at every "
            f"record; dV₂/dt along the solver's Godunov fluxes is ≤ {PLANT_TOL:g} of its scale (V₂ monotone), and V₁ "
            f"under the tracked field alone never rises by more than {V1_RTOL:g} V₁(0), where the law's hypothesis "
            "holds (the compensating law: no mass on a face with g < g_min, else inconclusive; the paper's law: "
            "everywhere). The verdict is the compensating law's on the dense crowd, and fails if the paper's law "
            "there does not fail; the jammed crowd is reported."
        ),
        cases=cases,
        figures=["figures/congested.png"],
        seconds=time.perf_counter() - start,
    )
