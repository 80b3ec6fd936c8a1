"""The evacuation law's jam density: the crowd's, or none (docs page *Buildings*, "The evacuation law's jam density").

The evacuation law asks the crowd for ``v_d = −f(ρ) ∇φ`` with ``f(ρ) = v_free (1 − ρ/ρ_max)``
(:mod:`meanfield.controllers.evacuation`).  With ``ρ_max = inf`` (the default) it asks for the free speed
everywhere and the crowd's own diagram slows it; with the crowd's jam density (``crowd.rho_max / crowd.n`` in the
unit-mass density's units) the law itself slows where the crowd is dense.  This runs the coverage controller
(8 robots, towards the exits, people who follow the latest sign: ``view.memory = "none"``) both ways on ``hall`` and
``l-room``, seeds 0–9, and prints RSET (everyone out; the horizon where someone is left) as the median and the
worst seed, and the ratio of the crowd's jam density to none on the same seed.  Each run is a line of
``studies/results/evacuation_jam_density.jsonl`` as it finishes (an interrupted study resumes).  Run from the
repository's root::

    python studies/evacuation_jam_density.py [--seeds 10] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

RESULTS = Path("studies/results/evacuation_jam_density.jsonl")
PLANS = ("hall", "l-room")
JAM = ("none", "the crowd's")


def run(job: tuple[str, str, int]) -> dict:
    """One run: ``(plan, jam, seed)``."""
    from meanfield import ClosedLoop
    from meanfield.scenarios.scenario import builtin_scenarios

    plan, jam, seed = job
    sc = builtin_scenarios()[plan](seed=seed)
    values = {"controller.kind": "coverage", "robots.n": 8, "view.memory": "none"}
    if jam != "none":
        values["controller.options.coverage.rho_max"] = sc.crowd.rho_max / sc.crowd.n
    s = ClosedLoop(sc.with_values(values)).run(progress=False).summary
    rset = s["evacuation_time_100"]
    return {"plan": plan, "jam": jam, "seed": seed, "status": s["status"], "out": s["fraction_evacuated"],
            "rset": rset if rset is not None else s["time_final"]}  # fmt: skip


def table(rows: list[dict]) -> str:
    """The markdown table of the rows: per plan and jam density, RSET median (worst) and the ratio to none."""
    by = {(r["plan"], r["jam"], r["seed"]): r for r in rows}
    lines = ["| plan | jam density in the law | RSET, s: median (worst seed) | least share out | ratio to none: median "
             "(worst seed) |", "|---|---|---|---|---|"]  # fmt: skip
    for plan in PLANS:
        for jam in JAM:
            seeds = sorted(s for (p, j, s) in by if p == plan and j == jam)
            if not seeds:
                continue
            rset = np.array([by[(plan, jam, s)]["rset"] for s in seeds])
            out = min(by[(plan, jam, s)]["out"] for s in seeds)
            both = [s for s in seeds if (plan, "none", s) in by]
            ratio = np.array([by[(plan, jam, s)]["rset"] / by[(plan, "none", s)]["rset"] for s in both])
            r = f"{np.median(ratio):.2f} ({ratio.max():.2f})" if len(ratio) else "–"
            lines.append(f"| `{plan}` | {jam} | {np.median(rset):.1f} ({rset.max():.1f}) | {out:.2f} | {r} |")
    return "\n".join(lines)


def main() -> None:
    from analysis.parallel import map_jobs

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    done = [json.loads(line) for line in RESULTS.read_text().splitlines()] if RESULTS.exists() else []
    have = {(r["plan"], r["jam"], r["seed"]) for r in done}
    jobs = [(p, j, s) for p in PLANS for j in JAM for s in range(a.seeds) if (p, j, s) not in have]

    def keep(_: int, row: dict) -> None:
        with RESULTS.open("a") as f:
            f.write(json.dumps(row) + "\n")
        done.append(row)

    if jobs:
        map_jobs(run, jobs, a.workers, "jam density", True, on_result=keep)
    print(table([r for r in done if r["status"] == "completed" and math.isfinite(r["rset"])]))


if __name__ == "__main__":
    main()
