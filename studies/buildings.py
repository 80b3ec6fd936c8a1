"""Robot guidance against the baselines on the shipped floor plans (docs page *Buildings*).

Run from the repository's root::

    python studies/buildings.py [--seeds 5] [--backends point-mass jupedsim] [--workers N] [--settings ...]

(``--workers``: Dask worker processes, default every core; each row is written as its run finishes.)

For each built-in plan (``l-room``, ``office``, ``hall``, ``hall-crowded-west``), seed and backend it runs

* robot guidance by the paper's Step II towards the exits (``controller.kind = "evacuation"``)
  with 4, 8 and 16 robots;
* static signs (``controller.kind = "static-signs"``) with 4, 8 and 16 robots;
* robot guidance by coverage and heading (``controller.kind = "coverage"``, the plans'
  default) with 4, 8 and 16 robots;
* the informed crowd (``crowd.guidance = "geodesic"``) and the uninformed crowd
  (``crowd.guidance = "random-walk"``), which have no use for robots;
* coverage with either metric (``walking coverage n``, ``straight coverage n``: the option
  ``controller.options.coverage.metric``), and with its signs turned to the nearest exits or to the exits
  balanced by their capacities (``nearest coverage 8``, ``balanced coverage 8``: the option
  ``controller.options.coverage.potential``, ``"distance"`` or ``"balanced"``);
* coverage 8 and 16, static 8 and evacuation 8 with people who remember the way once a sign has
  reached them (the label's ending ``, people remember``: ``view.memory = "route"``, the nearest
  exit; ``, people remember the sign's exit``: ``"sign"``), and coverage whose robots go where no
  sign has reached lately (``sweeping coverage n``: ``controller.options.coverage.weight = "unswept"``), its
  robots walking to a centroid they do not see (``routed ...``: ``controller.options.coverage.metric = "routed"``);
* the closed-exit variant of the informed crowd, static 8, coverage 8 and 16 and evacuation 8
  (the label's ending ``, exit 0 shut at 10 s``: ``[[events]]`` closes exit 0 at t = 10 s, the
  informed crowd re-plans), on the plans with two exits or more; its ratios are to the
  informed crowd of the same variant;
* the blocked variant of the informed crowd, static 8, evacuation 8 and coverage 8, static 8 and
  routed sweeping coverage 8 with people who remember (the label's ending ``, a region blocked at
  5 s``: ``[[events]] block``, the region :data:`BLOCKS` of the plan becomes wall at t = 5 s, on
  ``l-room``, ``office`` (the corridor blocked across: two halves, each with its exit) and ``hall``, for
  the crowds that declare ``changes_walls``: the point masses); its ratios are to the informed crowd of
  the same variant;

every setting whose label names no memory with the paper's humans (``view.memory = "none"``, set by
:func:`one_run`: the plans' default became ``"auto"``, ``"sign"`` in SI plans, after the table's first rows) and,
on :data:`BALANCED_BY_DEFAULT`, coverage whose label names no potential with the balanced one, and keeps each run's
evacuation figures in ``studies/results/buildings.jsonl`` (one line per run, appended as each finishes, so that an
interrupted study resumes where it stopped). The crowds walk by the plans' own ``crowd.congestion = "auto"``: point
masses by the linear diagram and their default door model, the headway (docs page *Congestion*), JuPedSim's bodies
by their own model; each row records the models (``congestion``, ``"none"`` for rows written before congestion;
``door_model``, ``"count"`` for rows written before the headway became the default), and the table reads the rows
of the models given by ``--congestion`` (``auto``: the plans' defaults) and today's door models. The table counts
the runs whose RSET is below the flow bound (``lower_bound_flow``: the crowd over the exits' width at the largest
specific flow measured, 2.5 persons/(m·s)), which no crowd that queues as people do beats. Then it prints the table
of the docs page (``--table``: only the table, from the file) and draws ``docs/figures/buildings_evacuation.png``.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

PLANS = ("l-room", "office", "hall", "hall-crowded-west")
SETTINGS = {  # label: overrides
    **{f"evacuation {n}": {"robots.n": n, "controller.kind": "evacuation"} for n in (4, 8, 16)},
    **{f"static {n}": {"robots.n": n, "controller.kind": "static-signs", "controller.options": {}} for n in (4, 8, 16)},
    **{f"coverage {n}": {"robots.n": n, "controller.kind": "coverage"} for n in (4, 8, 16)},
    **{
        f"{m} coverage {n}": {"robots.n": n, "controller.kind": "coverage", "controller.options.coverage.metric": m}
        for m in ("walking", "straight")
        for n in (8, 16)
    },
    "informed": {
        "crowd.guidance": "geodesic", "robots.n": 4, "controller.kind": "static-signs", "controller.options": {}
    },
    "uninformed": {
        "crowd.guidance": "random-walk", "robots.n": 4, "controller.kind": "static-signs", "controller.options": {}
    },
}
SETTINGS.update(
    {
        f"{name} coverage 8": {
            "robots.n": 8, "controller.kind": "coverage", "controller.options.coverage.potential": p
        }
        for name, p in (("nearest", "distance"), ("balanced", "balanced"))
    }
)
SETTINGS.update(
    {
        f"{s}, people remember{what}": {**SETTINGS[s], "view.memory": memory}
        for s in ("coverage 8", "coverage 16", "static 8", "evacuation 8")
        for what, memory in (("", "route"), (" the sign's exit", "sign"))
    }
)
SETTINGS.update(
    {
        f"sweeping coverage {n}, people remember{what}": {
            "robots.n": n, "controller.kind": "coverage", "controller.options.coverage.weight": "unswept",
            "view.memory": memory,
        }
        for n in (8, 16)
        for what, memory in (("", "route"), (" the sign's exit", "sign"))
    }
)
SETTINGS.update(
    {
        "routed coverage 8": {
            "robots.n": 8, "controller.kind": "coverage", "controller.options.coverage.metric": "routed"
        },
        **{
            f"routed sweeping coverage 8, people remember{what}": {
                "robots.n": 8, "controller.kind": "coverage", "controller.options.coverage.metric": "routed",
                "controller.options.coverage.weight": "unswept", "view.memory": memory,
            }
            for what, memory in (("", "route"), (" the sign's exit", "sign"))
        },
    }
)
SHUT = ", exit 0 shut at 10 s"
"""The closed-exit variant of a setting: exit 0 closes at t = 10 s (``[[events]]``); on plans with two exits or more."""
SETTINGS.update(
    {
        s + SHUT: {**SETTINGS[s], "events": [{"time": 10.0, "close_exit": 0}]}
        for s in (
            "informed", "static 8", "coverage 8", "coverage 16", "evacuation 8", "static 8, people remember",
            "sweeping coverage 8, people remember", "routed sweeping coverage 8, people remember",
        )
    }
)
BLOCK = ", a region blocked at 5 s"
"""The blocked variant of a setting: at t = 5 s the plan's region :data:`BLOCKS` becomes wall (``[[events]]``)."""
BLOCKS = {
    "l-room": "POLYGON ((14 -1, 17 -1, 17 5.5, 14 5.5, 14 -1))",  # the corridor before the door, 2.5 m left open
    "hall": "POLYGON ((24 2, 27 2, 27 18, 24 18, 24 2))",  # before the east door, 2 m left open at either end
    "office": "POLYGON ((14.5 5.9, 15.5 5.9, 15.5 8.1, 14.5 8.1, 14.5 5.9))",  # the corridor across: two halves
}
"""Where the blocked variant's region is, on the plans that have one (m)."""
SETTINGS.update(
    {
        s + BLOCK: dict(SETTINGS[s])
        for s in (
            "informed", "static 8", "coverage 8", "evacuation 8", "static 8, people remember",
            "routed sweeping coverage 8, people remember",
        )
    }
)
VARIANTS = (SHUT, BLOCK)
"""The endings of the variants' labels: each setting's ratio is to the informed crowd of the same variant."""
BALANCED_BY_DEFAULT = ("hall-crowded-west",)
"""The plans whose coverage rows sign the exits balanced by their capacities unless the setting names a potential:
the plan's own option before the guide became its default (2026-12-05), which the table's rows were measured with."""
RESULTS = Path("studies/results/buildings.jsonl")
KEYS = (
    "fraction_evacuated",
    "evacuation_time_95",
    "evacuation_time_100",
    "evacuation_lower_bound",
    "lower_bound_walk",
    "lower_bound_flow",
    "design_flow_time",
    "peak_density",
    "crush_risk",
    "time_final",
    "wall_seconds",
)


