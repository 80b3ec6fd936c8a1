"""Step I towards the exits: the geodesic distance to the nearest exit and the controller that follows it.

* ``φ``, the length of the shortest path from each cell to an exit inside Ω (around walls
  and pillars): :func:`meanfield.geometry.geodesic.exit_distance`.
* :class:`EvacuationController` — the paper's Step II (eq. (8)) tracking the desired field
  of Hughes' continuum model, ``v_d = −f(ρ) ∇φ − u_W[ρ]`` with ``f(ρ) = v_free (1 − ρ/ρ_max)``
  (walking speed falls with the density), instead of the paper's Step I.  Step II does not
  care which ``v_d`` it tracks: with the matching ``∂_t v_d = −f'(ρ) ρ̇ ∇φ − u_W[ρ̇]`` the law
  gives ``dV₂/dt = S − Σ k_u|b_i|² − Σ k_ω g_i²``, where the Step-I term
  ``S = ⟨∇ρ̃, (v_d + u_W)ρ − ∇(σρ)⟩`` replaces the paper's ``−∫α|∇ρ̃|²`` (reported as
  ``dissipation = −S``).  Registered as controller ``evacuation``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.controllers._law_loops import HUGHES_STEP_ONE
from meanfield.controllers.backstepping import BacksteppingController, _Prepared
from meanfield.errors import ParameterError
from meanfield.geometry.geodesic import exit_distance
from meanfield.geometry.grid import FaceField
from meanfield.interfaces import ControllerParts

__all__ = ["exit_distance", "EvacuationController"]


class EvacuationController(BacksteppingController):
    """The paper's Step II tracking Hughes' desired field towards the exits (see the module docstring).

    Parameters
    ----------
    *args : Any
        The arguments of :class:`~meanfield.controllers.backstepping.BacksteppingController` (grid, target,
        σ, α, gains, strategy, interaction, ``dvd_dt``; α is unused by this Step I).
    phi : ndarray
        The distance to the exits on the cells (:func:`exit_distance`).
    v_free : float
        Walking speed in free flow, > 0 (1.34 m/s, Weidmann, in metres and seconds).
    rho_max : float
        Density (of the toolkit's unit-mass ρ) at which walking stops, > 0; ``inf``: no congestion.
    **kwargs : Any
        Keyword arguments of :class:`~meanfield.controllers.backstepping.BacksteppingController`.
    """

    requires_exits = True
    """It steers towards the region's exits: a region without exits has nothing to offer it."""
    stability_step = None
    """Hughes' Step I (``v_d = -f(ρ) ∇φ``) is not the sampled diffusion the paper's step bounds."""

    def __init__(self, *args: Any, phi: np.ndarray, v_free: float = 1.34, rho_max: float = math.inf, **kwargs: Any):
        super().__init__(*args, **kwargs)
        if not (math.isfinite(v_free) and v_free > 0):
            raise ParameterError("controller.options.v_free", v_free, "a walking speed > 0")
        if not rho_max > 0:
            raise ParameterError("controller.options.rho_max", rho_max, "a density > 0, or inf for no congestion")
        self.v_free, self.rho_max = float(v_free), float(rho_max)
        finite = np.where(np.isfinite(phi), phi, 0.0)
        self.grad_phi = self.grid.gradient(finite)

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> EvacuationController:
        """Registry factory (kind ``controller``, name ``evacuation``): options ``v_free``, ``rho_max``."""
        from meanfield.geometry.exits import exit_segments

        allowed = {"v_free", "rho_max"}
        unknown = sorted(set(parts.options) - allowed)
        if unknown:
            raise ParameterError("controller.options", unknown, f"options among {sorted(allowed)}")
        phi = exit_distance(parts.grid, exit_segments(parts.region))
        opts = {k: float(v) for k, v in parts.options.items()}
        return cls(*cls.law_arguments(parts), phi=phi, scales=parts.scales, **opts)

    def _speed(self, rf: Any) -> tuple[Any, Any]:
        """``f(ρ)`` and ``f'(ρ)`` on the faces (0 beyond ``ρ_max``; complex ρ allowed for derivative checks)."""
        if math.isinf(self.rho_max):
            return self.v_free + 0 * rf, 0 * rf
        moving = np.real(rf) < self.rho_max
        f = np.where(moving, self.v_free * (1 - rf / self.rho_max), 0 * rf)
        return f, np.where(moving, -self.v_free / self.rho_max + 0 * rf, 0 * rf)

    def _compiled_step_one(self) -> tuple[int, float, float, Any] | None:
        """Hughes' Step I for :func:`~meanfield.controllers._law_loops.face_law` (this class exactly: a subclass
        may change Step I again, and then takes the numpy path)."""
        if type(self) is not EvacuationController:
            return None
        return HUGHES_STEP_ONE, self.v_free, self.rho_max, self.grad_phi

    def _virtual_velocity(self, p: _Prepared) -> FaceField:
        out = [-self._speed(p.rf[k])[0] * self.grad_phi[k] for k in range(2)]
        if p.uw is not None:
            out = [out[k] - p.uw[k] for k in range(2)]
        return out[0], out[1]

    def _virtual_velocity_rate(self, p: _Prepared, rho_dot: np.ndarray) -> FaceField:
        df = self.grid.face_average(rho_dot)
        out = [-self._speed(p.rf[k])[1] * df[k] * self.grad_phi[k] for k in range(2)]
        uw = self.interaction_on_faces(rho_dot)
        if uw is not None:
            out = [out[0] - uw[0], out[1] - uw[1]]
        return out[0], out[1]

    def _dissipation(self, p: _Prepared) -> float:
        """``−S = ⟨∇ρ̃, ∇(σρ) − (v_d + u_W)ρ⟩``: what Step I's own flux does to ``½∫ρ̃²``, negated."""
        v = self._virtual_velocity(p)
        if p.uw is not None:
            v = (v[0] + p.uw[0], v[1] + p.uw[1])
        return self.grid.face_inner(p.grt, (p.gs[0] - v[0] * p.rf[0], p.gs[1] - v[1] * p.rf[1]))
