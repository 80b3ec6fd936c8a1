"""The headway model's own diagram: an even crowd on a periodic strip, with and without the walk's direction (H4).

Run from the repository's root::

    python studies/headway_strip.py [--sigmas 0.01 0.05 0.1] [--densities 1 2 2.7 3.5 4.5] [--seeds 2]
    python studies/headway_strip.py --report        # only the table, from studies/results/headway_strip.jsonl

A strip :data:`LENGTH` = 30 m long and :data:`WIDTH` = 3 m wide, periodic along its length (the people within the
reach of one end see the others' images beyond it), walls along its sides (a step across one is reflected, as the
point masses' are), holds an even crowd at the density ``ρ``, placed at random, every one walking east at the
free speed ``v₀`` = 1.34 m/s slowed by the headway model (:class:`meanfield.crowds.headway.Headway`, the linear
diagram, ``ρ_max`` = 5.4 persons/m²), with the noise σ, stepped by Euler–Maruyama at ``dt`` = 0.05 s.  The mean
speed along the strip over :data:`MEASURE` (after :data:`SETTLE` s) is the model's speed at ``ρ``; the density's
is ``v₀ g(ρ)``, the diagram itself.  ``turns = "H4"`` is the shipped model; ``"none"`` is (H1) to (H3) alone
(``Headway(turns=(0.0,))``).  No exits and no routes: what is measured is the model's diagram, nothing else.
Each run is a line of ``studies/results/headway_strip.jsonl``, appended as it finishes (an interrupted study
resumes).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = Path("studies/results/headway_strip.jsonl")
LENGTH, WIDTH = 30.0, 3.0
"""m: the strip."""
DT = 0.05
"""s: the step."""
SETTLE, MEASURE = 20.0, 40.0
"""s: the time the random start is given to settle, then the time the speed is averaged over."""
FREE_SPEED, RHO_MAX = 1.34, 5.4


def one_run(rho: float, sigma: float, turns: str, seed: int) -> dict[str, Any]:
    """The mean speed along the strip of a crowd at ``rho`` persons/m² with noise ``sigma``."""
    from meanfield.crowds.congestion import Linear
    from meanfield.crowds.headway import TURNS, Headway

    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    n = int(round(rho * WIDTH * LENGTH))
    model = Headway(Linear(free_speed=FREE_SPEED, rho_max=RHO_MAX), turns=TURNS if turns == "H4" else (0.0,))
    x = np.column_stack([rng.uniform(0.0, LENGTH, n), rng.uniform(0.0, WIDTH, n)])
    reach = model.reach + model.jam_spacing
    steps, settle = round((SETTLE + MEASURE) / DT), round(SETTLE / DT)
    moved = 0.0
    for k in range(steps):
        images = np.vstack([x, x[x[:, 0] > LENGTH - reach] - [LENGTH, 0.0], x[x[:, 0] < reach] + [LENGTH, 0.0]])
        v = np.zeros_like(images)
        v[:, 0] = FREE_SPEED
        model.slow_down(v, images, None)
        v = v[:n]
        x = x + v * DT + np.sqrt(2.0 * sigma * DT) * rng.standard_normal((n, 2))
        x[:, 1] = WIDTH - np.abs(WIDTH - np.abs(x[:, 1]))  # the side walls reflect
        x[:, 0] %= LENGTH
        if k >= settle:
            moved += float(v[:, 0].mean()) * DT
    speed = moved / MEASURE
    rho = n / (WIDTH * LENGTH)
    diagram = FREE_SPEED * (1.0 - rho / RHO_MAX)
    return {"rho": rho, "sigma": sigma, "turns": turns, "seed": seed, "speed": speed, "diagram": diagram,
            "ratio": speed / diagram, "wall_seconds": time.perf_counter() - start}  # fmt: skip


def rows() -> list[dict[str, Any]]:
    if not RESULTS.exists():
        return []
    return [json.loads(line) for line in RESULTS.read_text().splitlines() if line.strip()]


def report() -> str:
    """The docs' table: speed over the diagram's (median of the seeds) per density, σ and model."""
    rs = rows()
    densities = sorted({round(r["rho"], 2) for r in rs})
    lines = ["| (H4) | σ (m²/s) | " + " | ".join(f"ρ = {d:g}" for d in densities) + " |",
             "|---" * (len(densities) + 2) + "|"]  # fmt: skip
    for turns in ("none", "H4"):
        for sigma in sorted({r["sigma"] for r in rs}):
            cells = []
            for d in densities:
                got = [r for r in rs if r["turns"] == turns and r["sigma"] == sigma and round(r["rho"], 2) == d]
                speed, ratio = (float(np.median([r[k] for r in got])) for k in ("speed", "ratio")) if got else (0, 0)
                cells.append(f"{speed:.2f} ({ratio:.2f})" if got else "—")
            lines.append(f"| {'yes' if turns == 'H4' else 'no'} | {sigma:g} | " + " | ".join(cells) + " |")
    diagram = [FREE_SPEED * (1.0 - d / RHO_MAX) for d in densities]
    lines.append("| the diagram | | " + " | ".join(f"{v:.2f}" for v in diagram) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sigmas", type=float, nargs="+", default=[0.01, 0.05, 0.1])
    p.add_argument("--densities", type=float, nargs="+", default=[1.0, 2.0, 2.7, 3.5, 4.5])
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--turns", nargs="+", default=["H4", "none"], choices=["H4", "none"])
    p.add_argument("--report", action="store_true", help="only print the table from the results")
    args = p.parse_args(argv)
    if not args.report:
        done = {(r["turns"], round(r["rho"], 2), r["sigma"], r["seed"]) for r in rows()}
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        for turns in args.turns:
            for sigma in args.sigmas:
                for rho in args.densities:
                    for seed in range(args.seeds):
                        actual = round(round(rho * WIDTH * LENGTH) / (WIDTH * LENGTH), 2)
                        if (turns, actual, sigma, seed) in done:
                            continue
                        row = one_run(rho, sigma, turns, seed)
                        with RESULTS.open("a") as f:
                            f.write(json.dumps(row) + "\n")
                        print(f"(H4) {turns} σ={sigma:g} ρ={row['rho']:.2f} seed={seed}: {row['speed']:.3f} m/s "
                              f"(diagram {row['diagram']:.3f})", flush=True)  # fmt: skip
    print(report())


if __name__ == "__main__":
    main()
