"""Speed of the bounded β/γ program (analysis.bounded), against anchors measured in the same run.

Run:  python benchmarks/bench_bounded.py [--solves 500] [--steps 2000] [--json FILE]

1. One re-solve of the program at n = 16 (the paper's robots): the cvxpy problem built
   once with Parameters (DPP) and re-solved by Clarabel, median and 90th percentile over
   ``--solves`` random instances at the paper scenario's scale with ``A`` reachable (so the
   cone program really runs).  Anchor: the same program rebuilt from scratch and solved
   each time (what code without Parameters does).  Beside it, the exact 1-D dual.
2. The paper scenario's closed loop with the ``bounded`` strategy, steps per second,
   against the same loop with the min-norm strategy (anchor) in the same run, with the
   number of steps at which Clarabel actually ran (the rest were answered in closed form
   because ``A`` was out of the robots' reach), and the worst case: the same loop with an
   extra Clarabel solve at every step.

Goals (issue 4): median re-solve ≤ 1.5 ms; closed loop ≥ 500 steps per second.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core

import argparse  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import cvxpy as cp  # noqa: E402
import numpy as np  # noqa: E402

from analysis.bounded import BoundedBetaGamma, achievable_range  # noqa: E402
from benchmarks.records import measured, settings  # noqa: E402
from benchmarks.reporting import emit, machine_line  # noqa: E402
from meanfield import ClosedLoop, paper_scenario  # noqa: E402

N, K_U, K_W, U_MAX, W_MAX = 16, 10.0, 10.0, 0.2, 3.0


def _instances(count: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Random integrals at the paper scenario's scale, with A at half the reachable maximum."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        b = rng.normal(scale=0.02, size=(N, 2))
        g = rng.normal(scale=0.02, size=N)
        hi = achievable_range(b, g, np.full(N, K_U), np.full(N, K_W), U_MAX, W_MAX)[1]
        out.append((b, g, 0.5 * hi))
    return out


def _timed(fn, instances) -> np.ndarray:
    times = []
    for b, g, A in instances:
        t0 = time.perf_counter()
        fn(b, g, A)
        times.append(time.perf_counter() - t0)
    return np.array(times)


def _rebuild_and_solve(b, g, A):
    du = cp.Variable((N, 2))
    dw = cp.Variable(N)
    cons = [
        cp.sum(cp.multiply(b, du)) - g @ dw >= A,
        cp.SOC(np.full(N, U_MAX), K_U * b + du, axis=1),
        cp.abs(-K_W * g + dw) <= W_MAX,
    ]
    cp.Problem(cp.Minimize(cp.sum_squares(du) + cp.sum_squares(dw)), cons).solve(
        solver=cp.CLARABEL, **BoundedBetaGamma.SOLVER_OPTIONS
    )


def resolve_times(solves: int) -> dict:
    inst = _instances(solves)
    dpp = BoundedBetaGamma(N, K_U, K_W, U_MAX, W_MAX)
    dpp(*inst[0])  # the first call compiles the parametrised problem
    ours = _timed(dpp, inst)
    assert dpp.cone_solves == solves + 1, "every instance must reach the cone program"
    exact = _timed(BoundedBetaGamma(N, K_U, K_W, U_MAX, W_MAX, method="exact"), inst)
    rebuild = _timed(_rebuild_and_solve, inst[: max(solves // 5, 20)])
    return {
        "dpp_resolve_ms_median": 1e3 * float(np.median(ours)),
        "dpp_resolve_ms_p90": 1e3 * float(np.percentile(ours, 90)),
        "anchor_rebuild_and_solve_ms_median": 1e3 * float(np.median(rebuild)),
        "ratio_resolve_over_rebuild": float(np.median(ours) / np.median(rebuild)),
        "exact_dual_ms_median": 1e3 * float(np.median(exact)),
        "goal_resolve_ms_median": 1.5,
    }


class _ConeEveryStep:
    """Worst case for the loop: besides the real call, solve the cone program every step on
    the step's own integrals with ``A`` at half the reachable maximum (so Clarabel runs)."""

    def __init__(self, strategy: BoundedBetaGamma):
        self.strategy = strategy

    def __call__(self, b, g, A):
        s = self.strategy
        hi = achievable_range(b, g, s.k_u, s.k_omega, s.u_max, s.omega_max)[1]
        if hi > 0:
            s._solve(b, g, 0.5 * hi)
        return s(b, g, A)


