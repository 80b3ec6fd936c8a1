"""Real signals to a real ``meanfield`` process (issue 16, items 1 and 3).

SIGTERM is handled as Ctrl-C: the run stops with ``"status": "interrupted"`` and writes its
last good state.  A kill at any moment of a save into a folder that holds an earlier run
never leaves a ``summary.json`` beside files of another run.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import xarray as xr

from meanfield.io.atomic import check_complete_folder

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


def _meanfield(*args: str, **kwargs) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "meanfield.cli.app", *args]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def _wait_for_progress(proc: subprocess.Popen, timeout: float = 60.0) -> None:
    """Block until the run's progress bar appears on stderr (the loop is stepping)."""
    start = time.monotonic()
    seen = ""
    while "step" not in seen:
        assert proc.poll() is None, f"meanfield ended early: {proc.stderr.read()}"
        assert time.monotonic() - start < timeout
        seen += proc.stderr.read(1)


def test_sigterm_stops_a_run_with_its_last_good_state(tmp_path):
    out = tmp_path / "run"
    proc = _meanfield("run", "paper", "--set", "t_final=10000", "--out", str(out), "--no-figures")
    _wait_for_progress(proc)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    rc = proc.wait(timeout=120)
    err = proc.stderr.read()
    assert rc == 1, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and 0 < summary["steps"] < 1_000_000
    with xr.open_dataset(out / "timeseries.nc", engine="h5netcdf") as ds:
        assert ds.attrs["status"] == "interrupted" and ds.attrs["run_id"] == summary["run_id"]
        assert ds["time"].values[-1] == pytest.approx(summary["time_final"])
    assert check_complete_folder(out) == []
    assert "interrupted" in err


def test_a_kill_during_a_save_into_a_used_folder_never_mixes_two_runs(tmp_path):
    out = tmp_path / "run"
    args = ["run", "paper", "--set", "t_final=0.5", "--out", str(out), "--quiet"]
    start = time.monotonic()
    assert _meanfield(*args, "--seed", "0").wait(timeout=120) == 0  # an earlier, complete run
    whole = time.monotonic() - start
    first = json.loads((out / "summary.json").read_text())
    outcomes = []
    # kill the second run (seed 1) at moments spread over its life, the save (figures) included
    for fraction in (0.02, 0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 3.0):
        proc = _meanfield(*args, "--seed", "1")
        try:
            proc.wait(timeout=fraction * whole)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        summary_path = out / "summary.json"
        if summary_path.exists():
            s = json.loads(summary_path.read_text())
            assert check_complete_folder(out) == [], (fraction, check_complete_folder(out))
            with xr.open_dataset(out / "timeseries.nc", engine="h5netcdf") as ds:
                assert ds.attrs["run_id"] == s["run_id"] and ds.attrs["seed"] == s["seed"]
            assert set(s["files"]) >= {"timeseries.nc", "scenario.toml"}
            outcomes.append(s["seed"])
        else:
            outcomes.append(None)  # killed between removing the old summary and writing the new
    print("outcomes (seed of the folder's run, None: no complete run):", outcomes)
    assert outcomes[0] == first["seed"] == 0  # killed while importing: the earlier run untouched
    assert outcomes[-1] == 1  # not killed: the new run, complete
    leftovers = [p.name for p in Path(out).iterdir() if ".part" in p.name]
    assert all(p.startswith(".") for p in leftovers)  # at most hidden temporaries of a killed write
