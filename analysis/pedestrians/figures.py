"""The figures of :func:`analysis.pedestrians.metrics.pedestrian_metrics`: N(t) and density maps.

:func:`plot_pedestrian_figures` draws a measured run (a
:class:`~analysis.pedestrians.metrics.PedestrianMetrics`): the fraction of humans in the
target region, PedPy's against the toolkit's, and the density maps side by side
(``docs/pedestrians.md``).  Every figure is written by the toolkit's one figure writer,
:func:`meanfield.io.atomic.save_figure`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.patches import Circle

from meanfield.io.atomic import subplots

__all__ = ["plot_pedestrian_figures"]


def plot_pedestrian_figures(
    metrics: Any, out_dir: str | Path, *, prefix: str = "", dpi: float = 90
) -> dict[str, Path]:
    """Draw the two figures of a measured run (a :class:`~analysis.pedestrians.metrics.PedestrianMetrics`,
    which calls this; hence no import of it here); return their paths.

    - ``{prefix}n_in_target.png``: ``N(t)/N`` from PedPy beside the toolkit's
      ``fraction_in_target``, and their difference in humans, the density window shaded;
    - ``{prefix}density_map.png``: PedPy's classic (and Voronoi) density maps beside the
      toolkit's KDE density ``N · ρ̂``, mean over the window, on one colour scale (square
      root), the target region dashed.

    Drawn without pyplot (the user's backend untouched) and written by :func:`meanfield.io.atomic.save_figure`
    (atomically; the figure is closed).
    """
    from matplotlib.colors import PowerNorm

    from meanfield.io.atomic import save_figure

    out = Path(out_dir)
    label = f"{metrics.scenario} ({metrics.backend}, seed {metrics.seed})"
    paths: dict[str, Path] = {}

    fig, (a0, a1) = subplots(
        2, 1, figsize=(6.4, 4.6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}, constrained_layout=True
    )
    t = metrics.times
    a0.plot(t, metrics.fraction_pedpy, "-", color="C0", lw=1.6, label="PedPy: N(t)/N (classic density × area)")
    a0.plot(t, metrics.fraction_toolkit, ":", color="C3", lw=1.8, label="toolkit: fraction_in_target")
    a0.axvspan(*metrics.window, color="0.85", lw=0, label="density-map window")
    a0.set_ylim(-0.02, 1.02)
    a0.set_ylabel("fraction in target region")
    a0.legend(fontsize=7.5, loc="lower right")
    a0.set_title(f"Humans in the target region: {label}", fontsize=9.5)
    a1.step(t, metrics.count_difference, where="mid", color="k", lw=1)
    a1.set_ylabel("toolkit − PedPy\n(humans)", fontsize=8)
    a1.set_xlabel("time")
    if metrics.max_fraction_difference == 0:
        note = "identical on every frame"
    else:
        note = f"max |difference| = {metrics.max_fraction_difference:.3g} of N" + (
            " (all humans between the polygonised disk and the circle, or on a wall)"
            if metrics.differences_explained
            else " (NOT explained by the disk polygonisation)"
        )
    a1.text(
        0.01,
        0.9,
        note,
        transform=a1.transAxes,
        fontsize=7.5,
        va="top",
    )
    paths["n_in_target"] = save_figure(fig, out / f"{prefix}n_in_target.png", dpi=dpi, bbox_inches="tight")

    panels = [("PedPy classic", metrics.density_classic)]
    if metrics.density_voronoi is not None:
        panels.append((f"PedPy Voronoi ({len(metrics.voronoi_frames)} frames)", metrics.density_voronoi))
    panels.append(("toolkit KDE, N·ρ̂", metrics.density_toolkit))
    vmax = max(float(np.max(p)) for _, p in panels) or 1.0
    norm = PowerNorm(gamma=0.5, vmin=0.0, vmax=vmax)
    fig, axes = subplots(1, len(panels), figsize=(3.3 * len(panels) + 0.8, 3.5), constrained_layout=True)
    x0, x1, y0, y1 = metrics.room_bounds
    im = None
    for ax, (title, dens) in zip(axes, panels, strict=True):
        im = ax.pcolormesh(metrics.x_edges, metrics.y_edges, dens.T, cmap="viridis", norm=norm, shading="flat")
        ax.add_patch(
            Circle(metrics.target_center, metrics.target_radius, fill=False, ec="w", ls="--", lw=1)
        )
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        ax.tick_params(labelsize=7)
    fig.colorbar(im, ax=axes, shrink=0.85, label="humans per unit area")
    w0, w1 = metrics.window
    fig.suptitle(f"Mean density over t ∈ [{w0:g}, {w1:g}]: {label}", fontsize=9.5)
    paths["density_map"] = save_figure(fig, out / f"{prefix}density_map.png", dpi=dpi, bbox_inches="tight")
    return paths
