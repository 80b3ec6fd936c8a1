"""Command-line interface: ``meanfield run``, ``meanfield compare``, ``meanfield scenario``.

Packages built on :mod:`meanfield` add sub-commands through the ``meanfield.commands``
entry points (:mod:`meanfield.plugins`): ``meanfield analyze`` comes from :mod:`analysis`.

Exit status: 0 success; 1 the run diverged or was interrupted (outputs of the last good
state are still written); 2 invalid input (bad parameter, unknown scenario or key).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from meanfield import plugins
from meanfield.errors import ParameterError

__all__ = [
    "main",
    "add_scenario_arguments",
    "scenario_from_args",
    "parse_set",
    "int_list",
    "float_list",
    "output_dir",
    "output_file",
]


def output_dir(text: str) -> Path:
    """argparse type of an ``--out`` folder: checked when the command line is read, before any work.

    A path that is a file, lies under a file or is not writable is refused (exit 2) with the reason.
    """
    from meanfield.io import check_output_dir

    try:
        return check_output_dir(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def output_file(text: str) -> Path:
    """argparse type of an ``--out`` file (a JSON report): not a folder, its folder writable."""
    from meanfield.io import check_output_file

    try:
        return check_output_file(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def parse_set(values: Sequence[str]) -> dict[str, object]:
    """``["robots.n=9", ...]`` as ``{"robots.n": 9, ...}``, each value read as TOML (else a string)."""
    import tomllib

    out: dict[str, object] = {}
    for item in values:
        if "=" not in item:
            raise ParameterError("--set", item, "KEY=VALUE with a dotted scenario key, e.g. kernel.eta=0.02")
        key, raw = item.split("=", 1)
        try:
            out[key.strip()] = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = raw
    return out


_SCENARIO_HELP = "a built-in scenario ({}) or a TOML file"


def builtin_names() -> list[str]:
    """The built-in scenarios (``meanfield/scenarios/*.toml``), read without importing the toolkit."""
    from importlib import resources

    folder = resources.files("meanfield").joinpath("scenarios")
    return sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml"))


def _builtin_description(name: str) -> str:
    """The first comment line of a built-in scenario's TOML (what it is)."""
    from importlib import resources

    text = resources.files("meanfield").joinpath("scenarios", f"{name}.toml").read_text(encoding="utf-8")
    first = next((line for line in text.splitlines() if line.startswith("#")), "")
    return first.lstrip("# ").strip()


def add_scenario_arguments(parser: argparse.ArgumentParser, seed_help: str = "random seed (overrides the scenario's)"):
    """The arguments every scenario command shares: ``[scenario] --out DIR [--seed S] [--set K=V]...``.

    Read them back with :func:`scenario_from_args`.  Command plugins use both.
    """
    parser.add_argument(
        "scenario", nargs="?", default="paper", help=_SCENARIO_HELP.format(", ".join(builtin_names()))
    )
    parser.add_argument("--out", required=True, type=output_dir, help="output directory (checked before any work)")
    parser.add_argument("--seed", type=int, default=None, help=seed_help)
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario field, e.g. --set robots.n=9 (repeatable)",
    )


def _build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="meanfield",
        description="Mean-field control of crowds by robots (Zheng et al.): simulate, analyse, verify.",
    )
    from importlib.metadata import PackageNotFoundError, version

    try:
        installed = version("meanfield-crowd")
    except PackageNotFoundError:  # pragma: no cover - run from a source tree without installing
        installed = "unknown (not installed)"
    p.add_argument("--version", action="version", version=f"meanfield {installed}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a closed-loop scenario and write its outputs")
    add_scenario_arguments(r)
    r.add_argument(
        "--backend",
        choices=plugins.available("crowd"),
        default=None,
        help="crowd (overrides pedestrians.backend): a registered crowd, e.g. point-mass (SDE humans), "
        "jupedsim (bodies), fokker-planck (the mean-field density)",
    )
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    r.add_argument("--animate", action="store_true", help="also write animation.gif")
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    c = sub.add_parser(
        "compare",
        help="agents (SDE) against the Fokker–Planck PDE under the same robot trajectories, for several N",
    )
    add_scenario_arguments(c)
    c.add_argument(
        "--n-agents", default="100,1000,10000,100000", help="comma-separated crowd sizes (default 100,...,100000)"
    )
    c.add_argument("--t-final", type=float, default=None, help="horizon (default: the scenario's t_final)")
    c.add_argument("--cells", type=int, default=64, help="PDE and density grid, cells per side (default 64)")
    c.add_argument(
        "--repulsion",
        default="0.5,0.1",
        help="STRENGTH,LENGTH of the repulsive Gaussian W for the second case, or 'none' (default 0.5,0.1)",
    )
    c.add_argument("--record-interval", type=float, default=1.0, help="time between measurements (default 1)")
    c.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    c.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    s = sub.add_parser("scenario", help="print a scenario as TOML (a starting point for your own)")
    s.add_argument(
        "scenario", nargs="?", default="paper", help=_SCENARIO_HELP.format(", ".join(builtin_names()))
    )
    s.add_argument("--list", action="store_true", help="list the built-in scenarios, one line each")
    for name in plugins.available("command"):  # e.g. `meanfield analyze` from the analysis package
        try:
            handler = plugins.load("command", name)(sub)
        except (ImportError, AttributeError) as exc:  # a broken plugin must not break the other commands
            handler = _unavailable(name, exc)
            stub = sub.add_parser(name, help=f"(unavailable: {exc})", add_help=False)
            stub.add_argument("rest", nargs=argparse.REMAINDER)
        sub.choices[name].set_defaults(plugin_handler=handler)
    return p


def _unavailable(name: str, exc: Exception):
    def handler(args: argparse.Namespace) -> int:
        print(f"meanfield: error: the '{name}' command could not be loaded: {exc}", file=sys.stderr)
        return 2

    return handler


def scenario_from_args(args: argparse.Namespace):
    """The scenario named by ``args.scenario``, after ``--seed``, ``--set`` and ``--backend``.

    The crowd it names is built when the loop is assembled, before anything runs: there,
    ``jupedsim`` without JuPedSim installed raises a :class:`ParameterError` that names the
    install command (exit status 2).
    """
    from meanfield.scenario import load_scenario

    if args.seed is not None and args.seed < 0:
        raise ParameterError("--seed", args.seed, "an integer >= 0")
    sc = load_scenario(args.scenario, seed=args.seed)
    if args.set:
        sc = sc.with_values(parse_set(args.set))
    backend = getattr(args, "backend", None)
    if backend is not None:
        sc = sc.with_values({"pedestrians.backend": backend})
    return sc


def _trajectory_file(result, folder: Path) -> dict[str, Path]:
    """``trajectories.sqlite``: the humans in JuPedSim's format, for PedPy and JuPedSim's viewer."""
    from meanfield.trajectories import write_jupedsim_sqlite

    if "human_x" not in result.dataset or result.dataset.sizes["time"] < 2:
        return {}  # a density crowd has no humans to trace
    area = result.scenario.domain.to_shapely()
    return {"trajectories": write_jupedsim_sqlite(result.dataset, area, folder / "trajectories.sqlite")}


def run_artifacts(figures: bool = True, animate: bool = False, progress: bool = False) -> list:
    """The files written beside a run's data: the trajectories (JuPedSim's SQLite format), the
    figures (:mod:`meanfield.plotting`) and the animation."""
    from meanfield import plotting

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


def _cmd_run(args: argparse.Namespace) -> int:
    from meanfield import compiled
    from meanfield.budget import check_fits
    from meanfield.loop import ClosedLoop

    sc = scenario_from_args(args)
    check_fits(sc, args.out)  # memory and the output's disk, before anything is allocated
    unregister = compiled.before_cold_compile(_say_compiling) if not args.quiet else None
    try:
        loop = ClosedLoop(sc)
        result = loop.run(progress=not args.quiet)
    finally:
        if unregister is not None:
            unregister()
    artifacts = run_artifacts(figures=not args.no_figures, animate=args.animate, progress=not args.quiet)
    result.save(args.out, artifacts=artifacts)
    s = result.summary
    if not args.quiet:
        keys = (
            "status",
            "fraction_in_target",
            "l2_error_initial",
            "l2_error_final",
            "w2_to_target_final",
            "time_to_90",
            "max_robot_speed",
            "speed_limit",
            "backend",
            "seen_fraction_final",
            "steps",
            "wall_seconds",
            "seed",
        )
        extra = ("body_overlap_max", "jupedsim_version")
        print(json.dumps({k: s[k] for k in keys + extra if k in s}, indent=2))
        print(f"outputs in {args.out}")
    for warning in s.get("warnings", ()):
        print(f"meanfield: warning: {warning}", file=sys.stderr)
    if s["status"] != "completed":
        print(f"meanfield: run {s['status']}: {s['message']} (outputs of the last good state written)", file=sys.stderr)
        return 1
    return 0


def int_list(name: str, text: str, ranges: bool = False) -> tuple[int, ...]:
    """Comma-separated integers (``"1,2,4"``), or with ``ranges`` also ``"A-B"`` (inclusive)."""
    try:
        if ranges and "-" in text and "," not in text:
            a, b = text.split("-")
            values = tuple(range(int(a), int(b) + 1))
        else:
            values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        allowed = "integers as 'A-B' or 'a,b,c'" if ranges else "comma-separated integers, e.g. 100,1000,10000"
        raise ParameterError(name, text, allowed) from None
    if not values:
        raise ParameterError(name, text, "at least one integer")
    return values


def float_list(name: str, text: str) -> tuple[float, ...]:
    """Comma-separated numbers, e.g. ``"0.05,0.1,0.2"``."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ParameterError(name, text, "comma-separated numbers, e.g. 0.05,0.1,0.2") from None
    if not values:
        raise ParameterError(name, text, "at least one number")
    return values


def _cmd_compare(args: argparse.Namespace) -> int:
    from meanfield.compare import run_comparison

    sc = scenario_from_args(args)
    sizes = int_list("--n-agents", args.n_agents)
    if args.cells < 4:
        raise ParameterError("--cells", args.cells, "an integer >= 4")
    if args.t_final is not None and not args.t_final > 0:
        raise ParameterError("--t-final", args.t_final, "a time > 0")
    repulsion = None
    if args.repulsion.strip().lower() != "none":
        try:
            repulsion = tuple(float(v) for v in args.repulsion.split(","))
        except ValueError:
            repulsion = ()
        if len(repulsion) != 2:
            raise ParameterError("--repulsion", args.repulsion, "STRENGTH,LENGTH (two numbers > 0) or 'none'")
    report = run_comparison(
        sc,
        sizes,
        repulsion=repulsion,
        t_final=args.t_final,
        cells=(args.cells, args.cells),
        record_interval=args.record_interval,
        seed=args.seed,
        progress=not args.quiet,
    )
    from meanfield import plotting

    report.save(args.out, artifacts=[] if args.no_figures else [plotting.save_comparison_figures])
    if not args.quiet:
        for case in report.cases:
            s = case.summary
            print(f"{s['label']}: status {s['status']}")
            for name in ("error_to_expected", "error_to_pde", "error_to_expected_paper_sign"):
                if f"{name}_mean" in s:
                    means = ", ".join(f"N={n}: {v:.4g}" for n, v in s[f"{name}_mean"].items())
                    print(f"  {name}: {means}; slope over 1e2..1e4: {s[f'{name}_slope_1e2_1e4']}")
        print(f"outputs in {args.out}")
    bad = [c.summary for c in report.cases if c.summary["status"] != "completed"]
    if bad:
        print(f"meanfield: compare {bad[0]['status']}: {bad[0]['message']}", file=sys.stderr)
        return 1
    return 0


def _cmd_scenario(args: argparse.Namespace) -> int:
    from meanfield.scenario import load_scenario

    if args.list:
        names = builtin_names()
        width = max(map(len, names))
        for name in names:
            print(f"{name:<{width}}  {_builtin_description(name)}")
        return 0
    sys.stdout.write(load_scenario(args.scenario).to_toml())
    return 0


def _terminated(signum: int, frame: object) -> None:
    """SIGTERM (batch schedulers, containers, ``kill``) as Ctrl-C: the run keeps its last good state."""
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``meanfield`` command; returns the exit status.

    SIGTERM is handled as SIGINT while a command runs: a run stops with ``"status":
    "interrupted"`` and writes its last good state, as after Ctrl-C.
    """
    import signal
    import threading

    args = _build_parser().parse_args(argv)
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "compare":
            return _cmd_compare(args)
        if args.command == "scenario":
            return _cmd_scenario(args)
        return args.plugin_handler(args)
    except ParameterError as exc:
        print(f"meanfield: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
