"""Options of the NMPC baseline: the ``[controller.options.nmpc]`` table of the ``nmpc`` controller.

:class:`NMPCOptions` parses and validates the options of
:class:`~analysis.nmpc.controller.NMPCController` (docs/nmpc.md, "Options"); a bad key or value
raises :class:`~meanfield.errors.ParameterError` naming ``controller.options.nmpc.<key>``.
:data:`FLUXES`, :data:`HESSIANS` and :data:`SOLVERS` are the allowed values of ``flux`` (the
advective fluxes of :class:`~analysis.nmpc.prediction_model.CoarseFokkerPlanck`), ``hessian`` and ``solver``.
Everything here is re-exported by :mod:`analysis.nmpc`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = ["FLUXES", "HESSIANS", "SOLVERS", "NMPCOptions"]

FLUXES = ("upwind", "central")
"""Advective fluxes of the coarse model: upwind (positive, first order) or central (second order)."""

HESSIANS = ("exact", "limited-memory", "gauss-newton")
"""The Hessian: exact (both solvers), L-BFGS (IPOPT only) or Gauss–Newton (SQP only)."""

SOLVERS = ("sqp", "ipopt")
"""The NLP solvers: SQP on the inputs (:mod:`analysis.nmpc.sqp`) or IPOPT on all states (:mod:`analysis.nmpc.ipopt`)."""

DEFAULT_ITERATIONS = {"sqp": 3, "ipopt": 50}
"""``max_iter`` when not given: QPs per solve (SQP; real-time iterations) or IPOPT iterations."""


def _opt_name(key: str) -> str:
    """The name of option ``key`` in error messages: ``controller.options.nmpc.<key>``."""
    return f"controller.options.nmpc.{key}"


def _int_option(key: str, value: Any, lo: int) -> int:
    """Option ``key`` as an integer >= ``lo`` (an integral float is accepted; a bool is not)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float)):
        raise ParameterError(_opt_name(key), value, f"an integer >= {lo}")
    if isinstance(value, float) and not value.is_integer():
        raise ParameterError(_opt_name(key), value, f"an integer >= {lo}")
    if value < lo:
        raise ParameterError(_opt_name(key), value, f"an integer >= {lo}")
    return int(value)


def _float_option(key: str, value: Any, *, positive: bool) -> float:
    """Option ``key`` as a finite float, > 0 if ``positive`` else >= 0 (a bool is refused)."""
    allowed = "a finite number > 0" if positive else "a finite number >= 0"
    if isinstance(value, bool):
        raise ParameterError(_opt_name(key), value, allowed)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(_opt_name(key), value, allowed) from None
    if not math.isfinite(x) or x < 0 or (positive and x == 0):
        raise ParameterError(_opt_name(key), value, allowed)
    return x