def one_run(plan: str, setting: str, seed: int, backend: str, congestion: str = "auto") -> dict:
    """One run's evacuation figures (the baselines' robots are parked and seen by no one)."""
    from meanfield import run
    from meanfield.scenarios.scenario import builtin_scenarios

    values = dict(SETTINGS[setting])
    # A setting that names no memory is the paper's humans, as its label says: the plans' default became
    # view.memory = "auto" ("sign" in SI plans) after the table's first rows (2026-12-05); the baselines ignore it.
    values.setdefault("view.memory", "none")
    if plan in BALANCED_BY_DEFAULT and values.get("controller.kind") == "coverage":
        values.setdefault("controller.options.coverage.potential", "balanced")
    if setting.endswith(BLOCK):
        values["events"] = [{"time": 5.0, "block": BLOCKS[plan]}]
    sc = builtin_scenarios()[plan](seed=seed).with_values({**values, "crowd.kind": backend})
    sc = sc.with_values({"crowd.congestion": congestion}) if congestion != "auto" else sc
    result = run(sc, progress=False)
    s = result.summary
    frames = result.timeseries  # the recorded frames, without xarray (result.dataset would import it)
    return {
        "plan": plan,
        "setting": setting,
        "seed": seed,
        "backend": backend,
        "congestion": sc.congestion_model,
        "door_model": sc.door_model,
        **{k: s.get(k) for k in KEYS},
        "curve_t": frames["time"].values.tolist(),
        "curve": frames["fraction_evacuated"].values.tolist(),
    }


