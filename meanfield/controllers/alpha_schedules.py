"""Step I's gain ``α``: the schedules ``α(ρ)`` of the paper's virtual control (paper, eq. (6); docs page *The
controller*, "The gain α").

``v_d = −(α ∇ρ̃ − ∇(σρ))/ρ − u_W[ρ]`` divides by ``ρ``; a schedule gives ``α/ρ`` and its derivative on the faces,
so that the law (:class:`~meanfield.controllers.backstepping.BacksteppingController`) never divides by a thin crowd
itself.  Each schedule implements :class:`~meanfield.interfaces.AlphaSchedule`.
"""

from __future__ import annotations

from dataclasses import dataclass

from meanfield.errors import positive_number

__all__ = ["ConstantAlpha", "SaturatingAlpha"]


@dataclass(frozen=True)
class ConstantAlpha:
    """``α(x, t) = α₀``: the paper's plain gain.  ``|v_d|`` grows like ``1/ρ`` where the crowd is thin."""

    alpha0: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "alpha0", positive_number("controller.alpha", self.alpha0))

    def over_rho(self, rho_f):
        return self.alpha0 / rho_f

    def over_rho_derivative(self, rho_f):
        return -self.alpha0 / (rho_f * rho_f)

    def alpha(self, rho_f):
        return self.alpha0 + 0.0 * rho_f


@dataclass(frozen=True)
class SaturatingAlpha:
    """Density-scheduled gain ``α = α₀ ρ / (ρ + ρ_floor)``.

    The Step-I term becomes ``α∇ρ̃/ρ = α₀ ∇ρ̃ / (ρ + ρ_floor)``: bounded by
    ``α₀ |∇ρ̃| / ρ_floor`` where the crowd is thin, equal to the plain gain ``α₀`` where
    ``ρ ≫ ρ_floor``.  The price: ``α_inf = α₀ ρ_min / (ρ_min + ρ_floor)`` in Theorems 1–2,
    which is small where the density is small (slower guaranteed decay there).
    """

    alpha0: float
    rho_floor: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "alpha0", positive_number("controller.alpha", self.alpha0))
        object.__setattr__(self, "rho_floor", positive_number("controller.rho_floor", self.rho_floor))

    def over_rho(self, rho_f):
        return self.alpha0 / (rho_f + self.rho_floor)

    def over_rho_derivative(self, rho_f):
        d = rho_f + self.rho_floor
        return -self.alpha0 / (d * d)

    def alpha(self, rho_f):
        return self.alpha0 * rho_f / (rho_f + self.rho_floor)
