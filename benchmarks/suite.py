"""``meanfield bench [--quick] --out FILE.json``: every benchmark of the toolkit in one command.

Each benchmark prints our figure, the figure of an *anchor* measured in the same run (an
established library doing the same job, or the straightforward way of doing it), and their
ratio, defined so that **ratio > 1 means ours is faster** (anchor time / our time, or our
rate / anchor rate).  The benchmarks, in the order they run:

==============  ==========================================================================
kde             KDE of 10⁴ points on 256² against ``scipy.stats.gaussian_kde``; of 10⁶
                points against the exact sum of the same estimate (``bench_kde.py``)
closed_loop     the paper scenario's closed loop (N = 200), steps per second, against
                ``gaussian_kde`` calls per second, 200 points on the 900 cells (``bench_closed_loop.py``)
fokker_planck   the Fokker–Planck solver (ADI, automatic step) against py-pde and FiPy on
                one drift–diffusion problem, 64² (quick) or 128² (``bench_fokker_planck.py``)
jupedsim        the JuPedSim crowd backend steered every step against JuPedSim alone
                (``bench_jupedsim.py``)
large_crowd     the closed loop at N = 10⁶ (``stadium``) against the same loop with v_r summed
                exactly at every human (``bench_large_crowd.py``, child processes)
bounded         the bounded β/γ program re-solved (cvxpy DPP) against rebuilt each time, and
                its closed loop against min-norm's (``bench_bounded.py``)
nmpc            NMPC solve per control step against the backstepping law (``bench_nmpc.py``)
==============  ==========================================================================

An anchor that is not installed (py-pde, FiPy, JuPedSim) gives a record with
``skipped: true`` and a ``note`` naming the install command, and no numbers.

Everything runs on one core: the thread variables (``OMP_NUM_THREADS`` …) are set to 1
for the child processes and for the libraries loaded later, and the thread pools of the
BLAS and OpenMP libraries already loaded are limited to one thread with ``threadpoolctl``
(a value already exported in the environment is kept, as the scripts do).

The JSON (``--out``) is rewritten atomically after every finished benchmark, with
``complete: false`` until the end; its layout is in ``docs/cli.md``.  Exit status: 0 when
every benchmark ran, whatever the verdicts of the speed goals (they are reported, not
enforced: they depend on the machine and its load); 1 when a benchmark crashed or the run
was interrupted (the JSON keeps what finished); 2 on bad input (unknown ``--only`` name),
before anything runs.

From Python: ``run_suite(quick=True, out="bench.json", only=["kde"])``.
"""

from __future__ import annotations

import os

THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

if __name__ == "__main__":  # python -m benchmarks.suite: one thread before numpy loads
    for _var in THREAD_VARIABLES:
        os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import importlib  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import shlex  # noqa: E402
import signal  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import textwrap  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from collections.abc import Callable, Iterator, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from datetime import UTC, datetime  # noqa: E402
from importlib import metadata  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from meanfield.errors import ParameterError  # noqa: E402
from meanfield.io import atomic_write_json  # noqa: E402

__all__ = ["BENCHMARKS", "SETTINGS", "Benchmark", "run_suite", "format_table", "register", "main"]

RATIO_MEANING = "ratio > 1 means ours is faster: anchor time / our time, or our rate / anchor rate"
BENCH_INSTALL = "pip install -e '.[bench]'"

