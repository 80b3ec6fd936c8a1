"""The closed loop: one step, written once, for any crowd and any controller.

One step of :class:`ClosedLoop` (``dt``; docs page *Architecture*):

1. observe: the crowd's density on the grid (a KDE of agents, or the PDE's density) and
   the robots' kernels at their states (:class:`~meanfield.interfaces.Observation`);
2. act: the controller's robot inputs ``(u_i, ω_i)`` (eq. (8) for the paper's law);
3. the crowd advances under the robots' signs (eq. (1) for agents, eq. (4) for the density);
4. the robots advance, their inputs saturated at the speed limits (eq. (2)), kept in
   their region;
5. the observers see the step (recording, time to 90 %, input statistics, ...).

The loop holds no recording and computes no summary: observers do
(:mod:`meanfield.observers`), as py-pde's trackers watch its solvers.
:func:`meanfield.runner.run` attaches the usual observers and returns a result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Protocol

import numpy as np

from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.interfaces import Command, Observation
from meanfield.robots import NavigationField, saturate_inputs

__all__ = ["ClosedLoop", "Observer", "StepRecord"]


@dataclass
class StepRecord:
    """What happened in one step, as observers see it.

    Attributes
    ----------
    index : int
        The step's index ``k`` (from ``t_k = k dt`` to ``t_{k+1}``).
    observation : Observation
        What the controller saw at ``t_k``.
    command : Command
        What it asked for.
    u, omega : ndarray
        The inputs applied (within the speed limits).
    robots : RobotTeam
        The robots (their limits).
    """

    index: int
    observation: Observation
    command: Command
    u: np.ndarray
    omega: np.ndarray
    robots: Any

    @cached_property
    def saturated(self) -> bool:
        """Whether the limits cut the command (some robot's speed or turn rate reduced)."""
        c = self.command
        speed = np.hypot(self.u[:, 0], self.u[:, 1])
        return bool((np.hypot(c.u[:, 0], c.u[:, 1]) > speed).any() or (np.abs(c.omega) > np.abs(self.omega)).any())

    @cached_property
    def at_limit(self) -> int:
        """How many robots' commands reached a speed or turn-rate limit."""
        return int(self.robots.at_limit(self.command.u, self.command.omega).sum())

    @cached_property
    def shortfall_applied(self) -> float:
        """The part of ``A`` the applied inputs did not cancel (NaN without the law's quantities)."""
        state = self.command.state
        return math.nan if state is None else state.applied_shortfall(self.u, self.omega)


class Observer(Protocol):
    """Watches the loop; never changes it."""

    def start(self, loop: ClosedLoop) -> None:
        """The initial state (before the first step)."""
        ...

    def step(self, loop: ClosedLoop, record: StepRecord) -> None:
        """After each step (the loop holds the new state)."""
        ...


class ClosedLoop:
    """Steps the parts of a closed loop: crowd, robots and controller.

    Parameters
    ----------
    parts : Parts or Scenario
        The parts from :func:`meanfield.assembly.assemble`; a scenario is assembled here
        (with ``overrides``).
    observers : sequence of Observer
        Called at the start and after every step.
    **overrides
        For a scenario: passed to :func:`~meanfield.assembly.assemble` (``sigma``,
        ``disturbance``, ``beta_gamma``, ``kernel``, ``crowd``, ``controller``).

    Examples
    --------
    >>> from meanfield import ClosedLoop, paper_scenario
    >>> loop = ClosedLoop(paper_scenario(seed=1).replace(t_final=0.1))
    >>> result = loop.run(progress=False)
    >>> sorted(result.summary)[:3]
    ['A_final', 'fraction_in_target', 'l2_error_final']
    """

    def __init__(self, parts: Any, *, observers: Any = (), **overrides: Any):
        from meanfield.assembly import Parts, assemble
        from meanfield.scenario import Scenario

        if isinstance(parts, Scenario):
            parts = assemble(parts, **overrides)
        elif overrides:
            raise ParameterError("overrides", sorted(overrides), "none when the loop is given assembled parts")
        if not isinstance(parts, Parts):
            raise ParameterError("scenario", type(parts).__name__, "a Scenario (or the Parts of one)")
        self.parts = parts
        self.scenario = parts.scenario
        self.crowd = parts.crowd
        self.robots = parts.robots
        self.controller = parts.controller
        self.grid = parts.grid
        self.dt = parts.scenario.dt
        self.observers = list(observers)
        self.t = 0.0
        self.step_index = 0
        self.density: np.ndarray = self.crowd.density()
        self.last: StepRecord | None = None  # the latest step, as observers saw it
        self._started = False

    # the parts, by name (read-only conveniences)
    @property
    def kernel(self):
        return self.parts.kernel

    @property
    def target(self) -> np.ndarray:
        return self.parts.target

    @property
    def domain(self):
        return self.parts.region

    @property
    def robot_region(self):
        return self.parts.robot_region

    def attach(self, observer: Any) -> None:
        """Add an observer (it sees the current state at once if the loop has started)."""
        self.observers.append(observer)
        if self._started:
            observer.start(self)

    def observe(self) -> Observation:
        """What the robots know now: the density on the grid, their kernels, the time."""
        field = NavigationField(self.parts.kernel, self.grid, self.robots.positions, self.robots.headings)
        return Observation(self.density, field, self.t, self.dt)

    def start(self) -> None:
        """Show the initial state to the observers (once; :meth:`step` calls it if needed)."""
        if not self._started:
            self._started = True
            for obs in self.observers:
                obs.start(self)

    def step(self) -> StepRecord:
        """Advance the closed loop by one ``dt``; raise :class:`SimulationDiverged` on NaN/inf.

        The state is only changed when the robot inputs and the crowd's velocities are
        finite, so after the exception the loop still holds the last good state.
        """
        self.start()
        k, dt = self.step_index, self.dt
        observation = self.observe()
        command = self.controller.act(observation)
        if not (np.isfinite(command.u).all() and np.isfinite(command.omega).all()):
            raise SimulationDiverged(
                f"non-finite robot inputs at t = {self.t:.4g} (step {k}); the state is kept at the last good step", k
            )
        u, w = saturate_inputs(command.u, command.omega, self.robots.u_max, self.robots.omega_max)
        try:
            self.crowd.advance(self.robots, self.t, dt)
        except SimulationDiverged as exc:
            raise SimulationDiverged(f"{exc} (step {k})", k) from None
        self.robots.advance(u, w, dt, self.parts.robot_region)
        self.step_index = k + 1
        self.t = self.step_index * dt
        self.density = self.crowd.density()
        if not np.isfinite(self.density).all():
            raise SimulationDiverged(f"non-finite density at t = {self.t:.4g}", self.step_index)
        record = self.last = StepRecord(k, observation, command, u, w, self.robots)
        for obs in self.observers:
            obs.step(self, record)
        return record

    def run(self, progress: bool = True, callback: Any = None):
        """Run to ``t_final`` with the usual observers; see :func:`meanfield.runner.run_loop`."""
        from meanfield.runner import run_loop

        return run_loop(self, progress=progress, callback=callback)
