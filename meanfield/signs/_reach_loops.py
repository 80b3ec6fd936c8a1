"""Where the signs reach, compiled: each robot's box of cells laid on the grid, with the cells of Ω it sees.

:func:`boxes_on_grid` is one pass over the robots' boxes and the grid, paired with its numpy twin; the caller is
:func:`meanfield.signs.kernels.reached_cells`.
"""

from __future__ import annotations

from meanfield._compiled.core import compiled

__all__ = ["boxes_on_grid"]


def _boxes_on_grid_numpy(inside, i0, j0, active, seen, hidden, out):
    n, bx, by = inside.shape
    out[:] = False
    for k in range(n):
        out[k, i0[k] : i0[k] + bx, j0[k] : j0[k] + by] = inside[k]
    out &= active
    if hidden:
        out &= seen
    return out


@compiled(fallback=_boxes_on_grid_numpy)
def boxes_on_grid(inside, i0, j0, active, seen, hidden, out):
    """``out[k]``: robot ``k``'s box ``inside[k]`` placed at cell ``(i0[k], j0[k])`` of the grid, False elsewhere, and
    only on the cells of Ω (``active``) that the robot sees (``seen[k]``, read when ``hidden``).

    Parameters
    ----------
    inside : ndarray of bool, shape (n, bx, by)
        The test within each robot's box of cells.
    i0, j0 : ndarray of int, shape (n,)
        Each box's first cell (the box lies inside the grid).
    active : ndarray of bool, shape (nx, ny)
    seen : ndarray of bool, shape (n, nx, ny)
        The cells each robot sees.
    hidden : bool
        Whether a wall may hide a cell from a robot.
    out : ndarray of bool, shape (n, nx, ny)
    """
    n, bx, by = inside.shape
    nx, ny = active.shape
    for k in range(n):
        for i in range(nx):
            for j in range(ny):
                out[k, i, j] = False
        for a in range(bx):
            i = i0[k] + a
            for b in range(by):
                j = j0[k] + b
                out[k, i, j] = inside[k, a, b] and active[i, j] and (not hidden or seen[k, i, j])
    return out
