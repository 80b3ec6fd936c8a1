"""analysis: the constants and designs behind the paper's guarantees.

- :mod:`analysis.poincare`: μ₂, the first non-zero Neumann eigenvalue of Ω (``c₂ = √μ₂``),
  the Payne–Weinberger bound, closed forms;
- :mod:`analysis.rates`: ``k_p = 2 α_inf μ₂`` and the ISS gain, a priori or along a run;
- :mod:`analysis.robot_count`: the coverage estimate and the empirical minimum;
- :mod:`analysis.bounded`: the speed-limited β/γ program (cvxpy + Clarabel), the
  ``bounded`` strategy of scenarios;
- :mod:`analysis.limits`: closed-loop runs over speed limits;
- :mod:`analysis.nmpc`: the NMPC baseline (CasADi), the ``nmpc`` controller of scenarios;
- :mod:`analysis.cli`: ``meanfield analyze``.

Built on :mod:`meanfield`; never imported by it (the strategy, the controller and the
command reach it through entry points, see :mod:`meanfield.plugins`).

Example::

    from meanfield import Domain
    from analysis import neumann_eigenvalue, payne_weinberger_bound
    mu2 = neumann_eigenvalue(Domain.disk(1.0), cells=(128, 128))
"""

from analysis.bounded import BoundedBetaGamma, BoundedInputs, achievable_range, bounded_inputs_exact
from analysis.limits import LimitsStudy, limits_study
from analysis.poincare import (
    PoincareReport,
    exact_neumann_eigenvalue,
    neumann_eigenvalue,
    payne_weinberger_bound,
    poincare_report,
)
from analysis.rates import GainReport, decay_rate, gains_for_scenario, gains_from_run, iss_gain
from analysis.robot_count import (
    CoverageLayout,
    RobotCountStudy,
    coverage_estimate,
    coverage_layout,
    coverage_radius,
    empirical_robot_count,
)

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
