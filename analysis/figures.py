"""Figures of the analysis: the Poincaré mode, the robot count, the cost of speed limits."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from analysis.limits import LimitsStudy
from analysis.robot_count import RobotCountStudy
from meanfield.domain import Domain
from meanfield.grid import Grid

__all__ = ["plot_poincare_mode", "plot_robot_count", "plot_limits", "save_figure"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, path: Path) -> Path:
    """Save a figure atomically as PNG and close it."""
    from meanfield.io import atomic_write_with

    plt = _pyplot()
    atomic_write_with(Path(path), lambda p: fig.savefig(p, dpi=130, bbox_inches="tight", format="png"))
    plt.close(fig)
    return Path(path)


def plot_poincare_mode(domain: Domain, grid: Grid, mode: np.ndarray, mu2: float, bound: float, exact: float | None):
    """The eigenfunction of μ₂ on Ω (the slowest mean-zero density error under Step I)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 4.2))
    x0, x1, y0, y1 = domain.bounds
    m = np.ma.masked_invalid(mode)
    lim = float(np.nanmax(np.abs(mode)))
    im = ax.imshow(m.T, origin="lower", extent=(x0, x1, y0, y1), cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(im, ax=ax, shrink=0.8)
    text = f"μ₂ = {mu2:.5g} (grid {grid.cells[0]}×{grid.cells[1]})\nPayne–Weinberger π²/d² = {bound:.4g}"
    if exact is not None:
        text += f"\nexact {exact:.6g}, rel. error {abs(mu2 - exact) / exact:.1e}"
    ax.set_title("Slowest Neumann mode of Ω", fontsize=10)
    ax.text(0.02, 0.02, text, transform=ax.transAxes, fontsize=7.5, va="bottom",
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
    ax.set_aspect("equal")
    return fig


def plot_robot_count(study: RobotCountStudy, coverage: dict[float, int], c: float):
    """Closed-loop success over robot counts, with the coverage estimates ``n(ε)`` marked."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    counts = study.counts
    for n in counts:
        ax.scatter([n] * len(study.values[n]), study.values[n], s=12, color="0.6", zorder=2)
    med = study.medians()
    ax.plot(counts, [med[n] for n in counts], "o-", color="C0", label=f"median over seeds {study.seeds}", zorder=3)
    ax.axhline(study.threshold, color="C3", lw=0.8, ls=":", label=f"success: median ≥ {study.threshold:g}")
    for k, (eps, n) in enumerate(sorted(coverage.items(), reverse=True)):
        ax.axvline(n, color=f"C{k + 1}", ls="--", lw=1.0, label=f"coverage, ε = {eps / c:.2g}·c: n = {n}")
    if study.minimum is not None:
        ax.annotate(f"empirical minimum n = {study.minimum}", (study.minimum, med[study.minimum]),
                    xytext=(10, -30), textcoords="offset points", arrowprops={"arrowstyle": "->"}, fontsize=8)
    ax.set_xlabel("robots n")
    ax.set_ylabel(study.metric.replace("_", " "))
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("Robot count: coverage estimate against closed-loop runs", fontsize=10)
    return fig


def plot_limits(study: LimitsStudy):
    """How often the speed limits bind and what they cost: error curves, the part of ``A`` the
    applied inputs leave uncancelled (the ISS input), the final fraction against ``u_max``."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.0))
    settings = study.settings()
    limits = sorted({u for _, u in settings})
    colors = {u: plt.cm.viridis(k / max(len(limits) - 1, 1)) for k, u in enumerate(limits)}
    styles = {"min-norm": "--", "bounded": "-"}
    for strategy, u in settings:
        runs = [r for r in study.runs if r.strategy == strategy and r.u_max == u]
        t = runs[0].time
        err = np.nanmedian(np.stack([r.rho_error for r in runs]), axis=0)
        axes[0].plot(t, err, styles[strategy], color=colors[u], label=f"{strategy}, u_max = {u:g}")
        short = np.stack([r.shortfall_applied for r in runs])
        keep = np.isfinite(short).any(axis=0)  # frames where control was recorded (not the last one)
        axes[1].plot(t[keep], np.nanmedian(short[:, keep], axis=0), styles[strategy], color=colors[u])
    axes[0].set_yscale("log")
    axes[0].set_xlabel("t")
    axes[0].set_ylabel("‖ρ̂ − ρ_*‖ (median over seeds)")
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel("t")
    axes[1].set_ylabel("applied shortfall: A not cancelled (median)")
    axes[1].set_yscale("symlog", linthresh=1e-2)
    axes[1].axhline(0.0, color="k", lw=0.6)
    binding = ", ".join(
        f"{s} {u:g}: {study.median(s, u, 'limits_binding_fraction'):.0%}" for s, u in settings
    )
    axes[1].set_title("steps with a robot at a limit (median): " + binding, fontsize=6.5, wrap=True)
    for strategy in dict.fromkeys(s for s, _ in settings):
        us = [u for s, u in settings if s == strategy]
        axes[2].plot(us, [study.median(strategy, u, "fraction_in_target") for u in us], "o" + styles[strategy],
                     color="k", label=f"{strategy} (median)")
        for r in study.runs:
            if r.strategy == strategy:
                axes[2].scatter(r.u_max * (1.03 if strategy == "bounded" else 0.97),
                                r.summary["fraction_in_target"], s=9, color="0.6")
    axes[2].set_xscale("log")
    axes[2].set_xticks(limits, [f"{u:g}" for u in limits])
    axes[2].minorticks_off()
    axes[2].set_xlabel("speed limit u_max")
    axes[2].set_ylabel("final fraction in target")
    axes[2].legend(fontsize=7)
    fig.suptitle(f"Speed limits on the {study.scenario_name} scenario ({study.robots} robots): "
                 "dashed = min-norm clipped, solid = bounded program", fontsize=10)
    fig.tight_layout()
    return fig
