"""Walking distances, compiled: the anchors of Dijkstra's trees, and the walk from a point to the one of its cells
nearest a target.

* :func:`tree_anchors`: each cell's nearest ancestor in sight on a tree, one pass over the cells (numpy twin: the
  pointer jumping of :mod:`meanfield.geometry.walking`);
* :func:`nearest_walk`: one pass over the active cells (numpy twin: the walks of
  :meth:`~meanfield.geometry.walking.WalkingDistances.walk_to` to the owned cells, then the nearest of those reached).

The caller is :class:`meanfield.geometry.walking.WalkingDistances`.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["nearest_walk", "tree_anchors"]


def _tree_anchors_numpy(pred, seen, out):
    own = np.broadcast_to(np.arange(pred.shape[1]), pred.shape)
    anchor = np.where(seen | (pred < 0), own, pred)
    while True:  # pointer jumping to the nearest ancestor in sight
        nxt = np.take_along_axis(anchor, anchor, axis=1)
        if np.array_equal(nxt, anchor):
            break
        anchor = nxt
    out[:] = anchor
    return out


@compiled(fallback=_tree_anchors_numpy)
def tree_anchors(pred, seen, out):
    """Each cell's anchor on each tree: the first cell of its path to the root, itself included, that is seen or
    has no predecessor (the root, or a cell the tree does not reach), module :mod:`meanfield.geometry.walking`.

    Each path is walked up once, to the first cell whose anchor is known, and every cell passed takes that anchor
    (integers: the pointer jumping's fixed point exactly).

    Parameters
    ----------
    pred : ndarray of int, shape (n, M)
        Each tree's predecessors (``< 0``: none).
    seen : ndarray of bool, shape (n, M)
        The cells seen from each tree's point.
    out : ndarray of int, shape (n, M)
        Out: the anchors.
    """
    n, m = pred.shape
    path = np.empty(m, np.intp)
    for r in range(n):
        for c in range(m):
            out[r, c] = -1
        for c in range(m):
            depth = 0
            x = c
            while out[r, x] < 0 and not (seen[r, x] or pred[r, x] < 0):
                path[depth] = x
                depth += 1
                x = pred[r, x]
            a = out[r, x] if out[r, x] >= 0 else x
            out[r, x] = a
            for k in range(depth):
                out[r, path[k]] = a
    return out


def _nearest_walk_numpy(xy, D, anchor, owner, robot, point, target, out):
    owned = np.flatnonzero(owner == robot)
    a = anchor[owned]
    to_anchor = xy[a] - point
    straight = np.hypot(to_anchor[:, 0], to_anchor[:, 1])
    with np.errstate(invalid="ignore"):  # inf − inf where no route reaches a cell
        distance = np.where(np.isfinite(D[owned]), straight + D[owned] - D[a], np.inf)
    leg = np.divide(to_anchor, straight[:, None], out=np.zeros_like(to_anchor), where=straight[:, None] > 0)
    reached = np.isfinite(distance)
    out[:] = np.inf, 0.0, 0.0
    if reached.any():
        mine = owned[reached]
        t = np.argmin(np.hypot(xy[mine, 0] - target[0], xy[mine, 1] - target[1]))
        out[0] = distance[reached][t]
        out[1:] = leg[reached][t]
    return out


@compiled(fallback=_nearest_walk_numpy)
def nearest_walk(xy, D, anchor, owner, robot, point, target, out):
    """The walk from ``point`` to the cell nearest ``target`` (straight) among the cells ``c`` with
    ``owner[c] == robot`` that a route reaches: its length ``d(c) = |x_a − R| + D(c) − D(a)`` and unit first leg
    ``e(c)`` towards the anchor ``a = a(c)`` (0 on it), module :mod:`meanfield.geometry.walking`; ties: the first cell.

    Parameters
    ----------
    xy : ndarray, shape (M, 2)
        The active cells' centres.
    D : ndarray, shape (M,)
        Dijkstra's distances of the tree of ``point``'s start cell (``inf``: not reached).
    anchor : ndarray of int, shape (M,)
        The anchors of that tree.
    owner : ndarray of int, shape (M,)
        Each cell's robot.
    robot : int
        The robot whose cells are walked to.
    point, target : ndarray, shape (2,)
    out : ndarray, shape (3,)
        Out: ``d`` and ``e`` (``inf, 0, 0`` when no such cell is reached).
    """
    out[0] = np.inf
    out[1] = 0.0
    out[2] = 0.0
    best = np.inf
    found = False
    for c in range(xy.shape[0]):
        if owner[c] != robot or not math.isfinite(D[c]):
            continue
        a = anchor[c]
        tx = xy[a, 0] - point[0]
        ty = xy[a, 1] - point[1]
        straight = math.hypot(tx, ty)
        distance = straight + D[c] - D[a]
        if not math.isfinite(distance):
            continue
        near = math.hypot(xy[c, 0] - target[0], xy[c, 1] - target[1])
        if not found or near < best:
            found = True
            best = near
            out[0] = distance
            if straight > 0:
                out[1] = tx / straight
                out[2] = ty / straight
            else:
                out[1] = 0.0
                out[2] = 0.0
    return out
