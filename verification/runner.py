"""Run every check on one scenario and collect the verdicts (``meanfield verify``).

The checks run on any region: boxes, disks, convex polygons and floor plans
(:class:`~meanfield.geometry.plan.Plan`: re-entrant corners, pillars, exits).  Theorems 1–3 need Ω
connected, not convex (the Poincaré–Wirtinger inequality; μ₂ is computed on the plan's
grid), and say themselves which hypothesis a scenario misses (:mod:`verification.hypotheses`:
a grid that splits Ω, exits that let mass out).  A scenario that cannot be loaded gives
``inconclusive`` verdicts with the reason: a non-convex vertex list under
``kind = "polygon"``, which :meth:`~meanfield.geometry.domain.Domain.polygon` refuses, is pointed to
``kind = "plan"``.  A check that raises is recorded with verdict ``"error"`` and the
exception, and the run goes on with the next check.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from meanfield.errors import ParameterError
from meanfield.scenarios.scenario import Scenario
from verification import agents, congested, mean_field, robot_count, theorem1, theorem2, theorem3, two_scales
from verification.result import CheckResult

__all__ = ["CHECKS", "CLAIMS", "VerificationRun", "verify", "unusable_scenario_reason"]

Check = Callable[..., CheckResult]

CHECKS: dict[str, Check] = {
    "theorem1": theorem1.check_theorem1,
    "theorem2": theorem2.check_theorem2,
    "theorem3": theorem3.check_theorem3,
    "congested": congested.check_congested,
    "mean_field": mean_field.check_mean_field,
    "two_scales": two_scales.check_two_scales,
    "robot_count": robot_count.check_robot_count,
    "agents": agents.check_agents,
    "pedestrians": agents.check_pedestrians,
}
"""Every check, in report order."""

CLAIMS: dict[str, str] = {
    "theorem1": theorem1.CLAIM,
    "theorem2": theorem2.CLAIM,
    "theorem3": theorem3.CLAIM,
    "congested": congested.CLAIM,
    "mean_field": mean_field.CLAIM,
    "two_scales": two_scales.CLAIM,
    "robot_count": robot_count.CLAIM,
    "agents": agents.CLAIM,
    "pedestrians": agents.PEDESTRIANS_CLAIM,
}


def unusable_scenario_reason(exc: Exception) -> str:
    """A reader's explanation of why a scenario could not be loaded for the checks."""
    return f"the scenario cannot be used: {exc}"


@dataclass
class VerificationRun:
    """The results of :func:`verify`, in check order."""

    scenario_name: str
    quick: bool
    results: list[CheckResult] = field(default_factory=list)
    status: str = "completed"
    seconds: float = 0.0

    @property
    def all_ran(self) -> bool:
        """Whether every check produced a verdict (none crashed, the run was not interrupted)."""
        return self.status == "completed" and all(r.verdict != "error" for r in self.results)

    def to_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario_name,
            "quick": self.quick,
            "status": self.status,
            "seconds": self.seconds,
            "verdicts": [r.to_dict() for r in self.results],
        }


def verify(
    scenario: Scenario | str | Exception,
    out_dir: str | Path,
    *,
    quick: bool = False,
    checks: list[str] | None = None,
    progress: bool = False,
    workers: int | None = None,
    on_result: Callable[[CheckResult], None] | None = None,
) -> VerificationRun:
    """Run the checks and return their results (nothing is written; see :mod:`verification.report`).

    Parameters
    ----------
    scenario : Scenario, or the exception raised while loading it
        An exception (the :class:`~meanfield.errors.ParameterError` that refused a scenario)
        makes every check ``inconclusive`` with the reason.
    out_dir : path
        Where the checks put their figures (``out_dir/figures``).
    quick : bool
        The short variant of every check (the whole run within about 2 minutes).
    checks : list of str, optional
        Keys of :data:`CHECKS` to run (default: all).
    progress : bool
        Progress bars inside the long checks.
    workers : int, optional
        Processes for the checks that fan out runs.
    on_result : callable, optional
        Called with each result as soon as it is available.
    """
    keys = list(CHECKS) if checks is None else list(checks)
    unknown = [k for k in keys if k not in CHECKS]
    if unknown:
        raise ParameterError("checks", unknown, f"names among {', '.join(CHECKS)}")
    out = Path(out_dir)
    name = scenario.name if isinstance(scenario, Scenario) else str(getattr(scenario, "name", "unusable"))
    run = VerificationRun(name, quick)
    start = time.perf_counter()
    try:
        for key in keys:
            if isinstance(scenario, Exception):
                result = CheckResult.inconclusive(key, CLAIMS[key], unusable_scenario_reason(scenario))
            else:
                t0 = time.perf_counter()
                try:
                    result = CHECKS[key](scenario, out, quick=quick, progress=progress, workers=workers)
                except KeyboardInterrupt:
                    raise
                except Exception as exc:  # recorded, and the command exits non-zero
                    result = CheckResult(
                        key,
                        CLAIMS[key],
                        "error",
                        summary=f"the check could not run: {type(exc).__name__}: {exc}",
                        reason="".join(traceback.format_exception_only(type(exc), exc)).strip(),
                        seconds=time.perf_counter() - t0,
                    )
            run.results.append(result)
            if on_result is not None:
                on_result(result)
    except KeyboardInterrupt:
        run.status = "interrupted"
    run.seconds = time.perf_counter() - start
    return run
