"""Check that a change leaves every result the same, number for number: run a fixed set of runs
before and after it, then compare the two folders.

Usage::

    python studies/same_results.py run DIR        # the runs below, each into DIR/<name> (about a minute)
    python studies/same_results.py compare A B    # exit 0 when every run of A equals B's, 1 otherwise

The runs cover each crowd and each controller the built-in scenarios ship: the paper's seeds
0–4, the density crowd, JuPedSim's bodies, the three plans with the evacuation, coverage and
static-signs controllers and the informed crowd.  Two runs are the same when every variable of
``timeseries.nc`` is equal (NaN equal to NaN) and every figure of ``summary.json`` is equal, but
for what measures the machine (wall time, steps per second, the run's id, the files' hashes, the
compiled loops' status).  The scenario each summary records is compared as the scenario it
describes: a table of an earlier release (the ``[pedestrians]`` table, say) read by today's
code must give today's scenario, JuPedSim's options filled in with their defaults on both sides.

This is how the move of ``meanfield`` into its subpackages was checked (docs page
*Architecture*); a change that is meant to change results (a new random generator, say) is
checked against it the other way: it must say which runs differ and why.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import warnings
from pathlib import Path

RUNS: dict[str, list[str]] = {
    **{f"paper{s}": ["paper", "--seed", str(s)] for s in range(5)},
    "paper-density": ["paper", "--seed", "0", "--crowd", "fokker-planck"],
    "unity-bodies": ["paper-unity", "--crowd", "jupedsim", "--set", "t_final=100"],
    "office0": ["office", "--seed", "0"],
    "hall1": ["hall", "--seed", "1"],
    "l-room0": ["l-room", "--seed", "0"],
    "office-coverage": ["office", "--seed", "2", "--set", 'controller.kind="coverage"'],
    "hall-static": ["hall", "--seed", "0", "--set", 'controller.kind="static-signs"'],
    "l-room-informed": ["l-room", "--seed", "3", "--set", 'crowd.guidance="geodesic"'],
}
"""Each run's name and its ``meanfield run`` arguments."""

MACHINE = {"wall_seconds", "steps_per_second", "run_id", "files", "compiled_loops", "python_overrides"}
"""Summary figures that measure the machine, not the run."""


def run_all(folder: Path) -> None:
    """Every run of :data:`RUNS` into ``folder/<name>`` (with the ``meanfield`` found on the PATH)."""
    for name, args in RUNS.items():
        print(f"{name}: meanfield run {' '.join(args)}", flush=True)
        cmd = ["meanfield", "run", *args, "--out", str(folder / name), "--quiet", "--no-figures"]
        subprocess.run(cmd, check=True)


def _same(a: object, b: object) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and a != a and b != b)


def _scenario(d: dict) -> dict:
    """The scenario a summary records, as today's code reads it, JuPedSim's options filled in, the door model
    as the crowd walks by it (``"none"`` for a crowd without congestion, which ignores it: the default was
    ``"count"`` before ``"auto"``), and what people remember of a sign as they do (``view.memory = "auto"``
    resolved: the default was ``"none"`` before it)."""
    from meanfield.crowds.jupedsim_engine import JuPedSimOptions
    from meanfield.scenarios.scenario import Scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an earlier release's fields, read on purpose
        scenario = Scenario.from_dict(d)
    out = scenario.to_dict()
    out["crowd"]["door_model"] = scenario.door_model if scenario.congestion_model != "none" else "none"
    out.setdefault("view", {})["memory"] = scenario.memory  # ("auto" resolved: "none" was the default before it)
    options = out["crowd"].setdefault("options", {})
    options["jupedsim"] = dataclasses.asdict(JuPedSimOptions(**options.get("jupedsim", {})))
    return out


def compare(a: Path, b: Path) -> list[str]:
    """The differences between the runs of two folders (empty: the same, number for number)."""
    import numpy as np
    import xarray as xr

    problems = []
    names = sorted(p.name for p in a.iterdir() if (p / "summary.json").is_file())
    if not names:
        return [f"{a}: no run folders"]
    for name in names:
        if not (b / name / "summary.json").is_file():
            problems.append(f"{name}: missing in {b}")
            continue
        sa = json.loads((a / name / "summary.json").read_text())
        sb = json.loads((b / name / "summary.json").read_text())
        keys = sorted((set(sa) | set(sb)) - MACHINE - {"scenario"})
        bad = [k for k in keys if not _same(sa.get(k), sb.get(k))]
        if _scenario(sa["scenario"]) != _scenario(sb["scenario"]):
            bad.append("scenario")
        with xr.open_dataset(a / name / "timeseries.nc") as ta, xr.open_dataset(b / name / "timeseries.nc") as tb:
            variables = sorted(set(ta.data_vars) | set(tb.data_vars))
            bad += [
                f"timeseries.{v}"
                for v in variables
                if v not in ta or v not in tb or not np.array_equal(ta[v].values, tb[v].values, equal_nan=True)
            ]
        print(f"{name}: {'the same' if not bad else 'differs in ' + ', '.join(bad)}")
        problems += [f"{name}: {k}" for k in bad]
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run", help="run the fixed set of runs into DIR")
    r.add_argument("folder", type=Path)
    c = sub.add_parser("compare", help="compare two folders of runs, number for number")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    args = parser.parse_args(argv)
    if args.what == "run":
        run_all(args.folder)
        return 0
    problems = compare(args.a, args.b)
    print("the same, number for number" if not problems else f"{len(problems)} differences")
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
