"""``meanfield run``: one closed-loop run, its data, figures and summary in a folder."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from meanfield import plugins
from meanfield.cli.arguments import add_scenario_arguments, output_file, scenario_from_args
from meanfield.errors import ParameterError

__all__ = ["register", "run_artifacts"]


def register(subparsers: Any) -> Callable[[argparse.Namespace], int]:
    """Add ``meanfield run`` to the ``meanfield`` parser; return its handler."""
    r = subparsers.add_parser("run", help="run a closed-loop scenario and write its outputs")
    add_scenario_arguments(r)
    r.add_argument(
        "--crowd",
        choices=plugins.available("crowd"),
        default=None,
        help="the crowd (overrides crowd.kind): a registered crowd, e.g. point-mass (SDE humans), "
        "jupedsim (bodies), fokker-planck (the mean-field density)",
    )
    r.add_argument(
        "--backend",
        choices=plugins.available("crowd"),
        default=None,
        help="deprecated and removed in 0.3.0: --crowd",
    )
    r.add_argument(
        "--threads",
        type=int,
        default=None,
        metavar="N",
        help="BLAS threads of the run (default 1, or MEANFIELD_BLAS_THREADS): small products run fastest on one",
    )
    r.add_argument(
        "--crowd-threads",
        type=int,
        default=None,
        metavar="N",
        help="threads of the crowd's per-human loops (default every core); the results do not depend on it",
    )
    r.add_argument(
        "--export-webapp",
        type=output_file,
        default=None,
        metavar="OUT.zip",
        help="for a run of a JuPedSim web-app export: write the export and the run's trajectory.sqlite into "
        "OUT.zip, which the web app and jupedsim-scenarios read back",
    )
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    r.add_argument("--animate", action="store_true", help="also write animation.gif")
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    return _cmd_run


def _trajectory_file(result, folder: Path) -> dict[str, Path]:
    """``trajectories.sqlite``: the humans in JuPedSim's format, for PedPy and JuPedSim's viewer."""
    from meanfield.io.trajectories import write_jupedsim_sqlite

    frames = result.timeseries  # (not result.dataset: no xarray import in a run)
    if "human_x" not in frames or frames.sizes["time"] < 2:
        return {}  # a density crowd has no humans to trace
    area = result.scenario.domain.to_shapely()
    return {"trajectories": write_jupedsim_sqlite(frames, area, folder / "trajectories.sqlite")}


def run_artifacts(figures: bool = True, animate: bool = False, progress: bool = False) -> list:
    """The files written beside a run's data: the trajectories (JuPedSim's SQLite format), the
    figures (:mod:`meanfield.plotting.figures`) and the animation."""
    from meanfield.plotting import figures as plotting

    out = [_trajectory_file]
    if figures:
        out.append(plotting.save_run_figures)
    if animate:
        out.append(
            lambda result, folder: {
                "animation": plotting.save_animation(result, folder / "animation.gif", progress=progress)
            }
        )
    return out


def _say_compiling() -> None:
    print(
        "meanfield: compiling the toolkit's loops for this machine (the first run only, a few seconds; "
        "numba caches them)",
        file=sys.stderr,
        flush=True,
    )


def _shipped_warnings(name: str, grid: Any, scenario: Any) -> set[str]:
    """The stability warnings a built-in scenario gives as shipped, when this run keeps its ``dt`` and
    its grid: documented with the scenario (``paper``'s ``dt`` is the paper's, above the sampled
    Step-I step: docs page *Scenarios*), kept in ``summary.json``'s ``warnings``, and not printed
    at every run.  A run that changes ``dt`` or the grid is told of every condition it breaks."""
    from meanfield.cli.arguments import builtin_names
    from meanfield.scenarios.scenario import load_scenario
    from meanfield.simulation.preflight import stability_warnings

    if name not in builtin_names():
        return set()
    shipped = load_scenario(name)
    if shipped.dt != scenario.dt or shipped.grid.cells != scenario.grid.cells or shipped.domain != scenario.domain:
        return set()
    return set(stability_warnings(scenario, grid, {}))


def _webapp_export(args: argparse.Namespace) -> Any:
    """The web-app export the run reads, when ``--export-webapp`` asks for it back (refused otherwise, before the
    run, naming ``--export-webapp``)."""
    if args.export_webapp is None:
        return None
    from meanfield.io.webapp import looks_like_export, read_export

    if not looks_like_export(args.scenario):
        allowed = "a run of a JuPedSim web-app export (meanfield run EXPORT.zip --export-webapp OUT.zip)"
        raise ParameterError("--export-webapp", str(args.export_webapp), allowed)
    out = Path(args.export_webapp).resolve()
    if out == Path(args.scenario).resolve():
        raise ParameterError("--export-webapp", str(args.export_webapp), "a file other than the export the run reads")
    return read_export(args.scenario)


def _write_webapp_export(export: Any, folder: Path, out: Path, quiet: bool) -> None:
    """The export and the run's ``trajectories.sqlite`` into ``out``
    (:func:`meanfield.io.webapp.write_export_with_trajectory`)."""
    from meanfield.io.webapp import write_export_with_trajectory

    trajectory = folder / "trajectories.sqlite"
    if not trajectory.is_file():
        raise ParameterError("--export-webapp", str(out), "a run that records its humans (a crowd of agents)")
    write_export_with_trajectory(export, trajectory, out)
    if not quiet:
        print(f"web-app export with the run's trajectory in {out}")


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it, else the machine's)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # (not on every system)
        return os.cpu_count() or 1


def _cmd_run(args: argparse.Namespace) -> int:
    """``meanfield run``: the threads it asks for hold while it runs (:func:`~meanfield._compiled.threads.
    command_threads`: a caller of :func:`meanfield.cli.app.main` from Python gets its own back), then the run."""
    from meanfield._compiled.threads import command_threads

    cores = available_cores()
    for name, value, what in (("--threads", args.threads, "BLAS threads"),
                              ("--crowd-threads", args.crowd_threads, "the crowd's loops")):  # fmt: skip
        if value is not None and not 1 <= value <= cores:
            raise ParameterError(name, value, f"an integer from 1 to {cores}, the cores available ({what})")
    with command_threads(args.threads, args.crowd_threads):
        return _run_scenario(args)


def _run_scenario(args: argparse.Namespace) -> int:
    from meanfield._compiled import core as compiled
    from meanfield.io.atomic import check_output_names, folder_lock
    from meanfield.simulation.loop import ClosedLoop, signals_deferred
    from meanfield.simulation.preflight import check_fits
    from meanfield.simulation.result import SimulationResult

    sc = scenario_from_args(args)
    export = _webapp_export(args)
    own = Path(args.scenario)
    if own.suffix == ".toml" and own.is_file() and own.resolve() == (Path(args.out) / "scenario.toml").resolve():
        raise ParameterError(
            "--out", str(args.out), f"a folder other than the one holding {own} (the run writes a scenario.toml there)"
        )
    check_fits(sc, args.out)  # memory and the output's disk, before anything is allocated
    check_output_names(args.out, SimulationResult.FILE_NAMES)  # each file the run writes, before any work
    unregister = compiled.before_cold_compile(_say_compiling) if not args.quiet else None
    with folder_lock(args.out):  # a second run into this folder is refused while this one lasts
        try:
            loop = ClosedLoop(sc)  # a signal here stops the command before anything is written (exit 130)
        finally:
            if unregister is not None:
                unregister()
        artifacts = run_artifacts(figures=not args.no_figures, animate=args.animate, progress=not args.quiet)
        with signals_deferred() as held:  # the loop stops between steps; the summary and the save finish
            result = loop.run(progress=not args.quiet)
            result.save(args.out, artifacts=artifacts)
    s = result.summary
    if export is not None:
        _write_webapp_export(export, Path(args.out), args.export_webapp, args.quiet)
    if held():
        print("meanfield: a signal came after the last step: the run was finished and saved", file=sys.stderr)
    if not args.quiet:
        print(json.dumps(printed_summary(s), indent=2))
        print(f"outputs in {args.out}")
    shipped = _shipped_warnings(args.scenario, loop.grid, sc)
    for warning in s.get("warnings", ()):
        if warning not in shipped:  # a built-in's own, documented condition is in summary.json, not repeated
            print(f"meanfield: warning: {warning}", file=sys.stderr)
    if s["status"] != "completed":
        print(f"meanfield: run {s['status']}: {s['message']} (outputs of the last good state written)", file=sys.stderr)
        return 1
    return 0


TARGET_KEYS = ("status", "fraction_in_target", "l2_error_initial", "l2_error_final", "w2_to_target_final", "time_to_90")
"""What ``meanfield run`` prints first for a run towards the target (the paper's question: is the crowd there?)."""
EVACUATION_KEYS = ("status", "fraction_evacuated", "evacuation_time_95", "evacuation_time_100", "rset_over_bound")
"""What it prints first for a plan with exits (an evacuation engineer's: who is out, when, and against the bound)."""
RUN_KEYS = ("max_robot_speed", "speed_limit", "backend", "seen_fraction_final", "steps", "wall_seconds", "seed",
            "body_overlap_max", "jupedsim_version")  # fmt: skip
"""Then, for every run: the robots' limits, the crowd, and the run itself."""


def printed_summary(summary: dict) -> dict:
    """The summary keys ``meanfield run`` prints (docs page *Command line*, ``run``): on a plan with exits the
    evacuation figures, each exit's flow in persons/(m·s) included, in place of the target's figures (0 in the
    target and no W2 to it look like a failed run there); otherwise the target's; then :data:`RUN_KEYS`."""
    evacuation = "fraction_evacuated" in summary
    out = {k: summary[k] for k in (EVACUATION_KEYS if evacuation else TARGET_KEYS) if k in summary}
    if evacuation and summary.get("exit_flows"):
        out["flow_per_exit"] = [
            None if f.get("persons_per_metre_second") is None else round(f["persons_per_metre_second"], 3)
            for f in summary["exit_flows"]
        ]
    out.update({k: summary[k] for k in RUN_KEYS if k in summary})
    return out
