"""Flow through a bottleneck against its width: the crowd models against the experiments (docs page *Congestion*).

(Not ``studies/bottleneck.py``: in this folder that name would hide the package ``bottleneck``, which
pandas imports, from every study run here.)  Run from the repository's root::

    python studies/bottleneck_flow.py [--seeds 5] [--models none weidmann linear] [--radii 0.6] [--workers 1]
    python studies/bottleneck_flow.py --models jupedsim --seeds 3      # JuPedSim's bodies, fewer seeds
    python studies/bottleneck_flow.py --report                          # only the table, JSON and figures

For each bottleneck width ``b`` (:data:`WIDTHS`), seed and crowd model it runs the built-in
``bottleneck`` scenario (a 10 m × 8 m room, a corridor 2 m long and ``b`` wide on its east wall,
200 informed people) to the end and measures

* the flow ``J`` (persons/s) in the steady part: ``(N₉₀ − N₁₀) / (t₉₀ − t₁₀)``, between the exit
  times of the 10 % and the 90 % of the crowd (from the engine's exit times), and ``J/b``;
* the peak local density: the largest number of other people within 0.6 m of someone still in
  the room, over ``π 0.6²`` (persons/m², the same measure for every model), and the robots'
  KDE peak (``summary.json``'s ``peak_density``).

The models: point masses without congestion (``none``), with Weidmann's diagram (``weidmann``)
or the linear one (``linear``), each with the local-density radius ``--radii`` (m), and JuPedSim's
bodies (``jupedsim``, no diagram: the bodies make their own congestion).  Each run is a line of
``studies/results/bottleneck.jsonl`` (appended as it finishes, so that an interrupted study
resumes); ``--report`` writes ``studies/results/bottleneck.json`` (medians and worst seeds),
prints the docs page's table and draws ``docs/figures/congestion_flow.png`` (``J`` against
``b``) and ``docs/figures/congestion_specific_flow.png`` (``J/b`` against ``b``) with the
measurements (:data:`LIDDLE`, :data:`MEASURED_RANGE`).
"""

from __future__ import annotations

import argparse
import json
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

WIDTHS = (0.8, 1.0, 1.2, 1.6, 2.0, 2.5)
"""Bottleneck widths, m."""
RESULTS = Path("studies/results/bottleneck.jsonl")
REPORT = Path("studies/results/bottleneck.json")
FIGURES = Path("docs/figures")
MEASURE_RADIUS = 0.6
"""m: the radius of the peak local density reported for every model."""

LIDDLE = {
    "width": [0.9, 1.0, 1.1, 1.2, 1.4, 1.6, 1.8, 2.0, 2.2, 2.5],
    "flow": [1.70998632, 2.02483801, 2.19426565, 2.53207292, 2.91149068]
    + [3.11461794, 3.90625, 3.91032325, 4.52352232, 5.54733728],
}
"""Liddle et al. (arXiv:0911.4350, as we read the label ``lid``): flows J (persons/s) of 150 persons through
bottlenecks of width b (m), as a validation script of JuPedSim's core (jpscore, ``testnr = 13``) tabulates
them, ``150 / (t_last − t_first)`` from ``Flow_vs_b_v2.dat`` (docs page *Congestion*)."""
MEASURED_RANGE = (1.6, 2.5)
"""persons/(m·s): the specific flows measured for widths 0.8–2.5 m as the issue states them
(Seyfried et al. 2009, Kretz et al. 2006, Müller 1981); not checked against the papers' tables."""


def scenario(b: float, model: str, seed: int) -> Any:
    """The built-in bottleneck with a corridor ``b`` wide and the crowd ``model``."""
    from meanfield.scenarios.scenario import builtin_scenarios

    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    values: dict[str, Any] = {
        "domain.wkt": f"POLYGON ((0 0, 10 0, 10 {lo:g}, 12 {lo:g}, 12 {hi:g}, 10 {hi:g}, 10 8, 0 8, 0 0))",
        "domain.exits": [[[12.0, lo], [12.0, hi]]],
    }
    if model == "jupedsim":
        values["crowd.kind"] = "jupedsim"
    else:
        values["crowd.congestion"] = model
    return builtin_scenarios()["bottleneck"](seed=seed).with_values(values)


