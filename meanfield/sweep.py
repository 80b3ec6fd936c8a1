"""Parameter sweeps on Dask: ``meanfield sweep`` and :func:`run_sweep`.

A sweep runs the closed loop (:class:`meanfield.simulate.ClosedLoop`) for every
combination of the swept scenario values × seeds, one Dask task per run, on a local
cluster (worker processes, one thread each) or on an existing Dask cluster named by
its scheduler's address.  Each run's summary is gathered into an :class:`xarray.Dataset`
with one dimension per swept key plus ``seed``, written to ``OUT/sweep.nc``.

Layout of the output directory::

    OUT/runs/<key>.json   one finished run: its values, seed and summary (atomic writes)
    OUT/sweep.nc          every run of the sweep (NetCDF, h5netcdf), rewritten at the end

Resuming
    ``<key>`` is a readable slug of the run's values and seed plus a hash of the run's
    *whole* scenario, so a run is reused only for exactly the same scenario.  Re-running
    a sweep with the same arguments (or a larger one that contains it) loads the runs whose
    status is ``"completed"`` or ``"diverged"`` (deterministic outcomes) and submits only
    the others.  A run that raised (``"error"``) or was ``"interrupted"`` is recorded in its
    JSON file but run again on resume (the cause may have been transient: a lost worker).

Bad input
    Refused with a :class:`~meanfield.errors.ParameterError` before any run starts (and
    before ``OUT`` is created): an unknown key or a value of the wrong type (every
    combination's scenario is built once), an empty sweep, a repeated value or key, an
    unreachable scheduler address.  A run that fails inside the sweep is recorded with
    ``status = "error"`` and its error text, and the sweep goes on.

Workers of an external cluster must have the same ``meanfield`` (and plugins) installed;
the runs' outputs travel back to the process that called :func:`run_sweep`, which alone
writes to ``OUT``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import math
import os
import re
import time
from collections.abc import Callable, Sequence
from itertools import product
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = [
    "run_sweep",
    "run_key",
    "parse_values",
    "parse_seeds",
    "register",
    "SUMMARY_KEYS",
    "CACHED_STATUSES",
    "CONNECT_TIMEOUT",
]

#: Numeric summary keys gathered into the dataset (``None`` becomes NaN).
SUMMARY_KEYS: tuple[str, ...] = (
    "fraction_in_target",
    "time_to_90",
    "l2_error_ratio",
    "l2_error_final",
    "w2_to_target_final",
    "max_robot_speed",
    "wall_seconds",
    "steps",
)
#: Statuses of a run that are reused on resume (the others are run again).
CACHED_STATUSES: tuple[str, ...] = ("completed", "diverged")
#: Seconds to wait for an external scheduler before refusing its address.
CONNECT_TIMEOUT: float = 10.0
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

    Short names are resolved to dotted keys (:func:`meanfield.scenario.resolve_key`):
    ``robots=4,9`` is ``robots.n=4,9``, ``eta=0.01`` is ``kernel.eta=0.01``.

    Each value is read like :func:`meanfield.cli.parse_set` reads one (TOML, else a string);
    values are split on commas outside brackets and quotes, so ``grid.cells=[12,12],[24,24]``
    gives two lists.

    Raises
    ------
    ParameterError
        For an item without ``=``, a key given twice, or an empty value.
    """
    from meanfield.cli import parse_set
    from meanfield.scenario import resolve_key

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
    from meanfield.cli import int_list

    t = text.strip()
    seeds = list(range(int(t))) if t.isdigit() else list(int_list("--seeds", t, ranges=True))
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


# ---------------------------------------------------------------------- worker side
def _run_one(scenario_toml: str) -> dict[str, Any]:
    """Run one closed loop from its scenario's TOML; never raises (errors come back as a summary)."""
    import traceback

    start = time.perf_counter()
    try:
        from meanfield.scenario import Scenario
        from meanfield.simulate import ClosedLoop

        summary = dict(ClosedLoop(Scenario.from_toml(scenario_toml)).run(progress=False).summary)
        summary.pop("scenario", None)
        return summary
    except Exception as exc:  # recorded, the sweep goes on
        return {
            "status": "error",
            "message": f"{type(exc).__name__}: {exc}",
            "traceback": traceback.format_exc(),
            "wall_seconds": time.perf_counter() - start,
        }


