"""How many humans are in the target disk, compiled (the fraction in the target).

:func:`count_in_disk` is one pass over the humans, paired with its numpy twin.
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["count_in_disk"]


def _count_in_disk_numpy(points, cx, cy, radius):
    dx = points[:, 0] - cx
    dy = points[:, 1] - cy
    return int(np.count_nonzero(dx * dx + dy * dy <= radius * radius))


@compiled(fallback=_count_in_disk_numpy)
def count_in_disk(points, cx, cy, radius):
    """How many of ``points`` (N, 2) lie within ``radius`` of ``(cx, cy)`` (NaN rows: none).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    cx, cy, radius : float
    """
    r2 = radius * radius
    count = 0
    for j in range(points.shape[0]):
        dx = points[j, 0] - cx
        dy = points[j, 1] - cy
        if dx * dx + dy * dy <= r2:
            count += 1
    return count
