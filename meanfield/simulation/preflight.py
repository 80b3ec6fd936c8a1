"""Before a run: will it fit?  After a run: did it break a known condition of the scheme?

:func:`estimate_run` gives the memory and the output size of a scenario's closed loop from
its sizes alone; :func:`check_fits` refuses, before anything is allocated, a run that
cannot fit in the memory available or on the output's disk, naming the field to change and
by how much.  :func:`stability_warnings` lists, for a finished run, the conditions of the
scheme it broke: such a run is not refused (it may still be what the user wants), but its
summary carries ``warnings`` and the command line prints them.

The memory model, measured on this toolkit (peak resident memory of ``meanfield run``):
250 MB for the interpreter and libraries (``paper``: 241 MB), about 200 bytes per human of
working arrays (positions, noise, drift, KDE binning; ``stadium``, 10⁶ humans: 359 MB,
estimated 460 MB), 200 bytes per grid cell, and the recorded frames twice (the frames, then
the stacked dataset).  It errs on the large side, so a refusal is never a run that fits easily.
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from meanfield import plugins
from meanfield.errors import ParameterError

__all__ = ["RunEstimate", "estimate_run", "available_memory", "check_fits", "stability_warnings"]

BYTES_PER_HUMAN = 200
BYTES_PER_CELL = 200
BASELINE_BYTES = 250 * 2**20
_MB = 2**20


@dataclass(frozen=True)
class RunEstimate:
    """Sizes of a run, from its scenario alone.

    Attributes
    ----------
    frames : int
        Recorded frames (every ``record_every`` steps, and the last).
    frame_bytes : int
        Bytes of one recorded frame (robots, recorded humans, density, scalars).
    crowd_bytes, grid_bytes, record_bytes : int
        Working memory of the crowd, of the grid's fields, and of the recorded frames.
    memory_bytes : int
        Estimated peak memory of the process.
    output_bytes : int
        Estimated size of ``timeseries.nc`` (uncompressed) plus the figures.
    """

    frames: int
    frame_bytes: int
    crowd_bytes: int
    grid_bytes: int
    record_bytes: int
    memory_bytes: int
    output_bytes: int


def estimate_run(scenario: Any) -> RunEstimate:
    """The memory and output size of ``scenario``'s closed loop (see the module docstring)."""
    n = int(scenario.crowd.n)
    robots = int(scenario.robots.n)
    nx, ny = scenario.grid.cells
    cells = nx * ny
    recorded = n if scenario.record_humans == "all" else min(n, int(scenario.record_humans))
    frames = scenario.steps // scenario.record_every + 2
    frame_bytes = 8 * (5 * robots + 2 * recorded + cells + 16)
    record_bytes = 2 * frames * frame_bytes + frames * 30 * 100  # the frames, the dataset; list and array headers
    crowd_bytes = BYTES_PER_HUMAN * n
    grid_bytes = BYTES_PER_CELL * cells
    memory = BASELINE_BYTES + crowd_bytes + grid_bytes + record_bytes
    output = frames * frame_bytes + 2 * _MB
    return RunEstimate(frames, frame_bytes, crowd_bytes, grid_bytes, record_bytes, memory, output)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _free_disk(path: Path) -> int | None:
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free
    except OSError:
        return None


def check_fits(scenario: Any, out_dir: str | Path | None = None) -> RunEstimate:
    """Refuse, before anything is allocated, a run that cannot fit; return its estimate.

    Raises
    ------
    ParameterError
        Named ``crowd.n`` when the crowd alone does not fit in the memory available, else
        ``record_every`` when the recorded frames do not (or do not fit on the disk of
        ``out_dir``), with the estimate and the fix (``record_every``, ``record_humans``).
    """
    est = estimate_run(scenario)
    avail = available_memory()
    if avail is not None and est.memory_bytes > avail:
        room = avail - BASELINE_BYTES - est.grid_bytes - est.record_bytes
        if est.crowd_bytes >= est.record_bytes:
            most = max(room // BYTES_PER_HUMAN, 0)
            raise ParameterError(
                "crowd.n",
                scenario.crowd.n,
                f"a crowd that fits: the run needs about {est.memory_bytes / _MB:,.0f} MB and "
                f"{avail / _MB:,.0f} MB are available, room for about {most:,} humans",
            )
        _refuse_record(scenario, est, est.memory_bytes, avail, "memory")
    free = _free_disk(out_dir) if out_dir is not None else None
    if free is not None and est.output_bytes > free:
        _refuse_record(scenario, est, est.output_bytes, free, f"disk space at {out_dir}")
    return est


def _refuse_record(scenario: Any, est: RunEstimate, need: int, have: int, what: str) -> None:
    factor = math.ceil(need / max(have, 1) * 1.2)
    raise ParameterError(
        "record_every",
        scenario.record_every,
        f"fewer recorded frames: {est.frames:,} frames of {est.frame_bytes / 1024:,.0f} kB need about "
        f"{need / _MB:,.0f} MB of {what} and {have / _MB:,.0f} MB are available; record_every = "
        f"{scenario.record_every * factor} (or fewer recorded humans, record_humans) would fit",
    )


def stability_warnings(scenario: Any, grid: Any, summary: dict[str, Any]) -> list[str]:
    """The known conditions of the scheme a finished run broke (empty: none).

    * the controller's own stability step, as it declares it (``stability_step(scenario, grid)``,
      a :class:`~meanfield.interfaces.StabilityStep`): for the paper's law, holding ``v_d(ρⁿ)``
      over a step is an explicit step of the closed-loop diffusion ``∇·(α∇ρ̃)``, stable for
      ``dt ≤ 0.9 h²/(4 α₀)`` (docs page *Verification*, Theorem 1);
    * the robots: a robot that crosses more than a grid cell in a step moves its sign
      farther than the grid resolves between two observations.
    """
    out = []
    h = min(grid.dx, grid.dy)
    dt = scenario.dt
    stability_step = plugins.declared("controller", scenario.controller.kind, "stability_step")
    step = stability_step(scenario, grid) if stability_step is not None else None
    if step is not None and dt > step.dt:
        out.append(f"dt = {dt:g} exceeds {step.what} = {step.dt:.3g} {step.why}")
    speed = summary.get("max_robot_speed") or 0.0
    if speed * dt > h:
        out.append(
            f"a robot moved {speed * dt:.3g} in one step, more than a grid cell (h = {h:.3g}): "
            "lower dt or robots.u_max"
        )
    return out
