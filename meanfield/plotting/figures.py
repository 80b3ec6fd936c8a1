"""Figures of a run, in the spirit of the paper's Figs. 2 and 3, and an animation.

* ``target_and_error.png`` — Fig. 2: target density ρ_*; convergence error ‖ρ̃‖, ‖ṽ‖, V₂
  and the fraction of humans in the target region over time.
* ``snapshots.png`` — Fig. 3: four instants; top row humans (red), robots (blue circles)
  and the arrows of v_r; bottom row the density estimates ρ̂.
* ``evacuation.png`` — with exits: the fraction of the crowd out over time, the times at
  which 95 % and everyone were out, and the lower bound on the evacuation time.
* ``animation.gif`` — the top row of Fig. 3 over the whole run (``--animate``).

In a floor plan the arrows of ``v_r`` are drawn inside Ω only, each robot's share hidden
behind walls (:mod:`meanfield.geometry.sight`), and every panel shows the walls and the exits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np  # noqa: E402
from matplotlib.patches import Circle

from meanfield.geometry.sight import SightLines  # noqa: E402
from meanfield.io.atomic import atomic_write_with, save_figure, subplots  # noqa: E402
from meanfield.signs.robots import navigation_velocity  # noqa: E402
from meanfield.simulation.result import SimulationResult  # noqa: E402

__all__ = ["plot_target_and_error", "plot_snapshots", "plot_evacuation", "save_run_figures", "save_animation"]


def _extent(ds):
    x, y = ds["x"].values, ds["y"].values
    dx, dy = x[1] - x[0], y[1] - y[0]
    return (x[0] - dx / 2, x[-1] + dx / 2, y[0] - dy / 2, y[-1] + dy / 2)


def _units(result: SimulationResult) -> dict[str, str]:
    """Axis-label units of the run's scenario: SI (densities in persons/m²), or the paper's
    dimensionless units (densities of unit mass, per room width²)."""
    if result.scenario.units == "SI":
        return {"length": "m", "time": "s", "density": "persons/m²"}
    return {"length": "room widths", "time": "time units", "density": "1/room width²"}


def _people(result: SimulationResult, k: int | None = None) -> float:
    """The factor from the recorded density to what the figures show: in SI the number of people it
    stands for (persons/m²: the crowd's N for the target; at frame ``k`` the people still inside,
    as the agents' estimate has unit mass over them and the Fokker–Planck density keeps the mass
    still inside), 1 in the paper's dimensionless units (a density of unit mass)."""
    if result.scenario.units != "SI":
        return 1.0
    n = float(result.scenario.crowd.n)
    ds = result.timeseries
    if k is None or "human_x" not in ds or "fraction_evacuated" not in ds:
        return n
    return n * (1.0 - float(ds["fraction_evacuated"].values[k]))


def _axes_labels(ax, u: dict[str, str]) -> None:
    ax.set_xlabel(f"x ({u['length']})")
    ax.set_ylabel(f"y ({u['length']})")


def plot_target_and_error(result: SimulationResult):
    """Fig. 2 of the paper: target density (left) and convergence error over time (right)."""
    ds = result.timeseries
    u = _units(result)
    fig, (a0, a1) = subplots(1, 2, figsize=(10.5, 4.4), constrained_layout=True)
    im = a0.imshow(ds["target_density"].values.T * _people(result), origin="lower", extent=_extent(ds), cmap="viridis")
    c = (ds.attrs["target_center_x"], ds.attrs["target_center_y"])
    a0.add_patch(Circle(c, ds.attrs["target_radius"], fill=False, ec="w", ls="--", lw=1))
    a0.set_title("target density ρ* (dashed: target region)")
    _axes_labels(a0, u)
    a0.set_xlim(_extent(ds)[:2])
    a0.set_ylim(_extent(ds)[2:])
    fig.colorbar(im, ax=a0, shrink=0.85, label=f"ρ* ({u['density']})")
    t = ds["time"].values
    a1.semilogy(t, ds["rho_error_l2"].values, label="‖ρ̃‖ (L²)")
    a1.semilogy(t, ds["v_error_l2"].values, label="‖ṽ‖ (L²)")
    a1.semilogy(t, ds["V2"].values, label="V₂ = ½‖ρ̃‖² + ½‖ṽ‖²")
    a1.set_xlabel(f"time ({u['time']})")
    a1.set_ylabel("convergence error (log scale)")
    a1.set_title("convergence error and evacuation")
    a2 = a1.twinx()
    a2.plot(t, ds["fraction_in_target"].values, "k:", label="fraction in target (right axis)")
    a2.set_ylim(0, 1)
    a2.set_ylabel("fraction of humans in target region")
    h1, l1 = a1.get_legend_handles_labels()
    h2, l2 = a2.get_legend_handles_labels()
    # below the axes: a legend inside would cover the curves, which cross the whole panel
    a1.legend(h1 + h2, l1 + l2, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2, fontsize=8, frameon=False)
    return fig


