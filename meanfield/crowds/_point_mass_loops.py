"""The point-mass crowd's Euler–Maruyama step, compiled (paper, eq. (1) discretized).

:func:`euler_maruyama`: ``X_j += b_j dt + a_j ξ_j``, with the box's reflecting walls folded in
when Ω is a box (any number of bounces, as :meth:`meanfield.geometry.domain.Domain.reflect` does).
The noise ``ξ_j`` of step ``n`` is drawn in the same pass, from the counter-based generator of
:mod:`meanfield._compiled.philox` keyed by the run's seed: a pure function of ``(seed, n, j)``, so
that the humans are stepped in chunks on numba's threads (:func:`~meanfield._compiled.core.prange`)
and a seed gives the same positions on any number of threads.  The numpy twin draws the same
numbers (bit for bit) and does the same arithmetic.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, inner, prange
from meanfield._compiled.philox import fill_normal_pairs, fill_pairs_rows

__all__ = ["euler_maruyama", "hold_at_capacity", "hold_at_doors"]


# ----------------------------------------------------------------------------- the SDE step
def _fold_numpy(col, lo, hi):
    out = (col < lo) | (col > hi)
    if out.any():
        period = 2.0 * (hi - lo)
        s = np.mod(col[out] - lo, period)
        col[out] = lo + np.where(s > hi - lo, period - s, s)


def _euler_maruyama_numpy(x, drift, noise, dt, amp, box, standing, key0, key1, step, ki, wi, fi):
    if not np.isfinite(drift).all():
        return False
    fill_normal_pairs.fallback(key0, key1, step, 0, noise, ki, wi, fi)  # (the numpy twin: the same bits)
    if standing.shape[0]:
        noise[standing] = 0.0
    x += drift * dt
    x += noise * amp
    if box.shape[0]:
        _fold_numpy(x[:, 0], box[0], box[1])
        _fold_numpy(x[:, 1], box[2], box[3])
    return True


@compiled(fallback=_euler_maruyama_numpy, parallel_over="x")
def euler_maruyama(x, drift, noise, dt, amp, box, standing, key0, key1, step, ki, wi, fi):
    """One Euler–Maruyama step of eq. (1), in place: ``X_j += b_j dt + a_j ξ_j``, then the box's walls;
    returns False, ``x`` untouched, when some drift is not finite (else True).

    The noise ``ξ_j = normal_pair(key, step, j)`` (:func:`meanfield._compiled.philox.normal_pair`) is
    drawn into ``noise`` in the same pass, after the drifts are checked (0 for those standing).  Chunks of
    :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans run on numba's threads; every human's
    numbers depend on its own row only, so the result is the same on any number of threads.

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions, updated in place.
    drift : ndarray, shape (N, 2)
        ``b_j = u_W + v_r + v_a`` at each human.
    noise : ndarray, shape (N, 2)
        Work array, overwritten with the draws ``ξ_j`` actually used.
    dt : float
    amp : ndarray, shape (N, 1) or (1, 1)
        ``sqrt(2 σ dt)`` per human (one row when σ is constant).
    box : ndarray, shape (4,) or (0,)
        ``(x0, x1, y0, y1)``: fold each coordinate back into the box (reflecting walls, any
        number of bounces); empty: no walls here (the caller reflects).
    standing : ndarray of bool, shape (N,) or (0,)
        Who does not move by the noise this step (their draws are made, then set to 0); empty: nobody.
    key0, key1 : np.uint64
        The noise's key (:func:`meanfield._compiled.philox.noise_key`).
    step : np.uint64
        The step's number (the counter).
    ki, wi, fi : ndarray
        The ziggurat's tables (:data:`meanfield._compiled.philox.ZIG_KI`, ``ZIG_WI``, ``ZIG_FI``).
    """
    n = x.shape[0]
    chunks = (n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    finite = empty_array(chunks, np.bool_)
    for c in prange(chunks):  # every drift finite, or nothing moves (the caller keeps the last good state)
        good = True
        for j in range(c * PARALLEL_CHUNK, n if n < (c + 1) * PARALLEL_CHUNK else (c + 1) * PARALLEL_CHUNK):
            if not (math.isfinite(drift[j, 0]) and math.isfinite(drift[j, 1])):
                good = False
                break
        finite[c] = good
    for c in range(chunks):
        if not finite[c]:
            return False
    walls = box.shape[0] == 4
    one = amp.shape[0] == 1
    for c in prange(chunks):
        lo = c * PARALLEL_CHUNK
        hi = n if n < lo + PARALLEL_CHUNK else lo + PARALLEL_CHUNK
        fill_pairs_rows(key0, key1, step, 0, noise, lo, hi, ki, wi, fi)  # the chunk's draws, used at once
        for j in range(lo, hi):
            if standing.shape[0] and standing[j]:
                noise[j, 0] = 0.0
                noise[j, 1] = 0.0
            a = amp[0, 0] if one else amp[j, 0]
            for k in range(2):
                v = x[j, k] + drift[j, k] * dt
                v = v + noise[j, k] * a
                if walls:
                    low = box[2 * k]
                    high = box[2 * k + 1]
                    if v < low or v > high:
                        period = 2.0 * (high - low)
                        r = (v - low) % period
                        v = low + (period - r if r > high - low else r)
                x[j, k] = v
    return True


# ----------------------------------------------------------------------------- the exits' queues
@inner
def _reaching(door_of, k, reached):
    """Those (indices ``i``) with ``door_of[i] == k``, in order, into ``reached``; returns how many."""
    count = 0
    for i in range(door_of.shape[0]):
        if door_of[i] == k:
            reached[count] = i
            count += 1
    return count


@inner
def _queue_order(reached, count, first, distance, previous, idx, segments, k):
    """Order ``reached[:count]`` (indices into ``idx``) in place as door ``k`` of ``segments`` serves them: those
    flagged in ``first`` (set by the caller) first, each the nearest to the door's segment at its step's start
    first, ties in their order (a stable insertion sort; the distances in :func:`_doorway_distance_numpy`'s
    arithmetic, into ``distance``)."""
    ax = segments[k, 0, 0]
    ay = segments[k, 0, 1]
    dx = segments[k, 1, 0] - ax
    dy = segments[k, 1, 1] - ay
    for c in range(count):
        sx = previous[idx[reached[c]], 0]
        sy = previous[idx[reached[c]], 1]
        along = ((sx - ax) * dx + (sy - ay) * dy) / (dx * dx + dy * dy)  # min(max(along, 0), 1), as numba's select
        along = 0.0 if 0.0 > along else along
        along = 1.0 if 1.0 < along else along
        distance[c] = math.hypot(sx - (ax + along * dx), sy - (ay + along * dy))
    for c in range(1, count):
        r = reached[c]
        f = first[c]
        d = distance[c]
        e = c - 1
        while e >= 0 and ((f and not first[e]) or (f == first[e] and d < distance[e])):
            reached[e + 1] = reached[e]
            first[e + 1] = first[e]
            distance[e + 1] = distance[e]
            e -= 1
        reached[e + 1] = r
        first[e + 1] = f
        distance[e + 1] = d


def _doorway_distance_numpy(start, a, b):
    """The distance from each of ``start`` (M, 2) to the exit ``[a, b]`` (m), in :func:`hold_at_capacity`'s
    arithmetic."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    along = np.clip(((start[:, 0] - a[0]) * dx + (start[:, 1] - a[1]) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
    return np.hypot(start[:, 0] - (a[0] + along * dx), start[:, 1] - (a[1] + along * dy))


