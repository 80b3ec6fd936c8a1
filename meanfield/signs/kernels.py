"""Navigation kernels K(ξ, θ) of the robots' signs and interaction potentials W.

Navigation field of one robot (paper, Section III; docs pages *The model* and *The paper's
slips*, ``docs/paper_slips.md#kernel-definitions``)::

    K(ξ, θ) = K̄(ξ) e(θ),            e(θ) = (cos θ, sin θ)
    K̄(ξ)    = c exp(-|ξ|²/η)         (c: strength, η: range)
    K_ξ     = ∂K/∂ξ = e(θ) ∇K̄(ξ)ᵀ    (2×2)
    K_θ     = ∂K/∂θ = K̄(ξ) e⊥(θ),    e⊥(θ) = (-sin θ, cos θ)

Any decaying magnitude K̄ with its gradient can be plugged in through
:class:`CustomKernel`.  Every function here accepts complex arrays too (used by the
complex-step tests of the Lyapunov identities).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from meanfield.errors import positive_number
from meanfield.signs._reach_loops import boxes_on_grid

__all__ = [
    "REACH_FRACTION",
    "NavigationKernel",
    "GaussianKernel",
    "CustomKernel",
    "kernel_value",
    "kernel_jacobian_xi",
    "kernel_jacobian_theta",
]

_MOVED_TO_INTERACTION = ("InteractionPotential", "GaussianPotential")
"""The interaction potential's names, in :mod:`meanfield.signs.interaction` since 0.2.0 (a "kernel" here is a sign's
field; the old names warn until 0.3.0)."""


def __getattr__(name: str) -> Any:
    if name in _MOVED_TO_INTERACTION:
        from meanfield.errors import deprecated
        from meanfield.signs import interaction

        deprecated(f"meanfield.signs.kernels.{name}", f"use meanfield.signs.interaction.{name}")
        return getattr(interaction, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


_NO_SIGHT = np.ones((0, 0, 0), dtype=bool)
"""The sight rows of :func:`reached_cells` without walls (never read)."""

REACH_FRACTION = 0.05
"""A sign *reaches* a point where its field is at least this share of one kernel's peak: a human there who sees the
robot is guided (:attr:`meanfield.crowds.agent_crowd.AgentCrowd.reached`, the stragglers of ``summary.json``, who
learns the way with ``view.memory``), and coverage's ``unswept`` weight counts the cell as swept."""


@runtime_checkable
class NavigationKernel(Protocol):
    """Magnitude K̄(ξ) of a sign's field and its gradient ∇K̄(ξ)."""

    def magnitude(self, xi_x: Any, xi_y: Any) -> np.ndarray:
        """K̄ at offsets ``ξ = x - R``."""
        ...

    def magnitude_gradient(self, xi_x: Any, xi_y: Any) -> tuple[np.ndarray, np.ndarray]:
        """∇K̄ at offsets ``ξ``."""
        ...


@dataclass(frozen=True)
class GaussianKernel:
    """The paper's kernel ``K̄(ξ) = c exp(-|ξ|²/η)``.

    Parameters
    ----------
    c : float
        Strength (peak speed of the guided humans), > 0.
    eta : float
        Range (squared length scale), > 0.  ``K̄`` falls below ``ε`` outside the disk of
        radius ``sqrt(η ln(c/ε))``.
    """

    c: float
    eta: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "c", positive_number("kernel.c", self.c))
        object.__setattr__(self, "eta", positive_number("kernel.eta", self.eta))

    separable = True

    def factor(self, d: Any) -> np.ndarray:
        """One-dimensional factor ``exp(-d²/η)``: ``K̄(ξ) = c·factor(ξx)·factor(ξy)``."""
        return np.exp(-(d * d) / self.eta)

    def magnitude(self, xi_x: Any, xi_y: Any) -> np.ndarray:
        """``K̄(ξ) = c exp(-|ξ|²/η)``."""
        return self.c * np.exp(-(xi_x * xi_x + xi_y * xi_y) / self.eta)

    def magnitude_gradient(self, xi_x: Any, xi_y: Any) -> tuple[np.ndarray, np.ndarray]:
        """``∇K̄(ξ) = -(2/η) ξ K̄(ξ)``."""
        k = self.magnitude(xi_x, xi_y)
        s = -2.0 / self.eta
        return s * xi_x * k, s * xi_y * k

    def radius(self, eps: float) -> float:
        """Radius ``r_ε = sqrt(η ln(c/ε))`` of the disk where ``K̄ > ε`` (0 if ``ε >= c``)."""
        eps = positive_number("eps", eps)
        return math.sqrt(self.eta * math.log(self.c / eps)) if eps < self.c else 0.0


@dataclass(frozen=True)
class CustomKernel:
    """A user kernel from two callables.

    Parameters
    ----------
    magnitude_fn : callable
        ``(xi_x, xi_y) -> K̄`` (arrays of equal shape), decaying with ``|ξ|``.
    gradient_fn : callable
        ``(xi_x, xi_y) -> (∂K̄/∂ξx, ∂K̄/∂ξy)``.
    """

    magnitude_fn: Callable[[Any, Any], Any]
    gradient_fn: Callable[[Any, Any], tuple[Any, Any]]

    separable = False

    def magnitude(self, xi_x: Any, xi_y: Any) -> np.ndarray:
        """K̄ from the user callable."""
        return self.magnitude_fn(xi_x, xi_y)

    def magnitude_gradient(self, xi_x: Any, xi_y: Any) -> tuple[np.ndarray, np.ndarray]:
        """∇K̄ from the user callable."""
        gx, gy = self.gradient_fn(xi_x, xi_y)
        return gx, gy


