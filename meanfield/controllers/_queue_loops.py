"""The exits' assignment and clearing times (eq. (B1)), compiled.

* :func:`assign_exits`: each cell's exit of least arrival plus offset, one pass over the cells;
* :func:`clearing_times`: one pass per exit over its cells in the order of arrival;
* :func:`assigned_clearing_times`: the two in one call (a pass of the price iteration);
* :func:`price_iteration`: the passes of the price iteration (:meth:`ExitAssignment.solve
  <meanfield.controllers.exit_assignment.ExitAssignment.solve>`) in one call;
* :func:`label_search`: the guide's search for its signs' labels (:meth:`GuideController.exit_here
  <meanfield.controllers.guide.GuideController.exit_here>`), each label's cost a clearing pass and a sum.

Sums are numpy's (:func:`_pairwise_sum`: ``np.sum``'s order of additions, so the same numbers).

Each is paired with its numpy twin; the callers are :class:`meanfield.controllers.exit_assignment.ExitAssignment` and
:class:`~meanfield.controllers.exit_assignment.ArrivalOrder`.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled, inner

__all__ = ["assign_exits", "assigned_clearing_times", "clearing_times", "label_search", "price_iteration"]


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
            if exit_of[c] != k:  # (its term is at most the next cell's the exit takes, its arrival too: skipped)
                continue
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
    (``exit_of[c] == k``), and keeps the largest ``a_j + rest_j / C_k`` and ``a_j`` over those cells with at least
    ``last`` persons from ``a_j`` on.  A cell assigned elsewhere is skipped: with the same persons still to come as
    the next cell the exit takes and an arrival no later, neither of its terms is larger (rounding is monotone), so
    the maxima are those over every cell of the row, which the numpy twin takes.

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


# ----------------------------------------------------------------------------- the guide's labels
@inner
def _pairwise_block(a, lo, n):
    """``a[lo:lo + n]``, ``n <= 128``, summed as numpy does (:func:`_pairwise_sum`)."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@inner
def _pairwise_sum(a, lo, n):
    """``a[lo:lo + n]`` summed in the order of numpy's pairwise summation (``np.add.reduce`` of a contiguous float64
    array, without its initial ``0.0 +``): below 8 terms one by one from ``-0.0``; up to 128 in eight running sums
    combined as a tree; above, the two halves (the first a multiple of 8) summed so and added.

    Without recursion (numba does not cache a recursive function): the halves' tree is walked with a stack, each
    block summed as it is reached and each pair of halves added once both are known.
    """
    if n <= 128:
        return _pairwise_block(a, lo, n)
    todo_lo = np.empty(128, np.int64)  # pending ranges (a range of 2^63 terms needs fewer than 128 levels)
    todo_n = np.empty(128, np.int64)
    todo_join = np.zeros(128, np.bool_)  # True: add the two sums on top of the value stack
    sums = np.empty(128)
    top, values = 0, 0
    todo_lo[0], todo_n[0], todo_join[0] = lo, n, False
    top = 1
    while top > 0:
        top -= 1
        if todo_join[top]:
            values -= 1
            sums[values - 1] = sums[values - 1] + sums[values]
            continue
        start, size = todo_lo[top], todo_n[top]
        if size <= 128:
            sums[values] = _pairwise_block(a, start, size)
            values += 1
            continue
        half = size // 2
        half -= half % 8
        todo_join[top] = True  # after both halves: their sum (the first half's sum is below the second's)
        todo_lo[top + 1], todo_n[top + 1], todo_join[top + 1] = start + half, size - half, False
        todo_lo[top + 2], todo_n[top + 2], todo_join[top + 2] = start, half, False
        top += 3
    return sums[0]


@inner
def _largest(values, rows):
    """``values[rows].max()`` as numpy gives it: a NaN if any."""
    out = values[rows[0]]
    for r in range(1, rows.shape[0]):
        x = values[rows[r]]
        if out != out:
            break
        if x != x or x > out:
            out = x
    return out


