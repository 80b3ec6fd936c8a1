"""Exit balancing: which exit each part of the crowd should take so that the building empties soonest.

The informed crowd takes its nearest exit and queues there while another stands idle.  This
module assigns the observed crowd to the exits by their capacities, and gives the potential
whose field sends each part to its exit (``controller.options.evacuation.potential = "balanced"`` of
:mod:`meanfield.controllers.evacuation`).

**The model** (a fluid crowd and a point queue at each exit).  People in cell ``c`` reach
exit ``k`` after ``a_k(c) = d_k(c)/v_free``, ``d_k`` the walking distance to exit ``k`` alone
(fast marching, :class:`meanfield.geometry.geodesic.ExitEikonal`).  Exit ``k`` passes at most
``C_k = w_k J`` persons/s (``w_k`` its width, ``J`` the specific flow, persons/(m·s)).  With the
cells assigned to it sorted by arrival, ``a_1 <= … <= a_m``, holding ``P_1 … P_m`` persons, the
exit is clear at::

    T_k = max_j ( a_j + (P_j + … + P_m) / C_k ),                                   (B1)

the time the queue fed from ``a_j`` on has passed (exact for a fluid point queue; ``j`` runs
over the cells before which at least ``1/(2K)`` of a person is still to come at each of the
``K`` open exits, so that half a person in all is the toolkit's "everyone out": half a person
per exit would let the assignment hide ``K/2`` persons by splitting them among the exits).

**The assignment.**  Cell ``c`` takes the exit ``argmin_k (a_k(c) + τ_k)``: each exit carries an
offset ``τ_k >= 0``, the wait the crowd accepts there, and the offsets minimise the makespan
``max_k T_k``.  Without offsets this is the informed crowd's choice (nearest exit); raising
``τ_k`` moves the cells on the watershed away from exit ``k``.  The offsets are found by a damped
price iteration, ``τ_k ← τ_k + s_i (T_k − mean T)`` with ``s_i = ½/(1 + i/10)``, shifted so that
``min τ = 0``, keeping the offsets of the least makespan met (:data:`ITERATIONS` passes, started
from the previous solution).  They are kept only where queues matter: when some queue at the
nearest exits (all ``τ_k = 0``) would hold at least :data:`MIN_QUEUE` (5) persons, and the
offsets shorten the nearest exits' makespan by at least :data:`MIN_GAIN` (5 %).  Otherwise the
fluid optimum would split a few stragglers' smeared density across the watershed, where two
signs point apart and hold them between.

**The potential.**  ``φ = min_k (d_k + v_free τ_k)``: ``|∇φ| = 1`` away from the watersheds, and
its descent leads each cell to its exit, so Hughes' ``v_d = −f(ρ) ∇φ`` sends each part of the
crowd to the exit it is assigned.  It is re-solved from the observed density every
``rebalance_period`` and constant in between: Step II's ``∂_t v_d`` sees it as the distance
potential's between two solutions.

Hughes' potential (R. L. Hughes, *Transp. Res. B* 36, 2002) sees a queue only by the speed
inside it, and only where the observed density is near jam; (B1) counts the people who will
join the queue, so a crowd gathered by one door is split before any queue has formed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.controllers import _queue_loops
from meanfield.errors import ParameterError

__all__ = ["ArrivalOrder", "ExitAssignment", "clearing_time", "distance_to_each_exit", "ITERATIONS", "SPECIFIC_FLOW"]

SPECIFIC_FLOW = 1.8
"""Default ``J``, persons/(m·s): the congested point masses' measured door flow, 1.6–1.9 at widths of
0.8–2.5 m (docs page *Congestion*, the bottleneck study), inside the experiments' 1.6–2.5."""
ITERATIONS = 40
"""Passes of the price iteration per solution."""
MIN_GAIN = 0.05
"""The offsets are kept only where they shorten the nearest exits' makespan by at least this share."""
MIN_QUEUE = 5.0
"""Persons: the exits are balanced only when some queue at the nearest exits would hold at least this many."""
LAST_PERSON = 0.5
"""A queue is clear when less than this many persons are still to pass (the toolkit's "everyone out")."""


def clearing_time(arrival: np.ndarray, persons: np.ndarray, capacity: float, last: float = LAST_PERSON) -> float:
    """Eq. (B1): when an exit of ``capacity`` persons/s has passed everyone who arrives at ``arrival``.

    Parameters
    ----------
    arrival : ndarray, shape (m,)
        Arrival times ``a_j`` (any order).
    persons : ndarray, shape (m,)
        Persons arriving at each ``a_j`` (>= 0).
    capacity : float
        ``C_k`` > 0.
    last : float
        The persons still to come below which the exit counts as clear (:data:`LAST_PERSON`).

    Returns
    -------
    float
        ``max_j (a_j + Σ_{i: a_i >= a_j} P_i / C_k)`` over the ``j`` with at least ``last`` persons from
        ``a_j`` on; 0 when fewer than that arrive at all.
    """
    order = np.argsort(arrival, kind="stable")
    a, p = arrival[order], persons[order]
    rest = np.cumsum(p[::-1])[::-1]  # persons from a_j on
    due = rest >= last
    if not due.any():
        return 0.0
    return float((a[due] + rest[due] / capacity).max())


