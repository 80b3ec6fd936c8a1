"""``meanfield bench`` (benchmarks.suite): registry, --only, skipped anchors, the JSON, errors, Ctrl-C.

Fast, and no speed is ever asserted: only the shape of what the suite writes.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import sys

import pytest

from benchmarks import suite
from meanfield import ParameterError, plugins
from meanfield.cli.app import main

EXPECTED = {
    *("kde", "closed_loop", "fokker_planck", "jupedsim", "large_crowd", "bounded", "nmpc", "startup", "compile"),
    *("plan", "controllers", "congestion", "hughes2d", "scaling"),
}
TOP_KEYS = {
    "suite",
    "command",
    "date",
    "quick",
    "machine",
    "threads",
    "ratio",
    "benchmarks",
    "settings",
    "finished",
    "seconds",
    "records",
    "complete",
    "interrupted",
    "errors",
    "all_goals_pass",
    "wall_seconds",
}
RECORD_KEYS = {
    "benchmark",
    "name",
    "what",
    "skipped",
    "ours",
    "ours_value",
    "unit",
    "anchor",
    "anchor_value",
    "anchor_unit",
    "ratio",
    "ratio_definition",
    "goal",
    "pass",
    "note",
    "detail",
}
NUMBERS = {"ours_value", "anchor_value", "ratio", "pass", "goal", "unit"}


def _replace(monkeypatch, name, run):
    monkeypatch.setitem(suite.BENCHMARKS, name, dataclasses.replace(suite.BENCHMARKS[name], run=run))


def _fake(name, ours=1.0, anchor=2.0):
    def run(quick):
        return [suite.measured(name, f"{name} fake", "w", "o", "a", ours, anchor, "s per call", faster="lower")]

    return run


def _never(quick):
    raise AssertionError("this benchmark must not run")


def test_the_registry_has_every_benchmark_and_the_command_is_installed():
    assert set(suite.BENCHMARKS) == EXPECTED
    assert set(suite.SETTINGS) == EXPECTED
    for name, b in suite.BENCHMARKS.items():
        assert b.name == name and callable(b.run) and b.measures and b.anchor
        assert set(suite.SETTINGS[name]) == {"quick", "full"}
    assert "bench" in plugins.available("command")


def test_an_unknown_only_name_exits_2_naming_the_valid_ones_before_anything_runs(tmp_path, monkeypatch, capsys):
    for name in EXPECTED:
        _replace(monkeypatch, name, _never)
    out = tmp_path / "bench.json"
    assert main(["bench", "--only", "kde,fastest", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--only" in err and "fastest" in err
    assert all(name in err for name in EXPECTED)
    assert not out.exists()
    with pytest.raises(ParameterError) as exc:
        suite.run_suite(out=tmp_path, only="kde")  # a directory
    assert exc.value.name == "--out"


def test_a_missing_anchor_gives_a_skipped_record_with_a_note_and_no_numbers(monkeypatch):
    monkeypatch.setitem(sys.modules, "pde", None)  # `import pde` now raises ImportError
    monkeypatch.setitem(sys.modules, "fipy", None)
    monkeypatch.setitem(sys.modules, "jupedsim", None)
    monkeypatch.setitem(suite.SETTINGS, "fokker_planck", {"quick": {"cells": 16}, "full": {"cells": 16}})
    records = suite.BENCHMARKS["fokker_planck"].run(True) + suite.BENCHMARKS["jupedsim"].run(True)
    assert [r["name"] for r in records] == [
        "fokker_planck 16^2 vs py-pde",
        "fokker_planck 16^2 vs FiPy",
        "jupedsim vs JuPedSim alone",
    ]
    for r in records:
        assert r["skipped"] is True and r["note"] and not NUMBERS & set(r)
    assert "py-pde" in records[0]["note"] and "pip install -e '.[bench]'" in records[0]["note"]
    assert "FiPy" in records[1]["note"] and "pip install -e '.[bench]'" in records[1]["note"]
    assert "jupedsim" in records[2]["note"] and "pip install" in records[2]["note"]
    table = suite.format_table(records)
    assert table.count("skipped: ") == 3


def test_a_small_real_run_writes_the_documented_json_atomically(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(suite.SETTINGS, "closed_loop", {"quick": {"steps": 20, "repeats": 1}, "full": {}})
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    written = []
    real_write = suite.atomic_write_json

    def spy(path, data):
        written.append((data["complete"], len(data["records"])))
        return real_write(path, data)

    monkeypatch.setattr(suite, "atomic_write_json", spy)
    out = tmp_path / "bench.json"
    assert main(["bench", "--quick", "--only", "closed_loop", "--out", str(out)]) == 0
    assert written[0] == (False, 0) and written[-1] == (True, 2)  # at the start, after the benchmark, at the end
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.json"]  # no temporary file left
    doc = json.loads(out.read_text())
    assert set(doc) == TOP_KEYS
    assert doc["complete"] is True and doc["interrupted"] is False and doc["errors"] == 0
    assert doc["quick"] is True and doc["benchmarks"] == doc["finished"] == ["closed_loop"]
    assert doc["command"] == f"meanfield bench --quick --only closed_loop --out {out}"
    assert doc["settings"] == {"closed_loop": {"steps": 20, "repeats": 1}}
    assert doc["threads"]["environment"]["OMP_NUM_THREADS"] == "1"
    assert "OMP_NUM_THREADS" not in os.environ  # restored after the run
    assert {"processor", "cpu_count", "python", "versions"} <= set(doc["machine"])
    plain, record = doc["records"]  # against the plain numpy loop, against gaussian_kde
    assert set(record) == set(plain) == RECORD_KEYS and record["skipped"] is plain["skipped"] is False
    assert record["unit"] == plain["unit"] == "steps/s" and record["anchor_unit"] == "calls/s"
    assert record["ours_value"] == plain["ours_value"]  # one measurement of ours, two anchors
    assert record["ratio"] == pytest.approx(record["ours_value"] / record["anchor_value"])
    assert isinstance(record["pass"], bool) and doc["all_goals_pass"] is (record["pass"] and plain["pass"])
    captured = capsys.readouterr()
    assert "closed_loop paper vs gaussian_kde" in captured.out and "ours faster" in captured.out
    assert "[1/1] closed_loop" in captured.err


def test_ctrl_c_keeps_the_finished_records_and_exits_1(tmp_path, monkeypatch):
    def interrupted(quick):
        raise KeyboardInterrupt

    _replace(monkeypatch, "kde", _fake("kde"))
    _replace(monkeypatch, "closed_loop", interrupted)
    _replace(monkeypatch, "nmpc", _never)
    out = tmp_path / "bench.json"
    assert main(["bench", "--quick", "--only", "kde,closed_loop,nmpc", "--out", str(out), "--quiet"]) == 1
    doc = json.loads(out.read_text())
    assert doc["complete"] is False and doc["interrupted"] is True
    assert doc["finished"] == ["kde"] and [r["name"] for r in doc["records"]] == ["kde fake"]
    assert doc["records"][0]["ratio"] == 2.0


def test_a_ctrl_c_swallowed_by_a_benchmark_still_stops_the_suite(tmp_path, monkeypatch):
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT has a non-default handler here")

    def swallows(quick):  # as ClosedLoop.run does: it returns status "interrupted"
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(10**6):  # the handler runs between bytecodes
                pass
        except KeyboardInterrupt:
            pass
        return _fake("closed_loop")(quick)

    _replace(monkeypatch, "kde", _fake("kde"))
    _replace(monkeypatch, "closed_loop", swallows)
    out = tmp_path / "bench.json"
    doc = suite.run_suite(quick=True, out=out, only="kde,closed_loop", progress=False)
    assert doc["interrupted"] is True and doc["finished"] == ["kde"]
    assert json.loads(out.read_text())["records"][0]["name"] == "kde fake"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_crashing_benchmark_is_recorded_and_the_others_still_run(tmp_path, monkeypatch, capsys):
    def crashes(quick):
        raise RuntimeError("solver exploded")

    _replace(monkeypatch, "kde", crashes)
    _replace(monkeypatch, "nmpc", _fake("nmpc", ours=4.0, anchor=1.0))
    out = tmp_path / "bench.json"
    assert main(["bench", "--only", "nmpc,kde", "--out", str(out), "--quiet"]) == 1
    doc = json.loads(out.read_text())
    assert doc["complete"] is True and doc["errors"] == 1 and doc["finished"] == ["kde", "nmpc"]
    assert doc["records"][0]["error"] == "RuntimeError: solver exploded"
    assert doc["records"][1]["ratio"] == 0.25 and doc["all_goals_pass"] is None
    assert "ERROR: RuntimeError: solver exploded" in capsys.readouterr().out


def test_the_congestion_bench_times_the_door_models_it_names():
    """Each timed setting of ``bench_congestion`` builds the crowd it names: the default is the forward cell, and
    the headway is asked for by name (it timed the forward cell twice while the default changed)."""
    from benchmarks import bench_congestion

    models = {m: bench_congestion.small_scenario(m, 0).door_model for m in ("forward-cell", "headway", "count")}
    assert models == {"forward-cell": "forward-cell", "headway": "headway", "count": "count"}
    assert bench_congestion.small_scenario("none", 0).congestion_model == "none"
