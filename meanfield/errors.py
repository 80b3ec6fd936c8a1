"""Exceptions of the toolkit (bad parameters, numerical blow-ups) and the shared checks of a value.

Every check of a named field (:func:`num`, :func:`integer`, :func:`choice`, :func:`point`,
:func:`optional_limit`, ...) takes the dotted field name first (``"crowd.sigma"``,
``"robots.u_max"``) and raises :class:`ParameterError` with that name, the value and the
allowed range, so that a bad scenario file or option is refused with a message that says which
key to fix (the command line exits with status 2 on it).  Scenario sections and the parts'
own options (a crowd's, a controller's) use them alike.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = [
    "ScenarioWarning",
    "num",
    "range_text",
    "integer",
    "choice",
    "point",
    "optional_limit",
    "all_numbers",
    "module_list",
    "MeanfieldDeprecationWarning",
    "ParameterError",
    "SimulationDiverged",
    "SigmaLike",
    "check_sigma",
    "deprecated",
    "REMOVED_IN",
    "deprecation_message",
    "options_table",
    "positive_number",
    "limit_or_inf",
]


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


class ScenarioWarning(UserWarning):
    """Something in the user's scenario that runs but may not do what was meant (an event after the run's end).

    The command line prints it as one line, ``meanfield: warning: ...``, without a source line of ours.
    """


class MeanfieldDeprecationWarning(FutureWarning):
    """A name, module path or scenario field that still works but has a new name, given in the message.

    A :class:`FutureWarning`, so that it is shown by default, to users of scripts as well as of
    the library's own tests; it can be filtered by this class alone.
    """


REMOVED_IN = "0.3.0"
"""The release that no longer reads what is deprecated today (the messages of :func:`deprecated` name it)."""


def deprecated(what: str, instead: str, stacklevel: int = 2) -> None:
    """Warn that ``what`` is deprecated and removed in :data:`REMOVED_IN`, saying what to do ``instead``.

    Parameters
    ----------
    what : str
        The old name, field or value, as the user wrote it.
    instead : str
        The replacement, as a sentence (``"use controller.options.guide.revisit_after"``).
    stacklevel : int
        Of the caller of this function, as :func:`warnings.warn` counts.
    """
    import warnings

    warnings.warn(deprecation_message(what, instead), MeanfieldDeprecationWarning, stacklevel=stacklevel + 1)


def deprecation_message(what: str, instead: str) -> str:
    """The text of every deprecation, ``"<what> is deprecated and removed in 0.3.0: <instead>"``
    (:data:`REMOVED_IN`)."""
    return f"{what} is deprecated and removed in {REMOVED_IN}: {instead}"


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


# ---------------------------------------------------------------------- checks of a named field
def num(
    name: str,
    value: Any,
    *,
    lo: float | None = None,
    lo_open: bool = False,
    hi: float | None = None,
    allowed: str | None = None,
) -> float:
    """A finite number, optionally bounded.

    Parameters
    ----------
    name : str
        The field, as named in the error.
    value : Any
        The value to check; booleans and strings are refused (``"0.5"`` is text, as ``robots.n = "4"`` is).
    lo, hi : float, optional
        Lower and upper bounds (inclusive unless ``lo_open``).
    lo_open : bool
        Whether the lower bound itself is refused (``x > lo``).
    allowed : str, optional
        The allowed range as the error states it (default: :func:`range_text`).

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        If the value is not a finite number in range.
    """
    desc = allowed or range_text(lo, lo_open, hi)
    if isinstance(value, (bool, str, bytes)):  # a number is a number: "0.5" is text, not coerced
        raise ParameterError(name, value, desc)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, value, desc) from None
    if not math.isfinite(x):
        raise ParameterError(name, value, desc)
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise ParameterError(name, value, desc)
    if hi is not None and x > hi:
        raise ParameterError(name, value, desc)
    return x


def range_text(lo: float | None, lo_open: bool, hi: float | None) -> str:
    """The allowed range of :func:`num` in words (``"a finite number > 0"``, ...).

    Parameters
    ----------
    lo : float or None
        Lower bound.
    lo_open : bool
        Whether the lower bound is excluded.
    hi : float or None
        Upper bound (inclusive).

    Returns
    -------
    str
    """
    if lo is None and hi is None:
        return "a finite number"
    if hi is None:
        return f"a finite number {'>' if lo_open else '>='} {lo:g}"
    return f"a number in [{lo:g}, {hi:g}]"


def integer(name: str, value: Any, lo: int, hi: int | None = None) -> int:
    """An integer ``>= lo`` (and ``<= hi``; a float with an integral value is accepted; booleans are not).

    Parameters
    ----------
    name : str
        The field, as named in the error.
    value : Any
        The value to check.
    lo : int
        Smallest allowed value.
    hi : int, optional
        Largest allowed value.

    Returns
    -------
    int

    Raises
    ------
    ParameterError
        If the value is not an integer in ``[lo, hi]``.
    """
    allowed = f"an integer >= {lo}" if hi is None else f"an integer from {lo} to {hi}"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise ParameterError(name, value, allowed)
    if value < lo or (hi is not None and value > hi):
        raise ParameterError(name, value, allowed)
    return int(value)


def choice(name: str, value: Any, options: tuple[str, ...]) -> str:
    """One of ``options``.

    Parameters
    ----------
    name : str
        The field, as named in the error.
    value : Any
        The value to check.
    options : tuple of str
        The allowed values, listed in the error.

    Returns
    -------
    str
        ``value``.

    Raises
    ------
    ParameterError
        If ``value`` is not among ``options``.
    """
    if value not in options:
        raise ParameterError(name, value, "one of " + ", ".join(repr(o) for o in options))
    return value


def options_table(name: str, options: Any, table: Any, none: str = "no options (this part takes none)") -> Any:
    """A part's options from a scenario's table: ``options(**table)``, its keys and values checked.

    Parameters
    ----------
    name : str
        The table, as named in the error (``"controller.options.guide"``, ``"crowd.options.jupedsim"``).
    options : type or None
        The part's options, a dataclass that checks its own fields (naming ``<name>.<field>``); None: the part
        takes none.
    table : Any
        The scenario's table (a mapping of field names to values).
    none : str
        What the error says a part that takes no options expects.

    Returns
    -------
    Any
        The options (``options()`` for an empty table); None when the part takes none.

    Raises
    ------
    ParameterError
        Naming ``name`` for a table that is not one, a key the part does not take (listing those it does), or any
        key for a part that takes none.
    """
    import dataclasses

    if not isinstance(table, dict):
        raise ParameterError(name, table, "a table of options")
    if options is None:
        if table:
            raise ParameterError(name, table, none)
        return None
    known = [f.name for f in dataclasses.fields(options)] if dataclasses.is_dataclass(options) else None
    unknown = sorted(set(table) - set(known)) if known is not None else []
    if unknown:
        raise ParameterError(f"{name}.{unknown[0]}", table[unknown[0]], f"a key among {known}")
    try:
        return options(**table)
    except TypeError:
        raise ParameterError(name, table, f"keys among {known or 'its options'}") from None


def point(name: str, value: Any) -> tuple[float, float]:
    """A pair ``[x, y]`` of finite numbers.

    Parameters
    ----------
    name : str
        The field; a bad coordinate is named ``name[0]`` or ``name[1]``.
    value : Any
        The value to check.

    Returns
    -------
    tuple of float

    Raises
    ------
    ParameterError
        If the value is not a pair, or a coordinate is not a finite number.
    """
    try:
        a, b = value
    except (TypeError, ValueError):
        raise ParameterError(name, value, "a pair [x, y] of finite numbers") from None
    return (num(f"{name}[0]", a), num(f"{name}[1]", b))


def optional_limit(name: str, value: Any, what: str = 'a number > 0, or "none" for no limit') -> float | None:
    """A number ``> 0``, or no limit (``None`` or the string ``"none"``).

    Parameters
    ----------
    name : str
        The field, as named in the error.
    value : Any
        The value to check.
    what : str
        The allowed values as the error states them.

    Returns
    -------
    float or None
        None for no limit.

    Raises
    ------
    ParameterError
        If the value is neither a number > 0 nor "none".
    """
    if value is None or (isinstance(value, str) and value == "none"):
        return None
    return num(name, value, lo=0.0, lo_open=True, allowed=what)


def all_numbers(x: Any) -> bool:
    """Whether ``x`` converts to a floating-point array (numbers, or nested lists of them).

    Parameters
    ----------
    x : Any

    Returns
    -------
    bool
    """
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        return False
    return arr.dtype.kind == "f"


def module_list(name: str, value: Any) -> tuple[str, ...]:
    """A list of plugin modules: dotted module names or paths to ``.py`` files.

    Parameters
    ----------
    name : str
        The field (the scenario's top-level ``plugins``).
    value : Any
        A list or tuple of non-empty strings (``None`` is the empty list).

    Returns
    -------
    tuple of str

    Raises
    ------
    ParameterError
        If the value is not a list of non-empty strings.
    """
    if value is None:
        return ()
    allowed = "a list of module names or paths to .py files"
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise ParameterError(name, value, allowed)
    for k, item in enumerate(value):
        if not isinstance(item, str) or not item:
            raise ParameterError(f"{name}[{k}]", item, "a module name or a path to a .py file")
    return tuple(value)
