"""Figures of the analysis: the Poincaré mode, the robot count, the cost of speed limits."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps

from analysis.limits import LimitsStudy
from analysis.poincare import NOT_CONVEX
from analysis.robot_count import RobotCountStudy
from analysis.robot_count_sweep import RobotCountSweep
from meanfield.geometry.domain import Domain
from meanfield.geometry.grid import Grid
from meanfield.io.atomic import subplots

__all__ = ["plot_poincare_mode", "plot_robot_count", "plot_robot_count_sweep", "plot_limits", "save_figure"]


def save_figure(fig: Any, path: Path) -> Path:
    """Save a figure atomically as PNG and close it (:func:`meanfield.io.atomic.save_figure` at 130 dpi, tight)."""
    from meanfield.io import atomic as io

    return io.save_figure(fig, path, dpi=130, bbox_inches="tight", format="png")


def plot_poincare_mode(
    domain: Domain, grid: Grid, mode: np.ndarray, mu2: float, bound: float | None, exact: float | None
):
    """The eigenfunction of μ₂ on Ω (the slowest mean-zero density error under Step I).

    ``bound`` is the Payne–Weinberger bound, ``None`` when Ω is not convex: the figure then
    says it is not applicable (``docs/poincare.md``, *Floor plans*).
    """
    fig, ax = subplots(figsize=(4.8, 4.2))
    x0, x1, y0, y1 = domain.bounds
    m = np.ma.masked_invalid(mode)
    lim = float(np.nanmax(np.abs(mode)))
    im = ax.imshow(m.T, origin="lower", extent=(x0, x1, y0, y1), cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(im, ax=ax, shrink=0.8)
    pw = f"π²/d² = {bound:.4g}" if bound is not None else NOT_CONVEX
    text = f"μ₂ = {mu2:.5g} (grid {grid.cells[0]}×{grid.cells[1]})\nPayne–Weinberger {pw}"
    if exact is not None:
        text += f"\nexact {exact:.6g}, rel. error {abs(mu2 - exact) / exact:.1e}"
    ax.set_title("Slowest Neumann mode of Ω", fontsize=10)
    ax.text(
        0.02,
        0.02,
        text,
        transform=ax.transAxes,
        fontsize=7.5,
        va="bottom",
        bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
    )
    ax.set_aspect("equal")
    return fig


def plot_robot_count(study: RobotCountStudy, coverage: dict[float, int], c: float):
    """Closed-loop success over robot counts, with the coverage estimates ``n(ε)`` marked."""
    fig, ax = subplots(figsize=(6.4, 4.0))
    counts = study.counts
    for n in counts:
        ax.scatter([n] * len(study.values[n]), study.values[n], s=12, color="0.6", zorder=2)
    med = study.medians()
    ax.plot(counts, [med[n] for n in counts], "o-", color="C0", label=f"median over seeds {study.seeds}", zorder=3)
    ax.axhline(study.threshold, color="C3", lw=0.8, ls=":", label=f"success: median ≥ {study.threshold:g}")
    for k, (eps, n) in enumerate(sorted(coverage.items(), reverse=True)):
        ax.axvline(n, color=f"C{k + 1}", ls="--", lw=1.0, label=f"coverage, ε = {eps / c:.2g}·c: n = {n}")
    if study.minimum is not None:
        ax.annotate(
            f"empirical minimum n = {study.minimum}",
            (study.minimum, med[study.minimum]),
            xytext=(10, -30),
            textcoords="offset points",
            arrowprops={"arrowstyle": "->"},
            fontsize=8,
        )
    ax.set_xlabel("robots n")
    ax.set_ylabel(study.metric.replace("_", " "))
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("Robot count: coverage estimate against closed-loop runs", fontsize=10)
    return fig


def _edges(values: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted centres (geometric midpoints on a log axis)."""
    v = np.log(values) if log else np.asarray(values, float)
    if len(v) == 1:
        e = np.array([v[0] - 0.5, v[0] + 0.5]) if not log else np.array([v[0] - 0.35, v[0] + 0.35])
    else:
        mid = 0.5 * (v[1:] + v[:-1])
        e = np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])
    return np.exp(e) if log else e


