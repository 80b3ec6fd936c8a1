"""The NMPC problem condensed onto the inputs (analysis.nmpc.condensed): its exact derivatives."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.nmpc import CondensedProblem
from tests.analysis.nmpc.conftest import model, random_density, random_robots


@pytest.mark.parametrize(("flux", "blocks"), [("upwind", (1, 1, 1)), ("central", (2, 1))])
def test_condensed_derivatives_are_exact(flux, blocks, rng):
    """The adjoint gradient and the exact reduced Hessian against central differences of the
    cost and of the gradient; the Gauss–Newton variant has the same gradient."""
    m = model(cells=(5, 4), sigma=0.02, step=0.3, flux=flux, n=3)
    p = CondensedProblem(m, blocks, r_u=0.1, r_omega=1e-3, terminal=1.0)
    rho0, target = random_density(m, rng), random_density(m, rng)
    R0, th0 = random_robots(3, rng)
    z = rng.uniform(-0.3, 0.3, (len(blocks), 3, 3))
    J, g, H = p.derivatives(rho0, R0, th0, z, target)
    u, w = z[p.beta, :, :2], z[p.beta, :, 2]
    P, _, _ = m.predict(rho0, R0, th0, u, w)
    e = P[1:] - target
    ref = m.step * (m.cell_volume * np.sum(e * e) + 0.1 * np.sum(u * u) + 1e-3 * np.sum(w * w))
    assert J == pytest.approx(ref + m.cell_volume * np.sum(e[-1] ** 2), rel=1e-12)  # the cost of docs/nmpc.md
    assert p.cost(rho0, R0, th0, z, target) == pytest.approx(J, rel=1e-12)
    eps = 1e-6
    for i in range(z.size):
        dz = np.zeros(z.size)
        dz[i] = eps
        fd = (p.cost(rho0, R0, th0, z.ravel() + dz, target) - p.cost(rho0, R0, th0, z.ravel() - dz, target)) / (2 * eps)
        assert g[i] == pytest.approx(fd, rel=1e-5, abs=1e-9)
        col = (
            p.derivatives(rho0, R0, th0, z.ravel() + dz, target)[1]
            - p.derivatives(rho0, R0, th0, z.ravel() - dz, target)[1]
        ) / (2 * eps)
        np.testing.assert_allclose(H[:, i], col, rtol=1e-4, atol=1e-7 * np.abs(H).max())
    _, g_gn, H_gn = p.derivatives(rho0, R0, th0, z, target, exact=False)
    np.testing.assert_allclose(g_gn, g, rtol=1e-14, atol=1e-15)
    assert np.linalg.eigvalsh(H_gn).min() > 0