def _field_arrows(result: SimulationResult, k: int, m: int = 15):
    ds = result.timeseries
    loop_kernel = result_kernel(result)
    x0, x1, y0, y1 = _extent(ds)
    xs = np.linspace(x0, x1, m + 2)[1:-1]
    ys = np.linspace(y0, y1, m + 2)[1:-1]
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    domain = _region_at(result, float(ds["time"].values[k]))
    pts = pts[domain.contains(pts[:, 0], pts[:, 1])]
    R = np.column_stack([ds["robot_x"].values[k], ds["robot_y"].values[k]])
    visible = SightLines(domain).mask(R, pts)  # exact segments (None in a convex room)
    v = navigation_velocity(loop_kernel, R, ds["robot_heading"].values[k], pts, visible)
    return pts, v


def _region_at(result: SimulationResult, t: float):
    """Ω at time ``t``: the scenario's region, less the regions its ``block`` events had made wall by then."""
    from meanfield.geometry.blocking import blocked_region

    region = result.scenario.domain
    for event in result.scenario.events:
        if event.block is not None and event.time <= t + 1e-9:
            region = blocked_region(region, event.block)
    return region


def result_kernel(result: SimulationResult):
    """The run's navigation kernel (the scenario's Gaussian unless overridden in Python)."""
    from meanfield.signs.kernels import GaussianKernel

    if result.kernel is not None:
        return result.kernel
    k = result.scenario.kernel
    return GaussianKernel(k.c, k.eta)


def _draw_crowd(ax, result: SimulationResult, k: int):
    ds = result.timeseries
    pts, v = _field_arrows(result, k)
    ax.quiver(pts[:, 0], pts[:, 1], v[:, 0], v[:, 1], color="0.55", scale=result.scenario.kernel.c * 12, width=0.004)
    if "human_x" in ds:  # agents; a density crowd has none (its density is the bottom row)
        ax.plot(ds["human_x"].values[k], ds["human_y"].values[k], ".", color="tab:red", ms=3)
    else:
        rho = ds["density"].values[k].T
        ax.contour(ds["x"].values, ds["y"].values, rho, levels=5, colors="tab:red", linewidths=0.7)
    rx, ry, th = ds["robot_x"].values[k], ds["robot_y"].values[k], ds["robot_heading"].values[k]
    ax.plot(rx, ry, "o", mfc="none", mec="tab:blue", ms=7, mew=1.5)
    ax.quiver(rx, ry, np.cos(th), np.sin(th), color="tab:blue", scale=18, width=0.006)
    _outline(ax, result, float(ds["time"].values[k]))
    ax.set_aspect("equal")
    _axes_labels(ax, _units(result))
    if "fraction_evacuated" in ds:
        state = f"out {ds['fraction_evacuated'].values[k]:.0%}"
    else:
        state = f"in target {ds['fraction_in_target'].values[k]:.0%}"
    ax.set_title(f"t = {ds['time'].values[k]:.1f} {_units(result)['time']}, {state}", fontsize=9)


def _crowd_legend(fig, ds) -> None:
    """One legend for the snapshots: humans (or the density), robots, their signs, v_r."""
    from matplotlib.lines import Line2D

    crowd = (
        Line2D([], [], ls="", marker=".", color="tab:red", label="humans")
        if "human_x" in ds
        else Line2D([], [], color="tab:red", lw=0.7, label="crowd density (contours)")
    )
    handles = [
        crowd,
        Line2D([], [], ls="", marker="o", mfc="none", mec="tab:blue", mew=1.5, label="robots"),
        Line2D([], [], color="tab:blue", marker=">", ms=5, label="sign heading θᵢ"),
        Line2D([], [], color="0.55", marker=">", ms=4, label="navigation field v_r"),
    ]
    fig.legend(handles=handles, loc="outside upper center", ncols=4, fontsize=8, frameon=False)


def _outline(ax, result: SimulationResult, t: float | None = None):
    """Ω's boundary: walls in black, exits in green (metres for plans); the regions blocked by time ``t``
    (a scenario's ``block`` events) hatched in red."""
    dom = result.scenario.domain
    for part in dom.boundary_parts():
        style = {"color": "k", "lw": 1} if part.kind == "wall" else {"color": "tab:green", "lw": 3}
        ax.plot(part.points[:, 0], part.points[:, 1], **style)
    if t is not None:
        import shapely

        for event in result.scenario.events:
            if event.block is not None and event.time <= t + 1e-9:
                xy = np.asarray(shapely.from_wkt(event.block).exterior.coords)
                ax.fill(xy[:, 0], xy[:, 1], facecolor="none", edgecolor="tab:red", hatch="///", lw=1)
    x0, x1, y0, y1 = dom.bounds
    pad = 0.02 * max(x1 - x0, y1 - y0)
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)


