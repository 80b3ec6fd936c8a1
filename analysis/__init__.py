"""analysis: the constants and designs behind the paper's guarantees.

- :mod:`analysis.poincare`: μ₂, the first non-zero Neumann eigenvalue of Ω (``c₂ = √μ₂``),
  the Payne–Weinberger bound, closed forms;
- :mod:`analysis.rates`: ``k_p = 2 α_inf μ₂`` and the ISS gain, a priori or along a run;
- :mod:`analysis.robot_count`: the coverage estimate and the empirical minimum;
- :mod:`analysis.bounded`: the speed-limited β/γ program (cvxpy + Clarabel), the
  ``bounded`` strategy of scenarios;
- :mod:`analysis.limits`: closed-loop runs over speed limits;
- :mod:`analysis.nmpc` (a subpackage): the NMPC baseline (CasADi), the ``nmpc`` controller of
  scenarios;
- :mod:`analysis.pedestrians` (a subpackage): PedPy measurements of finished runs, the command
  ``meanfield pedestrians``;
- :mod:`analysis.cli`: ``meanfield analyze``.

The modules ``analysis.nmpc_*`` and ``analysis.pedestrian_*`` of earlier releases moved into the
two subpackages; their old paths still import until 0.3.0, with a warning naming the new
module (:mod:`analysis._moved`).

Built on :mod:`meanfield`; never imported by it (the strategy, the controller and the
command reach it through entry points, see :mod:`meanfield.plugins`).

Example::

    from meanfield import Domain
    from analysis import neumann_eigenvalue, payne_weinberger_bound
    mu2 = neumann_eigenvalue(Domain.disk(1.0), cells=(128, 128))
"""

from analysis._moved import install_moved_modules
from meanfield._namespace import lazy_namespace

_LAZY = {
    "BoundedBetaGamma": "analysis.bounded",
    "BoundedInputs": "analysis.bounded",
    "achievable_range": "analysis.bounded",
    "bounded_inputs_exact": "analysis.bounded",
    "LimitsStudy": "analysis.limits",
    "limits_study": "analysis.limits",
    "PoincareReport": "analysis.poincare",
    "exact_neumann_eigenvalue": "analysis.poincare",
    "neumann_eigenvalue": "analysis.poincare",
    "payne_weinberger_bound": "analysis.poincare",
    "poincare_report": "analysis.poincare",
    "GainReport": "analysis.rates",
    "decay_rate": "analysis.rates",
    "gains_for_scenario": "analysis.rates",
    "gains_from_run": "analysis.rates",
    "iss_gain": "analysis.rates",
    "CoverageLayout": "analysis.robot_count",
    "RobotCountStudy": "analysis.robot_count",
    "coverage_estimate": "analysis.robot_count",
    "coverage_layout": "analysis.robot_count",
    "coverage_radius": "analysis.robot_count",
    "empirical_robot_count": "analysis.robot_count",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)
install_moved_modules()  # old module paths (analysis.nmpc_qp, analysis.pedestrian_metrics, ...) keep working

__all__ = [
    "BoundedBetaGamma",
    "BoundedInputs",
    "CoverageLayout",
    "GainReport",
    "LimitsStudy",
    "PoincareReport",
    "RobotCountStudy",
    "achievable_range",
    "bounded_inputs_exact",
    "coverage_estimate",
    "coverage_layout",
    "coverage_radius",
    "decay_rate",
    "empirical_robot_count",
    "exact_neumann_eigenvalue",
    "gains_for_scenario",
    "gains_from_run",
    "iss_gain",
    "limits_study",
    "neumann_eigenvalue",
    "payne_weinberger_bound",
    "poincare_report",
]
