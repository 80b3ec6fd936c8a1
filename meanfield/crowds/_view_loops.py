"""The humans' local view, compiled: which robots a human sees, and the random walkers' turns.

* :func:`in_view`: the robots within the view radius of each human, not hidden by a wall;
* :func:`turn_walkers`: the walkers whose step a wall turns
  (:meth:`meanfield.crowds.local_view.LocalView.walk_velocity`).

Each is paired with its numpy twin, the reference (:mod:`meanfield._compiled`).
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["in_view", "turn_walkers"]


def _in_view_numpy(humans, robots, r2, visible, hidden, out):
    out[:] = False
    for i in range(len(robots)):  # n is small: n passes over N
        dx = humans[:, 0] - robots[i, 0]
        dy = humans[:, 1] - robots[i, 1]
        near = dx * dx + dy * dy <= r2
        out |= near & visible[i] if hidden else near
    return out


@compiled(fallback=_in_view_numpy)
def in_view(humans, robots, r2, visible, hidden, out):
    """``out[j]``: some robot ``i`` is within ``sqrt(r2)`` of human ``j`` (and, if ``hidden``, ``visible[i, j]``).

    Parameters
    ----------
    humans : ndarray, shape (N, 2)
    robots : ndarray, shape (n, 2)
    r2 : float
        The view radius squared.
    visible : ndarray of bool, shape (n, N)
        Which robot each human sees (:meth:`meanfield.geometry.sight.SightLines.mask`; read when ``hidden``).
    hidden : bool
        Whether a wall may hide a robot.
    out : ndarray of bool, shape (N,)
    """
    for j in range(humans.shape[0]):
        seen = False
        for i in range(robots.shape[0]):
            if not hidden or visible[i, j]:
                dx = humans[j, 0] - robots[i, 0]
                dy = humans[j, 1] - robots[i, 1]
                if dx * dx + dy * dy <= r2:
                    seen = True
                    break
        out[j] = seen
    return out


def _turn_walkers_numpy(start, ahead, mirrored, e, headings, idx):
    out = (mirrored[:, 0] != ahead[:, 0]) | (mirrored[:, 1] != ahead[:, 1])
    d = mirrored[out] - start[out]
    norm = np.hypot(d[:, 0], d[:, 1])
    ok = norm > 0
    rows = np.flatnonzero(out)[ok]
    e[rows] = d[ok] / norm[ok, None]
    headings[idx[rows]] = np.arctan2(d[ok, 1], d[ok, 0])
    return e


@compiled(fallback=_turn_walkers_numpy)
def turn_walkers(start, ahead, mirrored, e, headings, idx):
    """Turn, in place, each walker whose step ``start → ahead`` a wall mirrored to ``mirrored``.

    Its direction ``e`` (M, 2) becomes the unit vector to the mirror image and its heading
    ``headings[idx[k]]`` that vector's angle (:meth:`meanfield.crowds.local_view.LocalView.walk_velocity`).
    """
    for k in range(start.shape[0]):
        if mirrored[k, 0] != ahead[k, 0] or mirrored[k, 1] != ahead[k, 1]:
            dx, dy = mirrored[k, 0] - start[k, 0], mirrored[k, 1] - start[k, 1]
            norm = np.hypot(dx, dy)
            if norm > 0:
                e[k, 0], e[k, 1] = dx / norm, dy / norm
                headings[idx[k]] = np.arctan2(dy, dx)
    return e