class PeakLocalDensity:
    """Observer: the largest local density (:data:`MEASURE_RADIUS`) of the people still in the room, and when."""

    def __init__(self) -> None:
        self.peak, self.time = 0.0, 0.0

    def start(self, loop: Any) -> None:
        self.step(loop, None)

    def step(self, loop: Any, record: Any) -> None:
        from meanfield.crowds.agent_crowd import local_density

        engine = loop.crowd.engine
        rho = local_density(engine.positions, engine.active, MEASURE_RADIUS)
        if len(rho) and rho.max() > self.peak:
            self.peak, self.time = float(rho.max()), float(loop.t)


def steady_flow(exit_times: np.ndarray, n: int, lo: float = 0.1, hi: float = 0.9) -> float | None:
    """``(N_hi − N_lo) / (t_hi − t_lo)``, persons/s, between the exits of the ``lo`` and ``hi`` shares of ``n``."""
    t = np.sort(exit_times[np.isfinite(exit_times)])
    i, j = int(round(lo * n)), int(round(hi * n))
    if len(t) < j or t[j - 1] <= t[i - 1]:
        return None
    return (j - i) / float(t[j - 1] - t[i - 1])


def one_run(b: float, model: str, radius: float, seed: int) -> dict[str, Any]:
    """One run's flow and densities."""
    import meanfield.crowds.agent_crowd as agents
    from meanfield.simulation.loop import ClosedLoop

    agents.DENSITY_RADIUS = radius  # the local-density radius of the congested crowd (no scenario field)
    sc = scenario(b, model, seed)
    peak = PeakLocalDensity()
    loop = ClosedLoop(sc, observers=[peak])
    result = loop.run(progress=False)
    s = result.summary
    engine = loop.crowd.engine
    flow = steady_flow(np.asarray(engine.exit_time, float), sc.crowd.n)
    return {
        "model": model,
        "radius": radius if model in ("weidmann", "linear") else None,
        "width": b,
        "seed": seed,
        "flow": flow,
        "specific_flow": None if flow is None else flow / b,
        "out": int(np.isfinite(engine.exit_time).sum()),
        "time_all_out": s.get("evacuation_time_100"),
        "peak_local_density": peak.peak,
        "peak_local_density_time": peak.time,
        "peak_kde_density": s.get("peak_density"),
        "wall_seconds": s.get("wall_seconds"),
    }


def _key(row: dict[str, Any]) -> tuple:
    return row["model"], row["radius"], row["width"], row["seed"]


def _rows() -> list[dict[str, Any]]:
    if not RESULTS.exists():
        return []
    return [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]


def run_all(seeds: int, models: list[str], radii: list[float], workers: int) -> None:
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    done = {_key(r) for r in _rows()}
    jobs = []
    for seed in range(seeds):
        for model in models:
            for radius in radii if model in ("weidmann", "linear") else [None]:
                for b in WIDTHS:
                    job = (b, model, radius if radius is not None else 0.6, seed)
                    if (model, radius, b, seed) not in done:
                        jobs.append(job)
    print(f"{len(jobs)} runs to do", flush=True)
    with ProcessPoolExecutor(workers) as pool, RESULTS.open("a") as out:
        futures = {pool.submit(one_run, *job): job for job in jobs}
        for i, f in enumerate(as_completed(futures), 1):
            row = f.result()
            out.write(json.dumps(row) + "\n")
            out.flush()
            os.fsync(out.fileno())
            print(f"[{i}/{len(jobs)}] {futures[f]}: J {row['flow']}, J/b {row['specific_flow']}", flush=True)


