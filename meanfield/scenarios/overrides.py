"""Scenario values read from text: ``--set KEY=VALUE`` overrides and lists of numbers.

:func:`parse_set` reads ``["robots.n=9", ...]`` the way a scenario file reads a value (TOML,
else a string); :func:`int_list` and :func:`float_list` read comma-separated numbers, each
refusal naming the option it came from.
"""

from __future__ import annotations

from collections.abc import Sequence

from meanfield.errors import ParameterError

__all__ = ["parse_set", "int_list", "float_list"]


def parse_set(values: Sequence[str]) -> dict[str, object]:
    """``["robots.n=9", ...]`` as ``{"robots.n": 9, ...}``, each value read as TOML (else a string)."""
    import tomllib

    out: dict[str, object] = {}
    for item in values:
        if "=" not in item:
            raise ParameterError("--set", item, "KEY=VALUE with a dotted scenario key, e.g. kernel.eta=0.02")
        key, raw = item.split("=", 1)
        try:
            out[key.strip()] = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = raw
    return out


def int_list(name: str, text: str, ranges: bool = False, most: int | None = None) -> tuple[int, ...]:
    """Comma-separated integers (``"1,2,4"``), or with ``ranges`` also ``"A-B"`` (inclusive); at most
    ``most`` of them (refused before a range is spelt out)."""
    try:
        if ranges and "-" in text and "," not in text:
            a, b = (int(v) for v in text.split("-"))
            values = range(a, b + 1)  # spelt out below, once its length is known to be allowed
        else:
            values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        allowed = "integers as 'A-B' or 'a,b,c'" if ranges else "comma-separated integers, e.g. 100,1000,10000"
        raise ParameterError(name, text, allowed) from None
    if not values:
        raise ParameterError(name, text, "at least one integer")
    if most is not None and len(values) > most:
        raise ParameterError(name, text, f"at most {most:,} integers")
    return tuple(values)


def float_list(name: str, text: str) -> tuple[float, ...]:
    """Comma-separated numbers, e.g. ``"0.05,0.1,0.2"``."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ParameterError(name, text, "comma-separated numbers, e.g. 0.05,0.1,0.2") from None
    if not values:
        raise ParameterError(name, text, "at least one number")
    return values
