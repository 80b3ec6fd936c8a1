"""The point-mass crowd's Euler–Maruyama step, compiled (paper, eq. (1) discretized).

:func:`euler_maruyama`: ``X_j += b_j dt + a ξ_j``, with the box's reflecting walls folded in
when Ω is a box (any number of bounces, as :meth:`meanfield.geometry.domain.Domain.reflect` does).
The noise ``ξ_j`` is drawn by the caller from its numpy Generator, so both paths (the compiled
loop and its numpy twin) consume the same random stream.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["euler_maruyama"]


# ----------------------------------------------------------------------------- the SDE step
def _fold_numpy(col, lo, hi):
    out = (col < lo) | (col > hi)
    if out.any():
        period = 2.0 * (hi - lo)
        s = np.mod(col[out] - lo, period)
        col[out] = lo + np.where(s > hi - lo, period - s, s)


def _euler_maruyama_numpy(x, drift, noise, dt, amp, box):
    if not np.isfinite(drift).all():
        return False
    x += drift * dt
    x += noise * amp
    if box.shape[0]:
        _fold_numpy(x[:, 0], box[0], box[1])
        _fold_numpy(x[:, 1], box[2], box[3])
    return True


@compiled(fallback=_euler_maruyama_numpy)
def euler_maruyama(x, drift, noise, dt, amp, box):
    """One Euler–Maruyama step of eq. (1), in place: ``X_j += b_j dt + a_j ξ_j``, then the box's walls;
    returns False, ``x`` untouched, when some drift is not finite (else True).

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions, updated in place.
    drift : ndarray, shape (N, 2)
        ``b_j = u_W + v_r + v_a`` at each human.
    noise : ndarray, shape (N, 2)
        Standard normal draws ``ξ_j``.
    dt : float
    amp : ndarray, shape (N, 1) or (1, 1)
        ``sqrt(2 σ dt)`` per human (one row when σ is constant).
    box : ndarray, shape (4,) or (0,)
        ``(x0, x1, y0, y1)``: fold each coordinate back into the box (reflecting walls, any
        number of bounces); empty: no walls here (the caller reflects).
    """
    for j in range(x.shape[0]):  # every drift finite, or nothing moves (the caller keeps the last good state)
        if not (math.isfinite(drift[j, 0]) and math.isfinite(drift[j, 1])):
            return False
    walls = box.shape[0] == 4
    one = amp.shape[0] == 1
    for j in range(x.shape[0]):
        a = amp[0, 0] if one else amp[j, 0]
        for k in range(2):
            v = x[j, k] + drift[j, k] * dt
            v = v + noise[j, k] * a
            if walls:
                lo = box[2 * k]
                hi = box[2 * k + 1]
                if v < lo or v > hi:
                    period = 2.0 * (hi - lo)
                    s = (v - lo) % period
                    v = lo + (period - s if s > hi - lo else s)
            x[j, k] = v
    return True
