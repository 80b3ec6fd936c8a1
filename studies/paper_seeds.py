"""Run a built-in scenario (`paper` by default) for several seeds and tabulate the summaries.

Usage:  python studies/paper_seeds.py [--scenario paper|paper-unity] [--seeds 0-9] [--set KEY=VALUE ...]
                                      [--out FILE.json]

Runs seeds in parallel processes (one per core), prints a Markdown table of
fraction_in_target, l2_error_initial, l2_error_final, their ratio, time_to_90 and the
largest robot speed against the limit, then the medians.  This is the command behind
the figures quoted in docs/scenarios.md (for paper-unity, also the fraction of humans who
see a robot at the end and, with the JuPedSim backend, the deepest body overlap).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
from concurrent.futures import ProcessPoolExecutor

from meanfield.scenarios.overrides import parse_set
from meanfield.scenarios.scenario import builtin_scenarios

KEYS = ("fraction_in_target", "l2_error_initial", "l2_error_final", "l2_error_ratio", "time_to_90",
        "max_robot_speed", "speed_limit", "w2_to_target_final", "steps_per_second")
EXTRA = ("backend", "seen_fraction_final", "body_overlap_max")


def _one(args: tuple[int, dict]) -> dict:
    from meanfield.simulation.loop import ClosedLoop

    name, seed, sets = args
    sc = builtin_scenarios()[name](seed=seed)
    if sets:
        sc = sc.with_values(sets)
    s = ClosedLoop(sc).run(progress=False).summary
    return {"seed": seed, **{k: s[k] for k in KEYS}, **{k: s.get(k) for k in EXTRA}}


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default="paper", choices=sorted(builtin_scenarios()))
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--out", default=None)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    a = ap.parse_args()
    sets = parse_set(a.set)
    with ProcessPoolExecutor(a.workers) as ex:
        rows = list(ex.map(_one, [(a.scenario, s, sets) for s in _seeds(a.seeds)]))
    print(f"{a.scenario}, backend {rows[0]['backend']}, settings {sets}")
    print("| seed | fraction_in_target | l2 initial | l2 final | ratio | time_to_90 | max speed / limit "
          "| seeing a robot at the end | deepest body overlap |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        t90 = "—" if r["time_to_90"] is None else f"{r['time_to_90']:.2f}"
        overlap = "—" if r["body_overlap_max"] is None else f"{r['body_overlap_max']:.2g}"
        print(f"| {r['seed']} | {r['fraction_in_target']:.3f} | {r['l2_error_initial']:.3g} | "
              f"{r['l2_error_final']:.3g} | {r['l2_error_ratio']:.3f} | {t90} | "
              f"{r['max_robot_speed']:.4f} / {r['speed_limit']} | {r['seen_fraction_final']:.3f} | {overlap} |")
    med = {k: statistics.median(r[k] for r in rows) for k in ("fraction_in_target", "l2_error_ratio")}
    print(f"\nmedian fraction_in_target = {med['fraction_in_target']:.3f}, "
          f"median l2_error_final / l2_error_initial = {med['l2_error_ratio']:.3f}, "
          f"all speeds within limit: "
          f"{all(r['speed_limit'] is None or r['max_robot_speed'] <= r['speed_limit'] + 1e-12 for r in rows)}")
    if a.out:
        with open(a.out, "w") as fh:
            json.dump({"scenario": a.scenario, "settings": sets, "rows": rows, "medians": med}, fh, indent=2)


if __name__ == "__main__":
    main()
