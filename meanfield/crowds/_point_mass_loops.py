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

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, prange
from meanfield._compiled.philox import fill_normal_pairs, fill_pairs_rows

__all__ = ["euler_maruyama"]


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
    finite = np.empty(chunks, np.bool_)
    for c in prange(chunks):  # every drift finite, or nothing moves (the caller keeps the last good state)
        good = True
        for j in range(c * PARALLEL_CHUNK, min((c + 1) * PARALLEL_CHUNK, n)):
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
        hi = min(lo + PARALLEL_CHUNK, n)
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
