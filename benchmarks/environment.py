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
import threading
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = ["THREAD_VARIABLES", "one_thread", "watch_interrupts", "machine"]

THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


@contextlib.contextmanager
def one_thread() -> Iterator[dict[str, Any]]:
    """Thread variables set to 1 (unless exported), the loaded BLAS/OpenMP pools limited to match
    (``threadpoolctl``); both restored after."""
    from threadpoolctl import threadpool_info, threadpool_limits

    saved = {v: os.environ.get(v) for v in THREAD_VARIABLES}
    for v in THREAD_VARIABLES:
        os.environ.setdefault(v, "1")
    try:
        want = max(1, int(os.environ["OPENBLAS_NUM_THREADS"]))
    except ValueError:
        want = 1
    before = {p["filepath"]: p["num_threads"] for p in threadpool_info()}
    try:
        with threadpool_limits(limits=want):
            info = {
                "environment": {v: os.environ[v] for v in THREAD_VARIABLES},
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
