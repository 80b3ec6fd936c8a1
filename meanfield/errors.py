"""Exceptions of the toolkit: bad parameters and numerical blow-ups."""

from __future__ import annotations

from typing import Any

__all__ = ["ParameterError", "SimulationDiverged"]


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
