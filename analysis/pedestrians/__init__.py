"""Pedestrian-dynamics measurements of finished runs with PedPy (``meanfield pedestrians``, docs/pedestrians.md).

- :mod:`~analysis.pedestrians.metrics`: :func:`pedestrian_metrics` (N(t) in the target region,
  density maps) and its steps (:func:`load_run`, :func:`walkable_area`,
  :func:`target_measurement_area`, :func:`load_pedpy_trajectories`, :func:`count_in_target`,
  :func:`density_maps`), its result :class:`PedestrianMetrics`;
- :mod:`~analysis.pedestrians.flow`: speed and flow into the target region
  (:func:`speed_and_flow`, across :func:`entry_line`);
- :mod:`~analysis.pedestrians.figures`: :func:`plot_pedestrian_figures`;
- :mod:`~analysis.pedestrians.cli`: the command ``meanfield pedestrians`` (entry point
  ``analysis.pedestrians.cli:register``).

Names are imported on first use (:mod:`meanfield._namespace`); PedPy itself only when a
measurement runs.  The old modules ``analysis.pedestrian_*`` still import, with a warning
(:mod:`analysis._moved`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "PedestrianMetrics": "analysis.pedestrians.metrics",
    "count_in_target": "analysis.pedestrians.metrics",
    "density_maps": "analysis.pedestrians.metrics",
    "entry_line": "analysis.pedestrians.flow",
    "load_pedpy_trajectories": "analysis.pedestrians.metrics",
    "load_run": "analysis.pedestrians.metrics",
    "pedestrian_metrics": "analysis.pedestrians.metrics",
    "plot_pedestrian_figures": "analysis.pedestrians.figures",
    "speed_and_flow": "analysis.pedestrians.flow",
    "target_measurement_area": "analysis.pedestrians.metrics",
    "walkable_area": "analysis.pedestrians.metrics",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
