"""The Wasserstein distance W₂ between the agents and a grid density (the summary's ``w2_to_target``)."""

from __future__ import annotations

import math

import numpy as np

from meanfield.geometry.grid import Grid

__all__ = ["wasserstein2_to_grid_density", "w2_block_size"]


def wasserstein2_to_grid_density(
    points: np.ndarray,
    grid: Grid,
    density: np.ndarray,
    max_points: int = 2000,
    seed: int = 0,
    max_cells: int = 1024,
) -> float:
    """Exact W₂ between the empirical measure of ``points`` and ``density`` on the cells.

    Solved as a transport linear program with POT's network simplex (``ot.emd2``), whose
    cost grows with points × cells: crowds larger than ``max_points`` are subsampled
    (deterministically from ``seed``), and grids with more than ``max_cells`` cells are
    coarsened into ``b × b`` blocks, each block's mass at its centre of mass.  The
    coarsening moves no mass farther than a block's diagonal ``b·√(dx² + dy²)``, so it
    changes W₂ by at most that (:func:`w2_block_size` gives ``b``).
    """
    import ot
    from scipy.spatial.distance import cdist

    if len(points) > max_points:
        idx = np.random.default_rng(seed).choice(len(points), max_points, replace=False)
        points = points[idx]
    X, Y = grid.centers
    w = density * grid.volume
    b = w2_block_size(grid, max_cells)
    if b > 1:
        nx, ny = grid.shape
        px, py = -nx % b, -ny % b

        def blocks(a: np.ndarray) -> np.ndarray:
            a = np.pad(a, ((0, px), (0, py)))
            return a.reshape((nx + px) // b, b, (ny + py) // b, b).sum(axis=(1, 3))

        mass = blocks(w)
        with np.errstate(invalid="ignore", divide="ignore"):
            X, Y = blocks(w * X) / mass, blocks(w * Y) / mass
        w = mass
    w = w.ravel()
    keep = w > 1e-12 * w.max()
    cells = np.column_stack([X.ravel()[keep], Y.ravel()[keep]])
    weights = w[keep] / w[keep].sum()
    a = np.full(len(points), 1.0 / len(points))
    # the cells as the sources: the same linear program, which POT's network simplex solves
    # several times faster this way round (12 against 49 ms for 200 humans on 30² cells)
    M = cdist(cells, points, "sqeuclidean")  # (ot.dist's |x|² + |y|² - 2x·y: 11× slower, and cancels)
    return float(math.sqrt(max(ot.emd2(weights, a, M, numItermax=1_000_000), 0.0)))


def w2_block_size(grid: Grid, max_cells: int = 1024) -> int:
    """Side ``b`` of the cell blocks :func:`wasserstein2_to_grid_density` merges (1: none)."""
    nx, ny = grid.shape
    return max(1, math.ceil(math.sqrt(nx * ny / max_cells)))
