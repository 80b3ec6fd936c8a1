"""Start-up: ``import meanfield`` and ``meanfield --help`` as whole processes, against the bare interpreter.

Run:  python benchmarks/bench_startup.py [--repeats 7]

Each command is a fresh ``python`` process, timed over ``repeats`` runs (median); the anchor
is ``python -c pass`` in the same run, so the ratio holds across machines.  The goal
(issue "Trustworthy outputs", item 8) is at most 0.5 s for each.  ``python -X importtime``
gives the modules that cost the most, reported beside the times.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from typing import Any

from benchmarks.records import measured, settings

GOAL_SECONDS = 0.5
COMMANDS = {
    "import meanfield": [sys.executable, "-c", "import meanfield"],
    "meanfield --help": [sys.executable, "-m", "meanfield.cli.app", "--help"],
}
ANCHOR = [sys.executable, "-c", "pass"]


def wall_seconds(cmd: list[str], repeats: int) -> float:
    """Median wall time of ``cmd`` as a whole process over ``repeats`` runs."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def heaviest_imports(cmd: list[str], count: int = 5) -> list[tuple[str, float]]:
    """The top-level imports that cost most (cumulative ms), from ``python -X importtime``."""
    out = subprocess.run([cmd[0], "-X", "importtime", *cmd[1:]], capture_output=True, text=True, check=True)
    rows = []
    for line in out.stderr.splitlines():
        if not line.startswith("import time:") or "|" not in line:
            continue
        _, cumulative, name = (part.strip() for part in line.split(":", 1)[1].split("|"))
        if cumulative.isdigit() and not name.startswith(" ") and not line.split("|")[2].startswith("  "):
            rows.append((name, int(cumulative) / 1000.0))
    return sorted(rows, key=lambda r: -r[1])[:count]


def suite_records(quick: bool) -> list[dict[str, Any]]:
    """The ``startup`` records of ``meanfield bench``: each command against ``python -c pass``."""
    repeats = settings("startup", quick)["repeats"]
    anchor = wall_seconds(ANCHOR, repeats)
    records = []
    for name, cmd in COMMANDS.items():
        ours = wall_seconds(cmd, repeats)
        records.append(
            measured(
                "startup",
                name,
                f"`{name}` as a fresh process, median of {repeats}",
                name,
                "python -c pass",
                ours,
                anchor,
                "s",
                faster="lower",
                goal=f"<= {GOAL_SECONDS} s",
                passed=ours <= GOAL_SECONDS,
                note="ratio < 1: the command costs that fraction more than the bare interpreter",
                detail={"heaviest_imports_ms": heaviest_imports(cmd)},
            )
        )
    return records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    anchor = wall_seconds(ANCHOR, a.repeats)
    out = {name: {"seconds": wall_seconds(cmd, a.repeats), "heaviest_imports_ms": heaviest_imports(cmd)}
           for name, cmd in COMMANDS.items()}
    print(json.dumps({"anchor_python_pass_seconds": anchor, **out}, indent=2))


if __name__ == "__main__":
    main()
