"""Target density and evacuation metrics.

* :func:`gaussian_target` — the paper's "narrow Gaussian" ρ_* on the grid, unit mass in Ω.
* :func:`target_region_radius` — the *target region*: the smallest disk around the
  target's centre holding 95 % of ρ_*'s mass inside Ω (perfect convergence therefore
  puts about 95 % of the humans in it).
* :func:`fraction_in_disk`, :func:`wasserstein2_to_grid_density`.
* :func:`max_body_overlap` — how deep the bodies of a pedestrian crowd interpenetrate.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield.crowd_loops import count_in_disk
from meanfield.domain import Domain
from meanfield.grid import Grid

__all__ = [
    "gaussian_target",
    "target_region_radius",
    "fraction_in_disk",
    "fit_slope",
    "wasserstein2_to_grid_density",
    "w2_block_size",
    "max_body_overlap",
]


def gaussian_target(grid: Grid, center: tuple[float, float], std: float) -> np.ndarray:
    """``ρ_*(x) ∝ exp(-|x - center|²/(2 std²))`` on the cell centres, zero outside Ω, unit mass."""
    X, Y = grid.centers
    r = np.exp(-((X - center[0]) ** 2 + (Y - center[1]) ** 2) / (2.0 * std * std))
    return grid.normalize(r)


def target_region_radius(
    domain: Domain, center: tuple[float, float], std: float, mass: float = 0.95, samples: int = 800
) -> float:
    """Smallest ``r`` with ``∫_{Ω ∩ B(center, r)} ρ_* >= mass`` (ρ_* normalised in Ω).

    Evaluated on a ``samples × samples`` midpoint lattice over Ω's bounding box
    (radius resolution about ``diam / samples``).
    """
    x0, x1, y0, y1 = domain.bounds
    xs = x0 + (np.arange(samples) + 0.5) * (x1 - x0) / samples
    ys = y0 + (np.arange(samples) + 0.5) * (y1 - y0) / samples
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    w = np.exp(-((X - center[0]) ** 2 + (Y - center[1]) ** 2) / (2.0 * std * std))
    w = np.where(domain.contains(X, Y), w, 0.0).ravel()
    d = np.hypot(X - center[0], Y - center[1]).ravel()
    order = np.argsort(d, kind="stable")
    cum = np.cumsum(w[order])
    k = int(np.searchsorted(cum, mass * cum[-1]))
    return float(d[order][min(k, len(d) - 1)])


def fraction_in_disk(points: np.ndarray, center: tuple[float, float], radius: float) -> float:
    """Fraction of ``points`` (N, 2) within ``radius`` of ``center`` (one compiled pass for float points)."""
    points = np.asarray(points)
    if points.dtype != float:
        return float(count_in_disk.fallback(points, center[0], center[1], radius)) / len(points)
    return float(count_in_disk(points, float(center[0]), float(center[1]), float(radius))) / len(points)


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


def max_body_overlap(x: np.ndarray, y: np.ndarray, radius: float) -> tuple[float, int]:
    """Deepest interpenetration of disks of ``radius`` over recorded frames.

    Parameters
    ----------
    x, y : ndarray, shape (T, N) or (N,)
        Positions of the N humans at T frames (e.g. a run's ``human_x``, ``human_y``).
    radius : float
        Body radius.

    Returns
    -------
    overlap : float
        ``max(0, 2 radius − |x_i − x_j|)`` over all pairs and frames (same unit as x).
    frame : int
        The frame where it occurs (-1 when no two bodies touch).
    """
    from scipy.spatial import cKDTree

    x = np.atleast_2d(np.asarray(x, float))
    y = np.atleast_2d(np.asarray(y, float))
    worst, where = 0.0, -1
    for k in range(x.shape[0]):
        pts = np.column_stack([x[k], y[k]])
        pairs = cKDTree(pts).query_pairs(2.0 * radius, output_type="ndarray")
        if len(pairs):
            d = np.hypot(*(pts[pairs[:, 0]] - pts[pairs[:, 1]]).T)
            depth = float(2.0 * radius - d.min())
            if depth > worst:
                worst, where = depth, k
    return worst, where


def fit_slope(n: np.ndarray, err: np.ndarray) -> float:
    """Least-squares slope of ``log err`` against ``log n`` (NaN with fewer than two points)."""
    n = np.asarray(n, float)
    err = np.asarray(err, float)
    if len(n) < 2:
        return math.nan
    return float(np.polyfit(np.log(n), np.log(err), 1)[0])
