"""The modules of ``analysis`` that moved into its subpackages, kept at their old paths until 0.3.0.

The NMPC baseline now lives in :mod:`analysis.nmpc` and the pedestrian measurements in
:mod:`analysis.pedestrians`.  ``from analysis.nmpc_qp import InputQP`` still gives the class,
with a :class:`~meanfield.errors.MeanfieldDeprecationWarning` naming its new place
(``analysis.nmpc.qp``), as :mod:`meanfield._namespace` does for meanfield's old modules
(:data:`MOVED`, :func:`install_moved_modules`; ``analysis`` calls it).

The old module ``analysis.nmpc`` is now the package of the same name, whose namespace gives
its names without a warning.
"""

from __future__ import annotations

from meanfield._namespace import install_moved_modules as _install

__all__ = ["MOVED", "install_moved_modules"]

PACKAGE = "analysis"

MOVED: dict[str, str] = {
    "nmpc_condensed": "nmpc.condensed",
    "nmpc_ipopt": "nmpc.ipopt",
    "nmpc_model": "nmpc.prediction_model",
    "nmpc_options": "nmpc.options",
    "nmpc_plan": "nmpc.plan",
    "nmpc_qp": "nmpc.qp",
    "nmpc_sqp": "nmpc.sqp",
    "pedestrian_cli": "pedestrians.cli",
    "pedestrian_figures": "pedestrians.figures",
    "pedestrian_flow": "pedestrians.flow",
    "pedestrian_metrics": "pedestrians.metrics",
}
"""Old module (under ``analysis.``) -> its new module (relative to ``analysis``); the names are unchanged."""


def install_moved_modules() -> None:
    """Let the old module paths of :data:`MOVED` be imported (once per process; ``analysis`` calls it),
    by meanfield's finder of moved modules (:func:`meanfield._namespace.install_moved_modules`)."""
    _install(PACKAGE, MOVED)
