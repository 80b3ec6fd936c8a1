"""verification: each claim of the paper checked numerically, with a verdict.

Built on :mod:`analysis` and :mod:`meanfield`; never imported by them.  One module per
claim (``theorem1``, ``theorem2``, ``theorem3``, ``congested``, ``mean_field``, ``two_scales``, ``robot_count``,
``agents``), the plants they run (``plant``), the hypotheses a scenario's grid meets
(``hypotheses``: Ω in one piece, no exits), the result type (``result``), the runner and
the report behind ``meanfield verify`` (``runner``, ``report``, ``cli``), and the mutation
demo (``python -m verification.mutation``).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "check_agents": "verification.agents",
    "check_congested": "verification.congested",
    "check_pedestrians": "verification.agents",
    "check_mean_field": "verification.mean_field",
    "render_markdown": "verification.report",
    "write_report": "verification.report",
    "VERDICTS": "verification.result",
    "CheckResult": "verification.result",
    "check_robot_count": "verification.robot_count",
    "CHECKS": "verification.runner",
    "VerificationRun": "verification.runner",
    "verify": "verification.runner",
    "check_theorem1": "verification.theorem1",
    "check_theorem2": "verification.theorem2",
    "check_theorem3": "verification.theorem3",
    "check_two_scales": "verification.two_scales",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = [
    "CHECKS",
    "VERDICTS",
    "CheckResult",
    "VerificationRun",
    "check_agents",
    "check_congested",
    "check_mean_field",
    "check_pedestrians",
    "check_robot_count",
    "check_theorem1",
    "check_theorem2",
    "check_theorem3",
    "check_two_scales",
    "render_markdown",
    "verify",
    "write_report",
]