def _hold_numpy(gone, idx, previous, x, exits, capacity, credit, waiting, waiting_at, is_open, dt):
    """The numpy twin of :func:`hold_at_capacity`."""
    if not len(waiting) and not (gone >= 0).any():  # nobody at a door: the credits refill, nothing else
        return np.minimum(credit, 1.0) + capacity * dt, waiting, waiting_at
    in_doorway = np.zeros(len(idx), dtype=bool)  # those in a doorway, by their place in idx
    busy = np.zeros(len(capacity), dtype=bool)
    if len(waiting) and len(idx):  # those in a doorway reach it again, whatever their step, while it is open
        at = np.minimum(np.searchsorted(idx, waiting), len(idx) - 1)
        here = (idx[at] == waiting) & is_open[waiting_at]
        gone[at[here]] = waiting_at[here]
        busy[waiting_at[here]] = True
        in_doorway[at[here]] = True
    credit = np.where(busy, credit, np.minimum(credit, 1.0)) + capacity * dt
    held_all, held_at = [], []
    for k in np.unique(gone[gone >= 0]):
        reached = np.flatnonzero(gone == k)
        allowed = int(credit[k])
        if len(reached) > allowed:
            distance = _doorway_distance_numpy(previous[idx[reached]], exits[k, 0], exits[k, 1])
            order = np.lexsort((distance, ~in_doorway[reached]))  # the waiting first, each the nearest first
            held = reached[order[allowed:]]
            gone[held] = -1
            x[idx[held]] = previous[idx[held]]
            held_all.append(idx[held])
            held_at.append(np.full(len(held), k, dtype=np.intp))
        credit[k] -= min(len(reached), allowed)
    if not held_all:
        return credit, np.empty(0, dtype=np.intp), np.empty(0, dtype=np.intp)
    who, at = np.concatenate(held_all), np.concatenate(held_at)
    order = np.argsort(who)
    return credit, who[order], at[order]


