"""The structured outcome of one check: a claim of the paper, a verdict and the figures behind it.

A verdict is one of three words:

``"holds"``
    The measured figures meet the claim's bound under the claim's hypotheses.
``"fails"``
    They do not: the claim (or the bound it was held against) is contradicted by the run.
``"inconclusive"``
    The check could not decide: a hypothesis of the claim is not met by the scenario (exits
    that let mass out, a grid that splits Ω, a backend that is not installed, inputs the
    theorem assumes unbounded but the robots have limits, ...).  ``reason`` says which.

A check that *crashed* is not a verdict: the runner records it with ``verdict = "error"``
and the command exits non-zero (see :mod:`verification.runner`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

CHECK_NAMES = (
    "theorem1",
    "theorem2",
    "theorem3",
    "congested",
    "mean_field",
    "two_scales",
    "robot_count",
    "agents",
    "pedestrians",
)
"""The checks of ``meanfield verify``, in report order (:data:`verification.runner.CHECKS` maps them)."""

__all__ = ["CHECK_NAMES", "VERDICTS", "Verdict", "CheckResult", "worst", "jsonable"]

Verdict = Literal["holds", "fails", "inconclusive", "error"]
VERDICTS: tuple[str, ...] = ("holds", "fails", "inconclusive", "error")
_SEVERITY = {"holds": 0, "inconclusive": 1, "fails": 2, "error": 3}


def worst(verdicts: list[str]) -> str:
    """The most severe of several verdicts (``error > fails > inconclusive > holds``)."""
    if not verdicts:
        return "inconclusive"
    return max(verdicts, key=_SEVERITY.__getitem__)


def jsonable(x: Any) -> Any:
    """``x`` with numpy scalars and arrays turned into plain Python, and non-finite floats into None."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.bool_ | bool):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.floating | float):
        x = float(x)
        return x if math.isfinite(x) else None
    if isinstance(x, Path):
        return str(x)
    return x


@dataclass
class CheckResult:
    """One claim, checked.

    Attributes
    ----------
    key : str
        Short identifier (``"theorem1"``, ``"mean_field"``, ...), used in file names.
    claim : str
        The claim as the paper makes it (one sentence, with the paper's numbering).
    verdict : {"holds", "fails", "inconclusive", "error"}
    summary : str
        One line with the deciding figure, for the report's table.
    measured : dict
        The measured figures (plain numbers, lists, nested dicts).
    bound : dict
        What the figures were held against (the theorem's constant, a threshold, ...).
    reason : str
        Why the verdict is what it is (always set for ``inconclusive`` and ``error``).
    criterion : str
        The decision rule, stated before the numbers.
    cases : list of dict
        Sub-runs (one per α schedule, robot count, ...), each with its own ``verdict``.
    figures : list of str
        Paths of the figures, relative to the report's directory.
    seconds : float
        Wall time of the check.
    """

    key: str
    claim: str
    verdict: Verdict
    summary: str = ""
    measured: dict[str, Any] = field(default_factory=dict)
    bound: dict[str, Any] = field(default_factory=dict)
    reason: str = ""
    criterion: str = ""
    cases: list[dict[str, Any]] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict must be one of {VERDICTS}, got {self.verdict!r}")
        if self.verdict in ("inconclusive", "error") and not self.reason:
            raise ValueError(f"a {self.verdict!r} verdict needs a reason")

    def to_dict(self) -> dict[str, Any]:
        """The entry of ``verdicts.json`` (``claim``, ``verdict``, ``measured``, ``bound`` first)."""
        return jsonable(
            {
                "key": self.key,
                "claim": self.claim,
                "verdict": self.verdict,
                "measured": self.measured,
                "bound": self.bound,
                "summary": self.summary,
                "reason": self.reason,
                "criterion": self.criterion,
                "cases": self.cases,
                "figures": self.figures,
                "seconds": self.seconds,
            }
        )

    @classmethod
    def inconclusive(cls, key: str, claim: str, reason: str, **kwargs: Any) -> CheckResult:
        """A check whose hypotheses the scenario does not meet."""
        return cls(key, claim, "inconclusive", summary=reason, reason=reason, **kwargs)