def kernel_value(kernel: NavigationKernel, xi_x: Any, xi_y: Any, theta: Any):
    """``K(ξ, θ) = K̄(ξ) e(θ)``: the velocity a sign at offset ``ξ`` asks for (paper, §III).

    Returns
    -------
    (Kx, Ky) : arrays broadcast from the inputs.
    """
    k = kernel.magnitude(xi_x, xi_y)
    return k * np.cos(theta), k * np.sin(theta)


def kernel_jacobian_xi(kernel: NavigationKernel, xi_x: Any, xi_y: Any, theta: Any) -> np.ndarray:
    """``K_ξ = ∂K/∂ξ = e(θ) ∇K̄(ξ)ᵀ`` (paper, eq. (5)); shape ``(..., 2, 2)``, rows = components."""
    gx, gy = kernel.magnitude_gradient(xi_x, xi_y)
    c, s = np.cos(theta), np.sin(theta)
    gx, gy, c, s = np.broadcast_arrays(gx, gy, c, s)
    return np.stack([np.stack([c * gx, c * gy], -1), np.stack([s * gx, s * gy], -1)], -2)


def kernel_jacobian_theta(kernel: NavigationKernel, xi_x: Any, xi_y: Any, theta: Any):
    """``K_θ = ∂K/∂θ = K̄(ξ) e⊥(θ)`` (paper, eq. (5)); returns ``(K_θx, K_θy)``."""
    k = kernel.magnitude(xi_x, xi_y)
    return -k * np.sin(theta), k * np.cos(theta)


# ---------------------------------------------------------------------- interaction W
def reached_cells(kernel: NavigationKernel, robots: np.ndarray, grid: Any, sight: Any = None) -> np.ndarray:
    """Which cells each robot's sign reaches: ``(n, nx, ny)``, True in a cell of Ω whose centre the robot sees and
    where its kernel is at least :data:`REACH_FRACTION` of its peak (the controllers' record of where signs have
    been, docs page *Buildings*).

    Parameters
    ----------
    kernel : NavigationKernel
    robots : ndarray, shape (n, 2)
    grid : Grid
    sight : SightLines, optional
        The walls that hide a cell from a robot (None: every cell is seen).
    """
    robots = np.real(np.asarray(robots, float)).reshape(-1, 2)
    X, Y = grid.centers
    peak = float(np.max(np.abs(kernel.magnitude(np.zeros(1), np.zeros(1)))))
    floor = REACH_FRACTION * peak
    radius = getattr(kernel, "radius", None)  # a kernel that says where it falls below a level (GaussianKernel's)
    if radius is None or not np.isfinite(robots).all():
        reach = np.abs(kernel.magnitude(X[None] - robots[:, 0, None, None], Y[None] - robots[:, 1, None, None]))
        reach = reach >= floor
    else:  # the same test, on the cells within the kernel's reach of each robot (nowhere else can it pass)
        r = radius(floor) * (1.0 + 1e-9) + max(grid.dx, grid.dy)
        i0, i1 = np.searchsorted(grid.x, robots[:, 0] - r), np.searchsorted(grid.x, robots[:, 0] + r, side="right")
        j0, j1 = np.searchsorted(grid.y, robots[:, 1] - r), np.searchsorted(grid.y, robots[:, 1] + r, side="right")
        # every robot's box of one size (the largest, moved inside the grid: its cells beyond the robot's own box are
        # beyond the kernel's reach, where the test fails), all tested at once; a cell's centre is (x_i, y_j)
        (nx, ny), n = grid.shape, len(robots)
        bx, by = int((i1 - i0).max(initial=0)), int((j1 - j0).max(initial=0))
        i_start, j_start = np.minimum(i0, nx - bx), np.minimum(j0, ny - by)
        xi_x = grid.x[i_start[:, None] + np.arange(bx)] - robots[:, 0, None]  # (n, bx)
        xi_y = grid.y[j_start[:, None] + np.arange(by)] - robots[:, 1, None]  # (n, by)
        inside = np.abs(kernel.magnitude(xi_x[:, :, None], xi_y[:, None, :])) >= floor
        seen = _NO_SIGHT if sight is None else np.asarray(sight.cell_rows(grid, robots), bool).reshape(n, nx, ny)
        # the boxes on the grid, on Ω's cells each robot sees, in one compiled pass (meanfield.signs._reach_loops)
        active = np.ascontiguousarray(grid.active, bool)
        return boxes_on_grid(np.ascontiguousarray(inside), i_start, j_start, active, np.ascontiguousarray(seen),
                             sight is not None, np.empty((n, nx, ny), dtype=bool))  # fmt: skip
    reach &= grid.active
    if sight is not None:
        reach &= np.asarray(sight.cell_rows(grid, robots), bool).reshape(reach.shape)
    return reach
