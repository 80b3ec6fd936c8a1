"""A sign whose pull decays algebraically instead of like a Gaussian.

The paper's kernel is K̄(ξ) = c exp(-|ξ|²/η). Any decaying magnitude can be used through
``CustomKernel(magnitude_fn, gradient_fn)``; here a Cauchy-type kernel

    K̄(ξ) = c / (1 + |ξ|²/ℓ²)²,      ∇K̄(ξ) = -4 c ξ / (ℓ² (1 + |ξ|²/ℓ²)³),

with a heavier tail: a sign is still noticed far away. The closed loop is the paper's
scenario with the kernel overridden. Run:  python docs/examples/custom_kernel.py [t_final]
"""

import sys

import numpy as np

from meanfield import CustomKernel, GaussianKernel, paper_scenario, run

C, ELL = 0.5, 0.12  # peak speed and length scale (same half-width as η = 0.03 roughly)


def magnitude(xi_x, xi_y):
    """K̄(ξ) = c / (1 + |ξ|²/ℓ²)²."""
    return C / (1.0 + (xi_x * xi_x + xi_y * xi_y) / ELL**2) ** 2


def gradient(xi_x, xi_y):
    """∇K̄(ξ) = -4 c ξ / (ℓ² (1 + |ξ|²/ℓ²)³)."""
    s = -4.0 * C / (ELL**2 * (1.0 + (xi_x * xi_x + xi_y * xi_y) / ELL**2) ** 3)
    return s * xi_x, s * xi_y


kernel = CustomKernel(magnitude, gradient)

# The controller uses ∇K̄ through K_ξ: check it against central differences first.
rng = np.random.default_rng(0)
x, y = rng.uniform(-0.3, 0.3, (2, 50))
h = 1e-6
fd_x = (magnitude(x + h, y) - magnitude(x - h, y)) / (2 * h)
fd_y = (magnitude(x, y + h) - magnitude(x, y - h)) / (2 * h)
gx, gy = gradient(x, y)
assert np.allclose(gx, fd_x, atol=1e-7) and np.allclose(gy, fd_y, atol=1e-7), "gradient is wrong"

t_final = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
scenario = paper_scenario(seed=0).replace(t_final=t_final)

for label, k in [("gaussian", GaussianKernel(0.5, 0.03)), ("cauchy", kernel)]:
    result = run(scenario, kernel=k, progress=False)
    s = result.summary
    print(
        f"{label:8s} status={s['status']:9s} in target={s['fraction_in_target']:.2f} "
        f"||rho~|| {s['l2_error_initial']:.3f} -> {s['l2_error_final']:.3f}  "
        f"V2 {s['V2_initial']:.3f} -> {s['V2_final']:.3f}"
    )
    # Save data only: the PNG figures draw the arrows of the scenario's Gaussian kernel.
    result.save(f"runs/custom_kernel/{label}")  # data only: timeseries.nc, scenario.toml, summary.json
