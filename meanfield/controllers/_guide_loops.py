"""The guide's coverage of its shares, compiled: each cell's robot within its exit's share and the robots' moments.

:func:`share_moments` is one pass over the covered cells, paired with its numpy twin (per share, the nearest robot
that sees each cell as :func:`meanfield.controllers._coverage_loops.owners`' twin finds it, and three ``np.bincount``:
the guide's code before); the caller is :meth:`meanfield.controllers.guide.GuideController.pulls`.
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["share_moments"]


def _share_moments_numpy(xy, robots, team, share, w, seen, cells, hidden, owner, mass, px, py):
    owner[:] = -1
    mass[:] = px[:] = py[:] = 0.0
    for k in np.unique(team[team >= 0]):
        mine = np.flatnonzero(team == k)
        here = np.flatnonzero(share == k)
        if not len(here):
            continue
        d2 = (xy[None, here, 0] - robots[mine, 0, None]) ** 2 + (xy[None, here, 1] - robots[mine, 1, None]) ** 2
        local = np.argmin(d2, axis=0)
        if hidden:
            sees = seen[mine][:, cells[here]]
            local = np.where(sees.any(axis=0), np.argmin(np.where(sees, d2, np.inf), axis=0), local)
        owner[here] = mine[local]
        mass[mine] = np.bincount(local, weights=w[here], minlength=len(mine))
        px[mine] = np.bincount(local, weights=w[here] * xy[here, 0], minlength=len(mine))
        py[mine] = np.bincount(local, weights=w[here] * xy[here, 1], minlength=len(mine))
    return owner, mass, px, py


@compiled(fallback=_share_moments_numpy)
def share_moments(xy, robots, team, share, w, seen, cells, hidden, owner, mass, px, py):
    """Each covered cell's robot, the nearest that sees it among the robots of the cell's share (when ``hidden``; the
    nearest of them when none does, or without walls), and each robot's weight and first moments over its cells:
    ``m_i = Σ w_c``, ``p_i = Σ w_c x_c`` (Lloyd's centroid ``p_i / m_i``, module
    :mod:`meanfield.controllers.guide`).

    The sums run over the cells in order, as ``np.bincount`` adds them; ties go to the robot listed first (as
    :func:`~meanfield.controllers._coverage_loops.owners`).

    Parameters
    ----------
    xy : ndarray, shape (M, 2)
        The covered cells' centres.
    robots : ndarray, shape (n, 2)
    team : ndarray of int, shape (n,)
        Each robot's share (``-1``: none).
    share : ndarray of int, shape (M,)
        Each cell's share (``-1``: none).
    w : ndarray, shape (M,)
        Each cell's weight times its area.
    seen : ndarray of bool, shape (n, K)
        Which cells of the grid (flat) each robot sees (read when ``hidden``).
    cells : ndarray of int, shape (M,)
        Each covered cell's column in ``seen``.
    hidden : bool
        Whether a wall may hide a cell from a robot.
    owner : ndarray of int, shape (M,)
        Out: each cell's robot (``-1``: its share has none).
    mass, px, py : ndarray, shape (n,)
        Out: ``m_i`` and the two components of ``p_i`` (0 for a robot without cells).
    """
    n = robots.shape[0]
    for i in range(n):
        mass[i] = 0.0
        px[i] = 0.0
        py[i] = 0.0
    for c in range(xy.shape[0]):
        k = share[c]
        best = best_seen = np.inf
        first = near = near_seen = -1
        if k >= 0:
            for i in range(n):
                if team[i] != k:
                    continue
                if first < 0:
                    first = i
                dx = xy[c, 0] - robots[i, 0]
                dy = xy[c, 1] - robots[i, 1]
                d2 = dx * dx + dy * dy
                if d2 < best:
                    best = d2
                    near = i
                if hidden and d2 < best_seen and seen[i, cells[c]]:
                    best_seen = d2
                    near_seen = i
        if near < 0:  # (no robot nearer than inf: the share's first, as owners)
            near = first
        if near_seen >= 0:
            near = near_seen
        owner[c] = near
        if near >= 0:
            mass[near] += w[c]
            px[near] += w[c] * xy[c, 0]
            py[near] += w[c] * xy[c, 1]
    return owner, mass, px, py