def plot_snapshots(result: SimulationResult, count: int = 4):
    """Fig. 3 of the paper: humans, robots, v_r arrows (top) and density estimates (bottom)."""
    ds = result.timeseries
    n = ds.sizes["time"]
    idx = np.unique(np.round(np.linspace(0, n - 1, count)).astype(int))
    fig, axes = subplots(2, len(idx), figsize=(3.2 * len(idx), 6.4), constrained_layout=True, squeeze=False)
    shown = {k: ds["density"].values[k] * _people(result, k) for k in idx}
    vmax = float(max(np.nanmax(v) for v in shown.values()))
    for col, k in enumerate(idx):
        _draw_crowd(axes[0, col], result, k)
        im = axes[1, col].imshow(shown[k].T, origin="lower", extent=_extent(ds), vmin=0, vmax=vmax, cmap="viridis")
        title = "density estimate ρ̂" if "human_x" in ds else "density ρ (Fokker–Planck)"
        axes[1, col].set_title(title, fontsize=9)
        _outline(axes[1, col], result, float(ds["time"].values[k]))
        _axes_labels(axes[1, col], _units(result))
    fig.colorbar(im, ax=axes[1, :].tolist(), shrink=0.8, label=f"density ({_units(result)['density']})")
    _crowd_legend(fig, ds)
    return fig


def plot_evacuation(result: SimulationResult):
    """The fraction of the crowd out over time, with RSET (95 %, 100 %), the lower bound and the events."""
    ds, s = result.timeseries, result.summary
    u = _units(result)
    fig, ax = subplots(figsize=(6.4, 4.0), constrained_layout=True)
    ax.plot(ds["time"].values, ds["fraction_evacuated"].values, color="tab:green", lw=2, label="fraction out")
    for key, label, style in (
        ("evacuation_time_95", "95 % out", ":"),
        ("evacuation_time_100", "everyone out (RSET)", "--"),
        ("evacuation_lower_bound", "lower bound", "-."),
    ):
        if s.get(key) is not None:
            ax.axvline(s[key], color="0.3", ls=style, lw=1, label=f"{label}: {s[key]:.1f} {u['time']}")
    for event in s.get("events") or ():  # the scenario's [[events]]: when each exit closed, each region was blocked
        what = f"exit {event['close_exit']} closes" if "close_exit" in event else "a region is blocked"
        label = f"{what}: {event['at']:.1f} {u['time']}"
        ax.axvline(event["at"], color="tab:red", ls="-", lw=1, alpha=0.7, label=label)
    ax.set(xlabel=f"time ({u['time']})", ylabel="fraction of the crowd out", ylim=(0, 1.02))
    peak = s.get("peak_density")
    title = "evacuation" if peak is None else f"evacuation (peak density {peak:.1f} {u['density'].replace('1/', '/')})"
    ax.set_title(title + (" — crush risk" if s.get("crush_risk") else ""))
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return fig


def _save(fig, path: Path, run_id: str | None = None) -> Path:
    meta = {"Comment": f"meanfield run {run_id}"} if run_id else {}
    return save_figure(fig, path, dpi=110, metadata=meta)


def save_run_figures(result: SimulationResult, out_dir: Path) -> dict[str, Path]:
    """Write ``target_and_error.png``, ``snapshots.png`` and, with exits, ``evacuation.png`` into
    ``out_dir`` (the run's id in their metadata)."""
    out_dir = Path(out_dir)
    rid = result.summary.get("run_id")
    out = {
        "target_and_error": _save(plot_target_and_error(result), out_dir / "target_and_error.png", rid),
        "snapshots": _save(plot_snapshots(result), out_dir / "snapshots.png", rid),
    }
    if "fraction_evacuated" in result.timeseries:
        out["evacuation"] = _save(plot_evacuation(result), out_dir / "evacuation.png", rid)
    return out


