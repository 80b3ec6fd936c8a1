"""Work made of many runs: the mean-field limit measured (:mod:`~meanfield.workflows.mean_field_limit`),
sweeps (:mod:`~meanfield.workflows.sweep`, :mod:`~meanfield.workflows.sweep_plan`), the controller study
(:mod:`~meanfield.workflows.controller_study`) and where their jobs run (:mod:`~meanfield.workflows.dask_cluster`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "AgentsPdeComparison": "meanfield.workflows.mean_field_limit",
    "CACHED_STATUSES": "meanfield.workflows.sweep_plan",
    "CONNECT_TIMEOUT": "meanfield.workflows.dask_cluster",
    "ComparisonReport": "meanfield.workflows.mean_field_limit",
    "RobotTrajectory": "meanfield.workflows.mean_field_limit",
    "SUMMARY_KEYS": "meanfield.workflows.sweep_plan",
    "SweepPlan": "meanfield.workflows.sweep_plan",
    "candidates": "meanfield.workflows.controller_study",
    "check_sweep": "meanfield.workflows.sweep_plan",
    "compare_agents_pde": "meanfield.workflows.mean_field_limit",
    "connect": "meanfield.workflows.dask_cluster",
    "expand_sweep": "meanfield.workflows.sweep_plan",
    "finished_runs": "meanfield.workflows.sweep_plan",
    "fit_slope": "meanfield.workflows.mean_field_limit",
    "gather_dataset": "meanfield.workflows.sweep_plan",
    "jobs_on": "meanfield.workflows.dask_cluster",
    "map_jobs": "meanfield.workflows.dask_cluster",
    "parse_seeds": "meanfield.workflows.sweep_plan",
    "parse_values": "meanfield.workflows.sweep_plan",
    "record_robot_trajectory": "meanfield.workflows.mean_field_limit",
    "run_comparison": "meanfield.workflows.mean_field_limit",
    "run_key": "meanfield.workflows.sweep_plan",
    "run_sweep": "meanfield.workflows.sweep",
    "study_controllers": "meanfield.workflows.controller_study",
    "table": "meanfield.workflows.controller_study",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
