"""Step I, the virtual control ``v_d`` the robots' field tracks: a part the backstepping law is composed with.

The law (:class:`~meanfield.controllers.backstepping.BacksteppingController`) computes the quantities of one
density once (:class:`Prepared`) and asks its Step I for four things, the whole of what Step II needs of it
(docs page *The controller*; paper, eqs. (6) and (8)):

* ``v_d`` on the faces;
* its rate ``∂_t v_d`` along ``∂_t ρ = ρ̇``, for ``A = ∫ ṽᵀ(ρ∇ρ̃ − ∂_t v_d)`` (the chain rule, exact for the law's
  own terms);
* the dissipation term of ``dV₂/dt`` (``∫α|∇ρ̃|²`` for the paper's; ``−S`` for another, docs page *Buildings*);
* its compiled form, where :func:`~meanfield.controllers._law_loops.face_law` computes it (or None: numpy).

:class:`PaperStepOne` is the paper's eq. (6); the evacuation law's Step I towards the exits is
:class:`~meanfield.controllers.evacuation.ExitsStepOne`.  A new Step I is a class with these methods, given to the
law (``BacksteppingController(..., step_one=...)``): no law overrides another's methods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from meanfield.controllers._law_loops import PAPER_STEP_ONE
from meanfield.controllers.alpha_schedules import ConstantAlpha, SaturatingAlpha
from meanfield.geometry.grid import FaceField

__all__ = ["Prepared", "StepOne", "PaperStepOne"]


@dataclass
class Prepared:
    """The quantities of one density shared by the terms of the law (computed once per evaluation).

    Attributes
    ----------
    rho, rho_t : ndarray
        ``ρ`` and ``ρ̃ = ρ − ρ_*`` on the cells.
    rf : FaceField
        ``ρ`` on the faces (1 on closed faces).
    grt : FaceField
        ``∇ρ̃``.
    sigma : float or ndarray
        ``σ`` on the cells.
    gs : FaceField
        ``∇(σρ)``.
    q : FaceField
        ``α/ρ`` of the law's schedule on the faces.
    uw : FaceField or None
        ``u_W[ρ]`` (None: ``W = 0``).
    """

    rho: np.ndarray
    rho_t: np.ndarray
    rf: FaceField
    grt: FaceField
    sigma: Any
    gs: FaceField
    q: FaceField
    uw: FaceField | None


@runtime_checkable
class StepOne(Protocol):
    """What the law asks of its Step I (module docstring); ``law`` is the law that asks, for its grid, schedule and
    interaction."""

    def prepare(self, law: Any, p: Prepared) -> Prepared:
        """``p``, with what this Step I needs of the density besides (e.g. Hughes' potential at it)."""
        ...

    def virtual_velocity(self, law: Any, p: Prepared) -> FaceField:
        """``v_d`` on the faces."""
        ...

    def virtual_velocity_rate(self, law: Any, p: Prepared, rho_dot: np.ndarray) -> FaceField:
        """``∂_t v_d`` along ``∂_t ρ = rho_dot``."""
        ...

    def dissipation(self, law: Any, p: Prepared) -> float:
        """The Step-I term of ``−dV₂/dt``."""
        ...

    def compiled(self, law: Any) -> tuple[int, float, float, FaceField | None] | None:
        """``(step, v_free, ρ_max, ∇φ)`` for :func:`~meanfield.controllers._law_loops.face_law`, or None."""
        ...


class PaperStepOne:
    """The paper's Step I, eq. (6): ``v_d = −(α ∇ρ̃ − ∇(σρ))/ρ − u_W[ρ]`` on the faces."""

    def prepare(self, law: Any, p: Prepared) -> Prepared:
        return p

    def virtual_velocity(self, law: Any, p: Prepared) -> FaceField:
        out = [-p.q[k] * p.grt[k] + p.gs[k] / p.rf[k] for k in range(2)]
        if p.uw is not None:
            out = [out[k] - p.uw[k] for k in range(2)]
        return out[0], out[1]

    def virtual_velocity_rate(self, law: Any, p: Prepared, rho_dot: np.ndarray) -> FaceField:
        """With ``q = α/ρ`` the schedule: ``∂_t v_d = −(q'(ρ) ρ̇ ∇ρ̃ + q ∇ρ̇) + ∇(σρ̇)/ρ − ∇(σρ) ρ̇/ρ² − u_W[ρ̇]``."""
        g = law.grid
        df = g.face_average(rho_dot)
        grd = g.gradient(rho_dot)
        gsd = g.gradient(p.sigma * rho_dot) if callable(law.sigma) else (p.sigma * grd[0], p.sigma * grd[1])
        out = []
        for k in range(2):
            dq = law.alpha.over_rho_derivative(p.rf[k])
            inv = 1.0 / p.rf[k]
            out.append(-(dq * df[k] * p.grt[k] + p.q[k] * grd[k]) + (gsd[k] - p.gs[k] * df[k] * inv) * inv)
        uw = law.interaction_on_faces(rho_dot)
        if uw is not None:
            out = [out[0] - uw[0], out[1] - uw[1]]
        return out[0], out[1]

    def dissipation(self, law: Any, p: Prepared) -> float:
        """``∫ α |∇ρ̃|²`` on the faces."""
        a = (p.q[0] * p.rf[0], p.q[1] * p.rf[1])  # α = (α/ρ)·ρ, as used in v_d
        return law.grid.face_inner((a[0] * p.grt[0], a[1] * p.grt[1]), p.grt)

    def compiled(self, law: Any) -> tuple[int, float, float, FaceField | None] | None:
        """The compiled paper's Step I with the constant or saturating α (another schedule: None)."""
        if type(law.alpha) in (ConstantAlpha, SaturatingAlpha):
            return PAPER_STEP_ONE, 0.0, math.inf, None
        return None
