"""NMPC against backstepping on the `paper` scenario: fraction in target, error curve, compute.

Usage:  python studies/nmpc_vs_backstepping.py [--seeds 0-4] [--set KEY=VALUE ...] [--out DIR]
                                                [--workers N] [--t-final T]
        python studies/nmpc_vs_backstepping.py --replot DIR/nmpc_comparison.json [--out DIR]

For every seed, runs the paper scenario twice — the paper's backstepping law and the NMPC
baseline of :mod:`analysis.nmpc` (``controller.kind = "nmpc"``; ``--set`` applies to the
NMPC run only, e.g. ``--set controller.options.nmpc.horizon=3``) — in parallel processes, and
writes under ``--out``:

* ``nmpc_comparison.json``: per run the summary figures (fraction_in_target, l2 ratio,
  time_to_90, max robot speed, saturated fraction), the compute per control step (NMPC:
  wall time of every solve; backstepping: wall time of ``robot_inputs`` every step, both
  in the NMPC run — the diagnostics call it — and in the backstepping run), the IPOPT
  statuses, the error and fraction curves (and the first seed's snapshots); then the medians;
* ``nmpc_error.png`` (‖ρ̂ − ρ_*‖ over time), ``nmpc_fraction.png`` (fraction in the target
  region over time), ``nmpc_compute.png`` (compute per control step),
  ``nmpc_snapshots.png`` (crowd and robots of the first seed at four times).

It prints a Markdown table of the runs and the medians.  This is the command behind the
figures of docs/nmpc.md.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core per run

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from meanfield.io.atomic import save_figure  # noqa: E402
from meanfield.scenarios.overrides import parse_set  # noqa: E402
from meanfield.scenarios.scenario import paper_scenario  # noqa: E402

SUMMARY_KEYS = (
    "fraction_in_target",
    "l2_error_initial",
    "l2_error_final",
    "l2_error_ratio",
    "time_to_90",
    "max_robot_speed",
    "speed_limit",
    "max_robot_turn_rate",
    "turn_rate_limit",
    "saturated_fraction",
    "w2_to_target_final",
    "wall_seconds",
    "status",
)
SNAPSHOT_TIMES = (0.0, 2.0, 10.0, 40.0)


class _Timed:
    """Wraps a controller and records the wall time of each ``act`` call."""

    def __init__(self, inner):
        self.inner = inner
        self.seconds: list[float] = []

    def act(self, observation):
        t0 = time.perf_counter()
        out = self.inner.act(observation)
        self.seconds.append(time.perf_counter() - t0)
        return out

    def reset(self) -> None:
        self.inner.reset()


def _percentiles(x) -> dict[str, float]:
    x = np.asarray(x, float)
    return {"median": float(np.median(x)), "p90": float(np.percentile(x, 90)), "mean": float(x.mean()), "n": len(x)}


def _one(job: tuple[int, str, dict, float | None]) -> dict:
    from meanfield.simulation.loop import ClosedLoop

    seed, kind, sets, t_final = job
    sc = paper_scenario(seed=seed)
    if t_final is not None:
        sc = sc.replace(t_final=t_final)
    if kind == "nmpc":
        sc = sc.with_values({"controller.kind": "nmpc", **sets})
    t0 = time.perf_counter()
    loop = ClosedLoop(sc)
    build = time.perf_counter() - t0
    if kind == "backstepping":
        loop.controller = _Timed(loop.controller)
    result = loop.run(progress=False)
    s, ds = result.summary, result.dataset
    row: dict = {"seed": seed, "controller": kind, "build_seconds": build, **{k: s.get(k) for k in SUMMARY_KEYS}}
    row["limits_binding_fraction"] = s.get("limits_binding_fraction")
    if kind == "nmpc":
        c = loop.controller
        solves = [st["seconds"] for st in c.stats]
        row["options"] = {k: v for k, v in vars(c.options).items()}
        row["compute"] = {
            "per_solve": _percentiles(solves),
            "backstepping_per_call_same_run": _percentiles(c.backstepping_seconds),
            "ratio_median_solve_over_backstepping": float(np.median(solves) / np.median(c.backstepping_seconds)),
            "solve_seconds_per_simulation_step": float(np.sum(solves) / s["steps"]),
            "solves": len(solves),
        }
        row["ipopt"] = c.summary()["statuses"]
        row["iterations"] = _percentiles([st["iterations"] for st in c.stats])
        row["max_speed_solver"] = max(st["max_speed_solver"] for st in c.stats)
        row["projected_solves"] = sum(st["projected"] for st in c.stats)
        row["solve_seconds"] = solves
    else:
        row["compute"] = {"per_call": _percentiles(loop.controller.seconds)}
        row["solve_seconds"] = loop.controller.seconds[:: max(1, len(loop.controller.seconds) // 400)]
    row["series"] = {
        "time": ds["time"].values.tolist(),
        "rho_error_l2": ds["rho_error_l2"].values.tolist(),
        "fraction_in_target": ds["fraction_in_target"].values.tolist(),
        "V2": ds["V2"].values.tolist(),
    }
    times = ds["time"].values
    row["snapshots"] = []
    for T in SNAPSHOT_TIMES:
        i = int(np.argmin(np.abs(times - T)))
        row["snapshots"].append(
            {
                "time": float(times[i]),
                "human_x": ds["human_x"].values[i].tolist(),
                "human_y": ds["human_y"].values[i].tolist(),
                "robot_x": ds["robot_x"].values[i].tolist(),
                "robot_y": ds["robot_y"].values[i].tolist(),
                "robot_heading": ds["robot_heading"].values[i].tolist(),
            }
        )
    row["target_radius"] = s["target_radius"]
    return row


def _late_ratio(r: dict) -> float:
    """Mean of ‖ρ̂ − ρ_*‖ over the second half of the run, over the initial error (less noisy
    than the final value, which catches the error curve wherever it happens to be)."""
    t = np.asarray(r["series"]["time"])
    e = np.asarray(r["series"]["rho_error_l2"])
    return float(e[t >= t[-1] / 2].mean() / r["l2_error_initial"])


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


COLORS = {"backstepping": "tab:blue", "nmpc": "tab:red"}


def _curves(rows: list[dict], key: str, ylabel: str, path: Path, log: bool = False) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for kind in ("backstepping", "nmpc"):
        runs = [r for r in rows if r["controller"] == kind]
        for r in runs:
            ax.plot(r["series"]["time"], r["series"][key], color=COLORS[kind], lw=0.6, alpha=0.35)
        n = min(len(r["series"]["time"]) for r in runs)
        med = np.median([r["series"][key][:n] for r in runs], axis=0)
        ax.plot(runs[0]["series"]["time"][:n], med, color=COLORS[kind], lw=2, label=f"{kind} (median of {len(runs)})")
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("time")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def _compute_figure(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nm = np.concatenate([r["solve_seconds"] for r in rows if r["controller"] == "nmpc"])
    bs = np.concatenate([r["solve_seconds"] for r in rows if r["controller"] == "backstepping"])
    fig, ax = plt.subplots(figsize=(7, 3.6))
    bins = np.logspace(np.log10(min(nm.min(), bs.min()) * 0.8), np.log10(max(nm.max(), bs.max()) * 1.2), 60)
    for x, kind, label in (
        (bs, "backstepping", "backstepping: robot_inputs, every step"),
        (nm, "nmpc", "NMPC: one IPOPT solve, every control period"),
    ):
        ax.hist(x, bins=bins, weights=np.full(len(x), 1 / len(x)), color=COLORS[kind], alpha=0.7, label=label)
    ax.set_xscale("log")
    ax.set_xlabel("wall seconds per control step")
    ax.set_ylabel("fraction of control steps")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def _snapshots(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    seed = min(r["seed"] for r in rows if "snapshots" in r)
    pick = {r["controller"]: r for r in rows if r["seed"] == seed}
    fig, axes = plt.subplots(2, len(SNAPSHOT_TIMES), figsize=(3 * len(SNAPSHOT_TIMES), 6.2))
    for a, kind in enumerate(("backstepping", "nmpc")):
        r = pick[kind]
        for b, snap in enumerate(r["snapshots"]):
            ax = axes[a, b]
            ax.add_patch(Circle((1.0, 1.0), r["target_radius"], color="tab:green", alpha=0.15))
            ax.scatter(snap["human_x"], snap["human_y"], s=4, color="k")
            rx, ry, th = (np.asarray(snap[k]) for k in ("robot_x", "robot_y", "robot_heading"))
            ax.quiver(rx, ry, np.cos(th), np.sin(th), color=COLORS[kind], scale=12, width=0.012)
            ax.set_xlim(0, 1)
            ax.set_ylim(0, 1)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{kind}, t = {snap['time']:g}", fontsize=9)
    fig.suptitle(f"paper scenario, seed {seed}: humans (dots), robots and sign headings (arrows), target region")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _medians(rows: list[dict], kind: str) -> dict:
    runs = [r for r in rows if r["controller"] == kind]
    out = {
        k: statistics.median(r[k] for r in runs) for k in ("fraction_in_target", "l2_error_ratio", "w2_to_target_final")
    }
    out["l2_ratio_mean_second_half"] = statistics.median(_late_ratio(r) for r in runs)
    t90 = [r["time_to_90"] for r in runs if r["time_to_90"] is not None]
    out["time_to_90"] = statistics.median(t90) if t90 else None
    out["all_speeds_within_limit"] = all(r["max_robot_speed"] <= r["speed_limit"] * (1 + 1e-12) for r in runs)
    out["max_saturated_fraction"] = max(r["saturated_fraction"] for r in runs)
    if kind == "nmpc":
        for k in ("per_solve", "backstepping_per_call_same_run"):
            out[f"{k}_median"] = statistics.median(r["compute"][k]["median"] for r in runs)
            out[f"{k}_p90"] = statistics.median(r["compute"][k]["p90"] for r in runs)
        out["ratio_median_solve_over_backstepping"] = statistics.median(
            r["compute"]["ratio_median_solve_over_backstepping"] for r in runs
        )
        out["solve_seconds_per_simulation_step"] = statistics.median(
            r["compute"]["solve_seconds_per_simulation_step"] for r in runs
        )
    else:
        out["per_call_median"] = statistics.median(r["compute"]["per_call"]["median"] for r in runs)
        out["per_call_p90"] = statistics.median(r["compute"]["per_call"]["p90"] for r in runs)
    out["wall_seconds_median"] = statistics.median(r["wall_seconds"] for r in runs)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--set", action="append", default=[], help="NMPC run only, e.g. controller.options.nmpc.horizon=3")
    ap.add_argument("--out", default="docs/figures", type=Path)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--t-final", type=float, default=None, help="shorter runs (default: the scenario's 40)")
    ap.add_argument("--replot", type=Path, default=None, help="redraw the figures from a nmpc_comparison.json")
    a = ap.parse_args()
    if a.replot is not None:
        saved = json.loads(a.replot.read_text())
        _figures(saved["rows"], a.out)
        _report(saved["rows"], {k: {**v, **_medians(saved["rows"], k)} for k, v in saved["medians"].items()})
        return
    sets = parse_set(a.set)
    seeds = _seeds(a.seeds)
    jobs = [(s, k, sets, a.t_final) for s in seeds for k in ("nmpc", "backstepping")]  # long jobs first
    with ProcessPoolExecutor(a.workers) as ex:
        rows = list(ex.map(_one, jobs))
    rows.sort(key=lambda r: (r["controller"] != "backstepping", r["seed"]))
    _figures(rows, a.out)
    med = {k: _medians(rows, k) for k in ("backstepping", "nmpc")}
    _report(rows, med)
    first = min(seeds)
    slim = [{k: v for k, v in r.items() if k != "snapshots" or r["seed"] == first} for r in rows]
    with open(a.out / "nmpc_comparison.json", "w") as fh:
        json.dump({"seeds": seeds, "nmpc_settings": sets, "t_final": a.t_final, "medians": med, "rows": slim}, fh)


def _figures(rows: list[dict], out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    _curves(rows, "rho_error_l2", "‖ρ̂ − ρ*‖ (L², 30×30 grid)", out / "nmpc_error.png", log=True)
    _curves(rows, "fraction_in_target", "fraction in the target region", out / "nmpc_fraction.png")
    _compute_figure(rows, out / "nmpc_compute.png")
    _snapshots(rows, out / "nmpc_snapshots.png")


def _report(rows: list[dict], med: dict) -> None:
    print(
        "| controller | seed | fraction_in_target | l2 final / initial | l2 mean over [T/2, T] / initial | w2 final | "
        "time_to_90 | max speed / limit | saturated | limits binding | compute per control step: median (p90) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        t90 = "—" if r["time_to_90"] is None else f"{r['time_to_90']:.2f}"
        lb = r.get("limits_binding_fraction")
        binding = "—" if lb is None else f"{lb:.3f}"
        if r["controller"] == "nmpc":
            c = r["compute"]["per_solve"]
            b = r["compute"]["backstepping_per_call_same_run"]
            comp = (
                f"{c['median'] * 1e3:.0f} ms ({c['p90'] * 1e3:.0f} ms) per solve; "
                f"backstepping {b['median'] * 1e3:.2f} ms same run; ratio "
                f"{r['compute']['ratio_median_solve_over_backstepping']:.0f}"
            )
        else:
            c = r["compute"]["per_call"]
            comp = f"{c['median'] * 1e3:.2f} ms ({c['p90'] * 1e3:.2f} ms)"
        print(
            f"| {r['controller']} | {r['seed']} | {r['fraction_in_target']:.3f} | {r['l2_error_ratio']:.3f} | "
            f"{_late_ratio(r):.3f} | {r['w2_to_target_final']:.3f} | {t90} | "
            f"{r['max_robot_speed']:.4f} / {r['speed_limit']} | {r['saturated_fraction']:.3f} | {binding} | {comp} |"
        )
    print()
    print(json.dumps(med, indent=2))


if __name__ == "__main__":
    main()
