"""The QP of the NMPC's SQP (analysis.nmpc.qp) against a conic solver."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.nmpc import InputQP, block_counts


def test_the_qp_solver_matches_a_conic_solver(rng):
    """The dense interior point of InputQP against Clarabel (through cvxpy) on the same QP,
    with speed disks, turn-rate bounds and region bounds active."""
    cp = pytest.importorskip("cvxpy")
    blocks, n, h = (1, 2), 3, 0.5
    N = block_counts(blocks)
    qp = InputQP(N, n, h, 0.2, 1.0, (0.0, 1.0, 0.0, 1.0))
    A = rng.normal(size=(30, 18))
    P, q = A.T @ A / 30 + 1e-3 * np.eye(18), rng.normal(0.0, 0.5, 18)
    R0 = np.array([[0.0, 0.0], [0.5, 0.5], [0.95, 0.98]])
    res = qp.solve(P, q, np.zeros(18), R0)
    assert res.converged and qp.constraints(res.x, R0).max() <= 1e-8
    x = cp.Variable((2 * n, 3))  # rows (block, robot), as InputQP's (B, n, 3)
    blk = [x[b * n : (b + 1) * n] for b in range(2)]
    cons = [cp.abs(x[:, 2]) <= 1.0, cp.norm(x[:, :2], axis=1) <= 0.2]
    for k in range(3):
        pos = R0 + h * sum(N[k, b] * blk[b][:, :2] for b in range(2))
        cons += [pos >= 0, pos <= 1]
    flat = cp.vec(x, order="C")
    cp.Problem(cp.Minimize(0.5 * cp.quad_form(flat, cp.psd_wrap(P)) + q @ flat), cons).solve(solver="CLARABEL")
    np.testing.assert_allclose(res.x, flat.value, atol=1e-6)
    assert np.sum(qp.constraints(res.x, R0) > -1e-7) >= 3  # not vacuous: constraints are active
