"""The plans' part of the ``two_scales`` check on ten seeds: the agents' t50 and t90 against the density's.

Run from the repository's root::

    python studies/two_scales_plans.py [--seeds 10] [--workers 2]

For each of ``l-room``, ``office`` and ``hall`` (the informed crowd on the fastest route; the point masses with
the check's door model, the density with Godunov's flux; :func:`verification.two_scales.informed`, on the check's
cells, :func:`verification.two_scales.refined`) it runs the density once (it is deterministic) and the agents on
seeds 0 to ``--seeds − 1``, and appends each run's times (:func:`verification.two_scales.exit_times`) to
``studies/results/two_scales_plans.jsonl`` as it finishes (an interrupted study resumes).  Each row records the
door model and the refinement it ran with (:func:`setup`); only the rows of today's are read.
Then it prints, per plan, the agents' median and worst seed of ``t50`` and ``t90``
and their gaps to the density's (``meanfield verify``'s ``two_scales`` judges the medians within 10 %; its full
variant runs the bottleneck and the scaled room as well, 1–2 hours).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

PLANS = ("l-room", "office", "hall")
RESULTS = Path("studies/results/two_scales_plans.jsonl")


def one_run(job: tuple[str, str, int]) -> dict[str, Any]:
    """One run: ``(plan, kind, seed)`` with ``kind`` ``"point-mass"`` or ``"fokker-planck"``."""
    from meanfield.scenarios.scenario import builtin_scenarios
    from verification.two_scales import exit_times, informed, refined

    plan, kind, seed = job
    row = exit_times(refined(informed(builtin_scenarios()[plan](seed=seed), kind)))
    return {"plan": plan, "kind": kind, "seed": seed, **setup(), **row}


def setup() -> dict[str, Any]:
    """What a row is measured with: the check's door model and cells (rows without them: the headway, the plans'
    own cells and uncapped inner doors, before 2026-12-06's doors)."""
    from verification.two_scales import DOOR_MODEL, PLAN_REFINEMENT

    return {"door_model": DOOR_MODEL, "plan_refinement": PLAN_REFINEMENT}


def _rows() -> list[dict[str, Any]]:
    if not RESULTS.exists():
        return []
    today = setup()
    rows = [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]
    return [r for r in rows if all(r.get(k) == v for k, v in today.items())]


def report(seeds: int) -> str:
    """Per plan and time, the agents' median (worst seed) and the density's, and the median's gap."""
    rows = _rows()
    lines = [
        "| plan | time | agents, median (worst seed) | density | gap of the median | seeds |",
        "|---|---|---|---|---|---|",
    ]
    for plan in PLANS:
        density = [r for r in rows if r["plan"] == plan and r["kind"] == "fokker-planck"]
        agents = [r for r in rows if r["plan"] == plan and r["kind"] == "point-mass" and r["seed"] < seeds]
        if not density or not agents:
            continue
        for key in ("t50", "t90"):
            a = np.array([r[key] for r in agents])
            d = density[0][key]
            worst = a[np.argmax(np.abs(a / d - 1.0))]
            lines.append(
                f"| {plan} | {key} | {np.median(a):.2f} s ({worst:.2f}) | {d:.2f} s | {np.median(a) / d - 1:+.1%} |"
                f" {len(a)} |"
            )
    return "\n".join(lines)


def main() -> None:
    from analysis.parallel import map_jobs

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=None, help="processes (default: every core)")
    args = ap.parse_args()
    done = {(r["plan"], r["kind"], r["seed"]) for r in _rows()}
    jobs = [(p, "fokker-planck", 0) for p in PLANS] + [(p, "point-mass", s) for p in PLANS for s in range(args.seeds)]
    todo = [j for j in jobs if j not in done]
    RESULTS.parent.mkdir(parents=True, exist_ok=True)

    def keep(k: int, row: dict[str, Any]) -> None:
        with RESULTS.open("a") as f:
            f.write(json.dumps(row) + "\n")

    if todo:
        map_jobs(one_run, todo, args.workers, "two scales, plans", True, on_result=keep)
    print(report(args.seeds))


if __name__ == "__main__":
    main()
