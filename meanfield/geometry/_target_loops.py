"""How many humans are in the target disk, compiled (the fraction in the target).

:func:`count_in_disk` is one pass over the humans, in chunks on numba's threads, paired with its numpy twin.
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, prange

__all__ = ["count_in_disk"]


def _count_in_disk_numpy(points, cx, cy, radius):
    dx = points[:, 0] - cx
    dy = points[:, 1] - cy
    return int(np.count_nonzero(dx * dx + dy * dy <= radius * radius))


@compiled(fallback=_count_in_disk_numpy, parallel_over="points")
def count_in_disk(points, cx, cy, radius):
    """How many of ``points`` (N, 2) lie within ``radius`` of ``(cx, cy)`` (NaN rows: none).

    Chunks of :data:`~meanfield._compiled.core.PARALLEL_CHUNK` points are counted on numba's threads,
    each into its own slot, and the counts added (integers: the same on any number of threads).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    cx, cy, radius : float
    """
    r2 = radius * radius
    n = points.shape[0]
    chunks = (n + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK
    counts = empty_array(chunks, np.int64)  # (each chunk writes its slot)
    for c in prange(chunks):
        count = 0
        for j in range(c * PARALLEL_CHUNK, n if n < (c + 1) * PARALLEL_CHUNK else (c + 1) * PARALLEL_CHUNK):
            dx = points[j, 0] - cx
            dy = points[j, 1] - cy
            if dx * dx + dy * dy <= r2:
                count += 1
        counts[c] = count
    total = 0
    for c in range(chunks):
        total += counts[c]
    return total
