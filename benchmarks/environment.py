"""Where ``meanfield bench`` runs: one core, Ctrl-C remembered, the machine described.

Used by :mod:`benchmarks.suite` around the whole run (``docs/cli.md``, "meanfield bench":
everything runs on one core).  This module imports no numerical library, so that
``python -m benchmarks.suite`` can set :data:`THREAD_VARIABLES` before numpy loads.
"""

from __future__ import annotations

import contextlib
import os
import platform
import signal
import sys
import threading
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = ["THREAD_VARIABLES", "one_thread", "one_thread_variables", "watch_interrupts", "machine"]

THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def one_thread_variables() -> None:
    """Set :data:`THREAD_VARIABLES` to 1 where they are not exported, before the libraries load.

    ``NUMBA_NUM_THREADS`` is left alone once numba is imported: its thread pool may be running,
    and numba then refuses any change of the variable at its next compile (a ``RuntimeError``);
    :func:`one_thread` holds numba to one thread with ``numba.set_num_threads`` instead.
    """
    for var in THREAD_VARIABLES:
        if var == "NUMBA_NUM_THREADS" and "numba" in sys.modules:
            continue
        os.environ.setdefault(var, "1")


@contextlib.contextmanager
def one_thread() -> Iterator[dict[str, Any]]:
    """Thread variables set to 1 (unless exported), the loaded BLAS/OpenMP pools limited to match
    (``threadpoolctl``); both restored after."""
    from threadpoolctl import threadpool_info, threadpool_limits

    saved = {v: os.environ.get(v) for v in THREAD_VARIABLES}
    one_thread_variables()
    numba = sys.modules.get("numba")
    numba_before = numba.get_num_threads() if numba is not None else None
    if numba is not None:
        numba.set_num_threads(1)
    try:
        want = max(1, int(os.environ["OPENBLAS_NUM_THREADS"]))
    except ValueError:
        want = 1
    before = {p["filepath"]: p["num_threads"] for p in threadpool_info()}
    try:
        with threadpool_limits(limits=want):
            info = {
                "environment": {v: os.environ.get(v) for v in THREAD_VARIABLES},
                "numba_threads": None if numba is None else numba.get_num_threads(),
                "thread_pools": [
                    {
                        "library": Path(p["filepath"]).name,
                        "api": p["internal_api"],
                        "threads_before": before.get(p["filepath"]),
                        "threads": p["num_threads"],
                    }
                    for p in threadpool_info()
                ],
            }
            yield info
    finally:
        if numba is not None:
            numba.set_num_threads(numba_before)
        for v, value in saved.items():
            if value is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = value


@contextlib.contextmanager
def watch_interrupts() -> Iterator[dict[str, bool]]:
    """Remember a Ctrl-C even when a benchmark swallows it (``ClosedLoop.run`` returns "interrupted")."""
    state = {"hit": False}

    def handler(signum, frame):
        state["hit"] = True
        raise KeyboardInterrupt

    install = threading.current_thread() is threading.main_thread() and (
        signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )
    if install:
        signal.signal(signal.SIGINT, handler)
    try:
        yield state
    finally:
        if install:
            signal.signal(signal.SIGINT, signal.default_int_handler)


def machine() -> dict[str, Any]:
    """Processor, cores, platform, Python, the versions of the libraries and anchors, the load average."""
    versions = {}
    for dist in ("meanfield-crowd", "numpy", "scipy", "cvxpy", "clarabel", "casadi", "py-pde", "fipy", "jupedsim"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return {
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
        "load_average_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
    }
