"""The records of ``meanfield bench`` and the settings of each benchmark.

Shared by :mod:`benchmarks.suite` (which runs the benchmarks) and by the adapter of every
benchmark, ``suite_records(quick)`` in its ``bench_*.py`` module, which turns that
benchmark's own figures into records.  A record's layout is documented in ``docs/cli.md``
("The JSON"); :func:`format_table` gives the table that ``meanfield bench`` prints.  This
module loads no benchmark; the adapters import it when the suite runs them, inside its
one-core set-up.
"""

from __future__ import annotations

import importlib
import traceback
from collections.abc import Sequence
from typing import Any

from meanfield.errors import ParameterError

__all__ = [
    "SETTINGS",
    "BENCH_INSTALL",
    "RATIO_MEANING",
    "measured",
    "skipped",
    "failed",
    "settings",
    "import_error",
    "format_table",
]

RATIO_MEANING = "ratio > 1 means ours is faster: anchor time / our time, or our rate / anchor rate"
BENCH_INSTALL = "pip install -e '.[bench]'"

#: what each benchmark runs, in quick and in full mode (recorded in the JSON as ``settings``)
SETTINGS: dict[str, dict[str, dict[str, Any]]] = {
    # bench_kde.run(quick, repeats): quick = ours best of 3, gaussian_kde once; full = best of 5 / 2;
    # the exact sum once; FFTKDE best of 3 / 5
    "kde": {"quick": {"repeats": 5}, "full": {"repeats": 5}},
    # the anchor makes max(steps // 3, 100) gaussian_kde calls, as the script does
    "closed_loop": {"quick": {"steps": 1000, "repeats": 2}, "full": {"steps": 3000, "repeats": 3}},
    # grid sizes n (n² cells); reference: finest grid of the Richardson reference; best of `repeats` solves
    "fokker_planck": {
        "quick": {"cells": [64], "reference": 512, "repeats": 3},
        "full": {"cells": [64, 128, 256, 512], "reference": 2048, "repeats": 3},
    },
    # agents -> steps (bench_jupedsim.QUICK_STEPS / FULL_STEPS), best of `repeats`
    "jupedsim": {
        "quick": {"steps": {200: 300, 2000: 60}, "repeats": 3},
        "full": {"steps": {200: 2000, 2000: 400, 10000: 100}, "repeats": 3},
    },
    # python benchmarks/bench_large_crowd.py --quick (20 steps ours, 3 of the frozen plain step, 2 of the
    # old anchor) / --steps 100 (5 and 5)
    "large_crowd": {
        "quick": {"ours_steps": 20, "anchor_steps": 3, "old_anchor_steps": 2},
        "full": {"ours_steps": 100, "anchor_steps": 5, "old_anchor_steps": 5},
    },
    "bounded": {
        "quick": {"solves": 100, "steps": 500, "repeats": 2},
        "full": {"solves": 500, "steps": 2000, "repeats": 2},
    },
    "nmpc": {"quick": {"t_final": 1.0, "repeats": 1}, "full": {"t_final": 4.0, "repeats": 3}},
    "startup": {"quick": {"repeats": 5}, "full": {"repeats": 11}},
    # each repeat: a cold and a warm first run with the parallel compile, and the same without
    "compile": {"quick": {"repeats": 1}, "full": {"repeats": 3}},
    "plan": {
        "quick": {"window": 30, "seeds": 4, "repeats": 2, "plan_seeds": 1},
        "full": {"window": 30, "seeds": 10, "repeats": 3, "plan_seeds": 3},
    },
    "controllers": {"quick": {"steps": 60, "repeats": 1}, "full": {"steps": 300, "repeats": 2}},
    # (steps, seeds, repeats) at N = 200 (the bottleneck) and N = 1e6 (bench_congestion.py)
    "congestion": {
        "quick": {"small": (40, 3, 2), "large": (4, 1, 1)},
        "full": {"small": (40, 10, 3), "large": (10, 1, 3)},
    },
    # our cells per metre and hughes2d's largest triangle (m^2), coarse to fine; our other sigma (m^2/s), on the
    # second of our grids (bench_hughes2d.py, hughes2d_peer.py)
    "hughes2d": {
        "quick": {"ours": [10], "peer": [0.12], "sigmas": []},
        "full": {"ours": [10, 20, 40], "peer": [0.12, 0.06, 0.03], "sigmas": [0.0, 0.005, 0.02]},
    },
    # bench_scaling.CROWDS / GRIDS: quick stops at N = 1e6 and 256^2
    "scaling": {
        "quick": {"max_humans": 1_000_000, "max_cells": 256},
        "full": {"max_humans": 10_000_000, "max_cells": 512},
    },
}


