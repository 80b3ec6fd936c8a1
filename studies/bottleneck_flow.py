"""Flow through a bottleneck against its width: the crowd models against the experiments (docs page *Congestion*).

(Not ``studies/bottleneck.py``: in this folder that name would hide the package ``bottleneck``, which
pandas imports, from every study run here.)  Run from the repository's root::

    python studies/bottleneck_flow.py [--seeds 5] [--models none weidmann linear] [--radii 0.6] [--workers 1]
    python studies/bottleneck_flow.py --models jupedsim --seeds 3      # JuPedSim's bodies, fewer seeds
    python studies/bottleneck_flow.py --models pde-linear pde-weidmann  # the density (one run per width)
    python studies/bottleneck_flow.py --models pde-hughes pde-hughes-weidmann   # the density on Hughes' route
    python studies/bottleneck_flow.py --models pde-linear --widths 1.0 --cells-per-metre 5 20   # its grids
    python studies/bottleneck_flow.py --report                          # only the table, JSON and figures
    python studies/bottleneck_flow.py --report --snapshots              # and the density's snapshots
                                                                        # (pde-linear and pde-hughes)

For each bottleneck width ``b`` (:data:`WIDTHS`), seed and crowd model it runs the built-in
``bottleneck`` scenario (a 10 m × 8 m room, a corridor 2 m long and ``b`` wide on its east wall,
200 informed people) to the end and measures

* the flow ``J`` (persons/s) in the steady part: ``(N₉₀ − N₁₀) / (t₉₀ − t₁₀)``, between the exit
  times of the 10 % and the 90 % of the crowd (from the engine's exit times), and ``J/b``;
* the peak local density: the largest number of other people within 0.6 m of someone still in
  the room, over ``π 0.6²`` (persons/m², the same measure for every model), and the robots'
  KDE peak (``summary.json``'s ``peak_density``).

The models: point masses without congestion (``none``), with Weidmann's diagram (``weidmann``)
or the linear one (``linear``), each walking by the count (``crowd.door_model = "count"``, the door model
this study calibrated; the default door model, the headway, has its rows in ``studies/door_models.py``) with
the local-density radius ``--radii`` (m), JuPedSim's
bodies (``jupedsim``, no diagram: the bodies make their own congestion), and the density itself,
the congested mean-field equation ``∂ₜρ + ∇·(ρ g(Nρ) v) = σΔρ`` with the informed crowd's route
``v = v₀ (−∇φ/|∇φ|)`` (``pde-linear``, ``pde-weidmann``: ``crowd.kind = "fokker-planck"``; docs page
*Congestion*, "The PDE"), or on Hughes' route, ``φ`` the travel time at the crowd's speed recomputed
every control period (``pde-hughes`` with the linear diagram, ``pde-hughes-weidmann``:
``crowd.guidance = "hughes"``), or on the fastest route to the exit (``pde-fastest``,
``crowd.guidance = "fastest-route"``; :data:`PDE_MODELS`).  The density is deterministic: one run per width
(seed 0), on the scenario's 0.1 m cells or, for the grid convergence, ``--cells-per-metre`` (those runs are
reported apart).  Its ``J`` is measured as the agents' is, from the exits' cumulative outflow
``N × mass out`` after every step of ``dt`` (the solver's count, the ``fraction_evacuated`` of the
run's records), linearly interpolated at ``N₁₀`` and ``N₉₀``; its peak local density is the mass
within 0.6 m of a cell's centre over ``π 0.6²`` (and ``peak_cell_density``, ``N max ρ``).  Each run is a line of
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
PDE_CELLS_PER_METRE = 10
"""The scenario's grid (0.1 m cells): the density's runs on another grid are its grid convergence."""
MEASURED_RANGE = (1.6, 2.5)
"""persons/(m·s): the specific flows measured for widths 0.8–2.5 m as the issue states them
(Seyfried et al. 2009, Kretz et al. 2006, Müller 1981); not checked against the papers' tables."""


PDE_MODELS = {
    "pde-linear": ("linear", "geodesic"),
    "pde-weidmann": ("weidmann", "geodesic"),
    "pde-fastest": ("linear", "fastest-route"),
    "pde-hughes": ("linear", "hughes"),
    "pde-hughes-weidmann": ("weidmann", "hughes"),
}
"""The density's models: ``(crowd.congestion, crowd.guidance)``; the bottleneck's own guidance is ``geodesic``."""


