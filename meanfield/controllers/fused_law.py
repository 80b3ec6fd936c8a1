"""Step II in one compiled call: when the backstepping law can be computed by one loop, and the call.

The law of :class:`~meanfield.controllers.backstepping.BacksteppingController` (paper, eqs. (6) and (8); docs page
*The controller*) is a chain of grid operations in numpy.  In its common cases the whole chain, from the density to
the robots' inputs, is one compiled loop (:mod:`meanfield.controllers._law_loops`, docs page *Large crowds*,
"Compiled loops"):

* :func:`~meanfield.controllers._law_loops.paper_law`: the paper's Step I (eq. (6)) on a box, every sign seen;
* :func:`~meanfield.controllers._law_loops.face_law`: any grid (cut cells, signs hidden by walls), with a Step I
  that says how it is compiled (:meth:`~meanfield.controllers.step_one.StepOne.compiled`: the paper's, or Hughes'
  and the exits' potentials).

:class:`FusedLaw` decides, at every call, which loop computes the law (:meth:`FusedLaw.which`) and keeps the
loops' per-run constants; the law reads it through its public attributes only (its grid, ``ρ_*`` and ``∇ρ_*``, its
gains, schedule and σ, its previous ``v_d``).  Both paths give the same numbers to round-off
(``tests/compiled/test_core.py``, ``tests/controllers/test_law_loops_on_plans.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield._compiled.core import UNAVAILABLE
from meanfield.controllers._law_loops import PAPER_STEP_ONE, face_law, paper_law
from meanfield.controllers.beta_gamma import MinimumNormBetaGamma
from meanfield.interfaces import ControlState
from meanfield.signs.kernels import GaussianKernel
from meanfield.signs.robots import NavigationField

__all__ = ["FusedLaw"]

_NOTHING_HIDDEN = np.ones((0, 0, 0), dtype=bool)


class FusedLaw:
    """The compiled path of one law: which loop applies (:meth:`which`), the call (:meth:`inputs`), and the loops'
    constants, packed once per run.

    Parameters
    ----------
    law : BacksteppingController
        The law it computes (read through its public attributes).
    """

    def __init__(self, law: Any) -> None:
        self.law = law
        self._constants: dict[str, Any] = {}

    def reset(self) -> None:
        """Forget the packed constants (the law's grid or ``ρ_*`` changed)."""
        self._constants = {}

    def which(self, rho: np.ndarray, field: NavigationField) -> tuple[str, tuple | None] | None:
        """Which compiled call computes the law now, checked at every call (a schedule or strategy may change).

        ``("paper", None)``: :func:`~meanfield.controllers._law_loops.paper_law`, the paper's Step I (eq. (6)) on a
        box, every sign seen; ``("faces", step_one)``: :func:`~meanfield.controllers._law_loops.face_law`, any grid
        (cut cells, signs hidden by walls), Step I as the law's
        :meth:`~meanfield.controllers.backstepping.BacksteppingController.compiled_step_one` says; None: numpy.
        Both need no congested plant, a constant σ, ``W = 0``, min-norm β/γ, ``∂_t v_d`` by a backward
        difference, the paper's units, gains per robot at most, the Gaussian kernel on this grid, real C arrays.
        """
        law = self.law
        if not (
            law.congestion is None
            and not callable(law.sigma) and law.interaction is None and type(law.strategy) is MinimumNormBetaGamma
            and law.dvd_dt == "finite-difference" and law.scales is None and law.k_u.ndim <= 1
            and law.k_omega.ndim <= 1 and type(field.kernel) is GaussianKernel and field.grid is law.grid
            and rho.dtype == float and rho.shape == law.grid.shape and rho.flags.c_contiguous
            and field.positions.dtype == float and field.headings.dtype == float
        ):  # fmt: skip
            return None
        step_one = law.compiled_step_one()
        if step_one is None:
            return None
        box = step_one[0] == PAPER_STEP_ONE and law.grid.is_box and field.separable
        return ("paper", None) if box else ("faces", step_one)

    def inputs(
        self, rho: np.ndarray, field: NavigationField, t: float, step_one: tuple | None = None
    ) -> ControlState | None:
        """The law's inputs in one compiled call; None when not compiled.

        Call it only in the cases :meth:`which` names: ``step_one`` None is the paper's law on a box with the signs
        seen everywhere (:func:`~meanfield.controllers._law_loops.paper_law`); otherwise it is
        ``(step, v_free, rho_max, ∇φ)`` for :func:`~meanfield.controllers._law_loops.face_law` (``step``
        :data:`~meanfield.controllers._law_loops.PAPER_STEP_ONE` or
        :data:`~meanfield.controllers._law_loops.HUGHES_STEP_ONE`; ``∇φ`` None for the paper's).  The previous
        ``v_d`` is read from and stored in the law's ``previous_vd``, as the numpy path does.  The outputs are new
        arrays at every call (the state is kept by observers).
        """
        law = self.law
        g = law.grid
        n = len(field.positions)
        nx, ny = g.cells
        vd = (np.empty((nx - 1, ny)), np.empty((nx, ny - 1)))
        vt = (np.empty((nx - 1, ny)), np.empty((nx, ny - 1)))
        rho_t, b, gg, u, w = np.empty((nx, ny)), np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)
        prev = law.previous_vd
        have_prev = prev is not None and t > prev[0]
        h = (t - prev[0]) if have_prev else 1.0
        if step_one is None:
            px, py = prev[1] if have_prev else vd  # (unused without a previous v_d)
            cst = self._paper_constants(g, field.kernel, n)
            # the fields flat (reshape(-1): views of the outputs, which are new C-ordered arrays; a copy of an input
            # that is not C-ordered)
            out = paper_law(nx, ny, rho.reshape(-1), law.target.reshape(-1), cst, field.positions, field.cos,
                            field.sin, px.reshape(-1), py.reshape(-1), have_prev, h, rho_t.reshape(-1),
                            vd[0].reshape(-1), vd[1].reshape(-1), vt[0].reshape(-1), vt[1].reshape(-1),
                            b, gg, u, w)  # fmt: skip
        else:
            k, tg = field.kernel, law.target_gradient
            k_u, k_w = self._gains(n)
            px, py = prev[1] if have_prev else tg  # (unused without a previous v_d)
            alpha = getattr(law.alpha, "alpha0", 1.0)
            floor = getattr(law.alpha, "rho_floor", 0.0)  # the constant schedule: α/ρ = α₀/(ρ + 0)
            step, v_free, rho_max, phi = step_one
            ph = tg if phi is None else phi  # (unused by the paper's Step I)
            seen = field.cell_sight()
            rx, ry = np.ascontiguousarray(field.positions.T)
            out = face_law(
                rho, law.target, tg[0], tg[1], 1.0 / g.dx, 1.0 / g.dy, g.aperture_x, g.aperture_y, g.weight_x,
                g.weight_y, step, float(law.sigma), alpha, floor, v_free, rho_max, ph[0], ph[1],
                g.x_faces, g.x, g.y_faces, g.y, rx, ry, field.cos, field.sin, k.c, k.eta,
                _NOTHING_HIDDEN if seen is None else seen, seen is not None, k_u, k_w,
                px, py, have_prev, h, rho_t, vd[0], vd[1], vt[0], vt[1], b, gg, u, w,
            )  # fmt: skip
        if out is UNAVAILABLE:
            return None
        law.previous_vd = (t, vd)
        A, shortfall, dissipation = out
        return ControlState(v_d=vd, v_tilde=vt, rho_tilde=rho_t, b=b, g=gg, A=A, u=u, omega=w, shortfall=shortfall,
                            dissipation=dissipation, k_u=law.k_u, k_omega=law.k_omega)  # fmt: skip

    def _gains(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``k_u`` and ``k_ω`` per robot, once per team size and gain arrays."""
        law = self.law
        kept = self._constants.get("gains")
        if kept is None or kept[0] != n or kept[1] is not law.k_u or kept[2] is not law.k_omega:
            gains = (np.broadcast_to(law.k_u, (n,)).astype(float), np.broadcast_to(law.k_omega, (n,)).astype(float))
            kept = self._constants["gains"] = (n, law.k_u, law.k_omega, gains)
        return kept[3]

    def _paper_constants(self, g: Any, k: Any, n: int) -> np.ndarray:
        """:func:`~meanfield.controllers._law_loops.paper_law`'s ``cst``, packed once and kept while its sources are
        the same objects (the grid, ``∇ρ_*``, the gains, the schedule, σ) and the kernel's numbers the same."""
        law = self.law
        c = self._constants.get("paper")
        tg = law.target_gradient
        if (
            c is None or c[0] is not g or c[1] is not tg or c[2] is not law.k_u or c[3] is not law.k_omega
            or c[4] != n or c[5] is not law.alpha or c[6] is not law.sigma or c[7] != k.c or c[8] != k.eta
        ):  # fmt: skip
            alpha, floor = getattr(law.alpha, "alpha0", 1.0), getattr(law.alpha, "rho_floor", 0.0)  # constant: 0
            gains = [np.broadcast_to(law.k_u, (n,)), np.broadcast_to(law.k_omega, (n,))]
            numbers = [1.0 / g.dx, 1.0 / g.dy, float(law.sigma), alpha, floor, k.c, k.eta]
            cst = np.concatenate([tg[0].ravel(), tg[1].ravel(), g.weight_x.ravel(), g.weight_y.ravel(), g.x,
                                  g.x_faces, g.y, g.y_faces, *gains, numbers], dtype=float)  # fmt: skip
            c = self._constants["paper"] = (g, tg, law.k_u, law.k_omega, n, law.alpha, law.sigma, k.c, k.eta, cst)
        return c[9]
