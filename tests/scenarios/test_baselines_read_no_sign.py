"""A crowd that reads no sign walks the same whatever its plan's robots do.

``studies/guide.py`` runs its baselines (the informed and the uninformed crowd) with the plan's robots standing
with static signs instead of running the plan's controller (the guide), because their crowd reads no sign; this
checks that the crowd is then the same to the last bit, so the study's rows are the rows of the plan's own
controller.
"""

from __future__ import annotations

import numpy as np
import pytest

from meanfield.scenarios.scenario import builtin_scenarios
from meanfield.simulation.loop import ClosedLoop

STANDING = {"controller.kind": "static-signs", "controller.options": {}}


def _crowd_after(plan: str, values: dict, steps: int) -> tuple[np.ndarray, np.ndarray]:
    loop = ClosedLoop(builtin_scenarios()[plan](seed=3).with_values(values))
    for _ in range(steps):
        loop.step()
    return loop.crowd.positions.copy(), loop.robots.positions.copy()


@pytest.mark.parametrize(("plan", "guidance"), [("hall", "random-walk"), ("office", "geodesic")])
def test_a_crowd_that_reads_no_sign_is_the_same_whatever_the_robots_do(plan: str, guidance: str) -> None:
    scenario = builtin_scenarios()[plan]()
    assert scenario.controller.kind == "guide"  # the plan's own controller, which moves its robots
    steps = 100  # 10 s of the plans' 0.1 s steps: the guide has moved its robots by then
    crowd, robots = _crowd_after(plan, {"crowd.guidance": guidance}, steps)
    crowd_standing, robots_standing = _crowd_after(plan, {"crowd.guidance": guidance, **STANDING}, steps)
    assert not np.allclose(robots, robots_standing)  # the robots did differ
    np.testing.assert_array_equal(crowd, crowd_standing)  # NaN (out) where NaN
