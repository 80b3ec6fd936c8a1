"""Options of the NMPC baseline: the ``[controller.options]`` table of the ``nmpc`` controller.

:class:`NMPCOptions` parses and validates the options of
:class:`~analysis.nmpc.NMPCController` (docs/nmpc.md, "Options"); a bad key or value
raises :class:`~meanfield.errors.ParameterError` naming ``controller.options.<key>``.
:data:`FLUXES` and :data:`HESSIANS` are the allowed values of ``flux`` (the advective
fluxes of :class:`~analysis.nmpc_model.CoarseFokkerPlanck`) and ``hessian`` (IPOPT's).
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

__all__ = ["FLUXES", "HESSIANS", "NMPCOptions"]

FLUXES = ("upwind", "central")
"""Advective fluxes of the coarse model: upwind (positive, first order) or central (second order)."""

HESSIANS = ("exact", "limited-memory")
"""IPOPT's Hessian: exact (CasADi's automatic differentiation) or L-BFGS."""


def _opt_name(key: str) -> str:
    """The name of option ``key`` in error messages: ``controller.options.<key>``."""
    return f"controller.options.{key}"


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
    """Options of :class:`~analysis.nmpc.NMPCController` (``[controller.options]`` of a scenario).

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
    max_iter : int
        IPOPT iteration limit per solve (>= 1).
    tol : float
        IPOPT tolerance (> 0).
    hessian : {"exact", "limited-memory"}
        IPOPT's Hessian.
    warm_start : bool
        Start each solve from the previous solution shifted (otherwise from zero inputs).
    """

    horizon: int = 5
    cells: tuple[int, int] = (10, 10)
    period: float = 0.2
    step: float | None = None
    r_u: float = 0.1
    r_omega: float = 1e-3
    terminal: float = 1.0
    flux: str = "upwind"
    max_iter: int = 50
    tol: float = 1e-6
    hessian: str = "exact"
    warm_start: bool = True

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
        set_(self, "max_iter", _int_option("max_iter", self.max_iter, 1))
        set_(self, "tol", _float_option("tol", self.tol, positive=True))
        if self.hessian not in HESSIANS:
            raise ParameterError(_opt_name("hessian"), self.hessian, " or ".join(map(repr, HESSIANS)))
        if not isinstance(self.warm_start, (bool, np.bool_)):
            raise ParameterError(_opt_name("warm_start"), self.warm_start, "true or false")
        set_(self, "warm_start", bool(self.warm_start))

    @property
    def prediction_step(self) -> float:
        """``Δt_p`` (``step``, or ``period`` when ``step`` is None)."""
        return self.period if self.step is None else self.step

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | None) -> NMPCOptions:
        """Options from a scenario's ``controller.options`` table.

        Raises
        ------
        ParameterError
            Naming ``controller.options.<key>`` for an unknown key or a bad value.
        """
        if options is None:
            return cls()
        if not isinstance(options, Mapping):
            raise ParameterError("controller.options", options, "a table of NMPC options")
        known = [f.name for f in dataclasses.fields(cls)]
        for key in options:
            if key not in known:
                raise ParameterError(_opt_name(key), options[key], f"a known NMPC option: one of {known}")
        return cls(**dict(options))
