"""Command-line interface: ``meanfield run``, ``meanfield scenario``.

Exit status: 0 success; 1 the run diverged or was interrupted (outputs of the last good
state are still written); 2 invalid input (bad parameter, unknown scenario or key).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from meanfield.errors import ParameterError

__all__ = ["main"]


def _parse_set(values: Sequence[str]) -> dict[str, object]:
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


def _build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="meanfield",
        description="Mean-field control of crowds by robots (Zheng et al.): simulate, analyse, verify.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a closed-loop scenario and write its outputs")
    r.add_argument("scenario", nargs="?", default="paper", help="built-in name (paper) or a TOML file")
    r.add_argument("--out", required=True, type=Path, help="output directory")
    r.add_argument("--seed", type=int, default=None, help="random seed (overrides the scenario's)")
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario field, e.g. --set robots.n=9 (repeatable)",
    )
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary printout")
    r.add_argument("--animate", action="store_true", help="also write animation.gif")
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    s = sub.add_parser("scenario", help="print a scenario as TOML (a starting point for your own)")
    s.add_argument("scenario", nargs="?", default="paper")
    return p


def _cmd_run(args: argparse.Namespace) -> int:
    from meanfield.scenario import load_scenario
    from meanfield.simulate import ClosedLoop

    if args.seed is not None and args.seed < 0:
        raise ParameterError("--seed", args.seed, "an integer >= 0")
    sc = load_scenario(args.scenario, seed=args.seed)
    if args.set:
        sc = sc.with_values(_parse_set(args.set))
    loop = ClosedLoop(sc)
    result = loop.run(progress=not args.quiet)
    result.save(args.out, figures=not args.no_figures, animate=args.animate)
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
            "steps",
            "wall_seconds",
            "seed",
        )
        print(json.dumps({k: s[k] for k in keys}, indent=2))
        print(f"outputs in {args.out}")
    if s["status"] != "completed":
        print(f"meanfield: run {s['status']}: {s['message']} (outputs of the last good state written)", file=sys.stderr)
        return 1
    return 0


def _cmd_scenario(args: argparse.Namespace) -> int:
    from meanfield.scenario import load_scenario

    sys.stdout.write(load_scenario(args.scenario).to_toml())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``meanfield`` command; returns the exit status."""
    args = _build_parser().parse_args(argv)
    try:
        if args.command == "run":
            return _cmd_run(args)
        return _cmd_scenario(args)
    except ParameterError as exc:
        print(f"meanfield: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
