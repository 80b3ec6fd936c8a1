"""The summary of a closed-loop run: the figures of ``summary.json``, from the loop and its observers.

:func:`run_summary` reads the final state of a :class:`~meanfield.simulation.loop.ClosedLoop` and the
standard observers (:mod:`meanfield.simulation.observers`); every key is documented on the docs page
*Command line* (``summary.json``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.interfaces import CrowdOfAgents, Reports
from meanfield.io.netcdf import NetCDFDataset
from meanfield.simulation.observers import InputStatistics, LoopView, Recorder, TargetTracker
from meanfield.simulation.wasserstein import w2_block_size, wasserstein2_to_grid_density

__all__ = ["run_summary", "run_id"]


def _finite_mean(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def _finite_max(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else None


def run_summary(
    loop: LoopView,
    target: TargetTracker,
    inputs: InputStatistics,
    recorder: Recorder,
    dataset: NetCDFDataset,
    *,
    status: str,
    message: str,
    rho_err0: float,
    wall: float,
    steps_run: int,
    measures: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """``summary.json`` of a run: outcome, errors, W₂, time to 90 %, input statistics, the crowd's own figures.

    Parameters
    ----------
    loop : LoopView
        The loop (:class:`~meanfield.simulation.loop.ClosedLoop`) at its final state.
    target, inputs, recorder
        The standard observers, attached for the whole run.
    dataset : NetCDFDataset
        The recorded frames, ``recorder.timeseries()`` (an :class:`xarray.Dataset` of them reads the same).
    status, message : str
        ``"completed"``, ``"diverged"`` or ``"interrupted"``, and why.
    rho_err0 : float
        ``‖ρ̂ − ρ_*‖`` at the start.
    wall : float
        Seconds spent stepping.
    steps_run : int
        Steps taken in this call (for ``steps_per_second``).
    measures : dict, optional
        The other observers' figures: with exits the evacuation measures
        (:meth:`~meanfield.simulation.evacuation_measures.EvacuationTracker.summary`), with agents
        following signs the stragglers (:meth:`~meanfield.simulation.stragglers.StragglerTracker.summary`).
    """
    sc = loop.scenario
    p = loop.parts
    crowd = loop.crowd
    final_err = loop.grid.norm(loop.density - p.target)
    steps = max(loop.step_index, 1)
    summary: dict[str, Any] = {
        "status": status,
        "message": message,
        "fraction_in_target": target.fraction,
        "target_radius": p.target_radius,
        "l2_error_initial": rho_err0,
        "l2_error_final": final_err,
        "l2_error_ratio": final_err / rho_err0 if rho_err0 > 0 else None,
        "w2_to_target_final": _w2_to_target(loop),
        "w2_coarsening_bound": _w2_coarsening_bound(loop),
        "time_to_90": target.time_to_level,
        "max_robot_speed": inputs.max_speed,
        "speed_limit": None if math.isinf(loop.robots.u_max) else loop.robots.u_max,
        "max_robot_turn_rate": inputs.max_turn_rate,
        "turn_rate_limit": None if math.isinf(loop.robots.omega_max) else loop.robots.omega_max,
        "saturated_fraction": inputs.saturated_steps / steps,
        "limits_binding_fraction": inputs.binding_steps / steps,
        "shortfall_mean": _finite_mean(dataset["shortfall"].values),
        "shortfall_max": _finite_max(dataset["shortfall"].values),
        "shortfall_applied_mean": _finite_mean(dataset["shortfall_applied"].values),
        "python_overrides": p.overrides,
        "backend": sc.crowd.kind,
        "controller": sc.controller.kind,
        "compiled_loops": _compiled_loops(),
        "field_error_bound_final": _field_error_bound(loop),
        "view_radius": sc.view.radius,
        **crowd.summary(),  # the crowd's own figures (agents: field_evaluation, seen_fraction_final, bodies)
        **(measures or {}),  # evacuation measures (with exits), stragglers (agents following signs)
        **_controller_summary(loop),  # a controller's own figures (coverage: idle robots)
        "V2_initial": recorder.first_V2,
        "V2_final": float(dataset["V2"].values[-1]) if dataset.sizes["time"] else None,
        "A_final": _last_A(recorder),
        "steps": loop.step_index,
        "time_final": loop.t,
        "wall_seconds": wall,
        "steps_per_second": steps_run / wall if wall > 0 else None,
        "seed": sc.seed,
        "scenario": sc.to_dict(),
    }
    return summary


def _controller_summary(loop: LoopView) -> dict[str, Any]:
    """A controller's own figures, if it reports any (``summary()``; the paper's law has none)."""
    return loop.controller.summary() if isinstance(loop.controller, Reports) else {}


def _last_A(recorder: Recorder) -> float | None:
    """``A`` of the last step's control (None before any step or without the law's quantities)."""
    state = recorder.last_state
    return float(state.A) if state is not None else None


def _w2_to_target(loop: LoopView) -> float | None:
    """W₂ from the agents to the target density (None for a crowd without positions)."""
    positions = loop.crowd.positions
    if positions is None:
        return None
    positions = positions[np.isfinite(positions).all(axis=1)]  # without those who left through an exit
    if not len(positions):
        return None
    return wasserstein2_to_grid_density(positions, loop.grid, loop.target, seed=loop.scenario.seed)


def _w2_coarsening_bound(loop: LoopView) -> float:
    """How far merging cells for the W₂ solve can move it (0: every cell kept)."""
    b = w2_block_size(loop.grid)
    return 0.0 if b == 1 else b * math.hypot(loop.grid.dx, loop.grid.dy)


def _field_error_bound(loop: LoopView) -> float | None:
    """Interpolation error bound of a sampled ``v_r`` at the final robots (None: exact or no agents)."""
    return loop.crowd.field_error_bound(loop.robots) if isinstance(loop.crowd, CrowdOfAgents) else None


def run_id(loop: LoopView, status: str) -> str:
    """An id of the run, derived from what it is: scenario, outcome, steps and final state.

    Two runs with the same id are the same run (reruns of a seed are bit-identical, and so is
    their id); a folder whose files carry different ids mixes runs.  SHA-256, 16 hex digits.
    """
    import hashlib

    h = hashlib.sha256()
    h.update(loop.scenario.to_toml().encode())
    h.update(f"|{status}|{loop.step_index}|{','.join(loop.parts.overrides)}|".encode())
    for arr in (loop.robots.positions, loop.robots.headings, loop.density):
        h.update(np.ascontiguousarray(arr, dtype=float).tobytes())
    return h.hexdigest()[:16]


def _compiled_loops() -> dict[str, Any]:
    """Which path ran (:mod:`meanfield._compiled.core`; chaotic runs agree between paths in distribution only)
    and on how many threads its parallel loops ran (their results do not depend on it)."""
    from meanfield._compiled import core as compiled
    from meanfield._compiled.threads import loop_threads

    st = compiled.status()
    return {"enabled": st["enabled"], "numba": st["numba"], "fallbacks": st["fallbacks"], "threads": loop_threads()}
