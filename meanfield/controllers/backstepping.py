"""The backstepping density-feedback controller (paper, Section IV).

Step I, virtual control (paper, eq. (6)), on the grid faces::

    v_d = -(α ∇ρ̃ - ∇(σρ)) / ρ - u_W[ρ],        ρ̃ = ρ - ρ_*

Step II, robot law (paper, eq. (8)), with ṽ = v_r - v_d::

    b_i = ∫ ṽᵀ K_ξ^i dx,   g_i = ∫ ṽᵀ K_θ^i dx,   A = ∫ ṽᵀ (ρ ∇ρ̃ - ∂_t v_d) dx
    u_i = k_u b_i + δu_i,  ω_i = -k_ω g_i + δω_i,  Σ_i b_i·δu_i - g_i δω_i = A

so that (semi-discrete, exactly)::

    dV₂/dt = -∫ α|∇ρ̃|² - Σ_i k_u |b_i|² - Σ_i k_ω g_i²,   V₂ = ∫ ½ρ̃² + ½|ṽ|²

The extra inputs ``(δu, δω)`` come from a :class:`BetaGammaStrategy`; the default is
the minimum-norm choice ``β_il = (b_i^(l))²/Z``, ``γ_i = g_i²/Z``,
``Z = Σ|b_i|² + Σ g_i²`` (docs page *The controller*, ``docs/controller.md#choosing-beta-and-gamma``),
i.e. ``δu_i = A b_i / Z``, ``δω_i = -A g_i / Z``.

``∂_t v_d`` is either *model-based* (chain rule through ``ρ`` with
``∂_t ρ = -∇·((v_r + u_W) ρ - ∇(σρ))``, the Fokker–Planck right-hand side) or a finite
difference of successive ``v_d``.

On a congested plant (``crowd.congestion``; docs page *Congestion*) the crowd walks at
``g(Nρ) v_r``: ``∂_t ρ = -∇·(ρ g(Nρ) v_r + ρ u_W) + Δ(σρ)``.  With a :class:`CongestedPlant`
(``controller.congestion = "compensate"``; opt-in) Step I is unchanged and Step II tracks
``v_d / ĝ``, ``ĝ = max(g(Nρ_f), g_min)``::

    ṽ = v_r - v_d/ĝ,   A = ∫ ṽᵀ (ρ g ∇ρ̃ - ∂_t(v_d/ĝ)) dx,
    dV₂/dt = -∫ α|∇ρ̃|² + J - Σ_i k_u |b_i|² - Σ_i k_ω g_i²,   J = ⟨∇ρ̃, ρ (g/ĝ - 1) v_d⟩,

with ``J = 0`` wherever ``g >= g_min`` (docs page *Verification*, "Steps I and II on the
congested plant").  Without congestion (``"none"``, the paper's scenarios) the law is the
paper's, number for number.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np

from meanfield.capabilities import ControllerCapabilities
from meanfield.controllers.alpha_schedules import ConstantAlpha, SaturatingAlpha
from meanfield.controllers.beta_gamma import MinimumNormBetaGamma, UserBetaGamma
from meanfield.controllers.congested_plant import (
    G_MIN,
    CongestedPlant,
    CongestionFaces,
    CongestionReport,
    congested_plant,
)
from meanfield.controllers.fused_law import FusedLaw
from meanfield.controllers.step_one import PaperStepOne, Prepared, StepOne
from meanfield.errors import ParameterError, SigmaLike, check_sigma
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.grid import FaceField, Grid
from meanfield.interfaces import (
    AlphaSchedule,
    BetaGammaStrategy,
    Command,
    ControllerParts,
    ControlState,
    ExtraInputs,
    Observation,
    StabilityStep,
)
from meanfield.signs.interaction import InteractionField
from meanfield.signs.robots import NavigationField

DVD_DT_OPTIONS = ("model", "fokker-planck", "finite-difference")
"""The ways :class:`BacksteppingController` obtains ``∂_t v_d``."""
CONGESTION_OPTIONS = ("compensate", "ignore")
"""``controller.congestion``: track ``v_d / g`` on a congested plant (:class:`CongestedPlant`), or ``v_d``."""
__all__ = [  # the α schedules, β/γ rules and congested plant live in their own modules; the law's names them too
    "DVD_DT_OPTIONS",
    "CONGESTION_OPTIONS",
    "G_MIN",
    "CongestedPlant",
    "CongestionFaces",
    "CongestionReport",
    "AlphaSchedule",
    "ConstantAlpha",
    "SaturatingAlpha",
    "BetaGammaStrategy",
    "MinimumNormBetaGamma",
    "UserBetaGamma",
    "ExtraInputs",
    "ControlState",
    "BacksteppingController",
]


# ---------------------------------------------------------------------- the controller
class BacksteppingController:
    """Density-feedback backstepping controller of the paper (eqs. (6) and (9)).

    Parameters
    ----------
    grid : Grid
    target : ndarray
        Target density ``ρ_*`` on ``grid.shape`` (unit mass).
    sigma : float or callable
        Diffusion ``σ`` (>= 0) or ``σ(x, y, t)``; the SDE noise is ``sqrt(2σ) dB``.
    alpha : AlphaSchedule
        Step-I gain.
    k_u, k_omega : float or array of shape (n,)
        Step-II gains, every entry >= 0 (the paper asks only Σ > 0; the bound needs each >= 0).
    strategy : BetaGammaStrategy
        Extra-input rule (default :class:`MinimumNormBetaGamma`).
    interaction : InteractionField or None
        ``u_W`` (None: ``W = 0``).
    dvd_dt : {"model", "fokker-planck", "finite-difference"}
        How ``∂_t v_d`` is obtained: the chain rule along the model's ``∂_t ρ`` with
        central fluxes (``"model"``, consistent with Theorem 1's identity) or with the
        Scharfetter–Gummel right-hand side of :class:`~meanfield.fokker_planck.solver.FokkerPlanck`
        (``"fokker-planck"``), or a backward difference of ``v_d`` between calls.
    scales : (float, float), optional
        ``(ℓ, c)``: run the law in the units of length ``ℓ`` and speed ``c`` (time ``ℓ/c``),
        so that it is the same law in any unit of length: ``V₂ = ½ℓ²∫ρ̃² + ½(cℓ)⁻²∫|ṽ|²``,
        dimensionless gains, β/γ of minimum norm in the scaled inputs (docs page
        *The controller*, "A law in any unit of length").  None: the paper's law.
    congestion : CongestedPlant, optional
        The plant's congestion: Step II then tracks ``v_d/ĝ`` (the module docstring; docs page
        *Verification*, "Steps I and II on the congested plant"), on the numpy path.  None: the
        paper's law (the crowd walks at ``v_r``).
    step_one : StepOne, optional
        Step I (:mod:`meanfield.controllers.step_one`): ``v_d``, its rate, the dissipation term and its compiled
        form.  None: the paper's, eq. (6) (:class:`~meanfield.controllers.step_one.PaperStepOne`).
    """

    def __init__(
        self,
        grid: Grid,
        target: np.ndarray,
        sigma: SigmaLike,
        alpha: AlphaSchedule,
        k_u: float | np.ndarray = 10.0,
        k_omega: float | np.ndarray = 10.0,
        strategy: BetaGammaStrategy | None = None,
        interaction: InteractionField | None = None,
        dvd_dt: Literal["model", "fokker-planck", "finite-difference"] = "finite-difference",
        scales: tuple[float, float] | None = None,
        congestion: CongestedPlant | None = None,
        step_one: StepOne | None = None,
    ):
        self.grid = grid
        self.step_one = PaperStepOne() if step_one is None else step_one
        if congestion is not None and not isinstance(congestion, CongestedPlant):
            raise ParameterError("congestion", type(congestion).__name__, "a CongestedPlant or None")
        self.congestion = congestion
        self.scales = None if scales is None else (float(scales[0]), float(scales[1]))
        target = np.asarray(target, float)
        if target.shape != grid.shape:
            raise ParameterError("target", target.shape, f"an array of grid.shape {grid.shape}")
        self.target = target
        self.sigma = check_sigma("sigma", sigma)
        self.alpha = alpha
        for name, k in (("k_u", k_u), ("k_omega", k_omega)):
            arr = np.asarray(k, float)
            if not np.all(np.isfinite(arr)) or np.any(arr < 0):
                raise ParameterError(f"controller.{name}", k, "finite gains, every one >= 0")
        self.k_u = np.asarray(k_u, float)
        self.k_omega = np.asarray(k_omega, float)
        self.strategy = strategy if strategy is not None else MinimumNormBetaGamma()
        self.interaction = interaction
        if dvd_dt not in DVD_DT_OPTIONS:
            raise ParameterError("controller.dvd_dt", dvd_dt, " or ".join(map(repr, DVD_DT_OPTIONS)))
        self.dvd_dt = dvd_dt
        self._fokker_planck = self._plant_model(grid)
        self.previous_vd: tuple[float, FaceField] | None = None  # (t, v_d) of the last call, for ∂_t v_d
        self.target_gradient = grid.gradient(self.target)  # ∇ρ_* on the faces
        self.fused = FusedLaw(self)  # the law in one compiled call where it applies (meanfield.controllers.fused_law)
        self.congestion_report: CongestionReport | None = None  # the last evaluation's, with a congested plant
        self._congestion_stats = [0, 0.0, 0.0, 0.0]  # calls, capped mass: sum, max; |residual| max

    def _plant_model(self, grid: Grid) -> FokkerPlanck | None:
        """With ``dvd_dt = "fokker-planck"`` the plant's right-hand side on ``grid``, congested as the plant is."""
        if self.dvd_dt != "fokker-planck":
            return None
        c = self.congestion
        slows = {} if c is None else {"congestion": c.diagram, "people": c.people}
        return FokkerPlanck(grid, self.sigma, interaction=self.interaction, **slows)

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event, :class:`~meanfield.geometry.blocking.WallsChange`): the law
        works on the new grid and its ``ρ_*`` from now on; ``v_d``'s time derivative starts again (its previous
        value lived on the old faces)."""
        self.grid = change.grid
        self.target = np.asarray(change.target, float)
        self.target_gradient = self.grid.gradient(self.target)
        self._fokker_planck = self._plant_model(self.grid)
        self.previous_vd = None
        self.fused.reset()

    @staticmethod
    def stability_step(scenario: Any, grid: Any) -> StabilityStep | None:
        """The largest ``dt`` at which the sampled Step-I feedback is stable: ``0.9 h²/(4 α₀)``.

        Holding ``v_d(ρⁿ)`` over a step is an explicit step of the closed-loop diffusion
        ``∇·(α∇ρ̃)`` (docs page *Verification*, Theorem 1); the preflight warns past it.
        """
        h = min(grid.dx, grid.dy)
        alpha = scenario.controller.alpha
        return StabilityStep(
            dt=0.9 * h * h / (4.0 * alpha),
            what="the sampled Step-I feedback's stability step 0.9 h²/(4 α₀)",
            why=f"(h = {h:.3g}, α₀ = {alpha:g}): where the robots realise v_d, the held feedback overshoots",
        )

    capabilities: ClassVar[ControllerCapabilities] = ControllerCapabilities(
        accepts_sensing=True,  # it runs on a group's knowledge ([sensing], meanfield.controllers.local_sensing)
        changes_walls=True,  # a region can become wall during a run ([[events]] block, walls_changed)
        stability_step=stability_step,
    )
    """What it can do (:class:`~meanfield.capabilities.ControllerCapabilities`): no options (a law that takes some
    declares their dataclass in its record)."""

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> BacksteppingController:
        """Registry factory (kind ``controller``, name ``backstepping``): the paper's law from parts.

        The law takes no ``controller.options``: its gains are fields of ``[controller]``
        (``alpha``, ``k_u``, ``k_omega``, ...).  Any option is refused, naming it, as every
        controller refuses an option it does not know (a misspelt ``alpah`` ran unnoticed).

        With a plant whose diagram slows (``parts.congestion``, filled by the assembly from
        ``crowd.congestion`` when ``controller.congestion = "compensate"``) the law compensates it
        (:class:`CongestedPlant`); a diagram that does not slow (``"none"``) leaves the paper's law.
        """
        if parts.options:
            raise ParameterError(
                "controller.options.backstepping",
                sorted(parts.options),
                "no options: the backstepping law's gains are fields of [controller] (alpha, k_u, k_omega, ...)",
            )
        return cls(*cls.law_arguments(parts), scales=parts.scales, congestion=congested_plant(parts))

    @staticmethod
    def law_arguments(parts: ControllerParts) -> tuple:
        """The constructor's positional arguments from the assembled parts (grid to ``dvd_dt``)."""
        p = parts
        return (p.grid, p.target, p.sigma, p.alpha, p.k_u, p.k_omega, p.beta_gamma, p.interaction, p.dvd_dt)

    def act(self, observation: Observation) -> Command:
        """The :class:`~meanfield.interfaces.Controller` interface: :meth:`robot_inputs` at the observation."""
        o = observation
        state = self.robot_inputs(o.density, o.field, o.t, o.dt)
        return Command(state.u, state.omega, state)

    # ------------------------------------------------------------------ pieces
    def sigma_on_cells(self, t: float):
        """σ at the cell centres (scalar if constant)."""
        if callable(self.sigma):
            X, Y = self.grid.centers
            return np.asarray(self.sigma(X, Y, t), float)
        return self.sigma

    def interaction_on_faces(self, rho: np.ndarray) -> FaceField | None:
        """``u_W[ρ]`` on the faces, or None when ``W = 0``."""
        return None if self.interaction is None else self.interaction.on_faces(rho)

    def _prepare(self, rho: np.ndarray, t: float) -> Prepared:
        """Face quantities of ``ρ`` shared by every term of the law (computed once per step)."""
        g = self.grid
        rho_t = rho - self.target
        rf = g.face_average(rho)
        if not g.is_box:  # closed faces (outside Ω) carry nothing; avoid 0/0 there
            rf = (np.where(g.aperture_x > 0, rf[0], 1.0), np.where(g.aperture_y > 0, rf[1], 1.0))
        grt = g.gradient(rho_t)
        sig = self.sigma_on_cells(t)
        if callable(self.sigma):
            gs = g.gradient(sig * rho)
        else:  # ∇(σρ) = σ (∇ρ̃ + ∇ρ_*) for constant σ
            gt = self.target_gradient
            gs = (sig * (grt[0] + gt[0]), sig * (grt[1] + gt[1]))
        q = (self.alpha.over_rho(rf[0]), self.alpha.over_rho(rf[1]))
        return self.step_one.prepare(self, Prepared(rho, rho_t, rf, grt, sig, gs, q, self.interaction_on_faces(rho)))

    def virtual_velocity(self, rho: np.ndarray, t: float = 0.0) -> FaceField:
        """Step I: ``v_d = -(α∇ρ̃ - ∇(σρ))/ρ - u_W[ρ]`` on the faces (paper, eq. (6)).

        ``ρ`` must be positive on the faces (the KDE always is); the schedule's ``α/ρ``
        is evaluated directly, so a saturating schedule stays bounded as ``ρ → 0``.
        """
        return self._virtual_velocity(self._prepare(rho, t))

    def _virtual_velocity(self, p: Prepared) -> FaceField:
        return self.step_one.virtual_velocity(self, p)

    def density_rate(self, rho: np.ndarray, v_r: FaceField, t: float = 0.0) -> np.ndarray:
        """Fokker–Planck right-hand side ``-∇·((v_r + u_W)ρ - ∇(σρ))`` with ``v_a = 0`` (eq. (4)).

        Central (face-average) fluxes, consistent with :meth:`virtual_velocity`, so that
        with ``v_r = v_d`` it reduces exactly to ``∇·(α∇ρ̃)`` (Theorem 1).
        """
        return self._density_rate(self._prepare(rho, t), v_r)

    def _density_rate(self, p: Prepared, v_r: FaceField) -> np.ndarray:
        flux = [v_r[k] * p.rf[k] - p.gs[k] for k in range(2)]
        if p.uw is not None:
            flux = [flux[k] + p.uw[k] * p.rf[k] for k in range(2)]
        return -self.grid.divergence((flux[0], flux[1]))

    def virtual_velocity_rate(self, rho: np.ndarray, rho_dot: np.ndarray, t: float = 0.0) -> FaceField:
        """``∂_t v_d`` by the chain rule along ``∂_t ρ = rho_dot`` (σ and ρ_* frozen in time).

        With ``q = α/ρ`` the schedule: ``∂_t v_d = -(q'(ρ) ρ̇ ∇ρ̃ + q ∇ρ̇) + ∇(σρ̇)/ρ
        - ∇(σρ) ρ̇/ρ² - u_W[ρ̇]`` on the faces.
        """
        return self._virtual_velocity_rate(self._prepare(rho, t), rho_dot)

    def _virtual_velocity_rate(self, p: Prepared, rho_dot: np.ndarray) -> FaceField:
        return self.step_one.virtual_velocity_rate(self, p, rho_dot)

    def dissipation(self, rho: np.ndarray) -> float:
        """``∫ α |∇ρ̃|² dx`` on the faces (the first term of dV₂/dt; dV₁/dt = -2× this)."""
        return self._dissipation(self._prepare(rho, 0.0))

    def _dissipation(self, p: Prepared) -> float:
        return self.step_one.dissipation(self, p)

    # ------------------------------------------------------------------ the congested plant
    def tracked_velocity(self, rho: np.ndarray, t: float = 0.0) -> FaceField:
        """What the robots' field tracks: ``v_d/ĝ`` on a congested plant (:class:`CongestedPlant`), else ``v_d``."""
        p = self._prepare(rho, t)
        v_d = self._virtual_velocity(p)
        if self.congestion is None:
            return v_d
        gain = self.congestion.on_faces(p.rf).gain
        return gain[0] * v_d[0], gain[1] * v_d[1]

    def tracked_velocity_rate(self, rho: np.ndarray, rho_dot: np.ndarray, t: float = 0.0) -> FaceField:
        """``∂_t`` of :meth:`tracked_velocity` along ``∂_t ρ = rho_dot``:
        ``∂_t(v_d/ĝ) = ∂_t v_d / ĝ + v_d · d(1/ĝ)/dρ_f · ρ̇_f`` (``d(1/ĝ)/dρ_f = 0`` where ``g < g_min``)."""
        p = self._prepare(rho, t)
        if self.congestion is None:
            return self._virtual_velocity_rate(p, rho_dot)
        return self._tracked_rate(p, self._virtual_velocity(p), self.congestion.on_faces(p.rf), rho_dot)

    def congested_density_rate(self, rho: np.ndarray, v_r: FaceField, t: float = 0.0) -> np.ndarray:
        """The law's model of the plant: ``-∇·(ρ_f g(Nρ_f) v_r + ρ_f u_W - ∇(σρ))`` (central fluxes, as
        :meth:`density_rate`; ``g ≡ 1`` without a congested plant)."""
        p = self._prepare(rho, t)
        if self.congestion is None:
            return self._density_rate(p, v_r)
        return self._congested_rate(p, v_r, self.congestion.on_faces(p.rf))

    def _congested_rate(self, p: Prepared, v_r: FaceField, cf: CongestionFaces) -> np.ndarray:
        return self._density_rate(p, (cf.g[0] * v_r[0], cf.g[1] * v_r[1]))

    def _tracked_rate(self, p: Prepared, v_d: FaceField, cf: CongestionFaces, rho_dot: np.ndarray) -> FaceField:
        dvd = self._virtual_velocity_rate(p, rho_dot)
        df = self.grid.face_average(rho_dot)
        return tuple(cf.gain[k] * dvd[k] + cf.gain_slope[k] * df[k] * v_d[k] for k in range(2))  # type: ignore[return-value]

    def congestion_at(self, rho: np.ndarray, t: float = 0.0) -> CongestionReport | None:
        """The :class:`CongestionReport` of density ``rho`` (None without a congested plant), not counted in
        :meth:`summary`."""
        if self.congestion is None:
            return None
        p = self._prepare(rho, t)
        return self._report(p, self._virtual_velocity(p), self.congestion.on_faces(p.rf), count=False)

    def _report(self, p: Prepared, v_d: FaceField, cf: CongestionFaces, count: bool = True) -> CongestionReport:
        """The share of the mass where ``g < g_min``, and ``J = ⟨∇ρ̃, ρ_f (g/ĝ - 1) v_d⟩`` (kept and counted)."""
        gr = self.grid
        open_ = (gr.weight_x > 0, gr.weight_y > 0)
        mass = [(gr.weight_x * p.rf[0]), (gr.weight_y * p.rf[1])]
        total = float(mass[0].sum() + mass[1].sum())
        capped = float(mass[0][cf.capped[0]].sum() + mass[1][cf.capped[1]].sum())
        faces = int(open_[0].sum() + open_[1].sum())
        n_capped = int((cf.capped[0] & open_[0]).sum() + (cf.capped[1] & open_[1]).sum())
        residual = gr.face_inner(p.grt, tuple(p.rf[k] * cf.excess[k] * v_d[k] for k in range(2)))  # type: ignore[arg-type]
        least = min(float(cf.g[k][open_[k]].min()) if open_[k].any() else 1.0 for k in range(2))
        report = CongestionReport(capped / total if total > 0 else 0.0, n_capped / max(faces, 1), residual, least)
        if not count:
            return report
        self.congestion_report = report
        st = self._congestion_stats
        st[0] += 1
        st[1] += report.capped_mass
        st[2] = max(st[2], report.capped_mass)
        st[3] = max(st[3], abs(residual))
        return report

    def summary(self) -> dict[str, Any]:
        """A run's congestion figures (``summary.json``), with a congested plant only (the paper's law: none).

        ``congestion_g_min``; ``congestion_capped_mass_mean`` and ``_max``: the share of the mass on faces
        where ``g < g_min``, where the guarantee does not hold, over the law's evaluations;
        ``congestion_residual_max``: the largest ``|J|``.
        """
        if self.congestion is None:
            return {}
        calls, total, most, residual = self._congestion_stats
        return {
            "congestion_g_min": self.congestion.g_min,
            "congestion_capped_mass_mean": total / calls if calls else 0.0,
            "congestion_capped_mass_max": most,
            "congestion_residual_max": residual,
        }

    # ------------------------------------------------------------------ the law
    def robot_inputs(
        self, rho: np.ndarray, field: NavigationField, t: float = 0.0, dt: float | None = None
    ) -> ControlState:
        """Step II: robot inputs ``(u_i, ω_i)`` of eq. (8) for density ``rho`` and robots ``field``.

        Parameters
        ----------
        rho : ndarray
            Density (estimate) on the grid, positive.
        field : NavigationField
            The robots' kernels on the faces at this instant.
        t : float
            Time.
        dt : float, optional
            Step since the previous call (needed by ``dvd_dt="finite-difference"``).
        """
        fused = self.fused.which(rho, field)
        if fused is not None:  # the common cases: one compiled call, the same numbers to round-off
            state = self.fused.inputs(rho, field, t, fused[1])
            if state is not None:
                return state
        g = self.grid
        p = self._prepare(rho, t)
        v_d = self._virtual_velocity(p)
        v_r = field.velocity()
        if self.congestion is not None:
            return self._congested_inputs(p, v_d, v_r, field, t)
        vt = (v_r[0] - v_d[0], v_r[1] - v_d[1])
        b, gg = field.moments(vt)
        if self.dvd_dt == "model":
            dvd = self._virtual_velocity_rate(p, self._density_rate(p, v_r))
        elif self.dvd_dt == "fokker-planck":
            dvd = self._virtual_velocity_rate(p, self._fokker_planck.rhs(rho, t, face_velocity=v_r))
        else:
            prev = self.previous_vd
            if prev is None or t <= prev[0]:
                dvd = (np.zeros_like(v_d[0]), np.zeros_like(v_d[1]))
            else:
                h = t - prev[0]
                dvd = ((v_d[0] - prev[1][0]) / h, (v_d[1] - prev[1][1]) / h)
            self.previous_vd = (t, v_d)
        k_u = self.k_u[:, None] if self.k_u.ndim else self.k_u
        if self.scales is not None:
            return self._scaled_inputs(p, v_d, vt, b, gg, dvd, k_u)
        A = g.face_inner(vt, (p.rf[0] * p.grt[0] - dvd[0], p.rf[1] * p.grt[1] - dvd[1]))
        extra = self.strategy(b, gg, A)
        return ControlState(
            v_d=v_d, v_tilde=vt, rho_tilde=p.rho_t, b=b, g=gg, A=A,
            u=k_u * b + extra.du, omega=-self.k_omega * gg + extra.domega, shortfall=extra.shortfall,
            dissipation=self._dissipation(p), k_u=self.k_u, k_omega=self.k_omega,
        )  # fmt: skip

    def _congested_inputs(
        self, p: Prepared, v_d: FaceField, v_r: FaceField, field: NavigationField, t: float
    ) -> ControlState:
        """Step II on the congested plant: track ``w = v_d/ĝ`` (the module docstring).

        ``ṽ = v_r - w``, ``A = ⟨ṽ, ρ_f g ∇ρ̃ - ∂_t w⟩`` with ``∂_t w`` as ``dvd_dt`` says (the chain rule
        along the congested model or the congested Fokker–Planck right-hand side, or a backward
        difference of ``w``); the reported ``v_d`` is ``w`` and the reported dissipation is the
        Step-I term ``∫α|∇ρ̃|² - J``, so that ``dV₂/dt = -dissipation - Σk_u|b_i|² - Σk_ω g_i² + shortfall``.
        """
        g = self.grid
        cf = self.congestion.on_faces(p.rf)
        w = (cf.gain[0] * v_d[0], cf.gain[1] * v_d[1])
        vt = (v_r[0] - w[0], v_r[1] - w[1])
        b, gg = field.moments(vt)
        if self.dvd_dt == "model":
            dw = self._tracked_rate(p, v_d, cf, self._congested_rate(p, v_r, cf))
        elif self.dvd_dt == "fokker-planck":
            dw = self._tracked_rate(p, v_d, cf, self._fokker_planck.rhs(p.rho, t, face_velocity=v_r))
        else:
            prev = self.previous_vd
            if prev is None or t <= prev[0]:
                dw = (np.zeros_like(w[0]), np.zeros_like(w[1]))
            else:
                dw = ((w[0] - prev[1][0]) / (t - prev[0]), (w[1] - prev[1][1]) / (t - prev[0]))
            self.previous_vd = (t, w)
        report = self._report(p, v_d, cf)
        pull = (p.rf[0] * cf.g[0], p.rf[1] * cf.g[1])
        k_u = self.k_u[:, None] if self.k_u.ndim else self.k_u
        if self.scales is not None:
            return self._scaled_inputs(p, w, vt, b, gg, dw, k_u, pull=pull, residual=report.residual)
        A = g.face_inner(vt, (pull[0] * p.grt[0] - dw[0], pull[1] * p.grt[1] - dw[1]))
        extra = self.strategy(b, gg, A)
        return ControlState(
            v_d=w, v_tilde=vt, rho_tilde=p.rho_t, b=b, g=gg, A=A,
            u=extra.du + k_u * b, omega=extra.domega - self.k_omega * gg, shortfall=extra.shortfall,
            dissipation=self._dissipation(p) - report.residual, k_u=self.k_u, k_omega=self.k_omega,
        )  # fmt: skip

    def compiled_step_one(self) -> tuple[int, float, float, FaceField | None] | None:
        """Step I as :func:`~meanfield.controllers._law_loops.face_law` computes it, ``(step, v_free, ρ_max, ∇φ)``,
        or None: what the law's Step I says (:meth:`~meanfield.controllers.step_one.StepOne.compiled`), unless a
        subclass changed how the law computes Step I (then the numpy path, which follows it; the compiled path's
        choice is :meth:`~meanfield.controllers.fused_law.FusedLaw.which`)."""
        law = BacksteppingController
        if any(getattr(type(self), m) is not getattr(law, m) for m in _STEP_ONE_METHODS):
            return None
        return self.step_one.compiled(self)

    def _scaled_inputs(
        self,
        p: Prepared,
        v_d: FaceField,
        vt: FaceField,
        b,
        gg,
        dvd,
        k_u,
        pull: FaceField | None = None,
        residual: float = 0.0,
    ) -> ControlState:
        """Step II in the units ``ℓ``, ``c`` (``scales``): the law run on ``x/ℓ``, ``t c/ℓ``, ``ρℓ²``, ``v/c``.

        ``b̂ = b/(c²ℓ)``, ``ĝ = g/(c²ℓ²)``, ``Â = (ℓ³/c)⟨ṽ, ρ∇ρ̃⟩ − ⟨ṽ, ∂_t v_d⟩/(c³ℓ)``; then
        ``û = k_u b̂ + δû``, ``ω̂ = −k_ω ĝ + δω̂`` and ``u = c û``, ``ω = (c/ℓ) ω̂``, so that
        ``dV̂₂/dt̂ = −D̂ − Σ k_u|b̂|² − Σ k_ω ĝ²`` with ``V̂₂ = ½ℓ²∫ρ̃² + ½(cℓ)⁻²∫|ṽ|²``,
        ``t̂ = tc/ℓ`` and ``D̂ = (ℓ³/c) D``.  On a congested plant ``pull`` is ``ρ_f g`` (else ``ρ_f``),
        ``v_d`` the tracked ``v_d/ĝ`` and ``D`` the Step-I term ``∫α|∇ρ̃|² − residual``.
        """
        g = self.grid
        ell, c = self.scales
        rf = p.rf if pull is None else pull
        pull = g.face_inner(vt, (rf[0] * p.grt[0], rf[1] * p.grt[1]))
        A = ell**3 / c * pull - g.face_inner(vt, dvd) / (c**3 * ell)
        b, gg = b / (c * c * ell), gg / (c * c * ell * ell)
        extra = self.strategy(b, gg, A)
        return ControlState(
            v_d=v_d, v_tilde=vt, rho_tilde=p.rho_t, b=b, g=gg, A=A,
            u=c * (k_u * b + extra.du), omega=c / ell * (-self.k_omega * gg + extra.domega), shortfall=extra.shortfall,
            dissipation=ell**3 / c * (self._dissipation(p) - residual), k_u=self.k_u, k_omega=self.k_omega,
            input_scale=(c, c / ell), v2_weights=(ell * ell, 1.0 / (c * ell) ** 2),
        )  # fmt: skip

    def reset(self) -> None:
        """Forget the previous ``v_d`` (finite-difference mode) and the congestion figures."""
        self.previous_vd = None
        self.congestion_report = None
        self._congestion_stats = [0, 0.0, 0.0, 0.0]


_STEP_ONE_METHODS = ("_prepare", "_virtual_velocity", "_virtual_velocity_rate", "_dissipation")
"""The law's own calls of its Step I: a subclass that overrides one takes the numpy path."""


def _fused_robot_inputs(law: Any, rho: np.ndarray, field: NavigationField, t: float, step_one: tuple | None = None):
    return law.fused.inputs(rho, field, t, step_one)


def __getattr__(name: str) -> Any:
    if name == "fused_robot_inputs":  # this module's function before 0.2.0
        from meanfield.errors import deprecated

        deprecated("meanfield.controllers.backstepping.fused_robot_inputs(law, ...)", "use law.fused.inputs(...)")
        return _fused_robot_inputs
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