def _exits(plan: str) -> int:
    """How many exits the plan has."""
    from meanfield.scenarios.scenario import builtin_scenarios

    return len(builtin_scenarios()[plan]().domain.exits)


def _model(plan: str, backend: str, congestion: str) -> tuple[str, str]:
    """The congestion model and door model a run of ``plan`` with ``backend`` walks by (``auto``: the plan's
    defaults; the door model is ``"count"`` for a crowd kind that has none of its own, which ignores it)."""
    from meanfield.scenarios.scenario import builtin_scenarios

    sc = builtin_scenarios()[plan]().with_values({"crowd.kind": backend})
    return (sc.congestion_model if congestion == "auto" else congestion), sc.door_model


def _rows(congestion: str) -> list[dict]:
    """The results of the runs by ``congestion`` and today's door model (rows without the keys ran before
    congestion, ``none``, or before the door models, ``count``)."""
    if not RESULTS.exists():
        return []
    rows = [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]
    for r in rows:
        r.setdefault("congestion", "none")
        r.setdefault("door_model", "count")
    models = {(p, b): _model(p, b, congestion) for p, b in {(r["plan"], r["backend"]) for r in rows}}
    return [r for r in rows if (r["congestion"], r["door_model"]) == models[r["plan"], r["backend"]]]


def _walk(row: dict) -> str:
    """How the row's crowd walks: its congestion model, and its door model where its kind has door models of its own
    (a kind whose queues are its own takes only ``"count"``, which it ignores)."""
    from meanfield.plugins import capabilities

    has_doors = capabilities("crowd", row["backend"]).door_models != ("count",)
    return f"{row['congestion']}, {row['door_model']}" if has_doors else row["congestion"]


def _done(congestion: str) -> set[tuple]:
    return {(r["plan"], r["setting"], r["seed"], r["backend"]) for r in _rows(congestion)}


def one_job(job: tuple) -> dict:
    """:func:`one_run` of a job ``(plan, setting, seed, backend, congestion)`` (a Dask worker's call)."""
    return one_run(*job)


def run_all(
    seeds: int, backends: list[str], workers: int | None, congestion: str = "auto", settings: list[str] | None = None
) -> None:
    """Run every case not in :data:`RESULTS` yet on the Dask cluster of the sweeps (``workers`` processes, default
    every core; :func:`meanfield.workflows.dask_cluster.map_jobs`), appending each row as it finishes."""
    from meanfield import plugins
    from meanfield.workflows.dask_cluster import map_jobs

    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    done = _done(congestion)
    todo = [
        (p, s, k, b, congestion)
        for b in backends
        for p in PLANS
        for s in (settings or SETTINGS)
        for k in range(seeds)
        if (p, s, k, b) not in done and (not s.endswith(SHUT) or _exits(p) > 1)
        and (not s.endswith(BLOCK) or (p in BLOCKS and plugins.capabilities("crowd", b).changes_walls))
    ]
    print(f"{len(todo)} runs to do")
    finished = 0
    with RESULTS.open("a") as out:

        def keep(k: int, row: dict) -> None:  # each row on disk as it finishes: an interrupted study resumes
            nonlocal finished
            finished += 1
            out.write(json.dumps(row) + "\n")
            out.flush()
            os.fsync(out.fileno())
            out_share, t100 = row["fraction_evacuated"], row["evacuation_time_100"]
            print(f"[{finished}/{len(todo)}] {todo[k]}: out {out_share:.3f}, t100 {t100}")

        map_jobs(one_job, todo, workers, "buildings", False, on_result=keep)


