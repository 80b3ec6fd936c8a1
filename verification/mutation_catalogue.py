"""The catalogue of the mutation demo: the deliberate bugs that the tests must catch.

Each :class:`Mutation` is one textual change ``old -> new`` to one source file, chosen to
break one claim of the paper (``docs/verification.md``, "Property tests and the mutation
demo"); :data:`MUTATIONS` lists them, each applied alone by
:func:`verification.mutation.run_demo` to a copy of the project.  :class:`MutationError`
says that a mutation no longer matches its source.  Every name here is re-exported by
:mod:`verification.mutation`.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["MUTATIONS", "Mutation", "MutationError"]


class MutationError(RuntimeError):
    """A mutation's ``old`` text does not occur exactly once in its file (the demo is stale)."""


@dataclass(frozen=True)
class Mutation:
    """One deliberate bug: replace ``old`` by ``new`` in ``path``.

    Attributes
    ----------
    name : str
        Short identifier (``--only`` selects by it).
    description : str
        What the change does, in words.
    path : str
        File relative to the repository root, e.g. ``"meanfield/controllers/backstepping.py"``.
    old, new : str
        The exact source text and its replacement; ``old`` must occur exactly once.
    claim : str
        The claim of the paper (or of the toolkit) the change breaks.
    """

    name: str
    description: str
    path: str
    old: str
    new: str
    claim: str


MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "u-sign",
        "robot law: u_i = k_u b_i + δu_i  ->  u_i = -k_u b_i + δu_i",
        "meanfield/controllers/backstepping.py",
        "u=k_u * b + extra.du,",
        "u=-k_u * b + extra.du,",
        "Theorem 3: dV2/dt = -∫α|∇ρ̃|² - Σk_u|b_i|² - Σk_ω g_i²",
    ),
    Mutation(
        "omega-sign",
        "robot law: ω_i = -k_ω g_i + δω_i  ->  ω_i = +k_ω g_i + δω_i",
        "meanfield/controllers/backstepping.py",
        "omega=-self.k_omega * gg + extra.domega,",
        "omega=self.k_omega * gg + extra.domega,",
        "Theorem 3: dV2/dt = -∫α|∇ρ̃|² - Σk_u|b_i|² - Σk_ω g_i²",
    ),
    Mutation(
        "beta-gamma-sum-2",
        "min-norm β/γ: extra inputs doubled (Σβ + Σγ = 2), shortfall still reported as 0",
        "meanfield/controllers/beta_gamma.py",
        "        s = A / Z\n",
        "        s = 2 * A / Z\n",
        "eq. (9): Σ_i (Σ_l β_il + γ_i) = 1",
    ),
    Mutation(
        "beta-gamma-sum-half",
        "min-norm β/γ: extra inputs halved (Σβ + Σγ = 1/2), shortfall still reported as 0",
        "meanfield/controllers/beta_gamma.py",
        "        s = A / Z\n",
        "        s = 0.5 * A / Z\n",
        "eq. (9): Σ_i (Σ_l β_il + γ_i) = 1",
    ),
    Mutation(
        "v_d-sign",
        "Step I: v_d = -(α∇ρ̃ - ∇(σρ))/ρ  ->  +α∇ρ̃/ρ + ∇(σρ)/ρ (anti-diffusion of ρ̃)",
        "meanfield/controllers/step_one.py",
        "out = [-p.q[k] * p.grt[k] + p.gs[k] / p.rf[k] for k in range(2)]",
        "out = [+p.q[k] * p.grt[k] + p.gs[k] / p.rf[k] for k in range(2)]",
        "Theorem 1: dV1/dt = -2∫α|∇ρ̃|² <= -2 α_inf μ₂ V1",
    ),
    Mutation(
        "v_d-interaction-sign",
        "Step I: v_d = ... - u_W[ρ]  ->  ... + u_W[ρ] (the paper's ∇W * ρ sign slip)",
        "meanfield/controllers/step_one.py",
        "out = [out[k] - p.uw[k] for k in range(2)]",
        "out = [out[k] + p.uw[k] for k in range(2)]",
        "Theorem 1 with W != 0 (u_W cancelled by v_d)",
    ),
    Mutation(
        "drop-dvd-dt",
        "A = ∫ṽᵀ(ρ∇ρ̃ - ∂_t v_d)  ->  A = ∫ṽᵀ ρ∇ρ̃ (∂_t v_d dropped)",
        "meanfield/controllers/backstepping.py",
        "A = g.face_inner(vt, (p.rf[0] * p.grt[0] - dvd[0], p.rf[1] * p.grt[1] - dvd[1]))",
        "A = g.face_inner(vt, (p.rf[0] * p.grt[0], p.rf[1] * p.grt[1]))",
        "Theorem 3 (A must contain ∂_t v_d)",
    ),
    Mutation(
        "saturating-alpha-derivative",
        "SaturatingAlpha: d(α/ρ)/dρ = -α₀/(ρ+ρ_f)²  ->  -α₀/(ρ+ρ_f) (wrong chain rule in ∂_t v_d)",
        "meanfield/controllers/alpha_schedules.py",
        "        return -self.alpha0 / (d * d)\n",
        "        return -self.alpha0 / d\n",
        "Theorem 3 (model-based ∂_t v_d)",
    ),
    Mutation(
        "dissipation-factor-2",
        "reported dissipation ∫α|∇ρ̃|² doubled (the V1 = ∫ρ̃² vs ½∫ρ̃² factor-2 slip)",
        "meanfield/controllers/step_one.py",
        "a = (p.q[0] * p.rf[0], p.q[1] * p.rf[1])  # α = (α/ρ)·ρ, as used in v_d",
        "a = (2 * p.q[0] * p.rf[0], 2 * p.q[1] * p.rf[1])",
        "Theorems 1 and 3 (the dissipation term)",
    ),
    Mutation(
        "fd-dvd-dt-sign",
        "finite-difference ∂_t v_d (the scenarios' default): (v_d(t) - v_d(t-h))/h  ->  /(-h)",
        "meanfield/controllers/backstepping.py",
        "                h = t - prev[0]\n",
        "                h = prev[0] - t\n",
        "Theorem 3 with dvd_dt='finite-difference' (A must contain ∂_t v_d)",
    ),
    Mutation(
        "sg-drift-reversed",
        "Scharfetter–Gummel: upwind coefficients swapped, the drift enters with the wrong sign "
        "(still an M-matrix, still mass-conserving)",
        "meanfield/fokker_planck/solver.py",
        "    np.maximum(a, 0.0, out=out_l)\n    np.subtract(out_l, a, out=out_r)  # max(-a, 0), exactly\n",
        "    np.maximum(-a, 0.0, out=out_l)\n    np.add(out_l, a, out=out_r)\n",
        "eq. (4): the solver discretises -∇·(vρ) + Δ(σρ)",
    ),
    Mutation(
        "implicit-outflow-dropped",
        "implicit solver: the outflow through the x-faces to the left of each cell dropped from "
        "the diagonal (mass leaks)",
        "meanfield/fokker_planck/solver.py",
        "        diag[1:, :] += dt * c.rx\n",
        "",
        "zero-flux walls: mass conserved",
    ),
    Mutation(
        "bounded-limit-margin",
        "bounded β/γ: totals projected onto (1 + 1e-6)·u_max instead of just inside u_max",
        "analysis/bounded.py",
        "    shrink = 1.0 - 1e-12\n",
        "    shrink = 1.0 + 1e-6\n",
        "speed limits ‖u_i‖ <= u_max, |ω_i| <= ω_max",
    ),
)
"""The mutations of the demo, each applied alone."""