@inner
def _smallest(values, rows):
    """``values[rows].min()`` as numpy gives it: a NaN if any."""
    out = values[rows[0]]
    for r in range(1, rows.shape[0]):
        x = values[rows[r]]
        if out != out:
            break
        if x != x or x < out:
            out = x
    return out


def _price_numpy(arrival, is_open, tau, iterations, order, arrival_sorted, persons, capacity, exits, last, exit_of,
                 clear, walk, gathered, best_tau):  # fmt: skip
    best = math.inf
    best_tau[:] = tau
    for i in range(iterations):
        masked = np.where(is_open, tau, np.inf)
        T = _assigned_clearing_numpy(arrival, masked, order, arrival_sorted, persons, capacity, exits, last, exit_of,
                                     clear, walk)[0]  # fmt: skip
        makespan = float(T[is_open].max())
        if makespan < best:
            best = makespan
            best_tau[:] = tau
        step = 0.5 / (1.0 + i / 10.0)
        tau[:] = tau + step * np.where(is_open, T - T[is_open].mean(), 0.0)
        tau[:] = np.where(is_open, tau - tau[is_open].min(), 0.0)
    return best


@compiled(fallback=_price_numpy)
def price_iteration(arrival, is_open, tau, iterations, order, arrival_sorted, persons, capacity, exits, last, exit_of,
                    clear, walk, gathered, best_tau):  # fmt: skip
    """The price iteration of :meth:`ExitAssignment.solve <meanfield.controllers.exit_assignment.ExitAssignment.solve>`
    from the offsets ``tau`` (in place): ``iterations`` passes, each the clearing times ``T`` of the assignment of
    ``tau`` (:func:`assigned_clearing_times`), then ``τ += s_i (T − mean T)`` over the open exits, ``s_i = 0.5 /
    (1 + i/10)``, shifted to a least open offset of 0 (the mean summed as ``np.mean`` does).

    Parameters
    ----------
    arrival : ndarray, shape (K, M)
    is_open : ndarray of bool, shape (K,)
    tau : ndarray, shape (K,)
        The offsets to start from (0 for a closed exit); the last pass's (out).
    iterations : int
    order, arrival_sorted, persons, capacity, exits, last
        As :func:`assigned_clearing_times` (``exits``: the open ones, at least one).
    exit_of, clear, walk, gathered : ndarray
        Work arrays, shapes (M,) of int, (K,), (K,), (K,).
    best_tau : ndarray, shape (K,)
        The offsets of the least makespan (out).

    Returns
    -------
    float
        That makespan (``inf`` when none is finite).
    """
    k_exits = tau.shape[0]
    n_open = exits.shape[0]
    best = math.inf
    for k in range(k_exits):
        best_tau[k] = tau[k]
    for i in range(iterations):
        for k in range(k_exits):
            gathered[k] = tau[k] if is_open[k] else math.inf
        _assign(arrival, gathered, exit_of)
        _clearing(order, arrival_sorted, exit_of, persons, capacity, exits, last, clear, walk)
        makespan = _largest(clear, exits)
        if makespan < best:
            best = makespan
            for k in range(k_exits):
                best_tau[k] = tau[k]
        step = 0.5 / (1.0 + i / 10.0)
        for e in range(n_open):
            gathered[e] = clear[exits[e]]
        mean = (0.0 + _pairwise_sum(gathered, 0, n_open)) / n_open
        for k in range(k_exits):
            tau[k] = tau[k] + step * ((clear[k] - mean) if is_open[k] else 0.0)
        least = _smallest(tau, exits)
        for k in range(k_exits):
            tau[k] = (tau[k] - least) if is_open[k] else 0.0
    return best


