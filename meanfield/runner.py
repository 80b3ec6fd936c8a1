"""Running a closed loop to the end: the usual observers, a progress bar, interruptions, the summary.

:func:`run` assembles a scenario and runs it; :func:`run_loop` runs an existing
:class:`~meanfield.loop.ClosedLoop` with :class:`~meanfield.observers.TargetTracker`,
:class:`~meanfield.observers.InputStatistics` and :class:`~meanfield.observers.Recorder`
attached, and returns a :class:`~meanfield.result.SimulationResult`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from meanfield.errors import SimulationDiverged
from meanfield.loop import ClosedLoop
from meanfield.metrics import w2_block_size, wasserstein2_to_grid_density
from meanfield.observers import InputStatistics, Recorder, TargetTracker
from meanfield.result import SimulationResult
from meanfield.scenario import Scenario

__all__ = ["run", "run_loop"]


def _finite_mean(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def _finite_max(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else None


def run_loop(
    loop: ClosedLoop, progress: bool = True, callback: Callable[[ClosedLoop], None] | None = None
) -> SimulationResult:
    """Run ``loop`` to ``t_final``, recording every ``record_every`` steps.

    Parameters
    ----------
    loop : ClosedLoop
    progress : bool
        Show a tqdm progress bar.
    callback : callable, optional
        Called as ``callback(loop)`` after every step.

    Returns
    -------
    SimulationResult
        With ``summary["status"]`` ``"completed"``, ``"diverged"`` (the message in
        ``summary["message"]``; frames up to the last good state) or ``"interrupted"``
        (KeyboardInterrupt; frames so far).
    """
    from tqdm.auto import tqdm

    sc = loop.scenario
    target, inputs = TargetTracker(0.9), InputStatistics()
    recorder = Recorder(target)
    for obs in (target, inputs, recorder):
        loop.attach(obs)
    loop.start()
    p = loop.parts
    rho_err0 = loop.grid.norm(loop.density - p.target)
    status, message = "completed", ""
    first = loop.step_index
    n_steps = sc.steps - first
    start = time.perf_counter()
    bar = tqdm(total=n_steps, disable=not progress, desc=f"meanfield run {sc.name}", unit="step", mininterval=0.5)
    try:
        for _ in range(n_steps):
            loop.step()
            if recorder.last_recorded_step == loop.step_index:
                bar.update(loop.step_index - first - bar.n)
            if callback is not None:
                callback(loop)
    except SimulationDiverged as exc:
        status, message = "diverged", str(exc)
    except KeyboardInterrupt:
        status, message = "interrupted", f"interrupted at t = {loop.t:.4g}"
    finally:
        bar.close()
        for obs in (target, inputs, recorder):
            loop.observers.remove(obs)
    wall = time.perf_counter() - start
    recorder.finish()
    dataset = recorder.dataset()
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
        "backend": sc.pedestrians.backend,
        "controller": sc.controller.kind,
        "field_evaluation": None,
        "field_error_bound_final": _field_error_bound(loop),
        "view_radius": sc.view.radius,
        **crowd.summary(),
        "V2_initial": recorder.first_V2,
        "V2_final": float(dataset["V2"].values[-1]) if dataset.sizes["time"] else None,
        "A_final": _last_A(recorder),
        "steps": loop.step_index,
        "time_final": loop.t,
        "wall_seconds": wall,
        "steps_per_second": (loop.step_index - first) / wall if wall > 0 else None,
        "seed": sc.seed,
        "scenario": sc.to_dict(),
    }
    return SimulationResult(sc, dataset, summary, p.kernel)


def _last_A(recorder: Recorder) -> float | None:
    """``A`` of the last step's control (None before any step or without the law's quantities)."""
    state = recorder.last_state
    return float(state.A) if state is not None else None


def _w2_to_target(loop: ClosedLoop) -> float | None:
    """W₂ from the agents to the target density (None for a crowd without positions)."""
    positions = loop.crowd.positions
    if positions is None:
        return None
    return wasserstein2_to_grid_density(positions, loop.grid, loop.target, seed=loop.scenario.seed)


def _w2_coarsening_bound(loop: ClosedLoop) -> float:
    """How far merging cells for the W₂ solve can move it (0: every cell kept)."""
    b = w2_block_size(loop.grid)
    return 0.0 if b == 1 else b * math.hypot(loop.grid.dx, loop.grid.dy)


def _field_error_bound(loop: ClosedLoop) -> float | None:
    """Interpolation error bound of a sampled ``v_r`` at the final robots (None: exact or no agents)."""
    bound = getattr(loop.crowd, "field_error_bound", None)
    return bound(loop.robots) if bound is not None else None


def run(
    scenario: Scenario | str, *, seed: int | None = None, progress: bool = True, **overrides: Any
) -> SimulationResult:
    """Assemble a scenario's closed loop and run it.

    Parameters
    ----------
    scenario : Scenario or str
        A scenario, a built-in name (``"paper"``) or a TOML path.
    seed : int, optional
        Override the scenario's seed.
    progress : bool
        Show a progress bar.
    **overrides
        Passed to :func:`~meanfield.assembly.assemble` (``sigma``, ``disturbance``,
        ``beta_gamma``, ``kernel``, ``crowd``, ``controller``).
    """
    from meanfield.scenario import load_scenario

    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if seed is not None:
        scenario = scenario.replace(seed=seed)
    return run_loop(ClosedLoop(scenario, **overrides), progress=progress)