def _label(model: str, radius: float | None) -> str:
    return model if radius is None else f"{model} r={radius:g}"


def report() -> dict[str, Any]:
    """Medians and worst seeds per model and width (``specific_flow_min``/``_max`` over the seeds; ``_worst``: the seed
    farthest outside the measured range, the first seed when every one is inside)."""
    rows = _rows()
    groups: dict[str, dict[float, list[dict]]] = {}
    for r in rows:
        groups.setdefault(_label(r["model"], r["radius"]), {}).setdefault(r["width"], []).append(r)
    lo, hi = MEASURED_RANGE
    out: dict[str, Any] = {
        "widths_m": list(WIDTHS),
        "flow_window": "between the exits of 10 % and 90 % of the 200 people",
        "measured_specific_flow_range": list(MEASURED_RANGE),
        "liddle_2011": LIDDLE,
        "models": {},
    }
    for label, by_width in sorted(groups.items()):
        per = {}
        for b, rs in sorted(by_width.items()):
            js = np.array([r["specific_flow"] if r["specific_flow"] is not None else np.nan for r in rs])
            dist = np.where(js < lo, lo - js, np.where(js > hi, js - hi, 0.0))
            worst = float(js[int(np.nanargmax(np.where(np.isnan(js), np.inf, dist)))]) if len(js) else None
            per[str(b)] = {
                "seeds": len(rs),
                "flow_median": float(np.nanmedian([r["flow"] or np.nan for r in rs])),
                "specific_flow_median": float(np.nanmedian(js)),
                "specific_flow_min": float(np.nanmin(js)),
                "specific_flow_max": float(np.nanmax(js)),
                "specific_flow_worst": worst,
                "peak_local_density_median": float(np.median([r["peak_local_density"] for r in rs])),
                "peak_local_density_max": float(np.max([r["peak_local_density"] for r in rs])),
                "peak_kde_density_median": float(np.median([r["peak_kde_density"] or np.nan for r in rs])),
                "all_out": all(r["out"] == 200 for r in rs),
                "seeds_without_flow": [r["seed"] for r in rs if r["specific_flow"] is None],  # clogged: < 90 % out
                "out_least": min(r["out"] for r in rs),
            }
        med = [per[str(b)]["flow_median"] for b in sorted(by_width)]
        per_all = [per[str(b)] for b in sorted(by_width)]
        liddle = dict(zip(LIDDLE["width"], np.array(LIDDLE["flow"]) / np.array(LIDDLE["width"]), strict=True))
        shared = [b for b in sorted(by_width) if b in liddle]
        gap = [per[str(b)]["specific_flow_median"] - liddle[b] for b in shared]
        out["models"][label] = {
            "rms_specific_flow_minus_liddle": float(np.sqrt(np.mean(np.square(gap)))) if gap else None,
            "liddle_widths_compared": shared,
            "per_width": per,
            "flow_grows_with_width": bool(np.all(np.diff(med) > 0)),
            "every_width_in_range": all(lo <= p["specific_flow_min"] and p["specific_flow_max"] <= hi for p in per_all),
            "every_median_in_range": all(lo <= p["specific_flow_median"] <= hi for p in per_all),
        }
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    REPORT.write_text(json.dumps(out, indent=1) + "\n")
    return out