def _label_search_numpy(reader, plan, persons, order, arrival, capacity, exits, last, walked, total, has, labels,
                        sweeps, exit_of, terms, clear, walk):  # fmt: skip
    cells = np.arange(len(plan))

    def cost(labels):
        exit_of[:] = np.where(reader >= 0, labels[np.maximum(reader, 0)], plan)
        makespan = float(_clearing_numpy(order, arrival, exit_of, persons, capacity, exits, last, clear, walk)[0][
            exits].max())  # fmt: skip
        with np.errstate(invalid="ignore"):
            detour = walked[exit_of, cells].sum() / total
        return makespan + detour if np.isfinite(detour) else math.inf

    best = start = cost(labels)
    for _ in range(sweeps):
        better = False
        for i in np.flatnonzero(has):
            keep = labels[i]
            for k in exits:
                if k == keep:
                    continue
                labels[i] = k
                c = cost(labels)
                if c < best - 1e-9:
                    best, keep, better = c, k, True
            labels[i] = keep
        if not better:
            break
    return best, start


@compiled(fallback=_label_search_numpy)
def label_search(reader, plan, persons, order, arrival, capacity, exits, last, walked, total, has, labels, sweeps,
                 exit_of, terms, clear, walk):  # fmt: skip
    """The guide's labels, robot by robot (:meth:`GuideController.exit_here
    <meanfield.controllers.guide.GuideController.exit_here>`): from ``labels`` (in place), each robot of ``has`` in
    turn takes each open exit whose labels cost less by ``1e-9``, for at most ``sweeps`` passes over the robots (none
    after a pass that changes nothing).  The cost of labels: the makespan (B1) of the cells' exits (a reader's: its
    robot's label; any other cell's: ``plan``), plus the persons' mean detour, ``Σ walked[exit_of[c], c] / total``
    (``inf`` when not finite).

    Parameters
    ----------
    reader : ndarray of int, shape (m,)
        Each cell's robot (``-1``: none).
    plan : ndarray of int, shape (m,)
        Each cell's exit under Step I.
    persons : ndarray, shape (m,)
    order, arrival : ndarray, shape (K, m)
        Each exit's cells in the order of arrival and their arrival times in that order (:class:`ArrivalOrder
        <meanfield.controllers.exit_assignment.ArrivalOrder>`).
    capacity : ndarray, shape (K,)
    exits : ndarray of int
        The open exits.
    last : float
        As :func:`clearing_times`.
    walked : ndarray, shape (K, m)
        Each cell's persons times its detour to each exit.
    total : float
        The persons in all (> 0).
    has : ndarray of bool, shape (n,)
        The robots whose labels are searched.
    labels : ndarray of int, shape (n,)
        The labels to start from; the labels found (out).
    sweeps : int
    exit_of, terms, clear, walk : ndarray
        Work arrays, shapes (m,) of int, (m,), (K,), (K,).

    Returns
    -------
    best, start : float
        The cost of the labels found and of those started from.
    """
    m = plan.shape[0]

    # (a closure would be the cost's natural form; numba compiles an inner function as well, but not into the
    # loop's on-disk cache: so the cost is written out twice, as the start and inside the search)
    for c in range(m):
        exit_of[c] = labels[reader[c]] if reader[c] >= 0 else plan[c]
        terms[c] = walked[exit_of[c], c]
    _clearing(order, arrival, exit_of, persons, capacity, exits, last, clear, walk)
    makespan = _largest(clear, exits)
    detour = (0.0 + _pairwise_sum(terms, 0, m)) / total
    start = makespan + detour if math.isfinite(detour) else math.inf
    best = start
    for _ in range(sweeps):
        better = False
        for i in range(has.shape[0]):
            if not has[i]:
                continue
            keep = labels[i]
            for e in range(exits.shape[0]):
                k = exits[e]
                if k == keep:
                    continue
                labels[i] = k
                for c in range(m):
                    exit_of[c] = labels[reader[c]] if reader[c] >= 0 else plan[c]
                    terms[c] = walked[exit_of[c], c]
                _clearing(order, arrival, exit_of, persons, capacity, exits, last, clear, walk)
                makespan = _largest(clear, exits)
                detour = (0.0 + _pairwise_sum(terms, 0, m)) / total
                cost = makespan + detour if math.isfinite(detour) else math.inf
                if cost < best - 1e-9:
                    best, keep, better = cost, k, True
            labels[i] = keep
        if not better:
            break
    return best, start
