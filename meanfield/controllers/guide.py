"""The guide: each robot guides one exit's share of the crowd, and its sign names the exit its readers should take.

The building plans' people walk to the exit the latest sign that reached them named (``view.memory = "sign"``,
the default in SI plans, :mod:`meanfield.crowds.memory`).  The robots' job is then to reach everyone once, each
person with the exit that empties the building soonest.  The guide (controller ``guide``, the plans' default;
docs page *Buildings*, "The guide", where each choice below is measured against its alternatives) re-solves four
things as the crowd moves:

**Step I: the shares** (:class:`~meanfield.controllers.exit_assignment.ExitAssignment`).  Every
``rebalance_period`` the observed density is assigned to the open exits by their capacities (eq. (B1) of
:mod:`meanfield.controllers.exit_assignment`): cell ``c`` belongs to the share of exit
``k(c) = argmin_k (a_k(c) + τ_k)``, ``a_k = d_k / v_free``, the nearest exit unless queues make another pay by
:data:`MIN_GAIN`.  A closed exit or a new wall is solved again at once.

**The team: robots per share.**  The weight of a cell is the crowd's density where no sign has reached for
``revisit_after`` seconds (the people still to be told), or, where every cell has been reached lately, the
density itself.  Share ``k`` gets ``n_k`` robots in proportion to its weight (:func:`allocate`).  The robots are
matched to the shares at the least total distance to the shares' people (a robot keeps its share unless another's
people are :data:`STAY` nearer).

**Positions: coverage of the share.**  Within its share, robot ``i`` drives to the weighted centroid ``C_i`` of
the share's cells nearest to it among those it sees (Lloyd's iteration restricted to the share,
``u_i = k_position (C_i − R_i)``), and where a wall hides ``C_i``, along the first leg of its walk there by the
walk's length (:mod:`meanfield.geometry.walking`), as coverage's ``routed`` metric.

**Labels and headings.**  Each sign names an exit (:attr:`~meanfield.interfaces.Command.shows`): the labels that,
with the people each sign reaches now walking to its label and everyone else to Step I's exit, clear the building
soonest by (B1), found robot by robot from the labels of least regret and kept where they save :data:`MIN_GAIN`
of those labels' makespan (:meth:`GuideController.exit_here`).  A robot turns its arrow along the route from where
it stands to the exit it names, ``ω_i = k_heading · wrap(θ*_i − θ_i)``.  Nothing is claimed of ``½‖ṽ‖²``: the
guide is judged against the informed crowd, on every plan (``studies/guide.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from meanfield.capabilities import ControllerCapabilities
from meanfield.controllers._guide_loops import share_moments
from meanfield.controllers._queue_loops import label_search
from meanfield.controllers.coverage import _NOTHING_HIDDEN, walk_towards
from meanfield.errors import ParameterError, num, options_table
from meanfield.interfaces import Command, ControllerParts, Observation

__all__ = ["GuideController", "GuideOptions", "allocate"]

REVISIT_AFTER = 20.0
"""Default ``revisit_after`` (s): a cell weighs again this long after a sign last reached it."""
REBALANCE_PERIOD = 1.0
"""Default ``rebalance_period`` (s): the shares and the team are solved again this often."""
MIN_GAIN = 0.15
"""Step I keeps the exits' offsets, and the labels' search its labels, only where they save this share of the
makespan of the nearest exits (of the labels of least regret): the fluid queue (B1) walks everyone at ``v_free``,
so it promises gains that congestion on the longer walk takes back (docs page *Buildings*, "The guide")."""
SEARCH_SWEEPS = 3
"""Passes over the robots of the labels' search (:meth:`GuideController.exit_here`)."""
STAY = 2.0
"""m: a robot keeps its share unless another share's people are this much nearer (the team's matching)."""


def allocate(weights: np.ndarray, robots: int) -> np.ndarray:
    """How many robots each share gets: one per share with weight (the heaviest first while robots last), the rest
    in proportion to the weights by largest remainders.

    Parameters
    ----------
    weights : ndarray, shape (K,)
        ``W_k`` >= 0.
    robots : int
        ``n`` >= 0.

    Returns
    -------
    ndarray of int, shape (K,)
        ``n_k``, summing to ``n`` when some share has weight (else all 0).
    """
    w = np.maximum(np.asarray(weights, float), 0.0)
    out = np.zeros(len(w), dtype=int)
    live = np.flatnonzero(w > 0)
    if robots <= 0 or not len(live):
        return out
    live = live[np.argsort(-w[live], kind="stable")]
    first = live[:robots]
    out[first] = 1
    rest = robots - len(first)
    if rest > 0:
        quota = rest * w / w.sum()
        extra = np.floor(quota).astype(int)
        short = rest - int(extra.sum())
        order = np.argsort(-(quota - extra), kind="stable")
        extra[order[:short]] += 1
        out += extra
    return out


