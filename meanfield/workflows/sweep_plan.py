"""What a sweep runs and what it gathers: ``meanfield sweep``'s plan and its dataset.

The Dask side (:mod:`meanfield.workflows.sweep`: :func:`~meanfield.workflows.sweep.run_sweep`, the
``meanfield sweep`` command) executes a :class:`SweepPlan`; this module builds it and
reads its outputs back (docs/cli.md, "``meanfield sweep``"):

* the ``--set`` and ``--seeds`` arguments (:func:`parse_values`, :func:`parse_seeds`);
* the checked input and its expansion into one run per combination of the swept values
  × seeds (:func:`check_sweep`, :func:`expand_sweep`), each with its scenario's TOML
  and its resumable file name (:func:`run_key`);
* the runs already finished in ``OUT/runs`` (:func:`finished_runs`);
* the :class:`xarray.Dataset` of every run's summary (:func:`gather_dataset`).

Nothing here imports Dask, and nothing runs a simulation.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import product
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = [
    "SweepPlan",
    "check_sweep",
    "expand_sweep",
    "finished_runs",
    "gather_dataset",
    "run_key",
    "parse_values",
    "parse_seeds",
    "SUMMARY_KEYS",
    "CACHED_STATUSES",
]

#: Numeric summary keys gathered into the dataset (``None`` becomes NaN).
SUMMARY_KEYS: tuple[str, ...] = (
    "fraction_in_target",
    "time_to_90",
    "l2_error_ratio",
    "l2_error_final",
    "w2_to_target_final",
    "max_robot_speed",
    "limits_binding_fraction",
    "stragglers",
    "fraction_evacuated",
    "evacuation_time_95",
    "evacuation_time_100",
    "wall_seconds",
    "steps_per_second",
    "steps",
)
#: The most runs one sweep may hold (each is a record file and a row of the dataset).
MAX_RUNS = 1_000_000
#: Statuses of a run that are reused on resume (the others are run again).
CACHED_STATUSES: tuple[str, ...] = ("completed", "diverged")
_NOT_RUN = "not run"


# ---------------------------------------------------------------------- parsing
def _split_outside_brackets(text: str) -> list[str]:
    """Split on commas that are not inside ``[]``, ``{}`` or quotes."""
    parts, depth, quote, cur = [], 0, "", []
    for ch in text:
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur))
    return [p.strip() for p in parts]


def parse_values(items: Sequence[str]) -> dict[str, list]:
    """``["robots.n=4,9", "kernel.eta=0.01,0.02"]`` as ``{"robots.n": [4, 9], "kernel.eta": [0.01, 0.02]}``.

    Short names are resolved to dotted keys (:func:`meanfield.scenarios.scenario.resolve_key`):
    ``robots=4,9`` is ``robots.n=4,9``, ``eta=0.01`` is ``kernel.eta=0.01``.

    Each value is read like :func:`meanfield.scenarios.overrides.parse_set` reads one (TOML, else a string);
    values are split on commas outside brackets and quotes, so ``grid.cells=[12,12],[24,24]``
    gives two lists.

    Raises
    ------
    ParameterError
        For an item without ``=``, a key given twice, or an empty value.
    """
    from meanfield.scenarios.overrides import parse_set
    from meanfield.scenarios.scenario import resolve_key

    out: dict[str, list] = {}
    for item in items:
        if "=" not in item:
            raise ParameterError("--set", item, "KEY=V1,V2,... with a dotted scenario key, e.g. robots.n=4,9,16")
        key, raw = (s.strip() for s in item.split("=", 1))
        key = resolve_key(key)  # robots -> robots.n, eta -> kernel.eta
        if key in out:
            raise ParameterError("--set", item, f"each key once (give all values of {key} in one --set)")
        raws = _split_outside_brackets(raw)
        if not raw.strip() or any(not r for r in raws):
            raise ParameterError(key, raw, "a comma-separated list of non-empty values")
        out[key] = [parse_set([f"{key}={r}"])[key] for r in raws]
    return out


def parse_seeds(text: str) -> list[int]:
    """``"10"`` as seeds 0..9; ``"3-5"`` as 3, 4, 5; ``"1,4,7"`` as those seeds."""
    from meanfield.scenarios.overrides import int_list

    t = text.strip()
    if t.isdigit() and int(t) > MAX_RUNS:
        raise ParameterError("--seeds", text, f"at most {MAX_RUNS:,} seeds (a sweep of at most {MAX_RUNS:,} runs)")
    seeds = list(range(int(t))) if t.isdigit() else list(int_list("--seeds", t, ranges=True, most=MAX_RUNS))
    if not seeds:
        raise ParameterError("--seeds", text, "at least one seed (an empty sweep runs nothing)")
    return seeds


# ---------------------------------------------------------------------- keys and coordinates
def _slug(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, separators=(",", ":"))
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_")[:24] or "_"


def run_key(values: dict[str, Any], seed: int, scenario_dict: dict[str, Any]) -> str:
    """Stable file name of one run: a readable slug of its values and seed + a hash of its scenario.

    Parameters
    ----------
    values : dict
        The swept key → value of this run.
    seed : int
        Its seed.
    scenario_dict : dict
        ``Scenario.to_dict()`` of the run (values and seed applied); the hash covers all of
        it, so a changed base scenario never reuses a run.
    """
    blob = json.dumps(scenario_dict, sort_keys=True, default=str, separators=(",", ":"))
    digest = hashlib.sha256(blob.encode()).hexdigest()[:16]
    slug = "_".join(f"{k.split('.')[-1]}={_slug(v)}" for k, v in values.items())[:100]
    return f"{slug + '_' if slug else ''}seed={seed}_{digest}"


def _coordinate(key: str, values: list) -> np.ndarray:
    """Values as a coordinate: numbers stay numbers, anything else becomes its text."""
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
    if numeric:
        arr = np.asarray(values, dtype=float if any(isinstance(v, float) for v in values) else np.int64)
    else:
        arr = np.asarray([v if isinstance(v, str) else json.dumps(v) for v in values], dtype=object)
    if len(set(arr.tolist())) != len(arr):
        raise ParameterError(key, values, "distinct values (each value once)")
    return arr


# ---------------------------------------------------------------------- the plan
@dataclass(frozen=True)
class SweepPlan:
    """A sweep expanded into its runs (built by :func:`expand_sweep`).

    Attributes
    ----------
    base : Scenario
        The base scenario.
    sets : dict of str to list
        Swept dotted key → its values, in order (the dataset's dimensions, then ``seed``).
    seeds : list of int
        The seeds, distinct.
    coords : dict of str to ndarray
        The dataset coordinate of each swept key (numbers, or the values' text).
    runs : list of dict
        One per combination × seed: ``index`` (its position in the dataset), ``values``,
        ``seed``, ``key`` (:func:`run_key`), ``toml`` (its scenario) and ``plugins_allowed``
        (the permission its worker is given to import the scenario's ``plugins``: they were
        allowed in this process when the scenario was built).
    """

    base: Any
    sets: dict[str, list]
    seeds: list[int]
    coords: dict[str, np.ndarray]
    runs: list[dict[str, Any]]


def check_sweep(
    scenario: Any, sets: dict[str, list], seeds: int | Sequence[int], *, allow_plugins: bool = False
) -> tuple[Any, dict[str, list], list[int]]:
    """The base scenario, the swept values and the seeds of a sweep, checked.

    Parameters
    ----------
    scenario, sets, seeds, allow_plugins
        As for :func:`meanfield.workflows.sweep.run_sweep`.

    Returns
    -------
    base : Scenario
        ``scenario`` loaded (a built-in name or a TOML file) unless it is one.
    sets : dict of str to list
        Each key's values as a list (a single value becomes a one-element list).
    seeds : list of int
        ``range(seeds)`` for an int, else the seeds as ints.

    Raises
    ------
    ParameterError
        ``sets`` not a dict, ``seed`` as a swept key, a key without values, no seed, a
        negative or non-integer seed, a repeated seed.
    """
    from meanfield.scenarios.scenario import Scenario, load_scenario

    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario, allow_plugins=allow_plugins)
    if not isinstance(sets, dict):
        raise ParameterError("sets", sets, "a dict of dotted scenario key -> list of values")
    sets = {str(k): list(v) if isinstance(v, list | tuple) else [v] for k, v in sets.items()}
    for key, values in sets.items():
        if key == "seed":
            raise ParameterError("--set", "seed", "seeds given with --seeds (seeds=...), not as a swept key")
        if not values:
            raise ParameterError(key, values, "at least one value (an empty sweep runs nothing)")
    if isinstance(seeds, int | np.integer) and not isinstance(seeds, bool):
        if seeds < 1:
            raise ParameterError("--seeds", seeds, "at least one seed (an empty sweep runs nothing)")
        if seeds > MAX_RUNS:
            raise ParameterError("--seeds", seeds, f"at most {MAX_RUNS:,} seeds (a sweep of at most {MAX_RUNS:,} runs)")
        seed_list = list(range(int(seeds)))
    else:
        seed_list = list(seeds)
        if not seed_list:
            raise ParameterError("--seeds", seed_list, "at least one seed (an empty sweep runs nothing)")
        if not all(isinstance(s, int | np.integer) and not isinstance(s, bool) and s >= 0 for s in seed_list):
            raise ParameterError("--seeds", seed_list, "integers >= 0")
        seed_list = [int(s) for s in seed_list]
    if len(set(seed_list)) != len(seed_list):
        raise ParameterError("--seeds", seed_list, "distinct seeds")
    runs = len(seed_list) * math.prod(len(v) for v in sets.values())
    if runs > MAX_RUNS:
        raise ParameterError(
            "--seeds", len(seed_list), f"a sweep of at most {MAX_RUNS:,} runs (values × seeds give {runs:,})"
        )
    return base, sets, seed_list


def expand_sweep(base: Any, sets: dict[str, list], seed_list: list[int]) -> SweepPlan:
    """One run per combination of the ``sets`` values × the seeds, each scenario built once.

    Parameters
    ----------
    base, sets, seed_list
        As returned by :func:`check_sweep`.

    Raises
    ------
    ParameterError
        A repeated value, an unknown key or a value of the wrong type (named with the
        sweep combination when the error is in another key than the swept ones).
    """
    coords = {key: _coordinate(key, values) for key, values in sets.items()}
    keys = list(sets)

    runs: list[dict[str, Any]] = []  # index, values, seed, key, toml
    for idx in product(*(range(len(sets[k])) for k in keys)):
        values = {k: sets[k][i] for k, i in zip(keys, idx, strict=True)}
        try:
            sc = base.with_values(values) if values else base
        except ParameterError as exc:
            if exc.name in values:
                raise
            combo = ", ".join(f"{k}={v!r}" for k, v in values.items())
            raise ParameterError(exc.name, exc.value, f"{exc.allowed} (in the sweep combination {combo})") from None
        for j, seed in enumerate(seed_list):
            run_sc = sc.replace(seed=seed)
            d = run_sc.to_dict()
            runs.append(
                {"index": (*idx, j), "values": values, "seed": seed, "key": run_key(values, seed, d),
                 "toml": run_sc.to_toml(), "plugins_allowed": bool(run_sc.plugins)}
            )
    return SweepPlan(base, sets, seed_list, coords, runs)


_FRACTIONS = ("fraction_in_target", "fraction_evacuated", "limits_binding_fraction")
"""Summary figures that are fractions, in [0, 1]."""


def _valid_record(rec: Any) -> bool:
    """Whether a run record read back from ``OUT/runs`` can be a result: a table whose summary is a
    table, whose numeric figures are numbers (or None), fractions within [0, 1] and the other
    figures of :data:`SUMMARY_KEYS` not negative.  A record edited by hand or cut short fails."""
    if not isinstance(rec, dict) or not isinstance(rec.get("summary"), dict):
        return False
    summary = rec["summary"]
    for name in SUMMARY_KEYS:
        v = summary.get(name)
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, int | float):
            return False
        if math.isnan(v):
            continue
        if v < 0 or (name in _FRACTIONS and v > 1):
            return False
    return True


def finished_runs(plan: SweepPlan, runs_dir: Path) -> dict[str, dict[str, Any]]:
    """The records in ``runs_dir`` of the plan's runs that are reused: key → record.

    A record is reused when it is a valid result (:func:`_valid_record`: a table, its figures
    within their ranges) and its status is one of :data:`CACHED_STATUSES` (a deterministic
    outcome); unreadable or invalid files and the other statuses are left to run again.
    """
    records: dict[str, dict[str, Any]] = {}
    if runs_dir.is_dir():
        for r in plan.runs:
            path = runs_dir / f"{r['key']}.json"
            try:
                rec = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            if _valid_record(rec) and rec["summary"].get("status") in CACHED_STATUSES:
                records[r["key"]] = rec
    return records


def gather_dataset(
    plan: SweepPlan,
    records: dict[str, dict[str, Any]],
    *,
    state: str,
    scheduler: str | None,
    workers: int | None,
    reused: int,
    executed: int,
):
    """Every run's summary as the sweep's :class:`xarray.Dataset` (see :func:`meanfield.workflows.sweep.run_sweep`).

    Parameters
    ----------
    plan : SweepPlan
        The sweep.
    records : dict
        Run key → its record (``summary`` holds the run's summary); runs without one are
        ``"not run"``.
    state : str
        ``"completed"`` or ``"interrupted"``; a completed sweep with a run that did not
        complete becomes ``"incomplete"``.
    scheduler, workers : optional
        Recorded in the ``sweep`` attribute.
    reused, executed : int
        Runs loaded from ``OUT/runs`` and run now (attributes ``runs_reused``, ``runs_executed``).
    """
    import xarray as xr

    base, sets, seed_list, coords, runs = plan.base, plan.sets, plan.seeds, plan.coords, plan.runs
    keys = list(sets)
    shape = tuple(len(sets[k]) for k in keys) + (len(seed_list),)
    data = {name: np.full(shape, np.nan) for name in SUMMARY_KEYS}
    status = np.full(shape, _NOT_RUN, dtype=object)
    message = np.full(shape, "", dtype=object)
    for r in runs:
        rec = records.get(r["key"])
        if rec is None:
            continue
        s = rec["summary"]
        for name in SUMMARY_KEYS:
            v = s.get(name)
            data[name][r["index"]] = float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan
        status[r["index"]] = str(s.get("status", "error"))
        message[r["index"]] = str(s.get("message") or "")
    if state != "interrupted" and any(st != "completed" for st in status.flat):
        state = "incomplete"
    dims = (*keys, "seed")
    ds = xr.Dataset(
        {name: (dims, arr) for name, arr in data.items()} | {"status": (dims, status), "message": (dims, message)},
        coords={**{k: (k, coords[k]) for k in keys}, "seed": ("seed", np.asarray(seed_list, dtype=np.int64))},
        attrs={
            "title": f"meanfield sweep of {base.name}",
            "scenario": base.to_toml(),
            "sweep": json.dumps(
                {"sets": sets, "seeds": seed_list, "scheduler": scheduler or "local", "workers": workers},
                default=str,
            ),
            "status": state,
            "runs_total": len(runs),
            "runs_reused": reused,
            "runs_executed": executed,
        },
    )
    return ds
