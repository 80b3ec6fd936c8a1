"""Coverage's cell owners, compiled: the nearest robot that sees each cell (Lloyd coverage).

:func:`owners` is one pass over the cells, paired with its numpy twin; the caller is
:mod:`meanfield.controllers.coverage`.
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["owners"]


def _owners_numpy(xy, robots, seen, cells, hidden, out):
    d2 = (xy[None, :, 0] - robots[:, 0, None]) ** 2 + (xy[None, :, 1] - robots[:, 1, None]) ** 2  # (n, M)
    if not hidden:
        out[:] = np.argmin(d2, axis=0)
        return out
    seen = seen[:, cells]
    nearest_seen = np.argmin(np.where(seen, d2, np.inf), axis=0)
    out[:] = np.where(seen.any(axis=0), nearest_seen, np.argmin(d2, axis=0))
    return out


@compiled(fallback=_owners_numpy)
def owners(xy, robots, seen, cells, hidden, out):
    """For each cell, the nearest robot that sees it (when ``hidden``), else the nearest robot; ties: the first.

    Robot by robot over all cells (the inner loop runs along the cells).

    Parameters
    ----------
    xy : ndarray, shape (M, 2)
        The cells' centres.
    robots : ndarray, shape (n, 2)
    seen : ndarray of bool, shape (n, K)
        Which cells of the grid (flat) each robot sees (read when ``hidden``).
    cells : ndarray of int, shape (M,)
        Each cell's column in ``seen``.
    hidden : bool
        Whether a wall may hide a cell from a robot.
    out : ndarray of int, shape (M,)
    """
    m = xy.shape[0]
    best, best_seen, k_seen = np.empty(m), np.empty(m), np.empty(m, np.intp)
    for c in range(m):
        best[c] = best_seen[c] = np.inf
        out[c] = 0
        k_seen[c] = -1
    for i in range(robots.shape[0]):
        rx, ry = robots[i, 0], robots[i, 1]
        for c in range(m):
            dx = xy[c, 0] - rx
            dy = xy[c, 1] - ry
            d2 = dx * dx + dy * dy
            if d2 < best[c]:
                best[c] = d2
                out[c] = i
            if hidden and d2 < best_seen[c] and seen[i, cells[c]]:
                best_seen[c] = d2
                k_seen[c] = i
    if hidden:
        for c in range(m):
            if k_seen[c] >= 0:
                out[c] = k_seen[c]
    return out
