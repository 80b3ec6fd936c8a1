"""``meanfield bench [--quick] --out FILE.json``: every benchmark of the toolkit in one command.

Each benchmark prints our figure, the figure of an *anchor* measured in the same run (an
established library doing the same job, or the straightforward way of doing it), and their
ratio, defined so that **ratio > 1 means ours is faster** (anchor time / our time, or our
rate / anchor rate).  The benchmarks, in the order they run:

==============  ==========================================================================
kde             KDE of 10⁴ points on 256² against ``scipy.stats.gaussian_kde``; of 10⁶
                points against the exact sum of the same estimate and against KDEpy's
                ``FFTKDE`` (``bench_kde.py``)
closed_loop     the paper scenario's closed loop (N = 200), steps per second, against the same
                loop in plain numpy (``plain_loop.py``) and against ``gaussian_kde`` calls per
                second, 200 points on the 900 cells (``bench_closed_loop.py``)
fokker_planck   the Fokker–Planck solver (ADI, ``courant=2``) against py-pde and FiPy on one
                drift–diffusion problem, 64² (quick) or 64² … 512² (full), each against a
                Richardson reference, set-up included and excluded (``bench_fokker_planck.py``)
jupedsim        the JuPedSim crowd backend steered every step against JuPedSim alone
                (``bench_jupedsim.py``)
large_crowd     the closed loop at N = 10⁶ (``stadium``) against a frozen plain-numpy step of the
                same scenario written from the equations (``plain_stadium.py``;
                ``bench_large_crowd.py``, child processes)
bounded         the bounded β/γ program re-solved (cvxpy DPP) against rebuilt each time, and
                its closed loop against min-norm's (``bench_bounded.py``)
nmpc            NMPC solve per control step against the backstepping law (``bench_nmpc.py``)
startup         ``import meanfield`` and ``meanfield --help`` against ``python -c pass``
compile         the paper's first run as a fresh process on an empty numba cache against the
                same on the filled cache: what compiling costs the first time; goal ≤ 3 s
                (``bench_compile.py``)
plan            a closed-loop step on the ``office`` plan against the same loop on a box of
                the same grid and crowd; goal: at most 1.5× (``bench_plan.py``)
controllers     each installed controller's ``act`` per control step against the paper's law,
                with its real-time factor in ``paper-unity``'s units (``bench_controllers.py``)
congestion      a congested closed-loop step (``crowd.congestion = "linear"``, by the headway and by the
                count) against the same step without congestion, at N = 200 (``bottleneck``) and 10⁶; goal: at most
                1.3× (``bench_congestion.py``)
hughes2d        the density on Hughes' route (5 m × 4 m room, a 1 m door, 18 people, the linear
                diagram): the times at which 10/50/90 % are out and the wall time, against the
                independent peer hughes2d (finite volumes on triangles, fast marching), each on
                its own refinement series; goal: the times within 3 % (``bench_hughes2d.py``)
scaling         steps per second and peak memory against N (10² … 10⁷) and the grid (30² …
                512²), with the fitted exponents (``bench_scaling.py``; the figure of
                ``docs/scale.md`` with ``--figure``)
==============  ==========================================================================

An anchor that is not installed (py-pde, FiPy, JuPedSim, hughes2d) gives a record with
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

Each benchmark's adapter, ``suite_records(quick)``, sits beside it in its ``bench_*.py`` module
(imported only when it runs); records, settings and the table are in :mod:`benchmarks.records`,
the one-core set-up in :mod:`benchmarks.environment`.

From Python: ``run_suite(quick=True, out="bench.json", only=["kde"])``.
"""

from __future__ import annotations

import os

from benchmarks.environment import THREAD_VARIABLES, machine, one_thread, watch_interrupts

if __name__ == "__main__":  # python -m benchmarks.suite: one thread before numpy loads
    for _var in THREAD_VARIABLES:
        os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import shlex  # noqa: E402
import sys  # noqa: E402
import textwrap  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from datetime import UTC, datetime  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks.records import RATIO_MEANING, SETTINGS, failed, format_table  # noqa: E402
from benchmarks.records import measured as measured  # noqa: E402
from benchmarks.records import skipped as skipped  # noqa: E402
from meanfield.cli.arguments import output_file
from meanfield.errors import ParameterError  # noqa: E402
from meanfield.io.atomic import atomic_write_json  # noqa: E402

__all__ = ["BENCHMARKS", "SETTINGS", "Benchmark", "run_suite", "format_table", "register", "main"]
# measured and skipped (benchmarks.records) stay importable from here, as SETTINGS and format_table


@dataclass(frozen=True)
class Benchmark:
    """One entry of the registry: ``run(quick) -> list of records``."""

    name: str
    measures: str
    anchor: str
    run: Callable[[bool], list[dict[str, Any]]]


def _adapter(module: str) -> Callable[[bool], list[dict[str, Any]]]:
    """``run(quick)`` of the benchmark in ``benchmarks.<module>``: its ``suite_records(quick)``.

    The module is imported when the benchmark runs, inside :func:`one_thread`, not before.
    """

    def run(quick: bool) -> list[dict[str, Any]]:
        return importlib.import_module(f"benchmarks.{module}").suite_records(quick)

    run.__qualname__ = run.__name__ = f"{module}.suite_records"
    return run


BENCHMARKS: dict[str, Benchmark] = {
    name: Benchmark(name, measures, anchor, _adapter(f"bench_{name}"))
    for name, measures, anchor in (
        ("kde", "kernel density estimate, N = 1e4 and 1e6 on 256^2", "scipy gaussian_kde; exact sum; KDEpy FFTKDE"),
        ("closed_loop", "closed loop, paper scenario (N = 200)", "plain numpy loop; gaussian_kde calls"),
        ("fokker_planck", "Fokker–Planck solver, 64^2 / 64^2 ... 512^2", "py-pde and FiPy (optional)"),
        ("jupedsim", "JuPedSim crowd backend, steered every step", "JuPedSim alone (optional)"),
        ("large_crowd", "closed loop at N = 1e6 (stadium)", "the frozen plain stadium step"),
        ("bounded", "bounded beta/gamma: re-solve and closed loop", "rebuild; min-norm"),
        ("nmpc", "NMPC solve per control step", "backstepping law"),
        ("startup", "import meanfield; meanfield --help (whole processes)", "python -c pass"),
        ("compile", "the paper's first run on an empty numba cache (whole processes)", "the same, cache filled"),
        ("plan", "closed-loop step on the office plan", "the same loop on a box"),
        ("controllers", "act() per step of every installed controller", "the paper's law"),
        ("congestion", "congested closed-loop step, N = 200 and 1e6", "the same step without congestion"),
        ("hughes2d", "density on Hughes' route: exit times and wall time, 5 m x 4 m room", "hughes2d (optional)"),
        ("scaling", "closed-loop step against N and the grid (log-log, fitted exponents)", "linear extrapolation"),
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

    with one_thread() as threads, watch_interrupts() as interrupt:
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
                    records = [failed(name, exc)]
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
    p.add_argument(
        "--out", required=True, type=output_file, help="the JSON file (rewritten after every benchmark; checked first)"
    )
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
