"""The density on Hughes' route against an independent peer, hughes2d: exit times and wall times.

Run:  python benchmarks/bench_hughes2d.py [--quick] [--json FILE]      (``meanfield bench --only hughes2d``)

The problem and both codes are in :mod:`benchmarks.hughes2d_peer` (a 5 m × 4 m room, a 1 m door, 18 people, the
linear diagram, Hughes' route).  Each code runs its own refinement series (ours: square cells of 1/10, 1/20, 1/40 m;
hughes2d: triangles of at most 0.12, 0.06, 0.03 m²; quick: the coarsest of each), until 90 % are out.

Records, one per level (ours level ``k`` against hughes2d's level ``k``): our wall time (set-up and run) against
hughes2d's, the times at which 10, 50 and 90 % are out in the note.  The goal (issue 42, item 5): the finest of
each series agree, every time within 3 % of hughes2d's; it is judged on the last record of the full run only
(the quick run's coarse meshes are a smoke test, with no verdict).  Also in the full run: ours at σ = 0, 0.005 and
0.02 m²/s on the 0.05 m cells (hughes2d has no diffusion; the record of the finest level carries them in its
``detail``, ``sigmas``).

Without hughes2d (``pip install -e '.[bench]'``, or ``pip install hughes2d``) the records are skipped with that
note and nothing runs.
"""

from __future__ import annotations

from benchmarks.environment import one_thread_variables

one_thread_variables()  # one core

import argparse  # noqa: E402
import sys  # noqa: E402
from typing import Any  # noqa: E402

from benchmarks import hughes2d_peer as peer  # noqa: E402
from benchmarks.records import BENCH_INSTALL, measured, settings, skipped  # noqa: E402
from benchmarks.reporting import emit, machine_line  # noqa: E402

OURS_LABEL = "meanfield density (fokker-planck, guidance hughes, linear diagram), ClosedLoop"
PEER_LABEL = "hughes2d {version} PedestrianSolver (model hughes, default options, documented CFL step)"
WHAT = (
    "the density on Hughes' route, 5 m x 4 m room, 1 m door, 18 people uniform in [0.5, 3.5]^2, linear diagram "
    "(1.34 m/s, 5.4 persons/m^2); set-up and run until 90 % are out"
)
GOAL = "t10, t50, t90 within 3 % of hughes2d's (finest of each series)"


def _level_names(o: dict[str, Any], p: dict[str, Any]) -> str:
    return f"{o['cell']:g} m cells vs triangles <= {p['max_area']:g} m^2"


def pct(r: float | None) -> str:
    """A relative difference as a signed percentage."""
    return "-" if r is None else f"{100 * r:+.1f} %"


def _times(t: list[float | None]) -> str:
    return "/".join("-" if x is None else f"{x:.3f}" for x in t)


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``hughes2d`` records of ``meanfield bench``: per level, our wall time against hughes2d's.

    Parameters
    ----------
    quick : bool
        Quick or full settings of :data:`benchmarks.records.SETTINGS` (``ours``: cells per metre, ``peer``: largest
        triangle areas, ``sigmas``: our other σ).

    Returns
    -------
    list of dict
        One record per pair of levels; skipped records naming the install command without hughes2d.
    """
    s = settings("hughes2d", quick)
    ours_levels, peer_levels = list(s["ours"]), list(s["peer"])
    why = peer.peer_missing()
    if why is not None:
        return [
            skipped(
                "hughes2d",
                f"hughes2d level {k + 1}",
                WHAT,
                OURS_LABEL,
                "hughes2d",
                f"hughes2d not available ({why}); install: {BENCH_INSTALL} (or pip install hughes2d)",
            )
            for k in range(min(len(ours_levels), len(peer_levels)))
        ]
    doc = peer.compare(ours_levels, peer_levels, sigmas=list(s.get("sigmas", [])))
    records = []
    pairs = list(zip(doc["ours"], doc["peer"], strict=False))
    for k, (o, p) in enumerate(pairs):
        rel = peer.relative(o["t"], p["t"])
        last = k == len(pairs) - 1
        verdict = None if quick or not last else doc["agrees"]
        note = (
            f"t10/t50/t90 {_times(o['t'])} s (ours) vs {_times(p['t'])} s (hughes2d), "
            f"differences {', '.join(pct(r) for r in rel)}; "
            f"set-up {o['setup_time']:.2g} + run {o['wall_time']:.3g} s vs "
            f"{p['setup_time']:.3g} + {p['wall_time']:.3g} s; "
            f"{o['cells']} cells vs {p['triangles']} triangles"
        )
        if quick:
            note += "; quick: coarse meshes, no verdict"
        detail: dict[str, Any] = {"ours": o, "peer": p, "relative": rel, "sigma": doc["sigma"]}
        if last:
            detail["relative_finest"] = doc["relative_finest"]
            detail["sigmas"] = doc["sigmas"]
        records.append(
            measured(
                "hughes2d",
                f"hughes2d level {k + 1}: {_level_names(o, p)}",
                WHAT,
                OURS_LABEL,
                PEER_LABEL.format(version=p["version"]),
                o["setup_time"] + o["wall_time"],
                p["setup_time"] + p["wall_time"],
                "s",
                faster="lower",
                goal=None if verdict is None else GOAL,
                passed=verdict,
                note=note,
                detail=detail,
            )
        )
    return records


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the quick settings of meanfield bench --quick")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    records = suite_records(a.quick)
    emit({"benchmark": "hughes2d", "machine": machine_line(), "records": records}, a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
