"""The exits' test of every step, compiled: which exit a human's step leaves through (docs page *Buildings*).

:func:`meanfield.geometry.exits.leaving` decides, for each human, in two passes:

* :func:`first_exit_crossed`: the first exit the step ``p → q`` crosses. Exit ``e`` is the
  segment ``a_e + u e_e``, ``0 <= u <= 1``; the step meets it at the fraction

  .. math::  t = \\frac{(a_e - p) \\times e_e}{d \\times e_e}, \\qquad
             u = \\frac{(a_e - p) \\times d}{d \\times e_e}, \\qquad d = q - p,

  and crosses it when ``d × e_e != 0``, ``0 < t <= 1`` and ``0 <= u <= 1``; the first is the
  smallest ``t``, ties to the lowest exit index;
* :func:`bridge_exits`: for those who crossed none, the Brownian-bridge test: the path
  touched exit ``e`` with probability ``p_e = exp(−d₀ d₁ / (σ Δt))`` (``d₀``, ``d₁`` the
  distances from the step's ends to the exit segment); the most likely exit ``k`` is taken
  when the human's uniform draw is below ``p_k``. The draws come from the caller (the
  scenario's numpy generator), one per such human, in order.

Each pass is one loop over the humans, paired with its numpy twin (the reference,
:mod:`meanfield._compiled.core`), with the same arithmetic; the exponential is the C library's
in the loop and numpy's in the twin, so ``p`` can differ in its last bit (a decision then
differs only for a draw within that bit of ``p``).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, prange

__all__ = ["first_exit_crossed", "bridge_exits", "segment_distances"]


def segment_distances(points: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Distance ``(N, E)`` from each point ``(N, 2)`` to each segment ``(E, 2, 2)`` (numpy)."""
    a, b = segs[:, 0], segs[:, 1]
    ab = b - a
    t = ((points[:, None, :] - a[None]) * ab[None]).sum(-1) / (ab * ab).sum(-1)[None]
    t = np.clip(t, 0.0, 1.0)
    q = a[None] + t[..., None] * ab[None]
    return np.hypot(*(points[:, None, :] - q).transpose(2, 0, 1))


def _first_exit_numpy(start, end, segs, out):
    d = end - start
    a, e = segs[:, 0], segs[:, 1] - segs[:, 0]
    cross = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
    w = a[None] - start[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / cross
        u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / cross
    hit = (cross != 0) & (t > 0) & (t <= 1) & (u >= 0) & (u <= 1)
    crossed = hit.any(axis=1)
    out[crossed] = np.argmax(np.where(hit, -t, -np.inf), axis=1)[crossed]  # the first exit on the way
    return out


@compiled(fallback=_first_exit_numpy, parallel_over="start")
def first_exit_crossed(start, end, segs, out):
    """Into ``out`` (N,) (left as it is for a step that crosses none): the first exit each step crosses.

    Chunks of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` steps run on numba's threads (each
    step is its own).

    Parameters
    ----------
    start, end : ndarray, shape (N, 2)
        Where each step starts and (before any reflection) ends.
    segs : ndarray, shape (E, 2, 2)
        The exits' end points.
    out : ndarray of intp, shape (N,)
        The exit index of each step that crosses one.
    """
    n = start.shape[0]
    for chunk in prange((n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        for i in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, n)):
            px, py = start[i, 0], start[i, 1]
            dx, dy = end[i, 0] - px, end[i, 1] - py
            best, first = -math.inf, -1
            for k in range(segs.shape[0]):
                ax, ay = segs[k, 0, 0], segs[k, 0, 1]
                ex, ey = segs[k, 1, 0] - ax, segs[k, 1, 1] - ay
                cross = dx * ey - dy * ex
                if cross == 0:
                    continue
                wx, wy = ax - px, ay - py
                t = (wx * ey - wy * ex) / cross
                u = (wx * dy - wy * dx) / cross
                if t > 0 and t <= 1 and u >= 0 and u <= 1 and -t > best:
                    best, first = -t, k
            if first >= 0:
                out[i] = first
    return out


def _bridge_numpy(start, end, segs, near, draws, sdt, out):
    d0 = segment_distances(start[near], segs)
    d1 = segment_distances(end[near], segs)
    p = np.exp(-d0 * d1 / sdt)  # (M, E): the bridge touched exit e
    k = np.argmax(p, axis=1)
    touched = draws < p[np.arange(len(near)), k]
    out[near[touched]] = k[touched]
    return out


@compiled(fallback=_bridge_numpy, parallel_over="near")
def bridge_exits(start, end, segs, near, draws, sdt, out):
    """The Brownian-bridge test of the humans ``near`` (indices): ``out[i] = k`` when ``draws[j] < p_k``.

    Chunks of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans run on numba's threads (each
    human's test is its own, its draw given).

    Parameters
    ----------
    start, end : ndarray, shape (N, 2)
    segs : ndarray, shape (E, 2, 2)
    near : ndarray of intp, shape (M,)
        The humans to test (those whose step crossed no exit).
    draws : ndarray, shape (M,)
        One uniform draw on [0, 1) per human of ``near``, in order.
    sdt : float
        ``σ Δt``.
    out : ndarray of intp, shape (N,)
        Set to the most likely exit ``k`` of each human whose path touched it.
    """
    m = near.shape[0]
    for chunk in prange((m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):
        for j in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m)):
            i = near[j]
            best, first = -math.inf, 0
            for k in range(segs.shape[0]):
                ax, ay = segs[k, 0, 0], segs[k, 0, 1]
                abx, aby = segs[k, 1, 0] - ax, segs[k, 1, 1] - ay
                den = abx * abx + aby * aby
                qx, qy = start[i, 0], start[i, 1]  # the distance from each end of the step to the segment
                t = min(max(((qx - ax) * abx + (qy - ay) * aby) / den, 0.0), 1.0)
                d0 = math.hypot(qx - (ax + t * abx), qy - (ay + t * aby))
                qx, qy = end[i, 0], end[i, 1]
                t = min(max(((qx - ax) * abx + (qy - ay) * aby) / den, 0.0), 1.0)
                d1 = math.hypot(qx - (ax + t * abx), qy - (ay + t * aby))
                p = math.exp(-d0 * d1 / sdt)
                if p > best:
                    best, first = p, k
            if draws[j] < best:
                out[i] = first
    return out