def save_animation(
    result: SimulationResult, path: Path, max_frames: int = 150, fps: int = 15, progress: bool = False
) -> Path:
    """Animated GIF of humans, robots and v_r over the run (at most ``max_frames`` frames).

    About 0.3 s a frame: ``progress`` shows a bar (the command line's ``--animate`` does).
    """
    from matplotlib.animation import FuncAnimation, PillowWriter
    from tqdm.auto import tqdm

    ds = result.timeseries
    n = ds.sizes["time"]
    frames = np.unique(np.round(np.linspace(0, n - 1, min(n, max_frames))).astype(int))
    fig, ax = subplots(figsize=(5, 5), constrained_layout=True)

    def draw(k):
        ax.clear()
        _draw_crowd(ax, result, int(k))

    anim = FuncAnimation(fig, draw, frames=frames, interval=1000 / fps)
    with tqdm(total=len(frames), disable=not progress, desc="animation.gif", unit="frame") as bar:

        def tick(i: int, n: int) -> None:
            bar.update(1)

        return atomic_write_with(
            Path(path), lambda p: anim.save(p, writer=PillowWriter(fps=fps), progress_callback=tick)
        )


def plot_comparison_errors(report):
    """Log–log error against ``N`` per case, with fitted slopes and an ``N^(-1/2)`` guide."""
    from meanfield.workflows.mean_field_limit import fit_slope

    cases = report.cases
    fig, axes = subplots(1, len(cases), figsize=(5.2 * len(cases), 4.4), constrained_layout=True, squeeze=False)
    styles = {
        "error_to_expected": ("o-", "C0", "KDE − E[KDE] under PDE"),
        "error_to_pde": ("s--", "C1", "KDE − PDE (incl. KDE bias)"),
        "error_to_expected_paper_sign": ("^:", "C3", "vs PDE with the paper's ∇W∗ρ sign"),
    }
    for ax, case in zip(axes[0], cases, strict=True):
        ns = case.dataset["n_agents"].values.astype(float)
        fit = (ns >= 100) & (ns <= 10_000)
        for name, (fmt, color, text) in styles.items():
            if name not in case.dataset:
                continue
            m = case.mean_errors(name)
            slope = fit_slope(ns[fit], m[fit]) if fit.sum() >= 2 else float("nan")
            ax.loglog(ns, m, fmt, color=color, label=f"{text}: slope {slope:.2f}")
        m0 = case.mean_errors("error_to_expected")[0]
        ax.loglog(ns, m0 * (ns / ns[0]) ** -0.5, color="0.6", lw=0.8, label="N^(-1/2)")
        ax.set_xlabel("number of agents N")
        ax.set_ylabel("time-mean L² distance")
        ax.set_title(case.label, fontsize=10)
        ax.legend(fontsize=7.5)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Agents (SDE) against the Fokker–Planck PDE, same robot trajectories (slopes fitted on N ≤ 10⁴)")
    return fig


def plot_comparison_snapshots(report, count: int = 3):
    """PDE density against the largest crowd's estimate at ``count`` times (first case).

    Each time (column) has its own colour scale, shared by the PDE and the agents, with a
    labelled colour bar: the density concentrates over the run, and one scale for all
    would wash the early frames out.
    """
    case = report.cases[0]
    ds = case.dataset
    units = "1/m²" if report.scenario.units == "SI" else "1/room width²"
    length = "m" if report.scenario.units == "SI" else "room widths"
    n_t = ds.sizes["time"]
    ks = np.unique(np.round(np.linspace(0, n_t - 1, count)).astype(int))
    fig, axes = subplots(2, len(ks), figsize=(3.4 * len(ks), 6.6), constrained_layout=True, squeeze=False)
    ext = _extent(ds)
    n_max = int(ds["n_agents"].values[-1])
    for col, k in enumerate(ks):
        pde = ds["pde_density"].values[k]
        est = ds["agents_density"].values[-1, k]
        vmax = max(np.percentile(pde, 99), np.percentile(est, 99))  # a corner peak would wash out the rest
        vmax = vmax if vmax > 0 else 1.0
        for row, (f, name) in enumerate(((pde, "PDE"), (est, f"agents KDE, N = {n_max}"))):
            ax = axes[row, col]
            im = ax.imshow(f.T, origin="lower", extent=ext, vmin=0, vmax=vmax, cmap="viridis")
            ax.set_title(f"{name}, t = {ds['time'].values[k]:.3g}", fontsize=9)
            ax.set_xlabel(f"x ({length})", fontsize=8)
            ax.set_ylabel(f"y ({length})", fontsize=8)
        fig.colorbar(im, ax=axes[:, col].tolist(), shrink=0.6, location="bottom", label=f"density ({units})")
    fig.suptitle(case.label)
    return fig


def save_comparison_figures(report, out_dir: Path) -> dict[str, Path]:
    """Write ``error_vs_n.png`` and ``comparison_snapshots.png`` into ``out_dir``."""
    out_dir = Path(out_dir)
    return {
        "error_vs_n": _save(plot_comparison_errors(report), out_dir / "error_vs_n.png"),
        "comparison_snapshots": _save(plot_comparison_snapshots(report), out_dir / "comparison_snapshots.png"),
    }