@compiled(fallback=_hold_numpy)
def hold_at_capacity(gone, idx, previous, x, exits, capacity, credit, waiting, waiting_at, is_open, dt):
    """The exits' queues, one step (docs page *Congestion*, "The exits' capacity"): each exit ``k`` lets through
    at most ``⌊c_k⌋`` of those who reached it, its credit ``c_k`` refilled by ``q_k dt`` (and kept at most 1
    while nobody waits in its doorway); those it cannot take step back to where they started and wait in its
    doorway, to pass first, the nearest first, when it has credit.

    Parameters
    ----------
    gone : ndarray of intp, shape (M,)
        The exit each human of ``idx`` reached this step (-1: none); those held get -1 (in place).
    idx : ndarray of intp, shape (M,)
        The humans who stepped (sorted).
    previous, x : ndarray, shape (N, 2)
        The positions before and after the step; those held get ``previous`` in ``x`` (in place).
    exits : ndarray, shape (K, 2, 2)
        The exits' segments.
    capacity : ndarray, shape (K,)
        ``q_k``, persons/s each exit passes at most.
    credit : ndarray, shape (K,)
        The credits before the step (not changed).
    waiting, waiting_at : ndarray of intp
        Who waited in a doorway after the last step (sorted) and at which exit.
    is_open : ndarray of bool, shape (K,)
        The exits still open (those waiting at a closed one wait no more).
    dt : float

    Returns
    -------
    credit, waiting, waiting_at : ndarray
        The credits after the step, and who waits in a doorway now (sorted) and at which exit.
    """
    # (no np.zeros, min, int or argsort: numba compiles their overloads in every process, the sort's alone 2 s)
    m = idx.shape[0]
    n_exits = capacity.shape[0]
    out = empty_array(n_exits, np.float64)
    anyone = waiting.shape[0] > 0
    for i in range(m):
        anyone = anyone or gone[i] >= 0
    if not anyone:  # nobody at a door: the credits refill, nothing else
        for k in range(n_exits):
            out[k] = (1.0 if 1.0 < credit[k] else credit[k]) + capacity[k] * dt
        return out, waiting, waiting_at
    in_doorway = empty_array(m, np.bool_)
    held_by = empty_array(m, np.intp)  # the exit holding each human of idx, -1: none
    for i in range(m):
        in_doorway[i] = False
        held_by[i] = -1
    busy = empty_array(n_exits, np.bool_)
    for k in range(n_exits):
        busy[k] = False
    if waiting.shape[0] and m:  # those in a doorway reach it again, whatever their step, while it is open
        p = 0
        for w in range(waiting.shape[0]):  # (both sorted: a merge, numpy's searchsorted)
            while p < m and idx[p] < waiting[w]:
                p += 1
            at = m - 1 if m - 1 < p else p
            if idx[at] == waiting[w] and is_open[waiting_at[w]]:
                gone[at] = waiting_at[w]
                busy[waiting_at[w]] = True
                in_doorway[at] = True
    for k in range(n_exits):
        out[k] = (credit[k] if busy[k] else (1.0 if 1.0 < credit[k] else credit[k])) + capacity[k] * dt
    held = 0
    reached = empty_array(m, np.intp)
    first = empty_array(m, np.bool_)  # (waiting first)
    distance = empty_array(m, np.float64)
    for k in range(n_exits):
        count = _reaching(gone, k, reached)
        if count == 0:
            continue
        allowed = np.int64(out[k])
        if count > allowed:
            for c in range(count):
                first[c] = in_doorway[reached[c]]
            _queue_order(reached, count, first, distance, previous, idx, exits, k)
            for c in range(allowed, count):
                i = reached[c]
                gone[i] = -1
                x[idx[i], 0] = previous[idx[i], 0]
                x[idx[i], 1] = previous[idx[i], 1]
                held_by[i] = k
                held += 1
        out[k] -= allowed if allowed < count else count
    held_who = empty_array(held, np.intp)  # by idx's order, which is the humans' (idx is sorted)
    held_at = empty_array(held, np.intp)
    h = 0
    for i in range(m):
        if held_by[i] >= 0:
            held_who[h] = idx[i]
            held_at[h] = held_by[i]
            h += 1
    return out, held_who, held_at


