"""The guide against the crowd that knows the way, on every shipped plan with exits (docs: *Buildings*, "The guide").

Run from the repository's root::

    python studies/guide.py [--seeds 10] [--workers N] [--plans ...] [--settings ...] [--table]

For each plan and seed it runs the informed crowd (``crowd.guidance = "geodesic"``) and, on the four building plans,
the uninformed crowd, static signs (8), the paper's Step II towards the exits (``evacuation 8``) and the guide
(``controller.kind = "guide"``, the plans' default) with 4, 8 and 16 robots; on ``bottleneck`` and the RiMEA plans,
whose own default is the informed crowd, the guide with 4, 8 and 16 robots (their people then read the signs:
``crowd.guidance = "signs"``).  The variants of the guide with 8 robots, each against the informed crowd of the same
variant: JuPedSim's bodies (``, bodies``), exit 0 closed at 10 s (``, exit 0 shut at 10 s``, with static signs too),
a region that becomes wall at 5 s (``, a region blocked at 5 s``) and compliance 0.95 (``, compliance 0.95``).

People read the signs as the plans' default says (``view.memory = "auto"``: who a sign reaches walks to the exit
it names).  Each run's figures are appended to ``studies/results/guide.jsonl`` as it finishes, so an interrupted
study resumes.  Each row records how its crowd walks (``walk``, :func:`walk_of`: the point masses' door model and
(H5), the noise among contacts, whether the plan's inner doors are capped, or JuPedSim's bodies); the table reads
only the rows of today's model, and a case whose row was written by an older one is run again (rows without ``walk``
predate (H5), 2026-12-06; rows of a plan with doors without ``inner doors capped`` predate the doors, the same day).
The table gives, per plan and setting, the share out at the end and RSET (everyone out) as the
median and worst seed, and the
ratio to the informed crowd's RSET on the same seed, median and worst; the last column of the guide's rows is the
smallest team of 4, 8 and 16 whose median ratio is at most 1.1 (the robots a building needs).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
from pathlib import Path

import numpy as np

BUILDINGS = ("l-room", "office", "hall", "hall-crowded-west")
"""The building plans: their default is the guide."""
INFORMED_PLANS = ("bottleneck", "rimea-9", "rimea-10", "rimea-12")
"""Plans whose default is the informed crowd (RiMEA's tests): the guide runs with people who read the signs."""
PLANS = BUILDINGS + INFORMED_PLANS
GUIDE = {"controller.kind": "guide", "crowd.guidance": "signs", "controller.options": {}}
SHUT = ", exit 0 shut at 10 s"
BLOCK = ", a region blocked at 5 s"
BODIES = ", bodies"
COMPLIANCE = ", compliance 0.95"
VARIANTS = (SHUT, BLOCK, BODIES, COMPLIANCE)
"""The endings of the variants' labels: each is compared with the informed crowd of the same variant."""
BLOCKS = {
    "l-room": "POLYGON ((14 -1, 17 -1, 17 5.5, 14 5.5, 14 -1))",
    "hall": "POLYGON ((24 2, 27 2, 27 18, 24 18, 24 2))",
    "office": "POLYGON ((14.5 5.9, 15.5 5.9, 15.5 8.1, 14.5 8.1, 14.5 5.9))",
}
"""The blocked variant's region (the buildings study's, ``studies/buildings.py``)."""
STANDING = {"controller.kind": "static-signs", "controller.options": {}}
"""The robots of the baselines: their crowd reads no sign, so the plan's robots (as many) stand with their signs
rather than run the plan's controller, whose work changes none of the crowd's figures (the crowd's positions are
the same to the last bit: ``tests/scenarios/test_baselines_read_no_sign.py``), and costs up to 70 % of a step."""
SETTINGS: dict[str, dict] = {
    "informed": {"crowd.guidance": "geodesic", **STANDING},
    "uninformed": {"crowd.guidance": "random-walk", **STANDING},
    "static 8": {"controller.kind": "static-signs", "robots.n": 8, "crowd.guidance": "signs"},
    "evacuation 8": {"controller.kind": "evacuation", "robots.n": 8, "crowd.guidance": "signs",
                     "controller.options": {}},  # fmt: skip
    **{f"guide {n}": {**GUIDE, "robots.n": n} for n in (4, 8, 16)},
}
SETTINGS.update({s + SHUT: {**SETTINGS[s], "events": [{"time": 10.0, "close_exit": 0}]}
                 for s in ("informed", "static 8", "guide 8")})  # fmt: skip
SETTINGS.update({s + BLOCK: dict(SETTINGS[s]) for s in ("informed", "guide 8")})
SETTINGS.update({s + BODIES: {**SETTINGS[s], "crowd.kind": "jupedsim"} for s in ("informed", "guide 8")})
SETTINGS.update({"informed" + COMPLIANCE: dict(SETTINGS["informed"]),
                 "guide 8" + COMPLIANCE: {**SETTINGS["guide 8"], "crowd.compliance": 0.95}})  # fmt: skip
RESULTS = Path("studies/results/guide.jsonl")
CAPPING = ("headway", "forward-cell")  # the door models that cap the exits and the plan's inner doors
KEYS = ("status", "fraction_evacuated", "evacuation_time_95", "evacuation_time_100", "lower_bound_flow", "time_final",
        "wall_seconds", "evacuated_per_exit")  # fmt: skip


def walk_of(scenario) -> str:
    """How the crowd of ``scenario`` walks, as a row records it: the point masses' door model, with (H5)'s power
    when the headway adds it (docs page *Congestion*, "The headway door model"), or the crowd's kind."""
    from meanfield.crowds._headway_loops import CONTACT_NOISE_POWER

    if scenario.crowd.kind != "point-mass":
        return scenario.crowd.kind
    model = scenario.door_model
    walk = f"{model}, (H5) m = {CONTACT_NOISE_POWER:g}" if model == "headway" else model
    if model in CAPPING and len(getattr(scenario.domain, "doors", ())):  # (the plan's inner doors, 2026-12-06)
        walk += ", inner doors capped"
    return walk


@functools.cache
def _today(plan: str, setting: str) -> str:
    """:func:`walk_of` a run of ``setting`` on ``plan`` today."""
    from meanfield.scenarios.scenario import builtin_scenarios

    return walk_of(builtin_scenarios()[plan]().with_values(SETTINGS[setting]))


def _walked(row: dict) -> str:
    """How a row's crowd walked (rows without ``walk``: the point masses before (H5), or JuPedSim's bodies)."""
    return row.get("walk", "jupedsim" if row["setting"].endswith(BODIES) else "before (H5)")


def applies(plan: str, setting: str) -> bool:
    """Whether ``setting`` is run on ``plan``: the baselines and variants on the building plans (a closed exit where
    there are two exits or more, a block where the plan has one), the informed crowd and the guide everywhere."""
    from meanfield.scenarios.scenario import builtin_scenarios

    if setting.endswith(SHUT):
        return plan in BUILDINGS and len(builtin_scenarios()[plan]().domain.exits) > 1
    if setting.endswith(BLOCK):
        return plan in BLOCKS
    if setting.endswith((BODIES, COMPLIANCE)):
        return plan in BUILDINGS
    return plan in BUILDINGS or setting == "informed" or setting.startswith("guide")


def one_run(job: tuple) -> dict:
    """One run's figures: ``job = (plan, setting, seed)``."""
    from meanfield import run
    from meanfield.scenarios.scenario import builtin_scenarios

    plan, setting, seed = job
    values = dict(SETTINGS[setting])
    if setting.endswith(BLOCK):
        values["events"] = [{"time": 5.0, "block": BLOCKS[plan]}]
    sc = builtin_scenarios()[plan](seed=seed).with_values(values)
    s = run(sc, progress=False).summary
    return {"plan": plan, "setting": setting, "seed": seed, "robots": sc.robots.n, "memory": sc.memory,
            "walk": walk_of(sc), **{k: s.get(k) for k in KEYS}}  # fmt: skip


def rows() -> list[dict]:
    """The rows on disk of today's model (:func:`walk_of`)."""
    if not RESULTS.exists():
        return []
    every = [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]
    return [r for r in every if _walked(r) == _today(r["plan"], r["setting"])]


def run_all(seeds: int, workers: int | None, plans: list[str], settings: list[str]) -> None:
    """Run every case not on disk yet (Dask workers, :func:`meanfield.workflows.dask_cluster.map_jobs`), appending
    each row as it finishes."""
    from meanfield.workflows.dask_cluster import map_jobs

    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    done = {(r["plan"], r["setting"], r["seed"]) for r in rows()}
    todo = [(p, s, k) for p in plans for s in settings for k in range(seeds)
            if applies(p, s) and (p, s, k) not in done]  # fmt: skip
    print(f"{len(todo)} runs to do")
    finished = 0
    with RESULTS.open("a") as out:

        def keep(k: int, row: dict) -> None:
            nonlocal finished
            finished += 1
            if row["status"] == "interrupted":  # (a worker stopped by a signal ends its run early: not a result)
                print(f"[{finished}/{len(todo)}] {todo[k]}: interrupted, not kept", flush=True)
                return
            out.write(json.dumps(row) + "\n")
            out.flush()
            os.fsync(out.fileno())
            print(f"[{finished}/{len(todo)}] {todo[k]}: out {row['fraction_evacuated']:.3f}, "
                  f"t100 {row['evacuation_time_100']}", flush=True)  # fmt: skip

        map_jobs(one_run, todo, workers, "guide", False, on_result=keep)


def _rset(r: dict) -> float:
    return np.inf if r["evacuation_time_100"] is None else float(r["evacuation_time_100"])


def _fmt(x: float, bound: float, digits: int) -> str:
    """``x``, or ``> bound`` for a run that did not end by the horizon (infinite)."""
    return f"{x:.{digits}f}" if np.isfinite(x) else f"> {bound:.{digits - 1}f}"


def table(seeds: int) -> str:
    """Per plan and setting: RSET (median, worst) and RSET over the informed crowd's on the same seed (median,
    worst); for the guide, the smallest team of 4, 8, 16 whose median ratio is at most 1.1."""
    by = {(r["plan"], r["setting"], r["seed"]): r for r in rows() if r["seed"] < seeds}
    lines = ["| plan | setting | seeds | out at the end: median (worst) | RSET, s: median (worst) |"
             " ÷ informed, same seed: median (worst) |", "|---|---|---|---|---|---|"]  # fmt: skip
    needs = []
    for p in PLANS:
        ratios_of: dict[str, np.ndarray] = {}
        for s in SETTINGS:
            got = [by[(p, s, k)] for k in range(seeds) if (p, s, k) in by]
            if not got:
                continue
            t = np.array([_rset(r) for r in got])
            horizon = max(r["time_final"] for r in got)
            base = "informed" + next((v for v in VARIANTS if s.endswith(v)), "")
            inf = [by.get((p, base, r["seed"])) for r in got]
            ratio = "—"
            if s != base and all(i is not None for i in inf):
                over = np.array([_rset(i) for i in inf])
                q = t / over
                ratios_of[s] = q
                bound = horizon / over.max()  # a run not out by the horizon: its ratio is at least this
                ratio = f"{_fmt(np.median(q), bound, 2)} ({_fmt(q.max(), bound, 2)})"
            rset = f"{_fmt(np.median(t), horizon, 1)} ({_fmt(t.max(), horizon, 1)})"
            out = np.array([r["fraction_evacuated"] for r in got])
            lines.append(f"| {p} | {s} | {len(got)} | {np.median(out):.3f} ({out.min():.3f}) | {rset} | {ratio} |")
        teams = [n for n in (4, 8, 16) if f"guide {n}" in ratios_of and np.median(ratios_of[f"guide {n}"]) <= 1.1]
        needs.append(f"| {p} | {min(teams) if teams else '> 16'} |")
    head = ["", "| plan | robots the guide needs (median ÷ informed at most 1.1) |", "|---|---|"]
    return "\n".join(lines + head + needs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=None, help="Dask worker processes (default: every core)")
    ap.add_argument("--plans", nargs="+", choices=PLANS, default=list(PLANS))
    ap.add_argument("--settings", nargs="+", choices=list(SETTINGS), default=list(SETTINGS))
    ap.add_argument("--table", action="store_true", help="only print the table from the results on disk")
    args = ap.parse_args()
    if not args.table:
        run_all(args.seeds, args.workers, args.plans, args.settings)
    print(table(args.seeds))


if __name__ == "__main__":
    main()
