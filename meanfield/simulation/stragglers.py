"""Stragglers: the humans no sign reached during the last half of a run.

A median over the crowd hides the few people a controller never fetches (design notes,
section 7).  :class:`StragglerTracker` watches the agents' :attr:`~meanfield.crowds.agent_crowd.AgentCrowd.reached`
(a human is reached at a step when a robot is in view and ``|v_r|`` at the human is at least
:data:`~meanfield.signs.kernels.REACH_FRACTION` of one kernel's peak) from the middle of the
run (``t >= t_final / 2``) to its end, and counts those still in Ω that were never reached:
``stragglers`` and ``stragglers_fraction`` in ``summary.json`` (absent for the density and
for the baselines, whose humans follow no sign).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.interfaces import CrowdOfAgents

__all__ = ["StragglerTracker"]


class StragglerTracker:
    """Observer of who was reached by a sign in the second half of the run."""

    def __init__(self) -> None:
        self.ever: np.ndarray | None = None
        self.half = 0.0
        self.watched_steps = 0

    def start(self, loop: Any) -> None:
        n = loop.crowd.n
        self.ever = np.zeros(n, dtype=bool) if n is not None and isinstance(loop.crowd, CrowdOfAgents) else None
        self.half = 0.5 * loop.scenario.t_final

    def step(self, loop: Any, record: Any) -> None:
        if self.ever is None or loop.t <= self.half:
            return
        reached = loop.crowd.reached
        if reached is None:
            return
        self.ever |= reached
        self.watched_steps += 1

    def summary(self, loop: Any) -> dict[str, Any]:
        """``stragglers`` (count) and ``stragglers_fraction`` (of the crowd), if they apply."""
        if self.ever is None or not self.watched_steps:
            return {}
        positions = loop.crowd.positions
        here = np.isfinite(positions).all(axis=1)  # those who left through an exit are no stragglers
        count = int(np.count_nonzero(here & ~self.ever))
        return {"stragglers": count, "stragglers_fraction": count / len(self.ever)}
