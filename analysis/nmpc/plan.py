"""One solution of the NMPC problem (:class:`NMPCSolution`) and the robot state a solve starts from.

Shared by the solvers of :class:`~analysis.nmpc.controller.NMPCController` (IPOPT and SQP); re-exported
by :mod:`analysis.nmpc`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from meanfield.signs.robots import NavigationField, RobotTeam

__all__ = ["NMPCSolution", "robot_state"]


@dataclass
class NMPCSolution:
    """One solution of the optimal-control problem.

    Attributes
    ----------
    u : ndarray (H, n, 2)
        Planned velocities ``u_{ik}`` (within the speed limit).
    omega : ndarray (H, n)
        Planned turn rates.
    positions, headings : ndarray (H+1, n, 2), (H+1, n)
        Predicted robot states, the initial state first.
    rho : ndarray (H+1, nx, ny)
        Predicted coarse densities, ``ρ_0`` first.
    cost : float
        The optimal cost.
    lam_g : ndarray
        Constraint multipliers (IPOPT's, for the next warm start; empty for SQP).
    status : str
        IPOPT's return status, or the SQP's (``"converged"``, ``"iteration_limit"``).
    success : bool
        Converged to the tolerance.
    iterations : int
        IPOPT iterations, or QPs of the SQP.
    seconds : float
        Wall time of the solve.
    damping : float
        The SQP's Levenberg–Marquardt ``ν`` at the end (for the next warm start).
    """

    u: np.ndarray
    omega: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    rho: np.ndarray
    cost: float
    lam_g: np.ndarray
    status: str
    success: bool
    iterations: int
    seconds: float
    damping: float = 0.0


def robot_state(field: NavigationField, robots: RobotTeam) -> tuple[np.ndarray, np.ndarray]:
    """``(R, θ)`` from the navigation field, else from the robot team (same instant in the loop)."""
    pos = getattr(field, "positions", None)
    if pos is None:
        pos = robots.positions
    heads = getattr(field, "headings", None)
    if heads is None:
        heads = np.arctan2(field.sin, field.cos)
    return np.array(pos, float).reshape(-1, 2), np.array(heads, float).ravel()


def __getattr__(name: str) -> object:
    if name == "NMPCPlan":  # its name before 0.2.0 (a floor plan is a Plan)
        from meanfield.errors import deprecated

        deprecated("analysis.nmpc.plan.NMPCPlan", "use analysis.nmpc.plan.NMPCSolution")
        return NMPCSolution
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
