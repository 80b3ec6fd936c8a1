"""The closed loop: a scenario assembled into parts once, one loop that steps them, observers that record.

:mod:`~meanfield.simulation.assembly` builds the parts, :mod:`~meanfield.simulation.preflight` checks a run
fits before it starts, :mod:`~meanfield.simulation.loop` steps them, :mod:`~meanfield.simulation.observers`,
:mod:`~meanfield.simulation.evacuation_measures` and :mod:`~meanfield.simulation.stragglers` record,
:mod:`~meanfield.simulation.summary` and :mod:`~meanfield.simulation.wasserstein` measure, and
:mod:`~meanfield.simulation.result` holds the outcome.

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "ArtifactWriter": "meanfield.simulation.result",
    "CRUSH_DENSITY": "meanfield.simulation.evacuation_measures",
    "ClosedLoop": "meanfield.simulation.loop",
    "EvacuationTracker": "meanfield.simulation.evacuation_measures",
    "InputStatistics": "meanfield.simulation.observers",
    "LoopView": "meanfield.simulation.observers",
    "Observer": "meanfield.simulation.observers",
    "Parts": "meanfield.simulation.assembly",
    "Recorder": "meanfield.simulation.observers",
    "RunEstimate": "meanfield.simulation.preflight",
    "SPECIFIC_FLOW": "meanfield.simulation.evacuation_measures",
    "DESIGN_SPECIFIC_FLOW": "meanfield.simulation.evacuation_measures",
    "SimulationResult": "meanfield.simulation.result",
    "StepRecord": "meanfield.simulation.observers",
    "StragglerTracker": "meanfield.simulation.stragglers",
    "TargetTracker": "meanfield.simulation.observers",
    "alpha_schedule_for": "meanfield.simulation.assembly",
    "assemble": "meanfield.simulation.assembly",
    "available_memory": "meanfield.simulation.preflight",
    "check_fits": "meanfield.simulation.preflight",
    "disturbance_for": "meanfield.simulation.assembly",
    "estimate_run": "meanfield.simulation.preflight",
    "initial_robots": "meanfield.simulation.assembly",
    "recorded_humans": "meanfield.simulation.observers",
    "run": "meanfield.simulation.loop",
    "run_id": "meanfield.simulation.summary",
    "run_summary": "meanfield.simulation.summary",
    "sensing_controllers": "meanfield.simulation.assembly",
    "signals_deferred": "meanfield.simulation.loop",
    "stability_warnings": "meanfield.simulation.preflight",
    "w2_block_size": "meanfield.simulation.wasserstein",
    "wasserstein2_to_grid_density": "meanfield.simulation.wasserstein",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