def measured(
    benchmark: str,
    name: str,
    what: str,
    ours: str,
    anchor: str,
    ours_value: float,
    anchor_value: float,
    unit: str,
    *,
    faster: str,
    anchor_unit: str | None = None,
    goal: str | None = None,
    passed: bool | None = None,
    note: str = "",
    detail: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """A record with numbers.  ``faster`` is ``"lower"`` for times, ``"higher"`` for rates."""
    ours_value, anchor_value = float(ours_value), float(anchor_value)
    if faster == "lower":
        ratio, definition = anchor_value / ours_value, "anchor time / our time"
    elif faster == "higher":
        ratio, definition = ours_value / anchor_value, "our rate / anchor rate"
    else:
        raise ParameterError("faster", faster, "'lower' (times) or 'higher' (rates)")
    return {
        "benchmark": benchmark,
        "name": name,
        "what": what,
        "skipped": False,
        "ours": ours,
        "ours_value": ours_value,
        "unit": unit,
        "anchor": anchor,
        "anchor_value": anchor_value,
        "anchor_unit": anchor_unit or unit,
        "ratio": ratio,
        "ratio_definition": definition,
        "goal": goal,
        "pass": None if passed is None else bool(passed),
        "note": note,
        "detail": detail or {},
    }


def skipped(benchmark: str, name: str, what: str, ours: str, anchor: str, note: str) -> dict[str, Any]:
    """A record of an anchor that could not run: a note, and no numbers."""
    return {
        "benchmark": benchmark,
        "name": name,
        "what": what,
        "skipped": True,
        "ours": ours,
        "anchor": anchor,
        "note": note,
    }


def failed(benchmark: str, exc: BaseException) -> dict[str, Any]:
    """The record of a benchmark that raised: the error and the end of its traceback."""
    return {
        "benchmark": benchmark,
        "name": benchmark,
        "skipped": False,
        "error": f"{type(exc).__name__}: {exc}",
        "traceback": "".join(traceback.format_exception(exc)[-6:]),
    }


def settings(name: str, quick: bool) -> dict[str, Any]:
    """The settings of benchmark ``name`` in quick or full mode (read from :data:`SETTINGS` at call time)."""
    return SETTINGS[name]["quick" if quick else "full"]


def import_error(module: str) -> str | None:
    """None when ``module`` imports, else why not (an optional anchor)."""
    try:
        importlib.import_module(module)
    except Exception as exc:  # ImportError, or a broken install (numba/numpy mismatch, ...)
        return f"{type(exc).__name__}: {exc}"
    return None


def _num(v: float) -> str:
    a = abs(v)
    if a >= 1000:
        return f"{v:,.0f}"
    if a >= 100:
        return f"{v:.0f}"
    return f"{v:.3g}"


def format_table(records: Sequence[dict[str, Any]]) -> str:
    """benchmark | ours | anchor | ratio | goal/pass or note, as a Markdown table."""
    head = ["benchmark", "ours", "anchor", "ratio (>1: ours faster)", "goal / pass or note"]
    rows = []
    for r in records:
        if "error" in r:
            rows.append([r["name"], "-", "-", "-", f"ERROR: {r['error']}"])
        elif r["skipped"]:
            rows.append([r["name"], "-", "-", "-", f"skipped: {r['note']}"])
        else:
            verdict = f"{'PASS' if r['pass'] else 'FAIL'} ({r['goal']})" if r["pass"] is not None else ""
            rows.append(
                [
                    r["name"],
                    f"{_num(r['ours_value'])} {r['unit']}",
                    f"{_num(r['anchor_value'])} {r['anchor_unit']}",
                    _num(r["ratio"]),
                    "; ".join(x for x in (verdict, r["note"]) if x),
                ]
            )
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=True)]
    widths[-1] = 0  # no padding of the last column

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(str(c).ljust(w) for c, w in zip(cells, widths, strict=True)) + " |"

    return "\n".join([line(head), line(["-" * max(w, 3) for w in widths]), *map(line, rows)])
