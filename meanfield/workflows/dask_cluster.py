"""Where independent jobs run: one Dask machinery for ``sweep``, ``analyze`` and ``verify``.

:func:`connect` gives a client on a local cluster (one single-threaded worker process per
core, Ctrl-C reaching only this process) or on a running scheduler (``--scheduler``), never
Dask's default client, so the user's global Dask configuration is left as it was.
:func:`map_jobs` maps a function over jobs on it, with a progress bar, results in order;
:func:`jobs_on` makes the ``map_jobs`` calls inside one command share one cluster.
"""

from __future__ import annotations

import contextvars
import logging
import os
import re
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from meanfield.errors import ParameterError

__all__ = ["CONNECT_TIMEOUT", "connect", "jobs_on", "map_jobs", "shared_client"]

T = TypeVar("T")

CONNECT_TIMEOUT: float = 10.0
"""Seconds to wait for a ``--scheduler`` before refusing it."""


def connect(scheduler: str | None, workers: int | None, timeout: float):
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
        return Client(cluster, set_as_default=False), cluster  # the global dask config stays the user's
    if not re.fullmatch(r"[a-z]+://[^\s/]+:\d+", scheduler):
        raise ParameterError("--scheduler", scheduler, "a Dask scheduler address, e.g. tcp://127.0.0.1:8786")
    try:
        client = Client(scheduler, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise ParameterError(
            "--scheduler",
            scheduler,
            f"the address of a running Dask scheduler (could not connect within {timeout:g} s: {exc})",
        ) from None
    return client, None




class _Jobs:
    """A cluster started at the first fan-out of a command and closed at its end."""

    def __init__(self, scheduler: str | None, workers: int | None, timeout: float):
        self.scheduler, self.workers, self.timeout = scheduler, workers, timeout
        self.client = self.cluster = None

    def get(self):
        if self.client is None:
            self.client, self.cluster = connect(self.scheduler, self.workers, self.timeout)
        return self.client

    def close(self) -> None:
        for closing in (self.client, self.cluster):
            if closing is not None:
                try:
                    closing.close()
                except BaseException:  # a second Ctrl-C while closing: the work is already done
                    pass


_CURRENT: contextvars.ContextVar[_Jobs | None] = contextvars.ContextVar("meanfield_jobs", default=None)


@contextmanager
def jobs_on(
    scheduler: str | None = None, workers: int | None = None, timeout: float = CONNECT_TIMEOUT
) -> Iterator[None]:
    """Within: :func:`map_jobs` runs on one Dask cluster, started when first needed and closed at the end.

    ``scheduler`` is a running Dask scheduler's address (``tcp://host:port``); default: a
    local cluster of ``workers`` processes (default: the cores).
    """
    jobs = _Jobs(scheduler, workers, timeout)
    token = _CURRENT.set(jobs)
    try:
        yield
    finally:
        _CURRENT.reset(token)
        jobs.close()


def shared_client(scheduler: str | None, workers: int | None) -> Any | None:
    """The client of the enclosing :func:`jobs_on` when it serves the same ``scheduler`` and ``workers``
    (started now if it was not yet), else None: several sweeps of one command then share one cluster
    instead of starting and closing one each (a few seconds each)."""
    current = _CURRENT.get()
    if current is None or current.scheduler != scheduler or workers not in (None, current.workers):
        return None
    return current.get()


def map_jobs(
    fn: Callable[[Any], T],
    jobs: Sequence[Any],
    workers: int | None,
    desc: str,
    progress: bool,
    on_result: Callable[[int, T], None] | None = None,
) -> list[T]:
    """``[fn(job) for job in jobs]`` on Dask, with a progress bar; results in the jobs' order.

    One job, or ``workers == 1`` without a scheduler, runs here, in this process.  Otherwise
    the jobs go to the cluster of the enclosing :func:`jobs_on`, or to a local cluster of
    ``workers`` processes started for this call.  ``fn`` must be a module-level function.
    ``on_result(k, result)``, if given, is called here as each job ``k`` finishes (in the order they
    finish), before the next result is awaited: a study that writes each result at once resumes
    where it was interrupted.

    The permission to import a scenario's ``plugins`` in force here
    (:func:`meanfield.plugins.current_permission`: ``--allow-plugins``, ``--plugin``) travels with
    each job, so a worker reads the scenarios this process was allowed to read.
    """
    from tqdm.auto import tqdm

    current = _CURRENT.get()
    local = current is None or current.scheduler is None
    n = (workers or (current.workers if current else None) or os.cpu_count() or 1) if local else None
    with tqdm(total=len(jobs), disable=not progress, desc=desc, unit="run") as bar:
        if len(jobs) <= 1 or (local and n == 1):
            out = []
            for k, job in enumerate(jobs):
                out.append(fn(job))
                if on_result is not None:
                    on_result(k, out[-1])
                bar.update()
            return out
        if current is None:
            with jobs_on(None, min(n, len(jobs))):
                return _on_cluster(fn, jobs, _CURRENT.get().get(), bar, on_result)
        return _on_cluster(fn, jobs, current.get(), bar, on_result)


def _permitted_call(job: Any, fn: Callable[[Any], T], permission: Any) -> T:
    """``fn(job)`` on a worker, under the permission of the process that submitted it."""
    from meanfield.plugins import permitted

    with permitted(permission):
        return fn(job)


def _on_cluster(fn: Callable[[Any], T], jobs: Sequence[Any], client: Any, bar: Any,
                on_result: Callable[[int, T], None] | None = None) -> list[T]:  # fmt: skip
    from distributed import as_completed

    from meanfield.plugins import PluginPermission, current_permission

    with client.as_current():
        permission = current_permission()
        if permission == PluginPermission():  # nothing allowed: the job as it is
            futures = client.map(fn, list(jobs), pure=False)
        else:  # the workers have no command line: the job carries what this process allowed
            futures = client.map(_permitted_call, list(jobs), fn=fn, permission=permission, pure=False)
        index = {f.key: k for k, f in enumerate(futures)}
        out: list[Any] = [None] * len(futures)
        try:
            for fut in as_completed(futures):
                k = index[fut.key]
                out[k] = fut.result()  # a job's exception is raised here, as a pool's would be
                if on_result is not None:
                    on_result(k, out[k])
                bar.update()
        except BaseException:
            client.cancel(futures)
            raise
    return out