def plot_robot_count_sweep(study: RobotCountSweep):
    """Median fraction in target and median time to 90 % over robot count × kernel range η,
    with the coverage estimates ``n_cov(η)`` drawn over them (:mod:`analysis.robot_count_sweep`).

    Cells where half the seeds or more never reached 90 % are grey and read "never";
    white circles mark the smallest count whose median fraction meets the threshold.
    """
    from matplotlib.colors import ListedColormap

    counts = np.array(study.counts)
    etas = np.array(study.etas)
    ci, ei = np.argsort(counts), np.argsort(etas)
    counts, etas = counts[ci], etas[ei]
    frac = study.fraction[np.ix_(ci, ei)]
    t90 = study.time_to_90[np.ix_(ci, ei)]
    xe, ye = _edges(etas, log=True), _edges(counts, log=False)
    fig, axes = subplots(1, 2, figsize=(12.0, 4.6), constrained_layout=True)
    panels = (
        (axes[0], frac, "viridis", (0.0, 1.0), "median fraction in target at t_final"),
        (axes[1], np.where(np.isinf(t90), np.nan, t90), "magma_r", (0.0, study.t_final), "median time to 90 % (s)"),
    )
    for ax, values, cmap, (lo, hi), label in panels:
        ax.set_facecolor("0.85")
        if ax is axes[1]:
            never = np.where(np.isinf(t90), 1.0, np.nan)
            ax.pcolormesh(xe, ye, never, cmap=ListedColormap(["0.75"]), shading="flat")
        mesh = ax.pcolormesh(xe, ye, values, cmap=cmap, vmin=lo, vmax=hi, shading="flat")
        fig.colorbar(mesh, ax=ax, label=label)
        for i, n in enumerate(counts):
            for j, eta in enumerate(etas):
                v = frac[i, j] if ax is axes[0] else t90[i, j]
                text = "never" if np.isinf(v) else ("" if np.isnan(v) else f"{v:.2f}" if ax is axes[0] else f"{v:.0f}")
                ax.text(
                    eta,
                    n,
                    text,
                    ha="center",
                    va="center",
                    fontsize=6.5,
                    color="w"
                    if (ax is axes[0] and v < 0.6) or (ax is axes[1] and np.isfinite(v) and v > 0.6 * hi)
                    else "k",
                )
        styles = ("-", "--", ":")
        for k, (f, ns) in enumerate(sorted(study.coverage.items(), reverse=True)):
            n_cov = np.array(ns)[ei]
            ax.plot(
                etas,
                np.minimum(n_cov, ye[-1]),
                styles[k % 3],
                color="C3",
                lw=1.4,
                marker="^",
                ms=4,
                label=f"coverage estimate, ε = {f:g}·c",
            )
        best = [(eta, study.minimum[float(eta)]) for eta in etas if study.minimum.get(float(eta)) is not None]
        if best:
            ax.plot(
                *zip(*best, strict=True),
                "o",
                mfc="none",
                mec="w",
                ms=11,
                mew=1.6,
                label=f"smallest n with median ≥ {study.threshold:g}",
            )
        ax.set_xscale("log")
        ax.set_xticks(etas)
        ax.set_xticklabels([f"{e:g}" for e in etas])
        ax.minorticks_off()
        ax.set_yticks(counts)
        ax.set_xlim(xe[0], xe[-1])
        ax.set_ylim(ye[0], ye[-1])
        ax.set_xlabel("kernel range η")
        ax.set_ylabel("robots n")
    handles, labels = axes[0].get_legend_handles_labels()
    from matplotlib.lines import Line2D

    # the white circles would not show on the white legend: a black-edged stand-in
    handles = [
        Line2D([], [], marker="o", mfc="none", mec="k", ls="none", ms=9) if lab.startswith("smallest") else h
        for h, lab in zip(handles, labels, strict=True)
    ]
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.suptitle(
        f"Robot count × kernel range: medians over {len(study.seeds)} seeds (coverage estimates beyond the "
        "top row are drawn at its edge)",
        fontsize=10,
    )
    return fig


def plot_limits(study: LimitsStudy):
    """How often the speed limits bind and what they cost: error curves, the part of ``A`` the
    applied inputs leave uncancelled (the ISS input), the final fraction against ``u_max``."""
    fig, axes = subplots(1, 3, figsize=(14, 4.0))
    settings = study.settings()
    limits = sorted({u for _, u in settings})
    colors = {u: colormaps["viridis"](k / max(len(limits) - 1, 1)) for k, u in enumerate(limits)}
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
    axes[0].set_xlabel("t (scenario time unit)")
    axes[0].set_ylabel("‖ρ̂ − ρ_*‖ (median over seeds)")
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel("t (scenario time unit)")
    axes[1].set_ylabel("applied shortfall: A not cancelled (median)")
    axes[1].set_yscale("symlog", linthresh=1e-2)
    axes[1].axhline(0.0, color="k", lw=0.6)
    binding = ", ".join(f"{s} {u:g}: {study.median(s, u, 'limits_binding_fraction'):.0%}" for s, u in settings)
    axes[1].set_title("steps with a robot at a limit (median): " + binding, fontsize=6.5, wrap=True)
    for strategy in dict.fromkeys(s for s, _ in settings):
        us = [u for s, u in settings if s == strategy]
        axes[2].plot(
            us,
            [study.median(strategy, u, "fraction_in_target") for u in us],
            "o" + styles[strategy],
            color="k",
            label=f"{strategy} (median)",
        )
        for r in study.runs:
            if r.strategy == strategy:
                axes[2].scatter(
                    r.u_max * (1.03 if strategy == "bounded" else 0.97),
                    r.summary["fraction_in_target"],
                    s=9,
                    color="0.6",
                )
    axes[2].set_xscale("log")
    axes[2].set_xticks(limits, [f"{u:g}" for u in limits])
    axes[2].minorticks_off()
    axes[2].set_xlabel("speed limit u_max")
    axes[2].set_ylabel("final fraction in target")
    axes[2].legend(fontsize=7)
    fig.suptitle(
        f"Speed limits on the {study.scenario_name} scenario ({study.robots} robots): "
        "dashed = min-norm clipped, solid = bounded program",
        fontsize=10,
    )
    fig.tight_layout()
    return fig
