"""verification: each claim of the paper checked numerically, with a verdict.

Built on :mod:`analysis` and :mod:`meanfield`; never imported by them.  One module per
claim (``theorem1``, ``theorem2``, ``theorem3``, ``mean_field``, ``robot_count``,
``agents``), the plants they run (``plant``), the result type (``result``), the runner and
the report behind ``meanfield verify`` (``runner``, ``report``, ``cli``), and the mutation
demo (``python -m verification.mutation``).
"""

from verification.agents import check_agents, check_pedestrians
from verification.mean_field import check_mean_field
from verification.report import render_markdown, write_report
from verification.result import VERDICTS, CheckResult
from verification.robot_count import check_robot_count
from verification.runner import CHECKS, VerificationRun, verify
from verification.theorem1 import check_theorem1
from verification.theorem2 import check_theorem2
from verification.theorem3 import check_theorem3

__all__ = [
    "CHECKS",
    "VERDICTS",
    "CheckResult",
    "VerificationRun",
    "check_agents",
    "check_mean_field",
    "check_pedestrians",
    "check_robot_count",
    "check_theorem1",
    "check_theorem2",
    "check_theorem3",
    "render_markdown",
    "verify",
    "write_report",
]
