"""Parameter sweeps on Dask: ``meanfield sweep`` and :func:`run_sweep`.

A sweep runs the closed loop (:class:`meanfield.simulation.loop.ClosedLoop`) for every
combination of the swept scenario values × seeds, one Dask task per run, on a local
cluster (worker processes, one thread each) or on an existing Dask cluster named by
its scheduler's address.  Each run's summary is gathered into an :class:`xarray.Dataset`
with one dimension per swept key plus ``seed``, written to ``OUT/sweep.nc``.  This module
runs the sweep on Dask and registers the command (docs/cli.md, "``meanfield sweep``");
what the sweep runs and gathers (parsing, the runs, resume records, the dataset) is
:mod:`meanfield.workflows.sweep_plan` (its parsers, :func:`run_key` and constants are re-exported here).

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

Plugins
    A base scenario read from a file imports its ``plugins`` only when allowed
    (``allow_plugins=True``, or the command line's ``--allow-plugins``), as everywhere
    (:mod:`meanfield.plugins`).  Every run's scenario is built in this process first, so its
    modules have been allowed here; each job carries that permission to its worker (a worker
    trusts the process that submitted the job), which imports them before it reads the rest.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from meanfield.errors import ParameterError
from meanfield.workflows.dask_cluster import CONNECT_TIMEOUT, shared_client
from meanfield.workflows.dask_cluster import connect as _connect
from meanfield.workflows.sweep_plan import (
    CACHED_STATUSES,
    SUMMARY_KEYS,
    check_sweep,
    expand_sweep,
    finished_runs,
    gather_dataset,
    parse_seeds,
    parse_values,
    run_key,
)

__all__ = [
    "run_sweep",
    "run_key",
    "parse_values",
    "parse_seeds",
    "SUMMARY_KEYS",
    "CACHED_STATUSES",
    "CONNECT_TIMEOUT",
]

#: Seconds to wait for an external scheduler before refusing its address.


# ---------------------------------------------------------------------- worker side
def _run_one(scenario_toml: str, allow_plugins: bool = False) -> dict[str, Any]:
    """Run one closed loop from its scenario's TOML; never raises (errors come back as a summary).

    ``allow_plugins`` is the permission the submitting process gives the job: whether the
    scenario's ``plugins`` may be imported here (it built the scenario, so it allowed them).
    """
    import traceback

    start = time.perf_counter()
    try:
        from meanfield.scenarios.scenario import Scenario
        from meanfield.simulation.loop import ClosedLoop

        scenario = Scenario.from_toml(scenario_toml, allow_plugins=allow_plugins)
        summary = dict(ClosedLoop(scenario).run(progress=False).summary)
        summary.pop("scenario", None)
        return summary
    except Exception as exc:  # recorded, the sweep goes on
        return {
            "status": "error",
            "message": f"{type(exc).__name__}: {exc}",
            "traceback": traceback.format_exc(),
            "wall_seconds": time.perf_counter() - start,
        }


# ---------------------------------------------------------------------- the sweep
def _collect(client: Any, todo: list, runs_dir: Path, records: dict, bar: Any, on_result: Any):
    """Submit the runs, record each as it completes; ``(state, pending exception, executed)``."""
    from distributed import as_completed

    from meanfield.io.atomic import atomic_write_json

    state, pending_exc, executed = "completed", None, 0
    # each run's scenario was built in this process (expand_sweep), its plugins allowed here: the job
    # carries the permission to its worker, where no command line or context variable reaches
    futures = {
        client.submit(_run_one, r["toml"], allow_plugins=r["plugins_allowed"], pure=False, retries=0): r
        for r in todo
    }
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
    return state, pending_exc, executed


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
    allow_plugins: bool = False,
):
    """Run the closed loop for every combination of ``sets`` × ``seeds`` on Dask.

    Parameters
    ----------
    scenario : Scenario or str or Path
        The base scenario: a :class:`~meanfield.scenarios.scenario.Scenario`, a built-in name or a TOML file.
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
    allow_plugins : bool
        Let a ``scenario`` read from a file import the modules its ``plugins`` lists (otherwise
        refused, unless :func:`meanfield.plugins.allow_scenario_plugins` allows them).  The
        workers are given the permission with each job.

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
    from meanfield.io.atomic import atomic_write_with

    # ---- validation: nothing is created or run before all of it passes
    base, sets, seed_list = check_sweep(scenario, sets, seeds, allow_plugins=allow_plugins)
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ParameterError("--workers", workers, "an integer >= 1")
    plan = expand_sweep(base, sets, seed_list)

    out = Path(out_dir)
    runs_dir = out / "runs"
    records = finished_runs(plan, runs_dir)
    todo = [r for r in plan.runs if r["key"] not in records]
    reused = len(records)

    client = cluster = None
    shared = shared_client(scheduler, workers) if todo else None  # the enclosing jobs_on's cluster, kept open
    if todo and shared is None:
        client, cluster = _connect(scheduler, workers, connect_timeout)  # refuses a bad address
    runs_dir.mkdir(parents=True, exist_ok=True)

    # ---- the runs
    from tqdm.auto import tqdm

    executed = 0
    state = "completed"
    pending_exc: BaseException | None = None
    bar = tqdm(total=len(plan.runs), initial=reused, disable=not progress, desc="meanfield sweep", unit="run")
    try:
        if todo:
            # this client serves the futures without becoming dask's default (its global config
            # stays the user's: an xarray or dask call after the sweep must not look for it)
            serving = shared if shared is not None else client
            with serving.as_current():
                state, pending_exc, executed = _collect(serving, todo, runs_dir, records, bar, on_result)
    finally:
        bar.close()
        # closing a local cluster takes seconds after 100 %, when a user is tempted to press
        # Ctrl-C: say so; a Ctrl-C then leaves a sweep whose every run is recorded completed,
        # and a second Ctrl-C while closing must not lose the runs so far (written below)
        every_run_recorded = len(records) == len(plan.runs)
        if progress and (client is not None or cluster is not None):
            import sys

            print("meanfield sweep: closing the Dask cluster (Ctrl-C keeps the runs)...", file=sys.stderr)
        for closing in (client, cluster):
            if closing is not None:
                try:
                    closing.close()
                except BaseException:
                    if not every_run_recorded:
                        state = "interrupted"

    # ---- the dataset
    ds = gather_dataset(
        plan, records, state=state, scheduler=scheduler, workers=workers, reused=reused, executed=executed
    )
    atomic_write_with(out / "sweep.nc", lambda p: ds.to_netcdf(p, engine="h5netcdf"))
    if pending_exc is not None:
        raise pending_exc
    return ds