@dataclass
class GuideOptions:
    """``[controller.options.guide]``: what a scenario may set of the guide.

    Parameters
    ----------
    revisit_after : float
        How long after a sign last reached a cell it weighs again, s, > 0.
    rebalance_period : float
        How often the shares and the team are solved again, s, > 0.
    specific_flow : float, optional
        Each exit's flow per metre of its width, persons/(m·s), > 0 (default:
        :data:`~meanfield.controllers.exit_assignment.SPECIFIC_FLOW`).
    """

    revisit_after: float = REVISIT_AFTER
    rebalance_period: float = REBALANCE_PERIOD
    specific_flow: float | None = None

    def __post_init__(self) -> None:
        name = "controller.options.guide."
        self.revisit_after = num(name + "revisit_after", self.revisit_after, lo=0.0, lo_open=True)
        self.rebalance_period = num(name + "rebalance_period", self.rebalance_period, lo=0.0, lo_open=True)
        if self.specific_flow is not None:
            self.specific_flow = num(name + "specific_flow", self.specific_flow, lo=0.0, lo_open=True,
                                     allowed="a flow > 0, persons/(m·s)")  # fmt: skip


class GuideController:
    """Each robot guides one exit's share of the crowd (module docstring).

    Parameters
    ----------
    grid : Grid
        The cells the shares and the coverage are computed on.
    sight : SightLines or None
        The walls that hide a cell from a robot (None: every cell is seen).
    assignment : ExitAssignment
        The exits' capacities and walking distances (Step I).
    routes : AssignedRoutes
        The routes to each exit alone (the signs' bearings).
    k_position : float
        Gain of the drive to the centroid, 1/s, > 0.
    k_heading : float
        Gain of the turn to the bearing, 1/s, > 0.
    revisit_after : float
        How long after a sign last reached a cell it weighs again, s, > 0.
    rebalance_period : float
        How often the shares and the team are solved again, s, > 0.
    """

    capabilities: ClassVar[ControllerCapabilities] = ControllerCapabilities(
        requires_exits=True,  # it guides to the plan's exits: a region without has nothing to offer it
        changes_walls=True,  # a region can become wall during a run ([[events]] block, walls_changed)
        options=GuideOptions,  # [controller.options.guide]
    )
    """What it can do (:class:`~meanfield.capabilities.ControllerCapabilities`): what a scenario may set is
    :class:`GuideOptions`.  The gains are the constructor's: the drive saturates at the robots' ``u_max`` beyond
    ``u_max / k_position`` metres, and no study has found a setting of them that wins.  It does not run on a group's
    knowledge (no ``accepts_sensing``)."""

    def __init__(self, grid: Any, sight: Any, assignment: Any, routes: Any, k_position: float = 1.0,
                 k_heading: float = 2.0, revisit_after: float = REVISIT_AFTER,
                 rebalance_period: float = REBALANCE_PERIOD) -> None:  # fmt: skip
        for name, k in (("k_position", k_position), ("k_heading", k_heading), ("revisit_after", revisit_after),
                        ("rebalance_period", rebalance_period)):  # fmt: skip
            if isinstance(k, bool) or not isinstance(k, (int, float)) or not (math.isfinite(k) and k > 0):
                raise ParameterError(f"controller.options.guide.{name}", k, "a finite number > 0")
        self.assignment = assignment
        self.routes = routes
        self.k_position = float(k_position)
        self.k_heading = float(k_heading)
        self.revisit_after = float(revisit_after)
        self.rebalance_period = float(rebalance_period)
        self._cover(grid, sight)
        self.reset()

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> GuideController:
        """Registry factory (kind ``controller``, name ``guide``): the options of :class:`GuideOptions`; the walking
        speed is the crowd's (``crowd.free_speed``)."""
        from meanfield.controllers.evacuation import V_FREE, EvacuationController
        from meanfield.geometry.exits import exit_segments
        from meanfield.geometry.geodesic import AssignedRoutes, ExitEikonal
        from meanfield.geometry.sight import SightLines

        o = options_table("controller.options.guide", GuideOptions, dict(parts.options))
        segs = exit_segments(parts.region)
        if not len(segs):
            raise ParameterError("controller.kind", "guide", "a plan with exits (domain.exits): it guides to them")
        sight = parts.sight if parts.sight is not None else SightLines(parts.region)
        v_free = V_FREE if parts.free_speed is None else float(parts.free_speed)
        eikonal = ExitEikonal(parts.grid, segs, sight)
        assignment = EvacuationController.balance(parts, segs, eikonal, v_free, o.specific_flow, MIN_GAIN)
        return cls(parts.grid, sight, assignment, AssignedRoutes(parts.grid, segs, sight),
                   revisit_after=o.revisit_after, rebalance_period=o.rebalance_period)  # fmt: skip

    def _cover(self, grid: Any, sight: Any) -> None:
        """The cells to cover on ``grid``, the walls that hide them and the walking distances between them."""
        from meanfield.geometry.walking import WalkingDistances

        self.grid = grid
        self.sight = None if sight is None or sight.trivial else sight
        self.walking = WalkingDistances(grid, self.sight)
        X, Y = grid.centers
        self._cells = np.flatnonzero(grid.active.ravel())
        self._xy = np.column_stack([X.ravel()[self._cells], Y.ravel()[self._cells]])
        self._volume = grid.volume.ravel()[self._cells]
        self.last_reached = np.full(grid.shape, -np.inf)
        self._next_balance = -math.inf

    # ------------------------------------------------------------------ Step I and the team
    def shares(self, rho: np.ndarray) -> np.ndarray:
        """Each covered cell's exit (Step I, solved again from ``rho``), ``-1`` for a cell no exit can be reached
        from: ``(M,)`` over the grid's active cells."""
        a = self.assignment
        tau = a.solve(rho)
        share = np.full(self.grid.shape, -1, dtype=np.intp)
        here = a.active.reshape(self.grid.shape)
        share[here] = a.assign(tau)
        column = np.full(self.grid.shape, -1, dtype=np.intp)
        column[here] = np.arange(int(here.sum()))
        self._assign_index = column.ravel()[self._cells]
        cost = a.arrival + np.where(a.open, tau, np.inf)[:, None]  # (K, M'): when each exit would take a cell's people
        regret = np.zeros((len(tau),) + self.grid.shape)
        regret[:, here] = np.where(np.isfinite(cost), cost - cost.min(axis=0), np.inf)
        self._regret = regret.reshape(len(tau), -1)[:, self._cells]
        return share.ravel()[self._cells]

    def sweep(self, field: Any, t: float) -> np.ndarray:
        """Mark the cells the signs reach now as reached at ``t`` (:func:`~meanfield.signs.kernels.reached_cells`, as
        coverage's ``unswept`` rule), keeping each robot's reach for the labels (:meth:`exit_here`, which reads it over
        the covered cells)."""
        from meanfield.signs.kernels import reached_cells

        reach = reached_cells(field.kernel, field.positions, self.grid, self.sight)
        self._reach = reach.reshape(len(reach), -1)
        self.last_reached[reach.any(axis=0)] = t
        return self.last_reached

    def weight(self, rho: np.ndarray, t: float) -> np.ndarray:
        """Each covered cell's weight times its area: the density where no sign has reached for
        :attr:`revisit_after`, or the density where every cell has been reached lately."""
        r = np.maximum(np.real(rho).ravel()[self._cells], 0.0) * self._volume
        unswept = (t - self.last_reached.ravel()[self._cells]) >= self.revisit_after
        w = np.where(unswept, r, 0.0)
        return w if w.sum() > 0 else r

    def form_team(self, robots: np.ndarray, share: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Each robot's share: :func:`allocate`'s counts, filled by the matching of least total cost (scipy's
        ``linear_sum_assignment``), a robot's cost for share ``k`` its distance to the nearest of the share's cells
        that hold weight, plus a tenth of its distance to their centroid, less :data:`STAY` for the share it has."""
        from scipy.optimize import linear_sum_assignment

        k_exits = len(self.assignment.capacity)
        held = share >= 0
        mass = np.bincount(share[held], weights=w[held], minlength=k_exits)
        want = allocate(mass, len(robots))
        team = np.full(len(robots), -1, dtype=np.intp)
        if not want.sum():
            return team
        before = self.team if len(self.team) == len(robots) else team
        cost = np.empty((len(robots), k_exits))
        for k in range(k_exits):
            cells = np.flatnonzero((share == k) & (w > 0))
            if not len(cells):
                cost[:, k] = np.inf
                continue
            d = np.hypot(robots[:, None, 0] - self._xy[None, cells, 0], robots[:, None, 1] - self._xy[None, cells, 1])
            centre = (w[cells, None] * self._xy[cells]).sum(axis=0) / w[cells].sum()
            cost[:, k] = d.min(axis=1) + 0.1 * np.hypot(*(robots - centre).T) - STAY * (before == k)
        slots = np.repeat(np.arange(k_exits), want)
        rows, cols = linear_sum_assignment(cost[:, slots])
        team[rows] = slots[cols]
        return team

    # ------------------------------------------------------------------ positions
    def pulls(self, robots: np.ndarray, share: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Each robot's pull ``u_i / k_position``: to the weighted centroid of its cells within its share (walking
        there when a wall hides it); 0 for a robot without a share or whose cells hold no weight."""
        n = len(robots)
        pull = np.zeros((n, 2))
        seen, hidden = _NOTHING_HIDDEN, False
        if self.sight is not None:
            seen, hidden = np.ascontiguousarray(self.sight.cell_rows(self.grid, robots)).reshape(n, -1), True
        centroid = robots.copy()
        team = self.team
        if len(team) != n:  # (a team of other robots: those beyond it have no share)
            team = np.concatenate([team[:n], np.full(max(n - len(team), 0), -1, np.intp)])
        cell_owner, m, px, py = share_moments(self._xy, np.ascontiguousarray(robots), team, share, w,
                                              np.ascontiguousarray(seen), self._cells, hidden,
                                              np.empty(len(share), np.intp), *np.empty((3, n)))  # fmt: skip
        held = ~(m > 0)
        centroid[~held] = np.column_stack([px[~held] / m[~held], py[~held] / m[~held]])
        pull[~held] = centroid[~held] - robots[~held]
        behind = ~held if self.sight is not None else np.zeros(n, dtype=bool)  # (no wall hides anything)
        if behind.any():
            behind[behind] = ~np.asarray(self.sight.visible(robots[behind], centroid[behind]), bool)
        if behind.any():  # a wall hides the centroid: the first leg of the walk to the robot's cell nearest it
            rows = np.flatnonzero(behind)
            pull[rows] = walk_towards(self.walking, robots, cell_owner, centroid, rows)
        return pull

    def exit_here(self, robots: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """The exit each robot's sign names (module docstring, "Labels"): the labels that, with the people each sign
        reaches now walking to its exit and everyone else to Step I's, clear the building soonest (eq. (B1)) and,
        among those, cost the walkers least, found robot by robot from the labels of least regret."""
        from meanfield.controllers.exit_assignment import LAST_PERSON, ArrivalOrder

        a = self.assignment
        n = len(robots)
        idx = self._assign_index  # each covered cell's column in the assignment's cells (-1: none)
        persons = a.people * np.maximum(np.real(rho).ravel()[self._cells], 0.0) * self._volume
        # each covered cell's reader: the nearest robot whose sign reaches it (the strongest kernel it sees)
        d2 = (self._xy[None, :, 0] - robots[:, None, 0]) ** 2 + (self._xy[None, :, 1] - robots[:, None, 1]) ** 2
        d2 = np.where(self._reach[:, self._cells], d2, np.inf)
        reader = np.where(np.isfinite(d2).any(axis=0), np.argmin(d2, axis=0), -1)
        live = idx >= 0
        reader, persons, cols = reader[live], persons[live], idx[live]
        plan = self._share[live]
        open_k = np.flatnonzero(a.open)
        kept = self._arrivals  # the covered cells' arrivals, sorted once while the cells and the walls stay
        if kept is None or kept[0] is not a.arrival or not np.array_equal(kept[1], cols):
            arrival = a.arrival[:, cols]  # (K, m)
            kept = self._arrivals = (a.arrival, cols, arrival, ArrivalOrder(arrival))
        arrival, queues = kept[2], kept[3]  # (the order: sorted once for the search's makespans)
        best_walk = np.where(a.open[:, None], arrival, np.inf).min(axis=0)
        last = LAST_PERSON / max(len(open_k), 1)
        total = max(persons.sum(), 1e-300)
        with np.errstate(invalid="ignore"):  # (a reader sent where no route reaches: inf − inf)
            walked = persons * (arrival - best_walk)  # (K, m): each cell's persons times their detour to each exit

        # the labels of least regret: each robot's readers' exits under Step I, weighted by their persons
        regret = np.where(np.isfinite(self._regret[:, live]), self._regret[:, live], 1e9)
        loss = np.zeros((n, len(a.capacity)))
        for i in range(n):
            mine = reader == i
            loss[i] = regret[:, mine] @ persons[mine]
        loss[:, ~a.open] = np.inf
        has = np.bincount(reader[reader >= 0], weights=persons[reader >= 0], minlength=n) > 0
        labels = np.argmin(loss, axis=1)
        least_regret = labels.copy()
        # robot by robot, each open exit whose labels cost less: the makespan (B1) of the readers sent to their
        # robot's label and everyone else to Step I's, plus the walkers' mean detour (one compiled call)
        k_exits, m = arrival.shape
        best, start = label_search(reader, plan, persons, queues.order, queues.arrival, np.asarray(a.capacity, float),
                                   open_k, float(last), walked, float(total), has, labels, SEARCH_SWEEPS,
                                   np.empty(m, np.intp), np.empty(m), np.empty(k_exits), np.empty(k_exits))  # fmt: skip
        if best > (1.0 - MIN_GAIN) * start:  # the search's gain is within the model's error: the least regret
            labels = least_regret
        grid_share = np.full(self.grid.shape[0] * self.grid.shape[1], -1, dtype=np.intp)
        grid_share[self._cells] = self._share
        i, j = self.grid.cell_of(robots)
        here = grid_share.reshape(self.grid.shape)[i, j]
        return np.where(has, labels, here)

    # ------------------------------------------------------------------ the controller
    def act(self, observation: Observation) -> Command:
        """Solve the shares and the team when due, drive each robot over its share, turn each sign to its share's
        exit (module docstring)."""
        o = observation
        robots = np.real(np.asarray(o.field.positions, float)).reshape(-1, 2)
        headings = np.real(np.asarray(o.field.headings, float)).reshape(-1)
        self.sweep(o.field, o.t)
        w = self.weight(o.density, o.t)
        if o.t >= self._next_balance or len(self.team) != len(robots):
            self._share = self.shares(o.density)
            self.team = self.form_team(robots, self._share, w)
            self._next_balance = o.t + self.rebalance_period * (1 - 1e-9)
            self._shows = self.exit_here(robots, o.density)
        u = self.k_position * self.pulls(robots, self._share, w)
        shows = self._shows
        bearing = headings.copy()
        e = self.routes.heading_to_each(robots, shows)  # (0 where a sign names no exit, or no route reaches it)
        ok = np.hypot(e[:, 0], e[:, 1]) > 0
        bearing[ok] = np.arctan2(e[ok, 1], e[ok, 0])
        omega = self.k_heading * np.angle(np.exp(1j * (bearing - headings)))
        self.steps += 1
        self.idle_robot_steps += int((self.team < 0).sum())
        return Command(u, omega, shows=shows)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Only the exits with ``open_exits[k]`` are open: the shares are solved again at once, over those."""
        open_exits = np.asarray(open_exits, dtype=bool)
        if not open_exits.any():
            return
        self.assignment.open = open_exits.copy()
        self._next_balance = -math.inf

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event): the walking distances to each exit, the routes, the cells and
        the sight are those of the new grid, and the shares are solved again at once (when a sign last reached
        each cell is kept: the cells are the same)."""
        from meanfield.controllers.exit_assignment import distance_to_each_exit

        segs = self.routes.segs
        self.assignment.walls_changed(distance_to_each_exit(change.grid, segs, change.sight), change.grid.volume)
        self.routes.walls_changed(change)
        reached = self.last_reached
        self._cover(change.grid, change.sight)
        self.last_reached = reached

    def reset(self) -> None:
        """Forget the team, the shares and where the signs have reached."""
        self.team = np.zeros(0, dtype=np.intp)
        self._share = np.zeros(0, dtype=np.intp)
        self._shows = np.zeros(0, dtype=np.intp)
        self._arrivals: tuple[Any, ...] | None = None  # exit_here's arrivals of the covered cells, sorted
        self.last_reached = np.full(self.grid.shape, -np.inf)
        self._next_balance = -math.inf
        self.steps = self.idle_robot_steps = 0

    def summary(self) -> dict[str, Any]:
        """``guide_idle_fraction`` (the share of robot-steps without a share), the exits' last offsets ``τ_k`` and
        the makespan Step I expects."""
        a = self.assignment
        n = max(len(self.team), 1)
        return {
            "guide_idle_fraction": self.idle_robot_steps / max(self.steps * n, 1),
            "exit_offsets": [float(x) for x in a.offsets],
            "balanced_makespan": float(a.makespan),
        }