class ExitAssignment:
    """Offsets ``τ_k`` per exit that minimise the crowd's makespan, and the balanced potential (module docstring).

    Parameters
    ----------
    distances : ndarray, shape (K, nx, ny)
        ``d_k``: the walking distance to each exit alone (``inf`` off Ω).
    widths : ndarray, shape (K,)
        The exits' widths (metres of the grid).
    volume : ndarray, shape (nx, ny)
        The cells' areas inside Ω.
    people : int
        ``N``: the unit-mass density ``ρ`` has ``N ρ`` persons per unit area.
    v_free : float
        Free walking speed, > 0.
    specific_flow : float
        ``J``, persons per unit width and time, > 0 (:data:`SPECIFIC_FLOW`).
    min_gain : float
        The share of the nearest exits' makespan the offsets must save to be kept, in [0, 1) (:data:`MIN_GAIN`).
    """

    def __init__(self, distances: np.ndarray, widths: np.ndarray, volume: np.ndarray, people: int,
                 v_free: float, specific_flow: float = SPECIFIC_FLOW, min_gain: float = MIN_GAIN):  # fmt: skip
        if not (isinstance(specific_flow, (int, float)) and math.isfinite(specific_flow) and specific_flow > 0):
            raise ParameterError("specific_flow", specific_flow, "a flow > 0, persons/(m·s)")
        self.capacity = np.asarray(widths, float) * float(specific_flow)
        if not 0.0 <= min_gain < 1.0:
            raise ParameterError("min_gain", min_gain, "a share of the makespan in [0, 1)")
        self.min_gain = float(min_gain)
        self.people = int(people)
        self.v_free = float(v_free)
        self.walls_changed(distances, volume)  # distances, arrivals and the active cells' areas
        self.open = np.ones(len(self.capacity), dtype=bool)
        self.offsets = np.zeros(len(self.capacity))
        self.makespan = math.nan  # the last solution's (eq. B1), s

    def walls_changed(self, distances: np.ndarray, volume: np.ndarray) -> None:
        """Each exit's walking distance and the cells' areas (at construction, and on the new grid after a ``block``
        event; the exits open and the last offsets are kept: the next solution starts from them)."""
        self.distances = np.asarray(distances, float)
        self.active = np.isfinite(self.distances).any(axis=0) & (np.asarray(volume) > 0)  # (some exit: a piece's)
        self.arrival = self.distances[:, self.active] / self.v_free  # (K, M)
        self.volume = np.asarray(volume, float)[self.active]
        self._order = ArrivalOrder(self.arrival)

    def assign(self, offsets: np.ndarray) -> np.ndarray:
        """Each active cell's exit, ``argmin_k (a_k(c) + τ_k)`` over the open exits: ``(M,)`` (one compiled pass,
        :func:`~meanfield.controllers._queue_loops.assign_exits`)."""
        tau = np.where(self.open, np.asarray(offsets, float), np.inf)
        return _queue_loops.assign_exits(self.arrival, tau, np.empty(self.arrival.shape[1], np.intp))

    def clearing_times(self, persons: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """``T_k`` of eq. (B1) for each exit under the assignment of ``offsets`` (0 for an exit nobody takes)."""
        return self._times(persons, offsets)[0]

    def queues(self, persons: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Persons each exit's queue holds at its worst under ``offsets``: ``C_k`` times what it adds to the walk,
        ``C_k (T_k − a_last,k)`` with ``a_last,k`` the last arrival that (B1) counts."""
        return self._queue_sizes(*self._times(persons, offsets))

    def _queue_sizes(self, clear: np.ndarray, walk: np.ndarray) -> np.ndarray:
        return np.maximum(clear - walk, 0.0) * self.capacity

    def _times(self, persons: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`ArrivalOrder.times` of :meth:`assign`'s exits, in one compiled call
        (:func:`~meanfield.controllers._queue_loops.assigned_clearing_times`)."""
        last = LAST_PERSON / max(int(self.open.sum()), 1)  # half a person in all: not half a person per exit
        tau = np.where(self.open, np.asarray(offsets, float), np.inf)
        k, m = self.arrival.shape
        return _queue_loops.assigned_clearing_times(self.arrival, tau, self._order.order, self._order.arrival,
                                                    np.asarray(persons, float), np.asarray(self.capacity, float),
                                                    np.flatnonzero(self.open), float(last), np.empty(m, np.intp),
                                                    np.empty(k), np.empty(k))  # fmt: skip

    def solve(self, rho: np.ndarray) -> np.ndarray:
        """The offsets ``τ`` for the unit-mass density ``rho`` on the cells (price iteration, module docstring)."""
        persons = self.people * np.maximum(np.real(rho)[self.active], 0.0) * self.volume
        zero = np.zeros(len(self.capacity))
        T, walk = self._times(persons, zero)  # the nearest exits (once: their clearing times and their queues)
        nearest = float(T[self.open].max())
        if self._queue_sizes(T, walk).max() < MIN_QUEUE or self.open.sum() < 2:  # no queue, or one exit: no choice
            self.offsets, self.makespan = zero, nearest
            return zero
        tau = np.where(self.open, np.asarray(self.offsets, float), 0.0)
        k, m = self.arrival.shape
        best_tau, last = np.empty(k), LAST_PERSON / max(int(self.open.sum()), 1)
        # the passes in one compiled call (meanfield.controllers._queue_loops.price_iteration)
        best = _queue_loops.price_iteration(self.arrival, self.open, tau, ITERATIONS, self._order.order,
                                            self._order.arrival, persons, np.asarray(self.capacity, float),
                                            np.flatnonzero(self.open), last, np.empty(m, np.intp), np.empty(k),
                                            np.empty(k), np.empty(k), best_tau)  # fmt: skip
        if best >= (1.0 - self.min_gain) * nearest:  # balancing does not pay
            best, best_tau = nearest, zero
        self.offsets = best_tau
        self.makespan = best
        return best_tau

    def potential(self, offsets: np.ndarray | None = None) -> np.ndarray:
        """``φ = min_k (d_k + v_free τ_k)`` over the open exits, on the cells (``inf`` off Ω)."""
        tau = self.offsets if offsets is None else offsets
        shifted = self.distances[self.open] + self.v_free * tau[self.open][:, None, None]
        return shifted.min(axis=0)


class ArrivalOrder:
    """Each exit's cells in the order of their arrival there, sorted once: eq. (B1) for any assignment of the cells
    to the exits without sorting again.

    (B1) reads an exit's queue in the order of arrival of the cells assigned to it.  Every cell of the sorted row
    is kept, those assigned elsewhere holding nobody: a cell with nobody adds ``0`` to the persons still to come
    (the same sums, to the bit) and its term ``a_j + rest_j / C_k`` is at most that of the next cell with someone
    (the same ``rest``, a later arrival), so the maximum is :func:`clearing_time`'s of the assigned cells alone,
    the same number.  A stable sort keeps the cells of equal arrival in their order, as :func:`clearing_time`'s.
    One compiled pass per exit (:func:`~meanfield.controllers._queue_loops.clearing_times`).

    Parameters
    ----------
    arrival : ndarray, shape (K, M)
        ``a_k(c)``, each exit's arrival time from each cell (``inf``: no route).
    """

    def __init__(self, arrival: np.ndarray) -> None:
        self.order = np.ascontiguousarray(np.argsort(arrival, axis=1, kind="stable"), dtype=np.intp)
        self.arrival = np.take_along_axis(np.asarray(arrival, float), self.order, axis=1)

    def times(self, exit_of: np.ndarray, persons: np.ndarray, capacity: np.ndarray, exits: np.ndarray,
              last: float = LAST_PERSON) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """``T_k`` of eq. (B1) and the last arrival (B1) counts, ``a_last,k``, of each exit of ``exits`` (0 for the
        others and for an exit nobody takes).

        Parameters
        ----------
        exit_of : ndarray of int, shape (M,)
            Each cell's exit.
        persons : ndarray, shape (M,)
            The persons in each cell (>= 0).
        capacity : ndarray, shape (K,)
            ``C_k`` > 0, persons/s.
        exits : ndarray of int
            The exits to compute (the open ones).
        last : float
            The persons still to come below which an exit counts as clear.
        """
        clear, walk = np.empty(len(capacity)), np.empty(len(capacity))
        return _queue_loops.clearing_times(self.order, self.arrival, np.asarray(exit_of, np.intp),
                                           np.asarray(persons, float), np.asarray(capacity, float),
                                           np.asarray(exits, np.intp), float(last), clear, walk)  # fmt: skip


def distance_to_each_exit(grid: Any, segs: np.ndarray, sight: Any) -> np.ndarray:
    """``d_k`` of :class:`ExitAssignment`: the walking distance to each exit alone, ``(K, nx, ny)`` (one fast march
    per exit, :class:`~meanfield.geometry.geodesic.ExitEikonal`, round the walls of ``sight``)."""
    from meanfield.geometry.geodesic import ExitEikonal

    return np.stack([ExitEikonal(grid, segs[k : k + 1], sight).distance for k in range(len(segs))])