@dataclass(frozen=True)
class NMPCOptions:
    """Options of :class:`~analysis.nmpc.controller.NMPCController` (``[controller.options.nmpc]`` of a scenario).

    Parameters
    ----------
    horizon : int
        ``H``, prediction steps (>= 1).
    cells : int or (int, int)
        Coarse cells ``(nx, ny)`` over Ω's bounding box (each >= 3).
    period : float
        ``Δt_c``: time between solves (> 0).  Inputs follow the plan in between.
    step : float or None
        ``Δt_p``: prediction step (> 0); None means ``period``.
    r_u, r_omega : float
        Input weights (>= 0) of ``r_u |u_i|²`` and ``r_ω ω_i²``.
    terminal : float
        ``q_T`` (>= 0, a time): weight of the terminal error ``‖ρ_H - ρ_*‖²``.
    flux : {"upwind", "central"}
        Advective fluxes of the coarse model.
    max_iter : int or None
        Iteration limit per solve (>= 1): QPs (SQP) or IPOPT iterations; None means
        :data:`DEFAULT_ITERATIONS` of the solver.
    tol : float
        Tolerance (> 0): IPOPT's, or the SQP's bound on the predicted decrease relative to ``1 + J``.
    hessian : {"exact", "limited-memory", "gauss-newton"}
        The Hessian (L-BFGS only with IPOPT, Gauss–Newton only with SQP).
    warm_start : bool
        Start each solve from the previous solution shifted (otherwise from zero inputs).
    solver : {"sqp", "ipopt"}
        SQP on the inputs with the exact Hessian (:mod:`analysis.nmpc.sqp`), or IPOPT on the
        full space (:mod:`analysis.nmpc.ipopt`).  Same problem, same minimisers.
    blocks : list of int or None
        Move blocking (SQP only): prediction steps per input block, summing to ``horizon``; an
        input is held over its block, ``[1] * horizon`` is no blocking.  None: the first two
        steps free, the rest one block (``[1, 1, horizon - 2]``; no blocking for ``horizon <= 3``).
    spread : bool or None
        Spread each solve over the control steps that follow it (SQP only): one slice per step
        (a derivative evaluation, or a QP), the plan adopted when done and applied from the
        time the solve started; the robots hold still until the first plan.  Bounds the compute
        of every step by a slice instead of a whole solve.  None: true with SQP, false with IPOPT.
    """

    horizon: int = 5
    cells: tuple[int, int] = (10, 10)
    period: float = 0.2
    step: float | None = None
    r_u: float = 0.1
    r_omega: float = 1e-3
    terminal: float = 1.0
    flux: str = "upwind"
    max_iter: int | None = None
    tol: float = 1e-6
    hessian: str = "exact"
    warm_start: bool = True
    solver: str = "sqp"
    blocks: tuple[int, ...] | None = None
    spread: bool | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "horizon", _int_option("horizon", self.horizon, 1))
        cells = self.cells
        if isinstance(cells, (int, np.integer, float)) and not isinstance(cells, bool):
            cells = (cells, cells)
        try:
            cx, cy = cells
        except (TypeError, ValueError):
            raise ParameterError(_opt_name("cells"), self.cells, "an integer >= 3 or a pair [nx, ny]") from None
        set_(self, "cells", (_int_option("cells", cx, 3), _int_option("cells", cy, 3)))
        set_(self, "period", _float_option("period", self.period, positive=True))
        if self.step is not None:
            set_(self, "step", _float_option("step", self.step, positive=True))
        for key in ("r_u", "r_omega", "terminal"):
            set_(self, key, _float_option(key, getattr(self, key), positive=False))
        if self.flux not in FLUXES:
            raise ParameterError(_opt_name("flux"), self.flux, " or ".join(map(repr, FLUXES)))
        if self.max_iter is not None:
            set_(self, "max_iter", _int_option("max_iter", self.max_iter, 1))
        set_(self, "tol", _float_option("tol", self.tol, positive=True))
        if self.solver not in SOLVERS:
            raise ParameterError(_opt_name("solver"), self.solver, " or ".join(map(repr, SOLVERS)))
        allowed = [h for h in HESSIANS if h != ("gauss-newton" if self.solver == "ipopt" else "limited-memory")]
        if self.hessian not in allowed:
            raise ParameterError(_opt_name("hessian"), self.hessian, f"with solver {self.solver!r}: {allowed}")
        if self.blocks is not None:
            try:
                blocks = tuple(_int_option("blocks", b, 1) for b in self.blocks)
            except TypeError:
                raise ParameterError(_opt_name("blocks"), self.blocks, "a list of integers >= 1") from None
            if sum(blocks) != self.horizon or self.solver != "sqp":
                raise ParameterError(
                    _opt_name("blocks"),
                    self.blocks,
                    f"integers >= 1 summing to horizon = {self.horizon} (solver 'sqp')",
                )
            set_(self, "blocks", blocks)
        if self.spread is None:
            set_(self, "spread", self.solver == "sqp")
        for key in ("warm_start", "spread"):
            if not isinstance(getattr(self, key), (bool, np.bool_)):
                raise ParameterError(_opt_name(key), getattr(self, key), "true or false")
            set_(self, key, bool(getattr(self, key)))
        if self.spread and self.solver != "sqp":
            raise ParameterError(_opt_name("spread"), self.spread, "false with solver 'ipopt' (one call, not sliced)")

    @property
    def iteration_limit(self) -> int:
        """``max_iter``, or the solver's default (:data:`DEFAULT_ITERATIONS`)."""
        return DEFAULT_ITERATIONS[self.solver] if self.max_iter is None else self.max_iter

    @property
    def input_blocks(self) -> tuple[int, ...]:
        """``blocks``, or by default ``(1, 1, horizon - 2)`` (one block per step for ``horizon <= 3``)."""
        if self.blocks is not None:
            return self.blocks
        return (1, 1, self.horizon - 2) if self.horizon > 3 else (1,) * self.horizon

    @property
    def prediction_step(self) -> float:
        """``Δt_p`` (``step``, or ``period`` when ``step`` is None)."""
        return self.period if self.step is None else self.step

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | None) -> NMPCOptions:
        """Options from a scenario's ``controller.options.nmpc`` table.

        Raises
        ------
        ParameterError
            Naming ``controller.options.nmpc.<key>`` for an unknown key or a bad value.
        """
        if options is None:
            return cls()
        if not isinstance(options, Mapping):
            raise ParameterError("controller.options.nmpc", options, "a table of NMPC options")
        known = [f.name for f in dataclasses.fields(cls)]
        for key in options:
            if key not in known:
                raise ParameterError(_opt_name(key), options[key], f"a known NMPC option: one of {known}")
        return cls(**dict(options))
