"""Step II's extra inputs: the rules that choose β and γ (paper, eq. (8) and (9); docs page *The controller*,
"Choosing β and γ: the minimum-norm rule").

A rule takes ``(b, g, A)`` and returns :class:`~meanfield.interfaces.ExtraInputs` ``(δu, δω, shortfall)`` with
``Σ_i b_i·δu_i − g_i δω_i = A − shortfall``; each implements :class:`~meanfield.interfaces.BetaGammaStrategy` and is
registered by name (``controller.beta_gamma``; the speed-limited ``bounded`` lives in :mod:`analysis.bounded`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from meanfield.capabilities import BetaGammaCapabilities
from meanfield.errors import ParameterError
from meanfield.interfaces import ExtraInputs

__all__ = ["MinimumNormBetaGamma", "UserBetaGamma"]


class MinimumNormBetaGamma:
    """Minimum-norm solution: ``δu_i = A b_i / Z``, ``δω_i = -A g_i / Z``.

    Derived on the docs page *The controller* (``docs/controller.md#choosing-beta-and-gamma``).

    Equivalent to ``β_il = (b_i^(l))²/Z`` and ``γ_i = g_i²/Z`` in the paper's eq. (8):
    non-negative, summing to 1, zero where the integral is zero, and with no division by
    a small integral.  When ``Z = 0`` (ṽ orthogonal to every kernel column) nothing can
    cancel ``A``: the inputs are zero and the shortfall is ``A``.
    """

    name = "min-norm"
    capabilities: ClassVar[BetaGammaCapabilities] = BetaGammaCapabilities(accepts_kernel_scaling=True)
    """Its inputs follow the law's own units (``controller.scaling = "kernel"``): it has no limits of its own."""

    @classmethod
    def from_scenario(cls, scenario: Any) -> MinimumNormBetaGamma:
        """Registry factory (kind ``beta_gamma``, name ``min-norm``): needs nothing of the scenario."""
        return cls()

    def __call__(self, b: np.ndarray, g: np.ndarray, A: float) -> ExtraInputs:
        Z = (b * b).sum() + (g * g).sum()
        if Z == 0:
            return ExtraInputs(np.zeros_like(b), np.zeros_like(g), A)
        s = A / Z
        return ExtraInputs(s * b, -s * g, 0.0 * A)


class UserBetaGamma:
    """Wraps a user rule ``(b, g, A) -> (β (n, 2), γ (n,))`` into extra inputs.

    The rule may return None when no admissible weights exist (e.g. every integral is
    zero); the inputs are then zero and the whole ``A`` is reported as the shortfall.

    The rule's output is checked against the paper's constraints (eq. (9)):
    ``Σ β + Σ γ = 1`` and ``β_il = 0`` where ``b_i^(l) = 0`` (``γ_i`` likewise).  Then
    ``δu_i^(l) = β_il A / b_i^(l)`` and ``δω_i = -γ_i A / g_i`` (paper, eq. (8)).
    """

    name = "user"

    def __init__(self, rule: Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]):
        if not callable(rule):
            raise ParameterError("beta_gamma", rule, "a callable (b, g, A) -> (beta, gamma)")
        self.rule = rule

    def __call__(self, b: np.ndarray, g: np.ndarray, A: float) -> ExtraInputs:
        weights = self.rule(b, g, A)
        if weights is None:  # the rule found no admissible weights: nothing cancels A
            return ExtraInputs(np.zeros_like(b), np.zeros_like(g), A)
        beta, gamma = weights
        beta = np.asarray(beta, float).reshape(b.shape)
        gamma = np.asarray(gamma, float).reshape(g.shape)
        total = beta.sum() + gamma.sum()
        if not np.isfinite(total) or abs(total - 1.0) > 1e-9:
            raise ParameterError("beta_gamma", f"sum {total}", "β and γ summing to 1 (eq. (9))")
        if np.any((b == 0) & (beta != 0)) or np.any((g == 0) & (gamma != 0)):
            raise ParameterError(
                "beta_gamma", "non-zero weight on a zero integral", "β_il = 0 where b_il = 0, γ_i = 0 where g_i = 0"
            )
        with np.errstate(divide="ignore", invalid="ignore"):
            du = np.where(b != 0, beta * A / np.where(b != 0, b, 1.0), 0.0)
            dw = np.where(g != 0, -gamma * A / np.where(g != 0, g, 1.0), 0.0)
        done = (b * du).sum() - (g * dw).sum()
        return ExtraInputs(du, dw, A - done)