#: what each benchmark runs, in quick and in full mode (recorded in the JSON as ``settings``)
SETTINGS: dict[str, dict[str, dict[str, Any]]] = {
    # bench_kde.run(quick, repeats): quick = ours best of 3, each anchor once; full = best of 5 / 2
    "kde": {"quick": {"repeats": 5}, "full": {"repeats": 5}},
    # the anchor makes max(steps // 3, 100) gaussian_kde calls, as the script does
    "closed_loop": {"quick": {"steps": 1000, "repeats": 2}, "full": {"steps": 3000, "repeats": 3}},
    "fokker_planck": {"quick": {"cells": 64}, "full": {"cells": 128}},
    # agents -> steps (bench_jupedsim.QUICK_STEPS / FULL_STEPS), best of `repeats`
    "jupedsim": {
        "quick": {"steps": {200: 300, 2000: 60}, "repeats": 3},
        "full": {"steps": {200: 2000, 2000: 400, 10000: 100}, "repeats": 3},
    },
    # python benchmarks/bench_large_crowd.py --quick (20 steps ours, 2 anchor) / --steps 100 (anchor 5)
    "large_crowd": {"quick": {"ours_steps": 20, "anchor_steps": 2}, "full": {"ours_steps": 100, "anchor_steps": 5}},
    "bounded": {
        "quick": {"solves": 100, "steps": 500, "repeats": 2},
        "full": {"solves": 500, "steps": 2000, "repeats": 2},
    },
    "nmpc": {"quick": {"t_final": 1.0, "repeats": 1}, "full": {"t_final": 4.0, "repeats": 3}},
}

GOAL_CLOSED_LOOP_STEPS_PER_SECOND = 2000.0  # bench_closed_loop.py's goal_steps_per_second


@dataclass(frozen=True)
class Benchmark:
    """One entry of the registry: ``run(quick) -> list of records``."""

    name: str
    measures: str
    anchor: str
    run: Callable[[bool], list[dict[str, Any]]]


