"""Worst-seed and median fraction in target against the sensing radius (docs page *Controllers*).

Run from the repository's root:  python studies/local_sensing.py [--seeds 10] [--out runs/sensing]

The paper scenario with its speed limits, ``backstepping`` and ``coverage``, sensing radius
0.1, 0.2, 0.35, 0.5 room widths with a communication radius twice as large, and the
centralized robots (no limit): one resumable sweep per radius (:func:`meanfield.workflows.sweep.run_sweep`).
"""

from __future__ import annotations

import argparse

import numpy as np

from meanfield import paper_scenario
from meanfield.workflows.sweep import run_sweep

RADII = (0.1, 0.2, 0.35, 0.5, None)
KINDS = ("backstepping", "coverage")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", default="runs/sensing")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    rows = []
    for r in RADII:
        sets = {"controller.kind": list(KINDS)}
        if r is not None:
            sets |= {"sensing.radius": [r], "sensing.comm_radius": [2 * r]}
        label = "all" if r is None else f"{r:g}"
        ds = run_sweep(paper_scenario(), sets, a.seeds, f"{a.out}/r{label}", workers=a.workers, progress=False)
        for kind in KINDS:
            f = np.asarray(ds["fraction_in_target"].sel({"controller.kind": kind}).values, float).ravel()
            rows.append((kind, label, float(np.median(f)), float(f.min())))
            print(f"{kind:>13} r = {label:>4}: median {np.median(f):.3f}, worst {f.min():.3f}", flush=True)
    print("| controller | sensing radius (comm 2×) | median | worst seed |\n|---|---|---|---|")
    for kind in KINDS:
        for k, label, med, worst in rows:
            if k == kind:
                print(f"| {k} | {label} | {med:.3f} | {worst:.3f} |")


if __name__ == "__main__":
    main()
