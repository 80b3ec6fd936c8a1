"""Field validators shared by the scenario sections: each check names the field it refuses.

Every function takes the dotted field name first (``"crowd.sigma"``, ``"robots.u_max"``)
and raises :class:`~meanfield.errors.ParameterError` with that name, the value and the
allowed range, so that a bad scenario file is refused with a message that says which key
to fix (the command line exits with status 2 on it).

:func:`region_from_table` turns a scenario's ``[domain]`` table into a region through the
registry (:mod:`meanfield.plugins`, kind ``"region"``).
"""

from __future__ import annotations

import inspect
import math
from typing import Any

import numpy as np

from meanfield import plugins
from meanfield.errors import ParameterError

__all__ = [
    "region_keywords",
    "all_numbers",
    "choice",
    "integer",
    "module_list",
    "num",
    "optional_limit",
    "point",
    "range_text",
    "region_from_table",
]


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
        The value to check; booleans are refused.
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
    if isinstance(value, bool):
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


def integer(name: str, value: Any, lo: int) -> int:
    """An integer ``>= lo`` (a float with an integral value is accepted; booleans are not).

    Parameters
    ----------
    name : str
        The field, as named in the error.
    value : Any
        The value to check.
    lo : int
        Smallest allowed value.

    Returns
    -------
    int

    Raises
    ------
    ParameterError
        If the value is not an integer ``>= lo``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise ParameterError(name, value, f"an integer >= {lo}")
    if value < lo:
        raise ParameterError(name, value, f"an integer >= {lo}")
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


def _keywords(factory: Any) -> tuple[set[str], set[str]] | None:
    """The keyword parameters of ``factory`` and the required ones; None if it takes any."""
    try:
        sig = inspect.signature(factory)
    except (TypeError, ValueError):
        return None
    names: set[str] = set()
    required: set[str] = set()
    for p in sig.parameters.values():
        if p.kind is p.VAR_KEYWORD:
            return None
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            names.add(p.name)
            if p.default is p.empty:
                required.add(p.name)
    return names, required


def region_keywords(kind: Any) -> set[str] | None:
    """The ``[domain]`` keys (besides ``kind``) a registered region kind takes; None if unknown or any."""
    if not isinstance(kind, str) or kind not in plugins.available("region"):
        return None
    keywords = _keywords(plugins.load("region", kind))
    return None if keywords is None else keywords[0]


def region_from_table(table: dict[str, Any]) -> Any:
    """The region a scenario's ``[domain]`` table describes, built by its registered factory.

    ``kind`` (default ``"box"``) names a region registered in :mod:`meanfield.plugins`
    (built in: ``"box"``, ``"disk"``, ``"polygon"``); the other keys are passed to that
    factory as keyword arguments (for a box, ``width``, ``height``, ``origin``).

    Parameters
    ----------
    table : dict
        The ``[domain]`` table.

    Returns
    -------
    Region
        What the factory returns (:class:`meanfield.domain.Domain` for the built-ins).

    Raises
    ------
    ParameterError
        Named ``domain.kind`` for an unregistered kind (listing the registered ones);
        ``domain`` for a key the factory does not take (listing those it does) or a
        malformed table; ``domain.<field>`` for a missing required key or a value the
        factory refuses (its own field name, prefixed).
    """
    if not isinstance(table, dict):
        raise ParameterError("domain", table, "a table")
    rest = dict(table)
    kind = rest.pop("kind", "box")
    kinds = plugins.available("region")
    if kind not in kinds:
        raise ParameterError("domain.kind", kind, "one of " + ", ".join(map(repr, kinds)))
    factory = plugins.load("region", kind)
    keywords = _keywords(factory)
    if keywords is not None:
        allowed, required = keywords
        unknown = set(rest) - allowed
        if unknown:
            raise ParameterError("domain", f"unknown key(s) {sorted(unknown)}", f"keys {sorted(allowed)}")
        missing = sorted(required - set(rest))
        if missing:
            raise ParameterError(f"domain.{missing[0]}", None, f"a value (the {kind!r} region requires it)")
    try:
        return factory(**rest)
    except ParameterError as exc:
        raise ParameterError(f"domain.{exc.name}", exc.value, exc.allowed) from None
    except (TypeError, ValueError, LookupError) as exc:
        raise ParameterError("domain", str(exc), f"a valid {kind} description") from None
