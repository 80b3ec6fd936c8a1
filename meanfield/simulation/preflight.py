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
estimated 460 MB), 200 bytes per robot, about 700 bytes per grid cell (a ``[40000, 2]`` grid:
51 MB over ``paper``'s), and the recorded frames three times (the frames, the stacked
dataset, and the copy the NetCDF writer makes).  It errs on the large side, so a refusal is
never a run that fits easily.  The memory available is the least of the system's free memory,
the process's address-space limit (``ulimit -v``) and its control group's limit.

A refusal names the field whose term dominates the estimate (``crowd.n``, ``robots.n``,
``grid.cells``, or the recorded frames: ``record_every``, with ``t_final``/``dt`` and
``record_humans``), with the sizes and what would fit.
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

MAX_STEPS = 10**9
"""The most steps a run may take (a day of the paper's loop at 15,000 steps/s is 1.3·10⁹)."""
BYTES_PER_HUMAN = 200
BYTES_PER_ROBOT = 200
BYTES_PER_CELL = 700
FRAME_COPIES = 3
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
    robot_bytes : int
        Working memory of the robots.
    kde_bytes : int
        Working memory of the density estimate (its fine lattice, padding and FFTs:
        :meth:`~meanfield.crowds.kde.KernelDensityEstimator.working_bytes`); part of ``grid_bytes``.
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
    robot_bytes: int = 0
    kde_bytes: int = 0


def estimate_run(scenario: Any) -> RunEstimate:
    """The memory and output size of ``scenario``'s closed loop (see the module docstring)."""
    n = int(scenario.crowd.n)
    robots = int(scenario.robots.n)
    nx, ny = scenario.grid.cells
    cells = nx * ny
    recorded = n if scenario.record_humans == "all" else min(n, int(scenario.record_humans))
    frames = scenario.steps // scenario.record_every + 2
    frame_bytes = 8 * (5 * robots + 2 * recorded + cells + 16)
    record_bytes = FRAME_COPIES * frames * frame_bytes + frames * 30 * 100  # + list and array headers
    crowd_bytes = BYTES_PER_HUMAN * n
    robot_bytes = BYTES_PER_ROBOT * robots
    kde_bytes = _kde_bytes(scenario)
    grid_bytes = BYTES_PER_CELL * cells + kde_bytes
    memory = BASELINE_BYTES + crowd_bytes + robot_bytes + grid_bytes + record_bytes
    output = frames * frame_bytes + 2 * _MB
    return RunEstimate(
        frames, frame_bytes, crowd_bytes, grid_bytes, record_bytes, memory, output, robot_bytes, kde_bytes
    )


def _kde_bytes(scenario: Any) -> int:
    """The density estimate's working memory, from the grid's sizes alone (no grid is built): a
    bandwidth given in the scenario, else the rule's floor, one cell (the smallest it takes)."""
    from types import SimpleNamespace

    from meanfield.crowds.kde import KernelDensityEstimator

    nx, ny = scenario.grid.cells
    x0, x1, y0, y1 = scenario.domain.bounds
    dx, dy = (x1 - x0) / nx, (y1 - y0) / ny
    box = scenario.domain.area >= (x1 - x0) * (y1 - y0) * (1.0 - 1e-12)  # Ω fills its bounding box
    grid = SimpleNamespace(shape=(nx, ny), cells=(nx, ny), dx=dx, dy=dy, is_box=box)
    d = scenario.density
    h = d.bandwidth if isinstance(d.bandwidth, int | float) else max(dx, dy)
    kde = KernelDensityEstimator(grid, bandwidth=h, boundary=d.boundary, method=d.method)  # type: ignore[arg-type]
    return kde.working_bytes(scenario.crowd.n, h)


def _system_available() -> int | None:
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


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None  # "max" (no limit) is None


def _cgroup_available() -> int | None:
    """What the process's control group still allows (cgroup v2, then v1), or None without a limit."""
    limit = _read_int("/sys/fs/cgroup/memory.max")
    used = _read_int("/sys/fs/cgroup/memory.current")
    if limit is None:
        limit = _read_int("/sys/fs/cgroup/memory/memory.limit_in_bytes")
        used = _read_int("/sys/fs/cgroup/memory/memory.usage_in_bytes")
    if limit is None or limit >= 2**60:  # v1 writes a huge number for "no limit"
        return None
    return max(limit - (used or 0), 0)


