"""Your own choice of the paper's weights β_il, γ_i (eq. (8)-(9)).

The robot law is u_i^(l) = k_u b_i^(l) + β_il A / b_i^(l),  ω_i = -k_ω g_i - γ_i A / g_i,
with β_il = 0 where b_i^(l) = 0 (γ_i likewise) and Σβ + Σγ = 1. The default rule is the
minimum-norm one, β_il = (b_i^(l))²/Z, γ_i = g_i²/Z. This example plugs in the
"equal-magnitude" rule

    β_il = |b_i^(l)| / S,   γ_i = |g_i| / S,   S = Σ|b_i^(l)| + Σ|g_i|,

which gives δu_i^(l) = A sign(b_i^(l)) / S: every robot axis with a non-zero integral
gets the same extra speed. UserBetaGamma checks the constraints of eq. (9) every step
and forms the paper's terms literally. Run:  python docs/examples/user_beta_gamma.py [t_final]
"""

import sys

import numpy as np

from meanfield import MinimumNormBetaGamma, UserBetaGamma, paper_scenario, run
from meanfield.plotting.figures import save_run_figures


def equal_magnitude(b, g, A):
    """(b (n, 2), g (n,), A) -> (β (n, 2), γ (n,)) with Σβ + Σγ = 1."""
    S = np.abs(b).sum() + np.abs(g).sum()
    # S == 0 only if ṽ is orthogonal to every kernel column. Then no weights satisfy
    # eq. (9) and UserBetaGamma raises ParameterError; a strategy that must survive this
    # case returns ExtraInputs(du, domega, shortfall=A) itself (see MinimumNormBetaGamma).
    return np.abs(b) / S, np.abs(g) / S


# The same check the closed loop runs, on a random instance.
rng = np.random.default_rng(1)
b, g, A = rng.normal(size=(16, 2)), rng.normal(size=16), 0.3
extra = UserBetaGamma(equal_magnitude)(b, g, A)
cancelled = (b * extra.du).sum() - (g * extra.domega).sum()
assert np.isclose(cancelled, A) and abs(extra.shortfall) < 1e-12
ref = MinimumNormBetaGamma()(b, g, A)
print(f"extra-input norm: equal-magnitude {np.hypot(np.linalg.norm(extra.du), np.linalg.norm(extra.domega)):.4f}"
      f"  >=  min-norm {np.hypot(np.linalg.norm(ref.du), np.linalg.norm(ref.domega)):.4f}")

t_final = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
scenario = paper_scenario(seed=0).replace(t_final=t_final)

for label, strategy in [("min-norm", MinimumNormBetaGamma()), ("equal-magnitude", UserBetaGamma(equal_magnitude))]:
    result = run(scenario, beta_gamma=strategy, progress=False)
    s, ds = result.summary, result.dataset
    print(
        f"{label:16s} status={s['status']:9s} in target={s['fraction_in_target']:.2f} "
        f"V2 {s['V2_initial']:.3f} -> {s['V2_final']:.3f}  "
        f"max |shortfall| {float(np.nanmax(np.abs(ds['shortfall'].values))):.1e}  "
        f"saturated {s['saturated_fraction']:.0%}"
    )
    result.save(f"runs/user_beta_gamma/{label}", artifacts=[save_run_figures])
