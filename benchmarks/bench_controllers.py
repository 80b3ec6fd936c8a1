"""Compute per control step of every installed controller against the paper's law, in the same run.

Run:  python benchmarks/bench_controllers.py [--steps 300] [--repeats 2] [--json FILE]

For each controller that applies to the paper scenario (:func:`meanfield.workflows.controller_study.candidates`:
the paper's law, with bounded β/γ, coverage, static signs, NMPC where installed), the closed
loop runs ``--steps`` steps and every call of the controller's ``act`` is timed; the paper's
law runs the same way in the same process, interleaved repeat by repeat, as the anchor.
Reported per controller: the mean ``act`` time (ms per control step, amortised: a controller
that solves once every few steps, as NMPC does, is charged its solves spread over the steps),
its ratio to the law's (ratio > 1: faster than the law), the slowest call, and the real-time
factor in the units of ``paper-unity`` (a control period of 0.25 s) and in the paper's own unit
taken as a second (a control period of ``dt = 0.01`` s, the measure NMPC is held to,
``benchmarks/bench_nmpc.py``): the share of the period the controller needs on average, and
the slowest step's.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import statistics  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import emit, machine_line, time_act_calls  # noqa: E402
from meanfield import ClosedLoop, paper_scenario  # noqa: E402
from meanfield.workflows.controller_study import candidates, reference_law  # noqa: E402

LAW = reference_law()[0]

UNITY_PERIOD = 0.25  # s: a control period of paper-unity, the paper's study in metres and seconds
PAPER_PERIOD = 0.01  # s: dt of paper, its time unit taken as a second (NMPC's real-time measure)


def act_times(overrides: dict[str, Any], steps: int, seed: int) -> list[float]:
    """Seconds of each ``act`` call in a closed loop of ``steps`` steps with ``overrides``."""
    sc = paper_scenario(seed=seed).with_values({**overrides, "t_final": (steps + 1) * 0.01})
    loop = ClosedLoop(sc)
    times = time_act_calls(loop.parts.controller)
    for _ in range(steps):
        loop.step()
    return times[1:]  # the first call builds what is built once


def measure(steps: int, repeats: int, names: list[str] | None = None) -> dict[str, tuple[float, float]]:
    """Mean and largest seconds per ``act`` of each controller (and of the law), interleaved over repeats."""
    configs = candidates(paper_scenario(seed=0))
    chosen = names or list(configs)
    samples: dict[str, list[float]] = {name: [] for name in {LAW, *chosen}}
    for r in range(repeats):
        for name in samples:
            samples[name].extend(act_times(configs[name], steps, r))
    return {name: (statistics.fmean(ts), max(ts)) for name, ts in samples.items()}


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``controllers`` records of ``meanfield bench``: each controller's ``act`` against the law's.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        One record per controller other than the law.
    """
    s = settings("controllers", quick)
    med = measure(s["steps"], s["repeats"])
    law = med[LAW][0]
    records = []
    for name, (t, slowest) in sorted(med.items()):
        if name == LAW:
            continue
        records.append(
            measured(
                "controllers",
                f"controller {name} vs the law",
                f"act() per control step on paper (N=200, n=16, 30x30), {s['steps']} steps x {s['repeats']} repeats",
                f"{name}: mean act() time (amortised)",
                "backstepping (the paper's law): mean act() time, same run",
                t * 1e3,
                law * 1e3,
                "ms per control step",
                faster="lower",
                note=(
                    f"slowest call {slowest * 1e3:.3g} ms; real-time factor in paper-unity's units: "
                    f"{t / UNITY_PERIOD:.3g} of a {UNITY_PERIOD:g} s period; in the paper's unit as a second: "
                    f"{t / PAPER_PERIOD:.3g} of a {PAPER_PERIOD * 1e3:g} ms step (slowest {slowest / PAPER_PERIOD:.3g})"
                ),
                detail={"steps": s["steps"], "repeats": s["repeats"], "slowest_ms": slowest * 1e3},
            )
        )
    return records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    med = measure(a.steps, a.repeats)
    law = med[LAW][0]
    out = {
        "benchmark": "controller act() per control step on paper, against the paper's law in the same run",
        "mean_ms_per_step": {k: v[0] * 1e3 for k, v in sorted(med.items())},
        "slowest_ms": {k: v[1] * 1e3 for k, v in sorted(med.items())},
        "ratio_law_over_controller": {k: law / v[0] for k, v in sorted(med.items())},
        "real_time_factor_paper_unity": {k: v[0] / UNITY_PERIOD for k, v in sorted(med.items())},
        "real_time_factor_paper_unit": {k: v[0] / PAPER_PERIOD for k, v in sorted(med.items())},
        "slowest_step_factor_paper_unit": {k: v[1] / PAPER_PERIOD for k, v in sorted(med.items())},
        "machine": machine_line(),
    }
    emit(out, a.json)


if __name__ == "__main__":
    main()