def _rlimit_available() -> int | None:
    """What the address-space limit (``ulimit -v``) leaves, or None without one."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, ValueError, OSError):
        return None
    if soft == resource.RLIM_INFINITY:
        return None
    size = 0
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    size = int(line.split()[1]) * 1024
    except OSError:
        pass
    return max(soft - size, 0)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation, or None if unknown: the least of the system's
    ``MemAvailable``, the control group's remaining limit and what the address-space limit
    (``ulimit -v``) leaves."""
    known = [v for v in (_system_available(), _cgroup_available(), _rlimit_available()) if v is not None]
    return min(known) if known else None


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
    if scenario.steps > MAX_STEPS:
        raise ParameterError(
            "dt",
            scenario.dt,
            f"a step that gives at most {MAX_STEPS:.0e} steps over t_final = {scenario.t_final:.3g} "
            f"(this one gives {scenario.steps:.3g}); or a shorter t_final",
        )
    est = estimate_run(scenario)
    avail = available_memory()
    if avail is not None and est.memory_bytes > avail:
        cells = scenario.grid.cells[0] * scenario.grid.cells[1]
        density_frames = FRAME_COPIES * est.frames * 8 * cells  # the grid's share of the recorded frames
        robot_frames = FRAME_COPIES * est.frames * 8 * 5 * scenario.robots.n  # the robots' share
        terms = {"crowd": est.crowd_bytes, "robots": est.robot_bytes + robot_frames}
        terms["grid"] = est.grid_bytes + density_frames
        terms["record"] = est.record_bytes - density_frames - robot_frames
        biggest = max(terms, key=terms.get)
        room = avail - BASELINE_BYTES - sum(v for k, v in terms.items() if k != biggest)
        needs = f"the run needs about {est.memory_bytes / _MB:,.0f} MB and {avail / _MB:,.0f} MB are available"
        if biggest == "crowd":
            most = max(room // BYTES_PER_HUMAN, 0)
            raise ParameterError("crowd.n", scenario.crowd.n, f"a crowd that fits: {needs}, room for about {most:,}")
        if biggest == "robots":
            most = max(room // (BYTES_PER_ROBOT + FRAME_COPIES * est.frames * 40), 0)
            raise ParameterError("robots.n", scenario.robots.n, f"fewer robots: {needs}, room for about {most:,}")
        if biggest == "grid":
            raise ParameterError(
                "grid.cells",
                list(scenario.grid.cells),
                f"a grid that fits: {needs}; on this grid the fields take about {est.grid_bytes / _MB:,.0f} MB "
                f"(the density estimate {est.kde_bytes / _MB:,.0f} MB of them, its cells against the bandwidth) "
                f"and the recorded densities {density_frames / _MB:,.0f} MB (fewer frames: record_every)",
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
        f"fewer recorded frames: {est.frames:,} frames (t_final / dt = {scenario.steps:,} steps) of "
        f"{est.frame_bytes / 1024:,.0f} kB need about {need / _MB:,.0f} MB of {what} and {have / _MB:,.0f} MB "
        f"are available; record_every = {scenario.record_every * factor} (or fewer recorded humans, "
        "record_humans, or a shorter t_final) would fit",
    )


def stability_warnings(scenario: Any, grid: Any, summary: dict[str, Any]) -> list[str]:
    """The known conditions of the scheme a finished run broke (empty: none).

    * the controller's own stability step, as its record declares it (``stability_step(scenario, grid)``,
      a :class:`~meanfield.interfaces.StabilityStep`): for the paper's law, holding ``v_d(ρⁿ)``
      over a step is an explicit step of the closed-loop diffusion ``∇·(α∇ρ̃)``, stable for
      ``dt ≤ 0.9 h²/(4 α₀)`` (docs page *Verification*, Theorem 1);
    * the robots: a robot that crosses more than a grid cell in a step moves its sign
      farther than the grid resolves between two observations.
    """
    out = []
    h = min(grid.dx, grid.dy)
    dt = scenario.dt
    step = plugins.capabilities("controller", scenario.controller.kind).largest_stable_step(scenario, grid)
    if step is not None and dt > step.dt:
        out.append(f"dt = {dt:g} exceeds {step.what} = {step.dt:.3g} {step.why}")
    speed = summary.get("max_robot_speed") or 0.0
    if speed * dt > h:
        out.append(
            f"a robot moved {speed * dt:.3g} in one step, more than a grid cell (h = {h:.3g}): "
            "lower dt or robots.u_max"
        )
    return out
