"""Robots that know only what they see: a sensing radius and a communication radius.

With ``[sensing] radius = r`` and ``comm_radius = r_c`` (:class:`~meanfield.scenarios.sections.SensingSpec`),
the scenario's controller (``backstepping``, ``coverage``, any registered one) runs once
per robot, on what that robot knows:

* robots within ``r_c`` of each other talk, and a connected group (a component of that
  graph) shares what its members see: the limit of consensus on their estimates on a
  connected graph (design notes, section 7), taken at once instead of iterated;
* the group sees the crowd's density only within ``r`` of one of its members (its window
  ``W``): the estimate it knows is ``ρ̂`` on ``W``, and outside ``W``, where it knows nothing
  but the crowd's total, the mass it does not see spread evenly,
  ``(1 − ∫_W ρ̂) / |Ω ∖ W|`` (the law needs a positive density of unit mass; the even spread
  assumes nothing about where the unseen people are), and at least ``10⁻⁹`` of the seen
  peak when the group sees all the mass;
* it knows its members' states, not the other robots': the navigation field it reasons
  with is its members' (eq. (3) summed over the group).

Robot ``i`` applies its own row of its controller's command; each robot keeps its own
controller (its own memory, e.g. the previous ``v_d``).  A robot whose group sees no one
holds its position and heading, and says so: ``sensing_blind_fraction`` in ``summary.json``
(the share of robot-steps spent so), with ``sensing_groups_mean`` (the mean number of groups).
With both radii unlimited every robot's command is the centralized controller's (tested).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.interfaces import Command, Observation
from meanfield.signs.robots import NavigationField

__all__ = ["LocalSensing", "groups", "UNSEEN_FLOOR"]

UNSEEN_FLOOR = 1e-9
"""The least density a group assumes where it does not look, as a share of the peak it sees
(``v_d`` divides by ρ: a group that sees all the mass must not assume zero elsewhere)."""


def groups(positions: np.ndarray, comm_radius: float | None) -> np.ndarray:
    """The group (connected component of the communication graph) of each robot."""
    n = len(positions)
    if comm_radius is None:
        return np.zeros(n, dtype=np.intp)
    from scipy.sparse.csgraph import connected_components

    d2 = ((positions[:, None, :] - positions[None, :, :]) ** 2).sum(-1)
    _, labels = connected_components(d2 <= comm_radius**2, directed=False)
    return labels


class LocalSensing:
    """One controller per robot, each fed what its robot's group knows (module docstring).

    Parameters
    ----------
    controllers : list of Controller
        One per robot, built as the centralized one is.
    grid : Grid
        The grid of the observations.
    kernel : NavigationKernel
        The robots' kernel (for the groups' fields).
    radius, comm_radius : float or None
        Sensing and communication radii (None: no limit).
    sight : SightLines or None
        The plan's walls that hide signs (passed to the groups' fields).
    """

    def __init__(
        self,
        controllers: list[Any],
        grid: Any,
        kernel: Any,
        radius: float | None,
        comm_radius: float | None,
        sight: Any = None,
    ):
        self.controllers = list(controllers)
        self.grid = grid
        self.kernel = kernel
        self.radius = radius
        self.comm_radius = comm_radius
        self.sight = sight
        X, Y = grid.centers
        self._cells = np.stack([X, Y], axis=-1)
        self.steps = 0
        self.blind_robot_steps = 0
        self.group_count = 0

    def _window(self, members: np.ndarray) -> np.ndarray:
        """1 on the cells within ``radius`` of some member, else 0 (ones without a radius)."""
        if self.radius is None:
            return np.ones(self.grid.shape)
        d2 = ((self._cells[None] - members[:, None, None, :]) ** 2).sum(-1).min(axis=0)
        return (d2 <= self.radius**2).astype(float)

    def _known(self, density: np.ndarray, window: np.ndarray, seen: float) -> np.ndarray:
        """``ρ̂`` on the window, the unseen mass spread evenly outside it (module docstring)."""
        unseen = float(((1.0 - window) * self.grid.volume).sum())
        if unseen <= 0:
            return density
        rest = max(max(1.0 - seen, 0.0) / unseen, UNSEEN_FLOOR * float(np.max(density * window)))
        return np.where(window > 0, density, rest)

    def act(self, observation: Observation) -> Command:
        """Each robot's own row of its controller's command on its group's knowledge."""
        o = observation
        positions = np.real(o.field.positions)
        headings = np.real(o.field.headings)
        n = len(positions)
        u = np.zeros((n, 2))
        omega = np.zeros(n)
        labels = groups(positions, self.comm_radius)
        self.steps += 1
        self.group_count += int(labels.max()) + 1
        for g in np.unique(labels):
            members = np.flatnonzero(labels == g)
            window = self._window(positions[members])
            seen = float((o.density * window * self.grid.volume).sum())
            if not seen > 0:  # the group sees no one: hold still
                self.blind_robot_steps += len(members)
                continue
            density = self._known(o.density, window, seen)
            field = NavigationField(self.kernel, self.grid, positions[members], headings[members], self.sight)
            known = Observation(density, field, o.t, o.dt)
            for k, i in enumerate(members):
                command = self.controllers[i].act(known)
                u[i], omega[i] = command.u[k], command.omega[k]
        return Command(u, omega, None)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Tell every group's controller which exits are open (those that plan to the exits plan again)."""
        from meanfield.geometry.exits import tell_exits_closed

        tell_exits_closed(self.controllers, open_exits)

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event): every group's controller is told, and the groups' fields are
        hidden by the new walls."""
        from meanfield.geometry.blocking import tell_walls_changed

        tell_walls_changed(self.controllers, change)
        self.grid, self.sight = change.grid, change.sight

    def reset(self) -> None:
        """Reset every robot's controller and the counts."""
        for c in self.controllers:
            c.reset()
        self.steps = self.blind_robot_steps = self.group_count = 0

    def summary(self) -> dict[str, Any]:
        """``sensing_blind_fraction`` and ``sensing_groups_mean`` (module docstring)."""
        n = max(len(self.controllers), 1)
        steps = max(self.steps, 1)
        return {
            "sensing_blind_fraction": self.blind_robot_steps / (steps * n),
            "sensing_groups_mean": self.group_count / steps,
        }
