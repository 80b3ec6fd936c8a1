"""Closed-loop speed of the paper scenario on one core, against two anchors measured in the same run.

Run:  python benchmarks/bench_closed_loop.py [--steps 3000] [--repeats 3] [--json FILE]

Our figure: closed-loop steps per second of ``meanfield run paper`` (200 humans, 16 robots,
30×30 grid, KDE + controller + SDE + robots + recording every 10 steps), best of
``--repeats``.  Anchors, each best of ``--repeats`` in the same run:

* **plain numpy** (:mod:`benchmarks.plain_loop`): the same closed loop written straight
  from the paper's equations in numpy, no trick (its KDE sums the Gaussians at every cell,
  mirror images included, and equals ours to 1e-15).  Goal (issue 19): ours ≥ 10× it.
* **gaussian_kde**: ``scipy.stats.gaussian_kde`` evaluating the same 200 points on the same
  900 cell centres — the density estimate alone, done the usual way.  Goal: ours ≥ 15× it
  (a whole step in a fifteenth of the time the usual KDE call takes).

The ratios, not the absolute rates, are what to compare across machines.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import gaussian_kde  # noqa: E402

from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import emit, machine_line  # noqa: E402
from meanfield import ClosedLoop, paper_scenario  # noqa: E402

GOAL_OVER_PLAIN = 10.0  # ours / plain numpy loop (issue 19)
GOAL_OVER_KDE = 15.0  # ours / gaussian_kde calls (issue 19)


def closed_loop_rate(steps: int, repeats: int) -> float:
    best = 0.0
    for r in range(repeats):
        sc = paper_scenario(seed=r).replace(t_final=steps * 0.01)
        loop = ClosedLoop(sc)
        t0 = time.perf_counter()
        result = loop.run(progress=False)
        wall = time.perf_counter() - t0
        assert result.summary["steps"] == steps
        best = max(best, steps / wall)
    return best


def anchor_rate(calls: int, repeats: int) -> float:
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 1, (2, 200))
    xs = (np.arange(30) + 0.5) / 30
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    grid = np.vstack([X.ravel(), Y.ravel()])
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            gaussian_kde(pts, bw_method=0.08 / pts.std())(grid)
        best = max(best, calls / (time.perf_counter() - t0))
    return best


def plain_rate(steps: int, repeats: int) -> float:
    """Steps per second of :class:`benchmarks.plain_loop.PlainPaperLoop`, best of ``repeats``."""
    from benchmarks.plain_loop import PlainPaperLoop

    best = 0.0
    for r in range(repeats):
        loop = PlainPaperLoop(seed=r)
        t0 = time.perf_counter()
        loop.run(steps)
        best = max(best, steps / (time.perf_counter() - t0))
    return best


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``closed_loop`` record of ``meanfield bench`` (``docs/cli.md``): steps/s against ``gaussian_kde`` calls/s.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones); the
        anchor makes ``max(steps // 3, 100)`` calls, as :func:`main` does.

    Returns
    -------
    list of dict
        One record, with the goal :data:`GOAL_STEPS_PER_SECOND`.
    """
    s = settings("closed_loop", quick)
    calls = max(s["steps"] // 3, 100)
    plain_steps = max(s["steps"] // 20, 20)
    ours = closed_loop_rate(s["steps"], s["repeats"])
    plain = plain_rate(plain_steps, s["repeats"])
    anchor = anchor_rate(calls, s["repeats"])
    what = "paper scenario (N=200, n=16, 30x30, dt=0.01)"
    ours_is = "ClosedLoop(paper).run(): KDE + controller + SDE + robots + recording, steps/s"
    return [
        measured(
            "closed_loop",
            "closed_loop paper vs plain numpy",
            f"{what}: a whole closed-loop step against the same loop in plain numpy",
            ours_is,
            "benchmarks.plain_loop.PlainPaperLoop (the paper's equations in plain numpy), steps/s",
            ours,
            plain,
            "steps/s",
            faster="higher",
            goal=f">= {GOAL_OVER_PLAIN:g}x the plain numpy loop",
            passed=ours >= GOAL_OVER_PLAIN * plain,
            note="the plain loop's KDE sums every Gaussian at every cell (mirror images included)",
            detail={"steps": s["steps"], "repeats": s["repeats"], "plain_steps": plain_steps},
        ),
        measured(
            "closed_loop",
            "closed_loop paper vs gaussian_kde",
            f"{what}: a whole closed-loop step against the density estimate alone",
            ours_is,
            "scipy.stats.gaussian_kde, 200 points on the 900 cell centres, calls/s",
            ours,
            anchor,
            "steps/s",
            anchor_unit="calls/s",
            faster="higher",
            goal=f">= {GOAL_OVER_KDE:g}x gaussian_kde's calls/s",
            passed=ours >= GOAL_OVER_KDE * anchor,
            note="ours is a whole step, the anchor the KDE alone",
            detail={"steps": s["steps"], "repeats": s["repeats"], "anchor_calls": calls},
        ),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    ours = closed_loop_rate(a.steps, a.repeats)
    plain = plain_rate(max(a.steps // 20, 20), a.repeats)
    anchor = anchor_rate(max(a.steps // 3, 100), a.repeats)
    out = {
        "benchmark": "closed loop, paper scenario (N=200, n=16, 30x30, dt=0.01)",
        "ours_steps_per_second": ours,
        "plain_numpy_steps_per_second": plain,
        "ratio_ours_over_plain": ours / plain,
        "anchor": "scipy.stats.gaussian_kde, 200 points on 900 cell centres",
        "anchor_calls_per_second": anchor,
        "ratio_ours_over_anchor": ours / anchor,
        "goals": {"over_plain": GOAL_OVER_PLAIN, "over_gaussian_kde": GOAL_OVER_KDE},
        "machine": machine_line(),
    }
    emit(out, a.json)


if __name__ == "__main__":
    main()
