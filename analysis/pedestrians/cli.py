"""``meanfield pedestrians RUN_DIR... --out DIR``: PedPy measurements of finished runs.

The command of :mod:`analysis.pedestrians.metrics` (entry point
``analysis.pedestrians.cli:register``): for every run,
:func:`~analysis.pedestrians.metrics.pedestrian_metrics` with its figures in ``DIR/<run>``,
and one report ``DIR/pedestrians.json`` (``docs/pedestrians.md``, ``docs/cli.md``).  The
measurements are imported when the command runs, so that registering it costs nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from meanfield.cli.arguments import output_dir
from meanfield.errors import ParameterError

__all__ = ["register"]


def register(subparsers: Any):
    """Add ``meanfield pedestrians`` to the ``meanfield`` parser; return its handler."""
    p = subparsers.add_parser(
        "pedestrians",
        help="PedPy measurements of finished runs: N(t) in the target region, density maps (JSON + figures)",
    )
    p.add_argument("run_dirs", nargs="+", metavar="RUN_DIR", help="directories written by meanfield run")
    p.add_argument("--out", required=True, type=output_dir, help="output directory (checked before any work)")
    p.add_argument(
        "--window", type=float, default=0.2, help="density maps over the last WINDOW of the run (default 0.2)"
    )
    p.add_argument(
        "--voronoi-frames", type=int, default=12, help="frames of the Voronoi map (0.3-1.2 s each; 0: skip)"
    )
    p.add_argument("--quiet", action="store_true", help="no summary printout")
    return _handle


def _labels(run_dirs: list[Path]) -> list[str]:
    labels, seen = [], {}
    for d in run_dirs:
        name = d.resolve().name or "run"
        k = seen.get(name, 0)
        seen[name] = k + 1
        labels.append(name if k == 0 else f"{name}-{k}")
    return labels


def _handle(args: argparse.Namespace) -> int:
    from analysis.pedestrians.metrics import _pedpy, pedestrian_metrics
    from meanfield.io.atomic import atomic_write_json

    if not 0 < args.window <= 1:
        raise ParameterError("--window", args.window, "a fraction in (0, 1]")
    if args.voronoi_frames < 0:
        raise ParameterError("--voronoi-frames", args.voronoi_frames, "an integer >= 0")
    try:
        _pedpy()
    except ImportError as exc:
        print(f"meanfield: error: {exc}", file=sys.stderr)
        return 2
    run_dirs = [Path(d) for d in args.run_dirs]
    for d in run_dirs:
        if not (d / "timeseries.nc").is_file():
            raise ParameterError("RUN_DIR", str(d), "a directory written by meanfield run (with timeseries.nc)")
    out = Path(args.out)
    report: dict[str, Any] = {"runs": {}}
    ok = True
    for d, label in zip(run_dirs, _labels(run_dirs), strict=True):
        m = pedestrian_metrics(d, out / label, window_fraction=args.window, voronoi_frames=args.voronoi_frames)
        report["runs"][label] = m.to_dict()
        ok &= m.differences_explained
        if not args.quiet:
            print(
                f"{label}: N(T)/N = {m.fraction_pedpy[-1]:.3f} (PedPy), {m.fraction_toolkit[-1]:.3f} (toolkit); "
                f"max difference {m.max_fraction_difference:.3g}"
                f"{'' if m.differences_explained else ' NOT explained by the disk polygonisation'}"
                + (f"; Voronoi failed: {m.voronoi_error}" if m.voronoi_error else "")
            )
    report["differences_explained"] = ok
    atomic_write_json(out / "pedestrians.json", report)
    if not args.quiet:
        print(f"outputs in {out}")
    return 0 if ok else 1