# ----------------------------------------------------------------------------- the inner doors' queues
@inner
def _door_crossed(p0x, p0y, p1x, p1y, doors, k):
    """+1 or -1 if the step ``p0 → p1`` crosses door ``k`` (the sign of its side's change: the cross product
    of the step and the door), 0 if it does not; the ends count as on the door."""
    ax = doors[k, 0, 0]
    ay = doors[k, 0, 1]
    ex = doors[k, 1, 0] - ax
    ey = doors[k, 1, 1] - ay
    dx = p1x - p0x
    dy = p1y - p0y
    den = dx * ey - dy * ex
    if den == 0.0:
        return 0
    wx = ax - p0x
    wy = ay - p0y
    t = (wx * ey - wy * ex) / den
    u = (wx * dy - wy * dx) / den
    if t < 0.0 or t > 1.0 or u < 0.0 or u > 1.0:
        return 0
    return 1 if den > 0.0 else -1


def _hold_doors_numpy(idx, previous, x, doors, capacity, credit, waiting, last_door, last_sign, dt):
    """The numpy twin of :func:`hold_at_doors` (the same arithmetic, door by door)."""
    n_doors = len(capacity)
    p0, p1 = previous[idx], x[idx]
    d = p1 - p0
    crossed = np.full(len(idx), -1, dtype=np.intp)  # the first door (by index) each step crosses
    sign = np.zeros(len(idx), dtype=np.int8)
    for k in range(n_doors - 1, -1, -1):
        a, e = doors[k, 0], doors[k, 1] - doors[k, 0]
        den = d[:, 0] * e[1] - d[:, 1] * e[0]
        w = a - p0
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[:, 0] * e[1] - w[:, 1] * e[0]) / den
            u = (w[:, 0] * d[:, 1] - w[:, 1] * d[:, 0]) / den
        hit = (den != 0.0) & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
        crossed[hit] = k
        sign[hit] = np.where(den[hit] > 0.0, 1, -1)
    busy = np.zeros(n_doors, dtype=bool)
    before = waiting[idx]
    busy[before[before >= 0]] = True
    out = np.where(busy, credit, np.minimum(credit, 1.0)) + capacity * dt
    who = np.flatnonzero(crossed >= 0)
    back = who[(last_door[idx[who]] == crossed[who]) & (last_sign[idx[who]] == -sign[who])]
    np.add.at(out, crossed[back], 1.0)  # a step back through the door one last passed gives its place back
    last_door[idx[back]] = -1
    waiting[idx] = -1
    charged = np.setdiff1d(who, back)
    for k in np.unique(crossed[charged]):
        reached = charged[crossed[charged] == k]
        allowed = int(out[k])
        passed = reached
        if len(reached) > allowed:
            distance = _doorway_distance_numpy(p0[reached], doors[k, 0], doors[k, 1])
            order = np.lexsort((distance, before[reached] != k))  # those who waited at it first, the nearest first
            passed, held = reached[order[:allowed]], reached[order[allowed:]]
            x[idx[held]] = previous[idx[held]]
            waiting[idx[held]] = k
        last_door[idx[passed]] = k
        last_sign[idx[passed]] = sign[passed]
        out[k] -= len(passed)
    return out