def is_pde(model: str) -> bool:
    """Whether ``model`` is the density (``pde-...``, :data:`PDE_MODELS`)."""
    return model.startswith("pde-")


def scenario(b: float, model: str, seed: int, cells_per_metre: int | None = None) -> Any:
    """The built-in bottleneck with a corridor ``b`` wide and the crowd ``model`` (for the density, on
    ``cells_per_metre`` cells per metre; None: the scenario's 0.1 m)."""
    from meanfield.scenarios.scenario import builtin_scenarios

    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    values: dict[str, Any] = {
        "domain.wkt": f"POLYGON ((0 0, 10 0, 10 {lo:g}, 12 {lo:g}, 12 {hi:g}, 10 {hi:g}, 10 8, 0 8, 0 0))",
        "domain.exits": [[[12.0, lo], [12.0, hi]]],
    }
    if model == "jupedsim":
        values["crowd.kind"] = "jupedsim"
    elif is_pde(model):
        values["crowd.kind"] = "fokker-planck"
        values["crowd.congestion"], values["crowd.guidance"] = PDE_MODELS[model]
        if cells_per_metre is not None:
            values["grid.cells"] = [12 * cells_per_metre, 8 * cells_per_metre]
    else:  # the count, as this study measured it (the headway's rows: studies/door_models.py)
        values["crowd.congestion"] = model
        values["crowd.door_model"] = "count"
    return builtin_scenarios()["bottleneck"](seed=seed).with_values(values)


class PeakLocalDensity:
    """Observer: the largest local density (:data:`MEASURE_RADIUS`, the disk cut by the walls, as the agents'
    own) of the people still in the room, and when."""

    def __init__(self) -> None:
        self.peak, self.time = 0.0, 0.0

    def start(self, loop: Any) -> None:
        from meanfield.crowds.local_density import LocalDensity

        self.density = LocalDensity(len(loop.crowd.engine.positions), MEASURE_RADIUS, loop.scenario.domain)
        self.step(loop, None)

    def step(self, loop: Any, record: Any) -> None:
        engine = loop.crowd.engine
        rho = self.density(engine.positions, engine.active)
        if len(rho) and rho.max() > self.peak:
            self.peak, self.time = float(rho.max()), float(loop.t)