def table(backends: list[str], congestion: str = "auto") -> str:
    """The docs page's table: per plan, crowd model and setting, medians and worst seeds.

    A time that was not reached within the run (``t_final``) counts as infinite; its ratios
    are then printed as lower bounds, ``> t_final / informed``.  "Below the flow bound" counts
    the runs whose RSET is under ``lower_bound_flow`` (physically impossible).
    """
    rows = _rows(congestion)
    lines = [
        "| plan | crowd | setting | out at the end, median (worst) | 95 % out, s | everyone out (RSET), s |"
        " RSET ÷ informed | RSET ÷ bound | below the flow bound | peak persons/m² |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def times(rs: list[dict], key: str) -> np.ndarray:
        return np.array([np.inf if r[key] is None else r[key] for r in rs])

    def fmt(x: float, horizon: float) -> str:
        return f"> {horizon:.0f}" if not np.isfinite(x) else f"{x:.1f}"

    def ratio(x: float, over: float, horizon: float) -> str:
        if not np.isfinite(over):
            return "—"
        return f"> {horizon / over:.1f}" if not np.isfinite(x) else f"{x / over:.2f}"

    for b in backends:
        for p in PLANS:
            here = [r for r in rows if r["plan"] == p and r["backend"] == b]
            runs = {s: [r for r in here if r["setting"] == s] for s in SETTINGS}
            informed_of = {
                label: float(np.median(times(runs[label], "evacuation_time_100"))) if runs[label] else np.inf
                for label in ("informed", *("informed" + v for v in VARIANTS))
            }
            for s, rs in runs.items():
                if not rs:
                    continue
                informed = informed_of["informed" + next((v for v in VARIANTS if s.endswith(v)), "")]
                horizon = max(r["time_final"] for r in rs)
                out = np.array([r["fraction_evacuated"] for r in rs])
                t95, t100 = times(rs, "evacuation_time_95"), times(rs, "evacuation_time_100")
                med95, med100 = float(np.median(t95)), float(np.median(t100))
                bound = float(np.median([r["evacuation_lower_bound"] for r in rs]))
                peak = np.array([r["peak_density"] for r in rs])
                below = sum(1 for r, t in zip(rs, t100, strict=True) if t < r["lower_bound_flow"])
                lines.append(
                    f"| {p} | {b} ({_walk(rs[0])}) | {s} ({len(rs)} seeds) | {np.median(out):.3f}"
                    f" ({out.min():.3f}) | {fmt(med95, horizon)} ({fmt(t95.max(), horizon)}) | {fmt(med100, horizon)}"
                    f" ({fmt(t100.max(), horizon)}) | {ratio(med100, informed, horizon)} |"
                    f" {ratio(med100, bound, horizon)} | {below} of {len(rs)} |"
                    f" {np.median(peak):.1f} ({peak.max():.1f}) |"
                )
    return "\n".join(lines)


def figure(backends: list[str], congestion: str = "auto", path: str = "docs/figures/buildings_evacuation.png") -> None:
    """The median evacuation curve of each setting on each plan (one panel per plan and crowd)."""
    from meanfield.io.atomic import save_figure, subplots

    rows = _rows(congestion)
    fig, axes = subplots(len(backends), len(PLANS), figsize=(4.2 * len(PLANS), 3.4 * len(backends)), squeeze=False)
    shown = ("evacuation 8", "evacuation 16", "coverage 8", "coverage 16", "static 8", "informed", "uninformed",
             "nearest coverage 8", "sweeping coverage 8, people remember")  # fmt: skip
    colour = {s: f"C{i}" for i, s in enumerate(shown)}  # the same colour for a setting on every panel
    for bi, b in enumerate(backends):
        for pi, p in enumerate(PLANS):
            ax = axes[bi][pi]
            for s in shown:
                rs = [r for r in rows if r["plan"] == p and r["backend"] == b and r["setting"] == s]
                if not rs:
                    continue
                t = max((r["curve_t"] for r in rs), key=len)
                curves = np.array([np.interp(t, r["curve_t"], r["curve"], right=r["curve"][-1]) for r in rs])
                wide = s.startswith(("evacuation", "coverage"))
                style = "--" if "16" in s else ":" if s.startswith("nearest") else "-." if "remember" in s else "-"
                ax.plot(t, np.median(curves, axis=0), label=s, color=colour[s], lw=1.6 if wide else 1.1, ls=style)
            model = _walk(rs[0]) if rs else "?"
            ax.set(title=f"{p} — {b} ({model})", xlabel="time (s)", ylabel="fraction evacuated (median of seeds)")
            ax.set_ylim(0, 1.02)
            ax.grid(alpha=0.3)
    for ax in axes[0]:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    save_figure(fig, path)
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--backends", nargs="+", default=["point-mass", "jupedsim"])
    ap.add_argument("--workers", type=int, default=None, help="Dask worker processes (default: every core)")
    ap.add_argument("--congestion", default="auto", help="crowd.congestion of every run (auto: the plans' defaults)")
    ap.add_argument("--settings", nargs="+", choices=list(SETTINGS), default=None, help="only these settings (all)")
    ap.add_argument("--table", action="store_true", help="only print the table and draw the figure from the results")
    args = ap.parse_args()
    if not args.table:
        run_all(args.seeds, args.backends, args.workers, args.congestion, args.settings)
    print(table(args.backends, args.congestion))
    figure(args.backends, args.congestion)


if __name__ == "__main__":
    main()