@compiled(fallback=_hold_doors_numpy)
def hold_at_doors(idx, previous, x, doors, capacity, credit, waiting, last_door, last_sign, dt):
    """The inner doors' queues, one step (docs page *Congestion*, "The doors' capacity"): each door ``k`` lets
    at most ``⌊c_k⌋`` steps through it, its credit ``c_k`` refilled by ``q_k dt`` (and kept at most 1 unless
    someone waited at it since the last step); those it cannot take go back to where they started and wait,
    to pass first, the nearest first, if their next step crosses it.  A step back through the door one last
    passed, the other way, takes no place and gives its place back: a door counts its net flow, so that the
    noise of one standing in the doorway does not use it up.

    Parameters
    ----------
    idx : ndarray of intp, shape (M,)
        The humans who stepped and are still in Ω (sorted).
    previous, x : ndarray, shape (N, 2)
        The positions before and after the step (after the walls); those held get ``previous`` in ``x``
        (in place).
    doors : ndarray, shape (D, 2, 2)
        The doors' segments.
    capacity : ndarray, shape (D,)
        ``q_k``, persons/s each door passes at most.
    credit : ndarray, shape (D,)
        The credits before the step (not changed).
    waiting : ndarray of intp, shape (N,)
        The door each human waited at after the last step (-1: none); now, after this one (in place).
    last_door, last_sign : ndarray of intp and int8, shape (N,)
        The door each human last passed (-1: none) and the way (±1) (in place).
    dt : float

    Returns
    -------
    credit : ndarray, shape (D,)
        The credits after the step.
    """
    m = idx.shape[0]
    n_doors = capacity.shape[0]
    crossed = empty_array(m, np.intp)  # (not np.full, np.zeros, min or int: their overloads compile in every process)
    sign = empty_array(m, np.int8)
    busy = empty_array(n_doors, np.bool_)
    for k in range(n_doors):
        busy[k] = False
    before = empty_array(m, np.intp)
    for i in range(m):
        crossed[i] = -1
        sign[i] = 0
        j = idx[i]
        before[i] = waiting[j]
        if waiting[j] >= 0:
            busy[waiting[j]] = True
        waiting[j] = -1
        for k in range(n_doors):
            s = _door_crossed(previous[j, 0], previous[j, 1], x[j, 0], x[j, 1], doors, k)
            if s != 0:
                crossed[i] = k
                sign[i] = s
                break
    out = empty_array(n_doors, np.float64)
    for k in range(n_doors):
        out[k] = (credit[k] if busy[k] else (1.0 if 1.0 < credit[k] else credit[k])) + capacity[k] * dt
    for i in range(m):  # a step back through the door one last passed gives its place back
        k = crossed[i]
        j = idx[i]
        if k >= 0 and last_door[j] == k and last_sign[j] == -sign[i]:
            out[k] += 1.0
            last_door[j] = -1
            crossed[i] = -1
    reached = empty_array(m, np.intp)
    first = empty_array(m, np.bool_)
    distance = empty_array(m, np.float64)
    for k in range(n_doors):
        count = _reaching(crossed, k, reached)
        if count == 0:
            continue
        allowed = np.int64(out[k])
        if count > allowed:
            for c in range(count):
                first[c] = before[reached[c]] == k
            _queue_order(reached, count, first, distance, previous, idx, doors, k)
        passed = allowed if allowed < count else count
        for c in range(count):
            i = reached[c]
            j = idx[i]
            if c < passed:
                last_door[j] = k
                last_sign[j] = sign[i]
            else:
                x[j, 0] = previous[j, 0]
                x[j, 1] = previous[j, 1]
                waiting[j] = k
        out[k] -= passed
    return out
