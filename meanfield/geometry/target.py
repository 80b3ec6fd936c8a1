"""The target: the density ρ* the crowd should take, and how much of the crowd is in it.

:func:`gaussian_target` is the paper's narrow Gaussian ρ* on the grid; :func:`target_region_radius`
the radius of the disk that holds 95 % of it; :func:`fraction_in_disk` the fraction of humans in a disk
(one compiled pass, :mod:`meanfield.geometry._target_loops`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.geometry._target_loops import count_in_disk
from meanfield.geometry.grid import Grid, exact_key, remember
from meanfield.geometry.region import Region

__all__ = ["gaussian_target", "target_region_radius", "fraction_in_disk"]


def gaussian_target(grid: Grid, center: tuple[float, float], std: float) -> np.ndarray:
    """``ρ_*(x) ∝ exp(-|x - center|²/(2 std²))`` on the cell centres, zero outside Ω, unit mass."""
    X, Y = grid.centers
    r = np.exp(-((X - center[0]) ** 2 + (Y - center[1]) ** 2) / (2.0 * std * std))
    if not np.any(np.where(grid.active, r, 0.0) > 0):  # narrower than the cells: nothing on their centres
        from meanfield.errors import ParameterError

        h = max(grid.dx, grid.dy)
        raise ParameterError(
            "target.std",
            std,
            f"a width the grid resolves (about a cell, {h:.3g}, or more): ρ* vanishes at every cell centre",
        )
    return grid.normalize(r)


def target_region_radius(
    domain: Region, center: tuple[float, float], std: float, mass: float = 0.95, samples: int = 800
) -> float:
    """Smallest ``r`` with ``∫_{Ω ∩ B(center, r)} ρ_* >= mass`` (ρ_* normalised in Ω).

    Evaluated on a ``samples × samples`` midpoint lattice over Ω's bounding box
    (radius resolution about ``diam / samples``).  Remembered for the last few regions: a study that runs one
    plan over many seeds draws the lattice once per process (the region is frozen; equal regions, equal radii).
    """
    args = ((float(center[0]), float(center[1])), float(std), float(mass), int(samples))
    key = exact_key(domain)
    if key is None:  # (a region that cannot say exactly what it is: drawn each time)
        return _radius(domain, *args)
    return remember(_RADII, (key, *args), lambda: _radius(domain, *args))


_RADII: dict[Any, float] = {}
""":func:`target_region_radius` of the last :data:`~meanfield.geometry.grid.REMEMBERED` regions and targets
(:func:`~meanfield.geometry.grid.remember`)."""


def _radius(domain: Region, center: tuple[float, float], std: float, mass: float, samples: int) -> float:
    """:func:`target_region_radius`, drawn."""
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