# --------------------------------------------------------------------------- records
def measured(
    benchmark: str,
    name: str,
    what: str,
    ours: str,
    anchor: str,
    ours_value: float,
    anchor_value: float,
    unit: str,
    *,
    faster: str,
    anchor_unit: str | None = None,
    goal: str | None = None,
    passed: bool | None = None,
    note: str = "",
    detail: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """A record with numbers.  ``faster`` is ``"lower"`` for times, ``"higher"`` for rates."""
    ours_value, anchor_value = float(ours_value), float(anchor_value)
    if faster == "lower":
        ratio, definition = anchor_value / ours_value, "anchor time / our time"
    elif faster == "higher":
        ratio, definition = ours_value / anchor_value, "our rate / anchor rate"
    else:
        raise ParameterError("faster", faster, "'lower' (times) or 'higher' (rates)")
    return {
        "benchmark": benchmark,
        "name": name,
        "what": what,
        "skipped": False,
        "ours": ours,
        "ours_value": ours_value,
        "unit": unit,
        "anchor": anchor,
        "anchor_value": anchor_value,
        "anchor_unit": anchor_unit or unit,
        "ratio": ratio,
        "ratio_definition": definition,
        "goal": goal,
        "pass": None if passed is None else bool(passed),
        "note": note,
        "detail": detail or {},
    }


def skipped(benchmark: str, name: str, what: str, ours: str, anchor: str, note: str) -> dict[str, Any]:
    """A record of an anchor that could not run: a note, and no numbers."""
    return {
        "benchmark": benchmark,
        "name": name,
        "what": what,
        "skipped": True,
        "ours": ours,
        "anchor": anchor,
        "note": note,
    }


def _failed(benchmark: str, exc: BaseException) -> dict[str, Any]:
    return {
        "benchmark": benchmark,
        "name": benchmark,
        "skipped": False,
        "error": f"{type(exc).__name__}: {exc}",
        "traceback": "".join(traceback.format_exception(exc)[-6:]),
    }


def _settings(name: str, quick: bool) -> dict[str, Any]:
    return SETTINGS[name]["quick" if quick else "full"]


def _bench(module: str) -> Any:
    return importlib.import_module(f"benchmarks.{module}")


def _import_error(module: str) -> str | None:
    """None when ``module`` imports, else why not (an optional anchor)."""
    try:
        importlib.import_module(module)
    except Exception as exc:  # ImportError, or a broken install (numba/numpy mismatch, ...)
        return f"{type(exc).__name__}: {exc}"
    return None


def _short_n(n: int) -> str:
    e = round(math.log10(n))
    return f"1e{e}" if 10**e == n else str(n)


# --------------------------------------------------------------------------- the benchmarks
def _kde(quick: bool) -> list[dict[str, Any]]:
    s = _settings("kde", quick)
    out = _bench("bench_kde").run(quick=quick, repeats=s["repeats"])
    records = []
    for r in out["results"]:
        n = int(r["name"].split("_")[1])
        exact = "separable" in r["anchor"]
        if exact:
            note = f"max error {r['max_error_over_peak']:.1e} of the peak"
        else:
            note = f"max difference {r['max_difference_over_peak']:.1e} of the peak"
        records.append(
            measured(
                "kde",
                f"kde N={_short_n(n)} vs {'exact sum' if exact else 'gaussian_kde'}",
                r["what"],
                r["ours"],
                r["anchor"],
                r["ours_seconds"] * 1e3,
                r["anchor_seconds"] * 1e3,
                "ms per call",
                faster="lower",
                goal=r["goal"],
                passed=r["pass"],
                note=note,
                detail=r,
            )
        )
    return records


def _closed_loop(quick: bool) -> list[dict[str, Any]]:
    s = _settings("closed_loop", quick)
    cl = _bench("bench_closed_loop")
    calls = max(s["steps"] // 3, 100)
    ours = cl.closed_loop_rate(s["steps"], s["repeats"])
    anchor = cl.anchor_rate(calls, s["repeats"])
    goal = GOAL_CLOSED_LOOP_STEPS_PER_SECOND
    return [
        measured(
            "closed_loop",
            "closed_loop paper vs gaussian_kde",
            "paper scenario (N=200, n=16, 30x30, dt=0.01): a whole closed-loop step against the density estimate alone",
            "ClosedLoop(paper).run(): KDE + controller + SDE + robots + recording, steps/s",
            "scipy.stats.gaussian_kde, 200 points on the 900 cell centres, calls/s",
            ours,
            anchor,
            "steps/s",
            anchor_unit="calls/s",
            faster="higher",
            goal=f">= {goal:g} steps/s",
            passed=ours >= goal,
            note="ours is a whole step, the anchor the KDE alone",
            detail={"steps": s["steps"], "repeats": s["repeats"], "anchor_calls": calls},
        )
    ]


def _fokker_planck(quick: bool) -> list[dict[str, Any]]:
    n = _settings("fokker_planck", quick)["cells"]
    fpb = _bench("bench_fokker_planck")
    comp = fpb.comp
    what = (
        f"Fokker–Planck, three Gaussian arrows, sigma={comp.SIGMA:g}, T={comp.T_FINAL:g}, {n}x{n} cells, "
        "time stepping after set-up, each solver with its own scheme and step"
    )
    ours_label = "meanfield FokkerPlanck, ADI, automatic positivity-preserving step"
    fpb.meanfield_solve(n, "adi", None)  # warm-up, as the anchors' first step is set-up
    ours = fpb.meanfield_solve(n, "adi", None)
    ours_detail = {k: ours[k] for k in ("wall_time", "setup_time", "steps", "min", "mass_drift")}
    records = []
    for label, module, runner, scheme in (
        ("py-pde", "pde", comp.run_pypde, "explicit Euler, numba, one thread, dt ~ h^2/(4 sigma)"),
        ("FiPy", "fipy", comp.run_fipy, f"implicit Euler, dt = {comp.FIPY_DT:g}"),
    ):
        name = f"fokker_planck {n}^2 vs {label}"
        anchor_label = f"{label}, {scheme}"
        why = _import_error(module)
        if why is None:
            res = runner(n)
            if not res["available"]:
                why = res["reason"]
        if why is not None:
            note = f"{label} not available ({why}); install: {BENCH_INSTALL}"
            records.append(skipped("fokker_planck", name, what, ours_label, anchor_label, note))
            continue
        diff = comp.l2_difference(ours["rho"], res["rho"])
        anchor_detail = {k: res[k] for k in ("wall_time", "setup_time", "steps", "dt", "solver")}
        anchor_detail["mass_drift"] = abs(comp.mass(res["rho"]) - 1.0)
        records.append(
            measured(
                "fokker_planck",
                name,
                what,
                ours_label,
                anchor_label,
                ours["wall_time"],
                res["wall_time"],
                "s per solve",
                faster="lower",
                note=(
                    f"L2 difference {diff:.1e}; steps {ours['steps']} vs {res['steps']}; "
                    f"set-up {ours['setup_time']:.2g} s vs {res['setup_time']:.2g} s"
                ),
                detail={"cells": n, "l2_difference": diff, "ours": ours_detail, "anchor": anchor_detail},
            )
        )
    return records


def _jupedsim(quick: bool) -> list[dict[str, Any]]:
    s = _settings("jupedsim", quick)
    plan = {int(k): int(v) for k, v in s["steps"].items()}
    what = "PedestrianCrowd.step (JuPedSim backend, every agent steered every step) in a 150x150 m room"
    ours_label = "meanfield PedestrianCrowd, JuPedSim backend, steps/s"
    anchor_label = "JuPedSim alone (sim.iterate, one fixed target per agent), steps/s"
    why = _import_error("jupedsim")
    if why is not None:
        from meanfield.jupedsim_api import INSTALL_HINT

        note = f"jupedsim not available ({why}); install: {INSTALL_HINT}"
        return [skipped("jupedsim", "jupedsim vs JuPedSim alone", what, ours_label, anchor_label, note)]
    jb = _bench("bench_jupedsim")
    results, _ = jb.measure(plan, s["repeats"])
    target = jb.TARGET_OVERHEAD_US
    return [
        measured(
            "jupedsim",
            f"jupedsim N={x['n']} vs JuPedSim alone",
            f"{what}, N={x['n']}, {x['steps']} steps",
            ours_label,
            anchor_label,
            x["ours_steps_per_second"],
            x["anchor_steps_per_second"],
            "steps/s",
            faster="higher",
            goal=f"adapter overhead <= {target:g} µs per agent-step",
            passed=x["pass"],
            note=f"overhead {x['overhead_us_per_agent_step']:.2f} µs per agent-step",
            detail={"repeats": s["repeats"], **x},
        )
        for x in results
    ]


def _large_crowd(quick: bool) -> list[dict[str, Any]]:
    s = _settings("large_crowd", quick)
    # The script, in a process of its own: its measurements run in child processes, and Linux
    # counts the parent's resident memory at the fork in a child's peak (ru_maxrss), so they
    # need a small parent -- not this one, which holds what the earlier benchmarks loaded.
    script = importlib.util.find_spec("benchmarks.bench_large_crowd").origin
    with tempfile.TemporaryDirectory(prefix="meanfield-bench-") as tmp:
        path = Path(tmp) / "large_crowd.json"
        args = ["--quick"] if quick else ["--steps", str(s["ours_steps"])]
        proc = subprocess.run(
            [sys.executable, script, *args, "--json", str(path)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        if proc.returncode != 0:
            raise RuntimeError(f"bench_large_crowd.py exited with {proc.returncode}: {proc.stderr.strip()[-800:]}")
        out = json.loads(path.read_text())
    r = out["results"][0]
    od = r["ours_detail"]
    return [
        measured(
            "large_crowd",
            "large_crowd N=1e6 vs exact v_r",
            "closed loop, stadium scenario (N=1e6 humans, n=64 robots, 128x128 grid), each side in its own process",
            f"{r['ours']}: ClosedLoop.run() all included (recording, dataset, summary)",
            r["anchor"],
            r["ours_us_per_human_step"],
            r["anchor_us_per_human_step"],
            "µs per human-step",
            faster="lower",
            goal=r["goal"],
            passed=r["pass"],
            note=(
                f"{r['ours_steps_per_second']:.2f} steps/s all included over {od['steps']} steps "
                f"(loop alone {od['loop_steps_per_second']:.2f}), peak {od['peak_mb']:.0f} MB"
            ),
            detail=r,
        )
    ]


def _bounded(quick: bool) -> list[dict[str, Any]]:
    s = _settings("bounded", quick)
    bb = _bench("bench_bounded")
    rt = bb.resolve_times(s["solves"])
    cl = bb.closed_loop(s["steps"], s["repeats"])
    what = f"bounded beta/gamma program, n = {bb.N} robots"
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


def _nmpc(quick: bool) -> list[dict[str, Any]]:
    s = _settings("nmpc", quick)
    nb = _bench("bench_nmpc")
    runs = [nb.one_run(seed, s["t_final"], {}) for seed in range(s["repeats"])]

    def med(key: str) -> float:
        return float(statistics.median(r[key] for r in runs))

    statuses: dict[str, int] = {}
    for r in runs:
        for k, v in r["ipopt_statuses"].items():
            statuses[k] = statuses.get(k, 0) + v
    amortised = med("solve_seconds_per_simulation_step") * 1e3
    return [
        measured(
            "nmpc",
            "nmpc solve vs backstepping",
            f"controller compute per control step, paper scenario, T={s['t_final']:g} per repeat, "
            f"median over {s['repeats']} repeat(s)",
            "NMPC (analysis.nmpc, CasADi + IPOPT): median solve, one per control period",
            "backstepping robot_inputs (the paper's law): median call, every step",
            med("solve_median") * 1e3,
            med("backstepping_median") * 1e3,
            "ms per control step",
            faster="lower",
            note=(
                f"amortised over the simulation steps: {amortised:.3g} ms per step; "
                f"{sum(r['solves'] for r in runs)} solves, IPOPT {statuses}"
            ),
            detail={"runs": runs, "t_final": s["t_final"], "repeats": s["repeats"]},
        )
    ]


BENCHMARKS: dict[str, Benchmark] = {
    b.name: b
    for b in (
        Benchmark("kde", "kernel density estimate, N = 1e4 and 1e6 on 256^2", "scipy gaussian_kde; exact sum", _kde),
        Benchmark("closed_loop", "closed loop, paper scenario (N = 200)", "scipy gaussian_kde calls", _closed_loop),
        Benchmark("fokker_planck", "Fokker–Planck solver, 64^2 / 128^2", "py-pde and FiPy (optional)", _fokker_planck),
        Benchmark("jupedsim", "JuPedSim crowd backend, steered every step", "JuPedSim alone (optional)", _jupedsim),
        Benchmark("large_crowd", "closed loop at N = 1e6 (stadium)", "v_r summed exactly", _large_crowd),
        Benchmark("bounded", "bounded beta/gamma: re-solve and closed loop", "rebuild; min-norm", _bounded),
        Benchmark("nmpc", "NMPC solve per control step", "backstepping law", _nmpc),
    )
}
"""The registry: name -> :class:`Benchmark`, in running order."""


def select(only: str | Sequence[str] | None) -> list[str]:
    """The benchmarks to run, in registry order; a :class:`ParameterError` names the valid ones."""
    if only is None:
        return list(BENCHMARKS)
    names = [s.strip() for s in only.split(",")] if isinstance(only, str) else [str(s).strip() for s in only]
    names = [s for s in names if s]
    if not names or any(s not in BENCHMARKS for s in names):
        raise ParameterError("--only", only, f"a comma-separated subset of {', '.join(BENCHMARKS)}")
    return [b for b in BENCHMARKS if b in names]


# --------------------------------------------------------------------------- one core, Ctrl-C
@contextlib.contextmanager
def one_thread() -> Iterator[dict[str, Any]]:
    """Thread variables set to 1 (unless exported), the loaded BLAS/OpenMP pools limited to match
    (``threadpoolctl``); both restored after."""
    from threadpoolctl import threadpool_info, threadpool_limits

    saved = {v: os.environ.get(v) for v in THREAD_VARIABLES}
    for v in THREAD_VARIABLES:
        os.environ.setdefault(v, "1")
    try:
        want = max(1, int(os.environ["OPENBLAS_NUM_THREADS"]))
    except ValueError:
        want = 1
    before = {p["filepath"]: p["num_threads"] for p in threadpool_info()}
    try:
        with threadpool_limits(limits=want):
            info = {
                "environment": {v: os.environ[v] for v in THREAD_VARIABLES},
                "thread_pools": [
                    {
                        "library": Path(p["filepath"]).name,
                        "api": p["internal_api"],
                        "threads_before": before.get(p["filepath"]),
                        "threads": p["num_threads"],
                    }
                    for p in threadpool_info()
                ],
            }
            yield info
    finally:
        for v, value in saved.items():
            if value is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = value


@contextlib.contextmanager
def _watch_interrupts() -> Iterator[dict[str, bool]]:
    """Remember a Ctrl-C even when a benchmark swallows it (``ClosedLoop.run`` returns "interrupted")."""
    state = {"hit": False}

    def handler(signum, frame):
        state["hit"] = True
        raise KeyboardInterrupt

    install = threading.current_thread() is threading.main_thread() and (
        signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )
    if install:
        signal.signal(signal.SIGINT, handler)
    try:
        yield state
    finally:
        if install:
            signal.signal(signal.SIGINT, signal.default_int_handler)


def machine() -> dict[str, Any]:
    versions = {}
    for dist in ("meanfield-crowd", "numpy", "scipy", "cvxpy", "clarabel", "casadi", "py-pde", "fipy", "jupedsim"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return {
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
        "load_average_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
    }


# --------------------------------------------------------------------------- the run
def _command(quick: bool, out: Path | None, names: list[str] | None) -> str:
    parts = ["meanfield", "bench"]
    if quick:
        parts.append("--quick")
    if names is not None:
        parts += ["--only", ",".join(names)]
    if out is not None:
        parts += ["--out", str(out)]
    return shlex.join(parts)


def run_suite(
    quick: bool = False,
    out: str | Path | None = None,
    only: str | Sequence[str] | None = None,
    progress: bool = True,
    command: str | None = None,
) -> dict[str, Any]:
    """Run the selected benchmarks (all by default) in registry order; return the JSON document.

    ``out`` (optional) is written atomically at the start and after every finished
    benchmark, ``complete`` staying false until the end.  A benchmark that raises gives a
    record with ``error`` and the suite goes on; Ctrl-C stops it (``interrupted: true``),
    keeping the records of the benchmarks that finished.  Progress lines go to stderr.

    Raises
    ------
    ParameterError
        An unknown name in ``only``, or ``out`` an existing directory (before anything runs).
    """
    names = select(only)
    out = None if out is None else Path(out)
    if out is not None and out.is_dir():
        raise ParameterError("--out", str(out), "a JSON file path, not a directory")
    mode = "quick" if quick else "full"
    start = time.perf_counter()
    doc: dict[str, Any] = {
        "suite": "meanfield bench",
        "command": command or _command(quick, out, None if only is None else names),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "quick": bool(quick),
        "machine": machine(),
        "threads": {},
        "ratio": RATIO_MEANING,
        "benchmarks": names,
        "settings": {n: SETTINGS[n][mode] for n in names},
        "finished": [],
        "seconds": {},
        "records": [],
        "complete": False,
        "interrupted": False,
        "errors": 0,
        "all_goals_pass": None,
        "wall_seconds": 0.0,
    }

    def save() -> None:
        doc["wall_seconds"] = time.perf_counter() - start
        if out is not None:
            atomic_write_json(out, doc)

    def say(text: str) -> None:
        if progress:
            print(text, file=sys.stderr, flush=True)

    with one_thread() as threads, _watch_interrupts() as interrupt:
        doc["threads"] = threads
        try:
            save()
            for i, name in enumerate(names, 1):
                say(f"[{i}/{len(names)}] {name} ...")
                t0 = time.perf_counter()
                try:
                    records = BENCHMARKS[name].run(quick)
                except Exception as exc:
                    if interrupt["hit"]:
                        raise KeyboardInterrupt from None
                    records = [_failed(name, exc)]
                if interrupt["hit"]:  # a Ctrl-C swallowed inside the benchmark: its figures are not whole
                    raise KeyboardInterrupt
                seconds = time.perf_counter() - t0
                doc["records"] += records
                doc["finished"].append(name)
                doc["seconds"][name] = seconds
                doc["errors"] = sum(1 for r in doc["records"] if "error" in r)
                save()
                state = "FAILED: " + records[0]["error"] if "error" in records[0] else "done"
                say(f"[{i}/{len(names)}] {name} {state} in {seconds:.0f} s")
            doc["complete"] = True
        except KeyboardInterrupt:
            doc["interrupted"] = True
            say("interrupted: the JSON keeps the benchmarks that finished")
    verdicts = [r["pass"] for r in doc["records"] if r.get("pass") is not None]
    doc["all_goals_pass"] = all(verdicts) if verdicts else None
    doc["machine"]["load_average_end"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    save()
    return doc


# --------------------------------------------------------------------------- the table
def _num(v: float) -> str:
    a = abs(v)
    if a >= 1000:
        return f"{v:,.0f}"
    if a >= 100:
        return f"{v:.0f}"
    return f"{v:.3g}"


def format_table(records: Sequence[dict[str, Any]]) -> str:
    """benchmark | ours | anchor | ratio | goal/pass or note, as a Markdown table."""
    head = ["benchmark", "ours", "anchor", "ratio (>1: ours faster)", "goal / pass or note"]
    rows = []
    for r in records:
        if "error" in r:
            rows.append([r["name"], "-", "-", "-", f"ERROR: {r['error']}"])
        elif r["skipped"]:
            rows.append([r["name"], "-", "-", "-", f"skipped: {r['note']}"])
        else:
            verdict = f"{'PASS' if r['pass'] else 'FAIL'} ({r['goal']})" if r["pass"] is not None else ""
            rows.append(
                [
                    r["name"],
                    f"{_num(r['ours_value'])} {r['unit']}",
                    f"{_num(r['anchor_value'])} {r['anchor_unit']}",
                    _num(r["ratio"]),
                    "; ".join(x for x in (verdict, r["note"]) if x),
                ]
            )
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=True)]
    widths[-1] = 0  # no padding of the last column

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(str(c).ljust(w) for c, w in zip(cells, widths, strict=True)) + " |"

    return "\n".join([line(head), line(["-" * max(w, 3) for w in widths]), *map(line, rows)])


# --------------------------------------------------------------------------- CLI
_DESCRIPTION = (
    "Every benchmark of the toolkit in one command: our figure, the anchor's figure measured in the "
    "same run, and their ratio (> 1: ours is faster), on one core. Anchors that are not installed are "
    "skipped with a note. The JSON is rewritten after every finished benchmark. "
    "Exit status: 0 every benchmark ran (whatever the PASS/FAIL verdicts of the speed goals, which "
    "are reported, not enforced); 1 a benchmark crashed or the run was interrupted (the JSON keeps "
    "what finished, complete: false); 2 bad input (unknown --only name), before anything runs."
)


def _epilog() -> str:
    lines = ["benchmarks (in running order):"]
    lines += [f"  {b.name:<14} {b.measures}; anchor: {b.anchor}" for b in BENCHMARKS.values()]
    lines.append("--quick takes about 1.5 minutes on 2 cores, the full run about 5.")
    return "\n".join(lines)


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="short settings (about 1.5 min on 2 cores; full: about 5)")
    p.add_argument("--out", required=True, type=Path, help="the JSON file (rewritten after every benchmark)")
    p.add_argument("--only", default=None, metavar="NAME,...", help=f"a subset of: {', '.join(BENCHMARKS)}")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield bench`` to the ``meanfield`` parser; return its handler."""
    p = subparsers.add_parser(
        "bench",
        help="every benchmark against its anchor, same run, one core: a table + FILE.json",
        description=textwrap.fill(_DESCRIPTION, 100),
        epilog=_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_arguments(p)
    return _handle


def _handle(args: argparse.Namespace) -> int:
    names = None if args.only is None else select(args.only)  # exit 2 before anything runs
    doc = run_suite(
        quick=args.quick,
        out=args.out,
        only=names,
        progress=not args.quiet,
        command=_command(args.quick, args.out, names),
    )
    print(format_table(doc["records"]))
    print(f"\n{RATIO_MEANING}.")
    state = "complete" if doc["complete"] else "interrupted"
    errors = f", {doc['errors']} benchmark(s) raised" if doc["errors"] else ""
    print(f"{state} in {doc['wall_seconds']:.0f} s{errors}; wrote {args.out}")
    return 0 if doc["complete"] and not doc["errors"] else 1


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m benchmarks.suite [--quick] --out FILE.json [--only ...]`` (same as ``meanfield bench``)."""
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.suite",
        description=textwrap.fill(_DESCRIPTION, 100),
        epilog=_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_arguments(p)
    args = p.parse_args(argv)
    try:
        return _handle(args)
    except ParameterError as exc:
        print(f"meanfield: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