def disk_density(grid: Any, persons: np.ndarray, radius: float = MEASURE_RADIUS) -> np.ndarray:
    """The persons within ``radius`` of each cell's centre over ``π radius²`` (persons/m²), the density's
    twin of the agents' local density (the cells whose centres are within ``radius``).  Unlike the agents'
    (:class:`~meanfield.crowds.local_density.LocalDensity`), this disk is not cut by the walls: beside a
    wall it reads up to half the density there is.

    Parameters
    ----------
    grid : Grid
    persons : ndarray
        Persons per cell (``N ρ V``).
    """
    from scipy import ndimage

    ri, rj = int(radius // grid.dx), int(radius // grid.dy)
    di, dj = np.meshgrid(np.arange(-ri, ri + 1) * grid.dx, np.arange(-rj, rj + 1) * grid.dy, indexing="ij")
    footprint = (di**2 + dj**2 <= radius**2 * (1 + 1e-12)).astype(float)
    return ndimage.correlate(persons, footprint, mode="constant") / (np.pi * radius**2)


def crossing_time(times: np.ndarray, out: np.ndarray, level: float) -> float | None:
    """When the cumulative outflow ``out`` (nondecreasing, at ``times``) reaches ``level``, linearly interpolated."""
    k = int(np.searchsorted(out, level, side="left"))
    if k >= len(out):
        return None
    if k == 0 or out[k] == out[k - 1]:
        return float(times[k])
    return float(times[k - 1] + (level - out[k - 1]) / (out[k] - out[k - 1]) * (times[k] - times[k - 1]))


def pde_flow(times: np.ndarray, persons_out: np.ndarray, n: int, lo: float = 0.1, hi: float = 0.9) -> float | None:
    """``(N_hi − N_lo) / (t_hi − t_lo)``, persons/s, the density's :func:`steady_flow`: when its cumulative
    outflow ``persons_out`` reaches ``lo n`` and ``hi n`` persons."""
    i, j = round(lo * n), round(hi * n)
    t_lo, t_hi = crossing_time(times, persons_out, i), crossing_time(times, persons_out, j)
    if t_lo is None or t_hi is None or t_hi <= t_lo:
        return None
    return (j - i) / (t_hi - t_lo)


def steady_flow(exit_times: np.ndarray, n: int, lo: float = 0.1, hi: float = 0.9) -> float | None:
    """``(N_hi − N_lo) / (t_hi − t_lo)``, persons/s, between the exits of the ``lo`` and ``hi`` shares of ``n``."""
    t = np.sort(exit_times[np.isfinite(exit_times)])
    i, j = int(round(lo * n)), int(round(hi * n))
    if len(t) < j or t[j - 1] <= t[i - 1]:
        return None
    return (j - i) / float(t[j - 1] - t[i - 1])


def one_run(b: float, model: str, radius: float, seed: int) -> dict[str, Any]:
    """One run's flow and densities."""
    from meanfield.simulation.loop import ClosedLoop

    sc = scenario(b, model, seed).with_values({"crowd.congestion_radius": radius})
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


def one_pde_run(b: float, model: str, cells_per_metre: int = PDE_CELLS_PER_METRE) -> dict[str, Any]:
    """One run of the density (``pde-<diagram>``, deterministic: seed 0) until less than half a person
    is left (the run summary's ``evacuation_time_100`` for the density) or ``t_final``."""
    import time

    from meanfield.simulation.loop import ClosedLoop

    sc = scenario(b, model, 0, cells_per_metre)
    n = sc.crowd.n
    start = time.perf_counter()
    loop = ClosedLoop(sc)
    crowd, grid = loop.crowd, loop.grid
    times, out = [0.0], [0.0]
    peak = peak_cell = peak_time = 0.0

    def look() -> None:
        nonlocal peak, peak_cell, peak_time
        persons = n * crowd.rho
        local = float(disk_density(grid, persons * grid.volume)[grid.active].max())
        peak_cell = max(peak_cell, float(persons[grid.active].max()))
        if local > peak:
            peak, peak_time = local, loop.t

    look()
    while loop.t < sc.t_final - 1e-9 and out[-1] < n - 0.5:
        loop.step()
        times.append(loop.t)
        out.append(n * float(crowd.out_per_exit.sum()) / crowd.initial_mass)  # the solver's count (mass_out)
        look()
    t, persons_out = np.array(times), np.array(out)
    flow = pde_flow(t, persons_out, n)
    rate = np.diff(persons_out) / np.diff(t)
    return {
        "model": model,
        "radius": None,
        "width": b,
        "seed": 0,
        "cells_per_metre": cells_per_metre,
        "flow": flow,
        "specific_flow": None if flow is None else flow / b,
        "out": float(persons_out[-1]),
        "time_all_out": float(t[-1]) if persons_out[-1] >= n - 0.5 else None,
        "peak_local_density": peak,
        "peak_local_density_time": peak_time,
        "peak_cell_density": peak_cell,
        "peak_kde_density": None,
        "peak_exit_flow": float(rate.max()),
        "exit_capacity": float(crowd.fp.congestion.door * n * b) if crowd.fp.congestion is not None else None,
        "fokker_planck_method": crowd.fp.method,
        "wall_seconds": time.perf_counter() - start,
    }


def _key(row: dict[str, Any]) -> tuple:
    return row["model"], row["radius"], row["width"], row["seed"], row.get("cells_per_metre")


def _pde_grid(row: dict[str, Any]) -> bool:
    """A run of the density on another grid than the scenario's (its grid convergence, reported apart)."""
    return row.get("cells_per_metre") not in (None, PDE_CELLS_PER_METRE)


def _rows() -> list[dict[str, Any]]:
    if not RESULTS.exists():
        return []
    return [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]


def run_all(
    seeds: int,
    models: list[str],
    radii: list[float],
    workers: int,
    widths: tuple[float, ...] = WIDTHS,
    cells_per_metre: tuple[int, ...] = (PDE_CELLS_PER_METRE,),
) -> None:
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    done = {_key(r) for r in _rows()}
    jobs = []
    for model in (m for m in models if is_pde(m)):  # deterministic: one run per width and grid
        for k in cells_per_metre:
            for b in widths:
                if (model, None, b, 0, k) not in done:
                    jobs.append((one_pde_run, (b, model, k)))
    for seed in range(seeds):
        for model in (m for m in models if not is_pde(m)):
            for radius in radii if model in ("weidmann", "linear") else [None]:
                for b in widths:
                    job = (b, model, radius if radius is not None else 0.6, seed)
                    if (model, radius, b, seed, None) not in done:
                        jobs.append((one_run, job))
    print(f"{len(jobs)} runs to do", flush=True)
    with ProcessPoolExecutor(workers) as pool, RESULTS.open("a") as out:
        futures = {pool.submit(fn, *job): job for fn, job in jobs}
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
    farthest outside the measured range, the first seed when every one is inside; NaN where every seed clogged)."""
    import warnings

    warnings.filterwarnings("ignore", "All-NaN slice", RuntimeWarning)  # every seed clogged: NaN, shown as "–"
    rows = _rows()
    groups: dict[str, dict[float, list[dict]]] = {}
    for r in rows:
        if not _pde_grid(r):
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
    out["pde_grid_convergence"] = grid_convergence(rows)
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    REPORT.write_text(json.dumps(out, indent=1) + "\n")
    return out


def grid_convergence(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The density's ``J/b`` per model and width on each grid that was run (cells per metre: value), at the
    widths where more than one grid was run."""
    table: dict[str, dict[str, dict[str, float | None]]] = {}
    for r in rows:
        if is_pde(r["model"]):
            k = r.get("cells_per_metre") or PDE_CELLS_PER_METRE
            table.setdefault(r["model"], {}).setdefault(str(r["width"]), {})[str(k)] = r["specific_flow"]
    out = {}
    for model, widths in sorted(table.items()):
        runs = {b: dict(sorted(g.items(), key=lambda kv: int(kv[0]))) for b, g in sorted(widths.items()) if len(g) > 1}
        if runs:
            out[model] = runs
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
                if len(p["seeds_without_flow"]) == p["seeds"]:  # every seed clogged: no flow to show
                    cells.append(f"– ({clogged[2:]})")
                elif p["seeds"] == 1 and not clogged:  # one run (the density): no spread to show
                    cells.append(f"{p['specific_flow_median']:.2f}")
                else:
                    cells.append(f"{p['specific_flow_median']:.2f} ({lo:.2f}–{hi:.2f}{clogged})")
        peaks = [p["peak_local_density_median"] for p in m["per_width"].values()]
        grows = "yes" if m["flow_grows_with_width"] else "no"
        rms = m["rms_specific_flow_minus_liddle"]
        rms_cell = "–" if rms is None else f"{rms:.2f}"
        peak_cell = f"{min(peaks):.0f}–{max(peaks):.0f}" if max(peaks) >= 10 else f"{min(peaks):.1f}–{max(peaks):.1f}"
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {grows} | {rms_cell} | {peak_cell} |")
    conv = rep.get("pde_grid_convergence") or {}
    if conv:
        lines.append("")
        grids = sorted({int(k) for m in conv.values() for w in m.values() for k in w})
        lines.append("| model, b | " + " | ".join(f"h = {1 / k:g} m" for k in grids) + " |")
        lines.append("|---" * (len(grids) + 1) + "|")
        for model, by_width in conv.items():
            for b, per in by_width.items():
                vals = [per.get(str(k)) for k in grids]
                row = " | ".join("–" if v is None else f"{v:.3f}" for v in vals)
                lines.append(f"| {model}, b = {float(b):g} m | {row} |")
    return "\n".join(lines)


