"""The exits' assignment and clearing times (eq. (B1)), compiled.

* :func:`assign_exits`: each cell's exit of least arrival plus offset, one pass over the cells;
* :func:`clearing_times`: one pass per exit over its cells in the order of arrival;
* :func:`assigned_clearing_times`: the two in one call (a pass of the price iteration).

Each is paired with its numpy twin; the callers are :class:`meanfield.controllers.exit_assignment.ExitAssignment` and
:class:`~meanfield.controllers.exit_assignment.ArrivalOrder`.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, inner

__all__ = ["assign_exits", "assigned_clearing_times", "clearing_times"]


def _assign_numpy(arrival, offsets, out):
    out[:] = np.argmin(arrival + offsets[:, None], axis=0)
    return out


@inner
def _assign(arrival, offsets, out):
    """:func:`assign_exits`' pass."""
    for c in range(arrival.shape[1]):
        best = arrival[0, c] + offsets[0]
        pick = 0
        if best == best:  # (a NaN first: np.argmin's answer)
            for k in range(1, arrival.shape[0]):
                v = arrival[k, c] + offsets[k]
                if v != v:  # the first NaN
                    pick = k
                    break
                if v < best:
                    best = v
                    pick = k
        out[c] = pick


@compiled(fallback=_assign_numpy)
def assign_exits(arrival, offsets, out):
    """``out[c] = argmin_k (a_k(c) + τ_k)``, as ``np.argmin`` along the exits: ties and a NaN to the first.

    Parameters
    ----------
    arrival : ndarray, shape (K, M)
        ``a_k(c)``.
    offsets : ndarray, shape (K,)
        ``τ_k`` (``inf`` for a closed exit).
    out : ndarray of int, shape (M,)
    """
    _assign(arrival, offsets, out)
    return out


def _clearing_numpy(order, arrival, exit_of, persons, capacity, exits, last, clear, walk):
    clear[:] = 0.0
    walk[:] = 0.0
    for k in exits:
        cells = order[k]
        p = np.where(exit_of[cells] == k, persons[cells], 0.0)
        rest = np.cumsum(p[::-1])[::-1]  # persons from a_j on
        due = rest >= last
        if due.any():
            a = arrival[k][due]
            clear[k] = (a + rest[due] / capacity[k]).max()
            walk[k] = a.max()
    return clear, walk


@inner
def _clearing(order, arrival, exit_of, persons, capacity, exits, last, clear, walk):
    """:func:`clearing_times`' passes."""
    for k in range(clear.shape[0]):
        clear[k] = 0.0
        walk[k] = 0.0
    m = order.shape[1]
    for e in range(exits.shape[0]):
        k = exits[e]
        rest = 0.0
        latest = -math.inf
        longest = -math.inf
        for j in range(m - 1, -1, -1):
            c = order[k, j]
            if exit_of[c] == k:
                rest = rest + persons[c]
            if rest >= last:
                a = arrival[k, j]
                t = a + rest / capacity[k]
                if t > longest:
                    longest = t
                if a > latest:
                    latest = a
        if longest > -math.inf:
            clear[k] = longest
            walk[k] = latest


@compiled(fallback=_clearing_numpy)
def clearing_times(order, arrival, exit_of, persons, capacity, exits, last, clear, walk):
    """``T_k`` of eq. (B1) and the last arrival it counts, for each exit of ``exits`` (0 for the others), in place.

    Exit ``k`` reads its row of cells from the last arrival back, adding the persons of the cells assigned to it
    (``exit_of[c] == k``; the others add nothing), and keeps the largest ``a_j + rest_j / C_k`` and ``a_j`` over
    the cells with at least ``last`` persons from ``a_j`` on.

    Parameters
    ----------
    order : ndarray of int, shape (K, M)
        Each exit's cells in the order of arrival.
    arrival : ndarray, shape (K, M)
        Each exit's arrival times in that order.
    exit_of : ndarray of int, shape (M,)
        Each cell's exit.
    persons : ndarray, shape (M,)
        The persons in each cell (>= 0).
    capacity : ndarray, shape (K,)
        ``C_k`` > 0.
    exits : ndarray of int
        The exits to compute.
    last : float
        The persons still to come below which an exit counts as clear.
    clear, walk : ndarray, shape (K,)
        ``T_k`` and ``a_last,k`` (out).
    """
    _clearing(order, arrival, exit_of, persons, capacity, exits, last, clear, walk)
    return clear, walk


def _assigned_clearing_numpy(arrival, offsets, order, arrival_sorted, persons, capacity, exits, last, exit_of, clear,
                             walk):  # fmt: skip
    _assign_numpy(arrival, offsets, exit_of)
    return _clearing_numpy(order, arrival_sorted, exit_of, persons, capacity, exits, last, clear, walk)


@compiled(fallback=_assigned_clearing_numpy)
def assigned_clearing_times(arrival, offsets, order, arrival_sorted, persons, capacity, exits, last, exit_of, clear,
                            walk):  # fmt: skip
    """:func:`assign_exits` into ``exit_of``, then :func:`clearing_times` of that assignment, in one call.

    Parameters
    ----------
    arrival : ndarray, shape (K, M)
        ``a_k(c)``.
    offsets : ndarray, shape (K,)
        ``τ_k`` (``inf`` for a closed exit).
    order, arrival_sorted : ndarray, shape (K, M)
        Each exit's cells in the order of arrival, and their arrival times in that order.
    persons, capacity, exits, last
        As :func:`clearing_times`.
    exit_of : ndarray of int, shape (M,)
        Each cell's exit (out).
    clear, walk : ndarray, shape (K,)
        ``T_k`` and ``a_last,k`` (out).
    """
    _assign(arrival, offsets, exit_of)
    _clearing(order, arrival_sorted, exit_of, persons, capacity, exits, last, clear, walk)
    return clear, walk
