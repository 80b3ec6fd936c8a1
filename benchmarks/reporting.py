"""What every benchmark script prints: the machine line and the JSON record (stdout and ``--json``)."""

from __future__ import annotations

import json
import os
import platform
from typing import Any

import numpy as np

__all__ = ["machine_line", "emit", "write_files", "peak_resident_mb"]


def machine_line(extra: str = "") -> str:
    """``"x86_64, 2 cores (1 used), Python 3.11.7, numpy 2.4.6"`` (+ ``extra``)."""
    line = (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores (1 used), "
        f"Python {platform.python_version()}, numpy {np.__version__}"
    )
    return f"{line}, {extra}" if extra else line


def emit(record: dict[str, Any], path: str | None) -> None:
    """Print the record as JSON and, if ``path`` is given, write it there atomically."""
    print(json.dumps(record, indent=2))
    write_files(record, path)


def write_files(
    record: dict[str, Any], json_path: str | None, report: str = "", report_path: str | None = None
) -> None:
    """Write the record as JSON and the printed report as text, each atomically, where a path is given."""
    from pathlib import Path

    from meanfield.io.atomic import atomic_write_json, atomic_write_text

    if json_path:
        atomic_write_json(Path(json_path), record)
    if report_path:
        atomic_write_text(Path(report_path), report + "\n")


def peak_resident_mb() -> float:
    """Peak resident memory of this process alone, in MB.

    ``VmHWM`` from ``/proc/self/status`` is reset by ``exec``; ``ru_maxrss`` is not (a child
    started by a large process inherits its parent's peak), so it is only the fallback.
    """
    import resource

    try:
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB on Linux


def time_act_calls(controller: Any) -> list[float]:
    """Wrap ``controller.act`` with a clock; the returned list receives the seconds of each call.

    The wrapper replaces the bound method on this controller only; the list grows as the
    loop runs (the first call, which builds what is built once, is the caller's to drop).
    """
    import time

    inner, times = controller.act, []

    def timed(observation: Any) -> Any:
        t0 = time.perf_counter()
        out = inner(observation)
        times.append(time.perf_counter() - t0)
        return out

    controller.act = timed
    return times