# ---------------------------------------------------------------------- client
def _connect(scheduler: str | None, workers: int | None, timeout: float):
    """A ``(client, cluster)`` pair; ``cluster`` is None for an external scheduler."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - dask is a dependency
        raise ParameterError("scheduler", scheduler, f"dask.distributed installed ({exc})") from None

    if scheduler is None:
        import signal
        import threading

        n = workers or os.cpu_count() or 1
        # the worker processes start with Ctrl-C ignored (an ignored signal stays ignored
        # across exec): Ctrl-C reaches this process alone, which records the runs so far
        # and closes the cluster, instead of every worker printing a KeyboardInterrupt
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                scheduler_port=0,
                silence_logs=logging.ERROR,  # not the warnings of tasks cancelled by a Ctrl-C
            )
        finally:
            if main:
                signal.signal(signal.SIGINT, previous)
        return Client(cluster), cluster
    if not re.fullmatch(r"[a-z]+://[^\s/]+:\d+", scheduler):
        raise ParameterError("--scheduler", scheduler, "a Dask scheduler address, e.g. tcp://127.0.0.1:8786")
    try:
        client = Client(scheduler, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        raise ParameterError(
            "--scheduler",
            scheduler,
            f"the address of a running Dask scheduler (could not connect within {timeout:g} s: {exc})",
        ) from None
    return client, None


# ---------------------------------------------------------------------- the sweep
def run_sweep(
    scenario: Any,
    sets: dict[str, list],
    seeds: int | Sequence[int],
    out_dir: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    connect_timeout: float = CONNECT_TIMEOUT,
    on_result: Callable[[dict[str, Any]], None] | None = None,
):
    """Run the closed loop for every combination of ``sets`` × ``seeds`` on Dask.

    Parameters
    ----------
    scenario : Scenario or str or Path
        The base scenario: a :class:`~meanfield.scenario.Scenario`, a built-in name or a TOML file.
    sets : dict of str to list
        Dotted scenario key → the values to sweep, e.g. ``{"robots.n": [4, 9], "kernel.eta": [0.01]}``.
        Values may be numbers, strings or lists (strings and lists become text coordinates).
    seeds : int or sequence of int
        ``N`` for seeds ``0..N-1``, or the seeds themselves.
    out_dir : str or Path
        Output directory (``runs/*.json`` and ``sweep.nc``); created once the input is valid.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:port``); default: a local cluster.
    workers : int, optional
        Worker processes of the local cluster (default: the cores); ignored with ``scheduler``.
    progress : bool
        Show a tqdm progress bar.
    connect_timeout : float
        Seconds to wait for ``scheduler`` before refusing it.
    on_result : callable, optional
        Called in this process as ``on_result(record)`` after each run is recorded (``record``
        holds ``key``, ``values``, ``seed`` and ``summary``).  An exception it raises stops the
        sweep like an interruption does (the outputs so far are written, then it propagates,
        except ``KeyboardInterrupt``, which is reported through ``attrs["status"]``).

    Returns
    -------
    xarray.Dataset
        Dimensions: the swept keys (in order) and ``seed``.  Data variables: :data:`SUMMARY_KEYS`
        as float (NaN for None or a run that did not finish), ``status`` (``"completed"``,
        ``"diverged"``, ``"error"``, ``"interrupted"`` or ``"not run"``) and ``message``.  Attrs:
        ``scenario`` (TOML), ``sweep`` (JSON of the sets, seeds and scheduler), ``status``
        (``"completed"`` when every run completed, ``"incomplete"``, or ``"interrupted"``),
        ``runs_total``, ``runs_reused`` and ``runs_executed``.

    Raises
    ------
    ParameterError
        Before any run: an unknown key, a value of the wrong type, an empty sweep, a repeated
        value, an invalid seed or worker count, an unreachable scheduler.
    """
    from meanfield.io import atomic_write_json, atomic_write_with
    from meanfield.scenario import Scenario, load_scenario

    # ---- validation: nothing is created or run before all of it passes
    base = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
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
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ParameterError("--workers", workers, "an integer >= 1")
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
                 "toml": run_sc.to_toml()}
            )

    out = Path(out_dir)
    runs_dir = out / "runs"
    records: dict[str, dict[str, Any]] = {}
    if runs_dir.is_dir():
        for r in runs:
            path = runs_dir / f"{r['key']}.json"
            try:
                rec = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            if rec.get("summary", {}).get("status") in CACHED_STATUSES:
                records[r["key"]] = rec
    todo = [r for r in runs if r["key"] not in records]
    reused = len(records)

    client = cluster = None
    if todo:
        client, cluster = _connect(scheduler, workers, connect_timeout)  # refuses a bad address
    runs_dir.mkdir(parents=True, exist_ok=True)

    # ---- the runs
    from tqdm.auto import tqdm

    executed = 0
    state = "completed"
    pending_exc: BaseException | None = None
    bar = tqdm(total=len(runs), initial=reused, disable=not progress, desc="meanfield sweep", unit="run")
    try:
        if todo:
            from distributed import as_completed

            futures = {}
            for r in todo:
                fut = client.submit(_run_one, r["toml"], pure=False, retries=0)
                futures[fut] = r
            try:
                for fut in as_completed(futures):
                    r = futures[fut]
                    if fut.status == "finished":
                        summary = fut.result()
                    else:  # a lost worker, a cancelled task: recorded, re-run on resume
                        exc = fut.exception() if fut.status == "error" else None
                        summary = {"status": "error", "message": f"{type(exc).__name__}: {exc}" if exc else fut.status}
                    rec = {"key": r["key"], "values": r["values"], "seed": r["seed"], "summary": summary}
                    atomic_write_json(runs_dir / f"{r['key']}.json", rec)
                    records[r["key"]] = rec
                    executed += 1
                    bar.update()
                    if on_result is not None:
                        on_result(rec)
            except BaseException as exc:
                state = "interrupted"
                if not isinstance(exc, KeyboardInterrupt):
                    pending_exc = exc
                try:
                    client.cancel(list(futures))
                except BaseException:  # a cluster already going down, or a second Ctrl-C
                    pass
    finally:
        bar.close()
        # a second Ctrl-C while closing must not lose the runs so far: they are written below
        for closing in (client, cluster):
            if closing is not None:
                try:
                    closing.close()
                except BaseException:
                    state = "interrupted"

    # ---- the dataset
    import xarray as xr

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
    atomic_write_with(out / "sweep.nc", lambda p: ds.to_netcdf(p, engine="h5netcdf"))
    if pending_exc is not None:
        raise pending_exc
    return ds


# ---------------------------------------------------------------------- CLI
def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield sweep`` to the ``meanfield`` parser; return its handler."""
    p = subparsers.add_parser(
        "sweep",
        help="closed-loop runs over a grid of scenario values x seeds on Dask: sweep.nc + runs/*.json",
        description=(
            "Run the closed loop for the cartesian product of the --set values and the seeds, on a local "
            "Dask cluster or an existing one (--scheduler). Resumable: re-running with the same arguments "
            "reuses the finished runs in OUT/runs. Exit status: 0 every run completed; 1 a run failed, "
            "diverged or the sweep was interrupted (outputs written); 2 bad input."
        ),
    )
    p.add_argument("scenario", nargs="?", default="paper", help="built-in name (paper) or a TOML file")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=V1,V2,...",
        help="a swept scenario field and its values, e.g. --set robots.n=4,9,16 (repeatable)",
    )
    p.add_argument("--seeds", default="1", help="N for seeds 0..N-1, or A-B, or a,b,c (default 1)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="an existing Dask scheduler, tcp://host:port")
    p.add_argument("--workers", type=int, default=None, help="worker processes of the local cluster (default: cores)")
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=CONNECT_TIMEOUT,
        help=f"seconds to wait for --scheduler before refusing it (default {CONNECT_TIMEOUT:g})",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    return _handle


def _handle(args: argparse.Namespace) -> int:
    from meanfield.scenario import load_scenario

    sets = parse_values(args.set)
    seeds = parse_seeds(args.seeds)
    if not args.connect_timeout > 0:
        raise ParameterError("--connect-timeout", args.connect_timeout, "a number of seconds > 0")
    ds = run_sweep(
        load_scenario(args.scenario),
        sets,
        seeds,
        args.out,
        scheduler=args.scheduler,
        workers=args.workers,
        progress=not args.quiet,
        connect_timeout=args.connect_timeout,
    )
    counts: dict[str, int] = {}
    for st in ds["status"].values.flat:
        counts[st] = counts.get(st, 0) + 1
    if not args.quiet:
        print(
            f"sweep {ds.attrs['status']}: {ds.attrs['runs_total']} runs "
            f"({ds.attrs['runs_reused']} reused, {ds.attrs['runs_executed']} run now); "
            + ", ".join(f"{n} {st}" for st, n in sorted(counts.items()))
        )
        print(f"outputs in {args.out}")
    if ds.attrs["status"] != "completed":
        import sys

        flat = zip(ds["status"].values.flat, ds["message"].values.flat, strict=True)
        bad = [f"{st}: {m}" if m else st for st, m in flat if st != "completed"]
        print(
            f"meanfield: sweep {ds.attrs['status']}: {len(bad)} run(s) not completed; first: {bad[0]}",
            file=sys.stderr,
        )
        return 1
    return 0
