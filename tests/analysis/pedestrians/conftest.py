"""Shared by the tests of :mod:`analysis.pedestrians`: synthetic runs whose answers are known."""

from __future__ import annotations

import numpy as np
import xarray as xr

from meanfield.geometry.target import fraction_in_disk
from meanfield.scenarios.scenario import paper_scenario

N = 20
CELLS = 10


def run_dataset(x: np.ndarray, y: np.ndarray, times, *, center=(1.0, 1.0), radius=0.3) -> xr.Dataset:
    """A run dataset on the paper's unit square with the given human positions (time, human)."""
    times = np.asarray(times, dtype=float)
    pts = np.stack([x, y], axis=-1)
    frac = [fraction_in_disk(p, center, radius) for p in pts]
    c = (np.arange(CELLS) + 0.5) / CELLS
    dens = np.ones((times.size, CELLS, CELLS))  # unit mass on the unit square
    return xr.Dataset(
        {
            "human_x": (("time", "human"), x),
            "human_y": (("time", "human"), y),
            "fraction_in_target": ("time", np.asarray(frac)),
            "density": (("time", "x", "y"), dens),
        },
        coords={"time": times, "human": np.arange(x.shape[1]), "x": c, "y": c},
        attrs={
            "target_center_x": center[0],
            "target_center_y": center[1],
            "target_radius": radius,
            "backend": "point-mass",
            "seed": 0,
            "scenario_toml": paper_scenario().to_toml(),
        },
    )


def crowd_positions(ks, center=(1.0, 1.0), radius=0.3, seed=0):
    """Frame j: ks[j] humans well inside the target disk (∩ room), the others well outside."""
    rng = np.random.default_rng(seed)
    T = len(ks)
    x, y = np.empty((T, N)), np.empty((T, N))
    for j, k in enumerate(ks):
        got = 0
        while got < N:
            p = rng.uniform(0.02, 0.98, 2)
            d = np.hypot(*(p - center))
            inside = d < 0.9 * radius
            if (got < k and inside) or (got >= k and d > 1.1 * radius):
                x[j, got], y[j, got] = p
                got += 1
    return x, y