def table(rep: dict[str, Any]) -> str:
    """The docs page's table: J/b per width, median (the seeds' lowest–highest; the seeds where fewer than 90 %
    got out, *clogged*, are left out of both and counted), J's growth, the gap to Liddle et al., the peak density."""
    widths = rep["widths_m"]
    head = "| model | " + " | ".join(f"b = {b:g} m" for b in widths)
    head += " | J grows with b | RMS J/b − Liddle | peak ρ, persons/m² |"
    lines = [head, "|---" * (len(widths) + 4) + "|"]
    for label, m in rep["models"].items():
        cells = []
        for b in widths:
            p = m["per_width"].get(str(b))
            if p is None:
                cells.append("–")
            else:
                lo, hi = p["specific_flow_min"], p["specific_flow_max"]
                clogged = ""
                if p["seeds_without_flow"]:
                    k, n = len(p["seeds_without_flow"]), p["seeds"]
                    clogged = f"; {k} of {n} seeds clogged, {p['out_least']} out"
                cells.append(f"{p['specific_flow_median']:.2f} ({lo:.2f}–{hi:.2f}{clogged})")
        peaks = [p["peak_local_density_median"] for p in m["per_width"].values()]
        grows = "yes" if m["flow_grows_with_width"] else "no"
        rms = m["rms_specific_flow_minus_liddle"]
        rms_cell = "–" if rms is None else f"{rms:.2f}"
        lines.append(
            f"| {label} | " + " | ".join(cells) + f" | {grows} | {rms_cell} | {min(peaks):.0f}–{max(peaks):.0f} |"
        )
    return "\n".join(lines)


def figures(rep: dict[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    lo, hi = MEASURED_RANGE
    lw, lf = np.array(LIDDLE["width"]), np.array(LIDDLE["flow"])
    styles = {"none": "s", "weidmann": "o", "linear": "^", "jupedsim": "D"}
    for name, specific in (("congestion_flow.png", False), ("congestion_specific_flow.png", True)):
        fig, ax = plt.subplots(figsize=(9.5, 4.8))
        bb = np.linspace(0.7, 2.6, 2)
        if specific:
            ax.axhspan(lo, hi, color="0.85", label=f"measured range {lo}–{hi} persons/(m·s) (issue)")
            ax.plot(lw, lf / lw, "k*", ms=10, label="Liddle et al. (150 persons; via JuPedSim test 13)")
        else:
            ax.fill_between(bb, lo * bb, hi * bb, color="0.85", label=f"J = ({lo}–{hi}) b (issue)")
            ax.plot(lw, lf, "k*", ms=10, label="Liddle et al. (150 persons; via JuPedSim test 13)")
        shown = [label for label in rep["models"] if label != "none"]  # none: 28 persons/s, off the scale
        for k, label in enumerate(shown):
            m = rep["models"][label]
            shift = 0.012 * (k - (len(shown) - 1) / 2)  # side by side, so that the seeds' bars do not overlap
            ws = [float(b) + shift for b in m["per_width"]]
            key = "specific_flow" if specific else "flow"
            med = [p[f"{key}_median"] for p in m["per_width"].values()]
            marker = styles.get(label.split()[0], "x")
            line = ax.plot(ws, med, marker=marker, ls="-", label=f"{label} (median; bars: lowest–highest seed)")[0]
            scale = [1.0 if specific else float(b) for b in m["per_width"]]
            mn = [p["specific_flow_min"] * f for p, f in zip(m["per_width"].values(), scale, strict=True)]
            mx = [p["specific_flow_max"] * f for p, f in zip(m["per_width"].values(), scale, strict=True)]
            ax.vlines(ws, mn, mx, color=line.get_color(), alpha=0.6)
        ax.set_xlabel("bottleneck width b (m)")
        ax.set_ylabel("specific flow J/b (persons/(m·s))" if specific else "flow J (persons/s)")
        ax.set_xlim(0.7, 2.6)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.set_title("200 informed people through a 2 m long bottleneck (10 %–90 % out)")
        fig.tight_layout()
        fig.savefig(FIGURES / name, dpi=120)
        plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--models", nargs="+", default=["none", "weidmann", "linear"])
    parser.add_argument("--radii", nargs="+", type=float, default=[0.6])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--report", action="store_true", help="only the JSON, the table and the figures")
    args = parser.parse_args()
    if not args.report:
        run_all(args.seeds, args.models, args.radii, args.workers)
    rep = report()
    print(table(rep))
    figures(rep)


if __name__ == "__main__":
    main()
