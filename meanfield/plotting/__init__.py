"""Figures of a run (the paper's Figs. 2 and 3), of a comparison, and an animation.

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "plot_evacuation": "meanfield.plotting.figures",
    "plot_snapshots": "meanfield.plotting.figures",
    "plot_target_and_error": "meanfield.plotting.figures",
    "save_animation": "meanfield.plotting.figures",
    "save_run_figures": "meanfield.plotting.figures",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