def figures(rep: dict[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    lo, hi = MEASURED_RANGE
    lw, lf = np.array(LIDDLE["width"]), np.array(LIDDLE["flow"])
    styles = {"none": "s", "weidmann": "o", "linear": "^", "jupedsim": "D", "pde-linear": "v", "pde-weidmann": "P"}
    styles |= {"pde-hughes": "X", "pde-hughes-weidmann": "h"}
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
            if is_pde(label):  # deterministic: one run per width, dashed
                ax.plot(ws, med, marker=marker, ls="--", ms=8, label=f"{label} (density, one run)")
                continue
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


SNAPSHOT_TIMES = (10.0, 25.0, 40.0)
"""s: when :func:`pde_snapshots` draws the density in the widest bottleneck."""
SNAPSHOT_FIGURES = {"pde-linear": "congestion_pde.png", "pde-hughes": "congestion_pde_hughes.png"}
"""The density's models that ``--snapshots`` draws, and their figures in ``docs/figures``."""


def pde_snapshots(model: str = "pde-linear", widths: tuple[float, ...] = (1.0, 2.5)) -> None:
    """``docs/figures/`` :data:`SNAPSHOT_FIGURES` ``[model]``: the density ``N ρ`` (persons/m²) in the widest
    bottleneck at :data:`SNAPSHOT_TIMES`, and the exit's flow against time for ``widths`` beside its capacity
    ``q_max b``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from meanfield.simulation.loop import ClosedLoop

    fig, axes = plt.subplots(1, len(SNAPSHOT_TIMES) + 1, figsize=(15, 3.6))
    widest = max(widths)
    for b in widths:
        sc = scenario(b, model, 0)
        loop = ClosedLoop(sc)
        crowd, grid, n = loop.crowd, loop.grid, sc.crowd.n
        times, out = [0.0], [0.0]
        while loop.t < sc.t_final - 1e-9 and out[-1] < n - 0.5:
            loop.step()
            times.append(loop.t)
            out.append(n * float(crowd.out_per_exit.sum()) / crowd.initial_mass)
            k = [i for i, ts in enumerate(SNAPSHOT_TIMES) if abs(loop.t - ts) < 1e-9]
            if b == widest and k:
                ax = axes[k[0]]
                rho = np.where(grid.active, n * crowd.rho, np.nan)
                x0, x1, y0, y1 = grid.domain.bounds
                im = ax.imshow(rho.T, origin="lower", extent=(x0, x1, y0, y1), vmin=0, vmax=sc.crowd.rho_max)
                ax.set_title(f"b = {b:g} m, t = {loop.t:g} s, {out[-1]:.0f} of {n} out", fontsize=9)
                ax.set_xlabel("x (m)")
                ax.set_ylabel("y (m)")
                fig.colorbar(im, ax=ax, label="N ρ (persons/m²)", shrink=0.8)
        t, p = np.array(times), np.array(out)
        window = 20  # 1 s
        rate = (p[window:] - p[:-window]) / (t[window:] - t[:-window])
        line = axes[-1].plot(0.5 * (t[window:] + t[:-window]), rate, label=f"b = {b:g} m")[0]
        cap = crowd.fp.congestion.door * n * b
        axes[-1].axhline(cap, color=line.get_color(), ls=":", label=f"capacity q_max b = {cap:.2f}")
    axes[-1].set_xlabel("t (s)")
    axes[-1].set_ylabel("exit flow (persons/s, 1 s mean)")
    axes[-1].set_title(f"{model}: the exit's flow", fontsize=9)
    axes[-1].legend(fontsize=7)
    axes[-1].grid(alpha=0.3)
    fig.tight_layout()
    FIGURES.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURES / SNAPSHOT_FIGURES[model], dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--models", nargs="+", default=["none", "weidmann", "linear"])
    parser.add_argument("--radii", nargs="+", type=float, default=[0.6])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--widths", nargs="+", type=float, default=list(WIDTHS))
    parser.add_argument(
        "--cells-per-metre", nargs="+", type=int, default=[PDE_CELLS_PER_METRE], help="the density's grids"
    )
    parser.add_argument("--report", action="store_true", help="only the JSON, the table and the figures")
    parser.add_argument(
        "--snapshots", action="store_true", help="also draw the density in the bottleneck (congestion_pde*.png)"
    )
    args = parser.parse_args()
    unknown = [m for m in args.models if is_pde(m) and m not in PDE_MODELS]
    if unknown:
        parser.error(f"unknown density models {unknown}: one of {sorted(PDE_MODELS)}")
    if not args.report:
        run_all(args.seeds, args.models, args.radii, args.workers, tuple(args.widths), tuple(args.cells_per_metre))
    rep = report()
    print(table(rep))
    figures(rep)
    if args.snapshots:
        for model in SNAPSHOT_FIGURES:
            pde_snapshots(model)


if __name__ == "__main__":
    main()
