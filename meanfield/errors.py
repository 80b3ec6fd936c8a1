"""Exceptions of the toolkit (bad parameters, numerical blow-ups) and the shared checks of a value."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["ParameterError", "SimulationDiverged", "SigmaLike", "check_sigma", "positive_number", "limit_or_inf"]


class ParameterError(ValueError):
    """An invalid parameter, named with its value and what is allowed.

    Parameters
    ----------
    name : str
        The parameter (dotted path for nested scenario fields, e.g. ``"crowd.sigma"``).
    value : object
        The offending value (or a short description of it).
    allowed : str
        What the parameter accepts.
    """

    def __init__(self, name: str, value: Any, allowed: str):
        self.name = name
        self.value = value
        self.allowed = allowed
        super().__init__(f"invalid {name} = {value!r}: expected {allowed}")


class SimulationDiverged(RuntimeError):
    """The state became NaN or infinite; ``last_good_step`` is the last finite step."""

    def __init__(self, message: str, last_good_step: int):
        self.last_good_step = last_good_step
        super().__init__(message)


def positive_number(name: str, value: Any) -> float:
    """``value`` as a finite float ``> 0``, or a :class:`ParameterError` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, value, "a finite number > 0") from None
    if not math.isfinite(v) or v <= 0:
        raise ParameterError(name, value, "a finite number > 0")
    return v


def limit_or_inf(name: str, value: Any) -> float:
    """A speed or turn-rate limit: ``value`` as a float ``> 0``, ``math.inf`` for None (no limit).

    Raises :class:`ParameterError` naming ``name`` for NaN or a value ``<= 0``.
    """
    if value is None:
        return math.inf
    value = float(value)
    if math.isnan(value) or value <= 0:
        raise ParameterError(name, value, "a number > 0, or None/inf for no limit")
    return value


SigmaLike = float | Callable[[np.ndarray, np.ndarray, float], np.ndarray]
"""The crowd's diffusion: a constant ``σ >= 0`` or ``σ(x, y, t)`` (noise ``sqrt(2σ) dB``, eq. (1))."""


def check_sigma(name: str, sigma: Any) -> Any:
    """The crowd's diffusion σ (eq. (1)): a callable ``σ(x, y, t)`` as it is, or a finite float ``>= 0``.

    The one validation of σ in the toolkit (crowd, controller, Fokker–Planck solver); the
    type is :data:`SigmaLike`.  Raises :class:`ParameterError` naming ``name``.
    """
    if callable(sigma):
        return sigma
    try:
        s = float(sigma)
    except (TypeError, ValueError):
        raise ParameterError(name, sigma, "a finite number >= 0, or a callable σ(x, y, t)") from None
    if not math.isfinite(s) or s < 0:
        raise ParameterError(name, sigma, "a finite number >= 0, or a callable σ(x, y, t)")
    return s
