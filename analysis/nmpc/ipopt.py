"""The full-space NMPC problem solved by IPOPT (``solver = "ipopt"`` of the NMPC controller).

The solver of :class:`~analysis.nmpc.controller.NMPCController` with ``solver = "ipopt"``: the
problem of :mod:`analysis.nmpc.controller` (docs/nmpc.md, "The optimal-control problem") written
with CasADi's Opti stack with every state lifted as a decision variable (inputs, robot
states, coarse densities: sparse Jacobians and Hessians), compiled once with
``Opti.to_function`` into one function of ``ρ_0``, ``R``, ``θ``, ``ρ_*`` and the initial
guesses (primal and multipliers), and solved by IPOPT (exact Hessian by default, MUMPS).
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

from analysis.nmpc.options import NMPCOptions
from analysis.nmpc.prediction_model import CoarseFokkerPlanck

__all__ = ["ipopt_function", "ipopt_arrays"]

INPUTS = ["rho0", "rx0", "ry0", "th0", "target", "ux", "uy", "omega", "rx", "ry", "th", "rho", "lam_g"]
OUTPUTS = ["ux_opt", "uy_opt", "omega_opt", "rx_opt", "ry_opt", "th_opt", "rho_opt", "lam_g_opt", "cost"]


def ipopt_function(
    model: CoarseFokkerPlanck,
    options: NMPCOptions,
    n: int,
    u_max: float,
    omega_max: float,
    region: tuple[float, float, float, float],
) -> ca.Function:
    """The compiled Opti problem (eqs. (2), (4) as constraints; the cost of docs/nmpc.md).

    Parameters
    ----------
    model : CoarseFokkerPlanck
        The prediction model.
    options : NMPCOptions
        ``horizon``, the weights, ``max_iter``, ``tol``, ``hessian``.
    n : int
        Robots.
    u_max, omega_max : float
        Limits (``inf``: no constraint).
    region : (x0, x1, y0, y1)
        Box the planned positions stay in.

    Returns
    -------
    casadi.Function
        Inputs :data:`INPUTS`, outputs :data:`OUTPUTS`.
    """
    o, m = options, model
    H, C, h = o.horizon, m.size, m.step
    opti = ca.Opti()
    rho0, target = opti.parameter(C), opti.parameter(C)
    rx0, ry0, th0 = opti.parameter(n), opti.parameter(n), opti.parameter(n)
    Ux, Uy, W = opti.variable(n, H), opti.variable(n, H), opti.variable(n, H)
    Rx, Ry, Th = opti.variable(n, H), opti.variable(n, H), opti.variable(n, H)
    P = opti.variable(C, H)
    J = 0
    px, py, pt, pr = rx0, ry0, th0, rho0
    for k in range(H):
        opti.subject_to(Rx[:, k] == px + h * Ux[:, k])  # eq. (2), forward Euler
        opti.subject_to(Ry[:, k] == py + h * Uy[:, k])
        opti.subject_to(Th[:, k] == pt + h * W[:, k])
        opti.subject_to(m.residual_function(P[:, k], pr, Rx[:, k], Ry[:, k], Th[:, k]) == 0)  # eq. (4)
        e = P[:, k] - target
        J += h * (
            m.cell_volume * ca.sumsqr(e)
            + o.r_u * (ca.sumsqr(Ux[:, k]) + ca.sumsqr(Uy[:, k]))
            + o.r_omega * ca.sumsqr(W[:, k])
        )
        px, py, pt, pr = Rx[:, k], Ry[:, k], Th[:, k], P[:, k]
    J += o.terminal * m.cell_volume * ca.sumsqr(P[:, H - 1] - target)
    opti.minimize(J)
    if math.isfinite(u_max):
        opti.subject_to(ca.vec(Ux * Ux + Uy * Uy) <= u_max**2)
    if math.isfinite(omega_max):
        opti.subject_to(opti.bounded(-omega_max, ca.vec(W), omega_max))
    x0, x1, y0, y1 = region
    opti.subject_to(opti.bounded(x0, ca.vec(Rx), x1))
    opti.subject_to(opti.bounded(y0, ca.vec(Ry), y1))
    ipopt = {
        "print_level": 0,
        "sb": "yes",
        "max_iter": o.iteration_limit,
        "tol": o.tol,
        "hessian_approximation": o.hessian,
    }
    opti.solver("ipopt", {"print_time": False, "error_on_fail": False, "expand": True}, ipopt)
    return opti.to_function(
        "nmpc",
        [rho0, rx0, ry0, th0, target, Ux, Uy, W, Rx, Ry, Th, P, opti.lam_g],
        [Ux, Uy, W, Rx, Ry, Th, P, opti.lam_g, opti.f],
        INPUTS,
        OUTPUTS,
    )


def ipopt_arrays(out: dict[str, Any], n: int, H: int, shape: tuple[int, int]) -> dict[str, Any]:
    """The compiled function's outputs as arrays: ``u (H, n, 2)``, ``omega (H, n)``, ``R (H, n, 2)``,
    ``T (H, n)``, ``P (H, nx, ny)``, ``lam_g``, ``cost``."""
    col = lambda key: np.asarray(out[key]).reshape(n, H).T  # noqa: E731
    return {
        "u": np.stack([col("ux_opt"), col("uy_opt")], axis=-1),
        "omega": col("omega_opt"),
        "R": np.stack([col("rx_opt"), col("ry_opt")], axis=-1),
        "T": col("th_opt"),
        "P": np.asarray(out["rho_opt"]).reshape(-1, H).T.reshape(H, *shape),
        "lam_g": np.asarray(out["lam_g_opt"]).ravel(),
        "cost": float(out["cost"]),
    }