def forced_rate(steps: int, repeats: int) -> tuple[float, int]:
    best, cone = 0.0, 0
    for r in range(repeats):
        sc = paper_scenario(seed=r).with_values({"t_final": steps * 0.01, "controller.beta_gamma": "bounded"})
        loop = ClosedLoop(sc)
        loop.controller.strategy = _ConeEveryStep(loop.controller.strategy)
        t0 = time.perf_counter()
        loop.run(progress=False)
        best = max(best, steps / (time.perf_counter() - t0))
        cone += loop.controller.strategy.strategy.cone_solves
    return best, cone


def closed_loop(steps: int, repeats: int) -> dict:
    rates = {"min-norm": 0.0, "bounded": 0.0}
    cone = closed = 0
    for r in range(repeats):
        for strategy in rates:
            sc = paper_scenario(seed=r).with_values({"t_final": steps * 0.01, "controller.beta_gamma": strategy})
            loop = ClosedLoop(sc)
            t0 = time.perf_counter()
            res = loop.run(progress=False)
            rate = steps / (time.perf_counter() - t0)
            assert res.summary["steps"] == steps
            rates[strategy] = max(rates[strategy], rate)
            if strategy == "bounded":
                cone += loop.controller.strategy.cone_solves
                closed += loop.controller.strategy.closed_form_solves
    forced, forced_cone = forced_rate(steps, repeats)
    return {
        "bounded_steps_per_second": rates["bounded"],
        "bounded_with_a_cone_solve_every_step_steps_per_second": forced,
        "cone_solves_in_that_run": forced_cone,
        "anchor_min_norm_steps_per_second": rates["min-norm"],
        "ratio_bounded_over_min_norm": rates["bounded"] / rates["min-norm"],
        "bounded_steps_with_clarabel": cone,
        "bounded_steps_in_closed_form": closed,
        "goal_steps_per_second": 500,
    }


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``bounded`` records of ``meanfield bench`` (``docs/cli.md``): re-solve vs rebuild, closed loop vs min-norm.

    Parameters
    ----------
    quick : bool
        The quick settings of :data:`benchmarks.records.SETTINGS` (else the full ones).

    Returns
    -------
    list of dict
        Two records: :func:`resolve_times`, then :func:`closed_loop`.
    """
    s = settings("bounded", quick)
    rt = resolve_times(s["solves"])
    cl = closed_loop(s["steps"], s["repeats"])
    what = f"bounded beta/gamma program, n = {N} robots"
    goal_ms = rt["goal_resolve_ms_median"]
    goal_rate = cl["goal_steps_per_second"]
    return [
        measured(
            "bounded",
            "bounded re-solve vs rebuild",
            f"{what}: one solve with A reachable (Clarabel runs), median over {s['solves']} instances",
            "BoundedBetaGamma: cvxpy problem built once with Parameters (DPP), re-solved",
            "the same program rebuilt from scratch and solved each time",
            rt["dpp_resolve_ms_median"],
            rt["anchor_rebuild_and_solve_ms_median"],
            "ms per solve",
            faster="lower",
            goal=f"median <= {goal_ms:g} ms",
            passed=rt["dpp_resolve_ms_median"] <= goal_ms,
            note=f"p90 {rt['dpp_resolve_ms_p90']:.2f} ms; exact 1-D dual {rt['exact_dual_ms_median']:.3f} ms",
            detail={**rt, "solves": s["solves"]},
        ),
        measured(
            "bounded",
            "bounded closed loop vs min-norm",
            f"{what}: the paper scenario's closed loop, {s['steps']} steps, best of {s['repeats']}",
            "closed loop with controller.beta_gamma = 'bounded'",
            "the same loop with the min-norm strategy",
            cl["bounded_steps_per_second"],
            cl["anchor_min_norm_steps_per_second"],
            "steps/s",
            faster="higher",
            goal=f">= {goal_rate:g} steps/s",
            passed=cl["bounded_steps_per_second"] >= goal_rate,
            note=(
                f"Clarabel ran at {cl['bounded_steps_with_clarabel']} of "
                f"{cl['bounded_steps_with_clarabel'] + cl['bounded_steps_in_closed_form']} steps; with a cone "
                f"solve every step {cl['bounded_with_a_cone_solve_every_step_steps_per_second']:.0f} steps/s"
            ),
            detail={**cl, "steps": s["steps"], "repeats": s["repeats"]},
        ),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solves", type=int, default=500)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    out = {
        "benchmark": "bounded beta/gamma program (cvxpy DPP + Clarabel), n = 16",
        **resolve_times(a.solves),
        **closed_loop(a.steps, a.repeats),
        "machine": machine_line(f"cvxpy {cp.__version__}"),
    }
    emit(out, a.json)


if __name__ == "__main__":
    main()
