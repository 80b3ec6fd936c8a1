"""``meanfield pedestrians`` (analysis.pedestrians.cli): the report of several runs, bad arguments refused."""

from __future__ import annotations

import argparse
import json

import pytest

from meanfield.errors import ParameterError
from tests.analysis.pedestrians.conftest import crowd_positions, run_dataset


@pytest.mark.requires("pedpy")
def test_command_writes_report_and_refuses_bad_arguments(tmp_path, capsys):
    from analysis.pedestrians.cli import register

    x, y = crowd_positions([1, 3], seed=3)
    run = tmp_path / "run"
    run.mkdir()
    run_dataset(x, y, [0.0, 1.0]).to_netcdf(run / "timeseries.nc", engine="h5netcdf")
    parser = argparse.ArgumentParser()
    handler = register(parser.add_subparsers(dest="command"))
    out = tmp_path / "out"
    args = parser.parse_args(["pedestrians", str(run), str(run), "--out", str(out), "--voronoi-frames", "0", "--quiet"])
    assert handler(args) == 0
    report = json.loads((out / "pedestrians.json").read_text())
    assert set(report["runs"]) == {"run", "run-1"} and report["differences_explained"]
    assert report["runs"]["run"]["voronoi_frames"] == []
    for bad, name in [(["--window", "0"], "--window"), (["--voronoi-frames", "-1"], "--voronoi-frames")]:
        with pytest.raises(ParameterError) as exc:
            handler(parser.parse_args(["pedestrians", str(run), "--out", str(out), *bad]))
        assert exc.value.name == name
    with pytest.raises(ParameterError) as exc:
        handler(parser.parse_args(["pedestrians", str(tmp_path / "nothing"), "--out", str(out)]))
    assert exc.value.name == "RUN_DIR"
