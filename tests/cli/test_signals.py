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


_AT_PHASE = r"""
import os, signal, sys
import meanfield.io.atomic as atomic
import meanfield.simulation.assembly as assembly
import meanfield.simulation.loop as loop
from meanfield.cli.app import main

phase, times, argv = sys.argv[1], int(sys.argv[2]), sys.argv[3:]


def signalling(function):
    def wrapped(*args, **kwargs):
        for _ in range(times):
            os.kill(os.getpid(), signal.SIGTERM)
        return function(*args, **kwargs)
    return wrapped


if phase == "start-up":
    assembly.assemble = signalling(assembly.assemble)
    loop.assemble = assembly.assemble
elif phase == "summary":
    loop.run_summary = signalling(loop.run_summary)
elif phase == "save":
    atomic.write_complete_folder = signalling(atomic.write_complete_folder)
sys.exit(main(argv))
"""


def _signalled_at(phase: str, times: int, out: Path, earlier: bool = False) -> tuple[int, str]:
    """``meanfield run paper`` into ``out`` (over an earlier run if ``earlier``), the process sending
    itself ``times`` SIGTERMs as ``phase`` begins: the phases are reached for certain, not by timing."""
    argv = ["run", "paper", "--set", "t_final=0.5", "--out", str(out), "--quiet", "--no-figures"]
    if earlier:
        subprocess.run([sys.executable, "-m", "meanfield.cli.app", *argv[:3], "t_final=0.3", *argv[4:]], check=True)
    done = subprocess.run([sys.executable, "-c", _AT_PHASE, phase, str(times), *argv], capture_output=True, text=True)
    return done.returncode, done.stderr


@pytest.mark.parametrize("earlier", [False, True], ids=["empty-folder", "over-an-earlier-run"])
@pytest.mark.parametrize("phase", ["summary", "save"])
def test_a_signal_after_the_last_step_lets_the_run_finish_and_save(tmp_path, phase, earlier):
    """The summary and the save (about 40 % of a paper run) were cut by a signal: a traceback, no
    summary, and an earlier run's files already deleted (issue "Nothing lost", item 1).  Now the
    signal is held until the run is saved: one complete run, no traceback."""
    out = tmp_path / "run"
    rc, err = _signalled_at(phase, 1, out, earlier)
    assert rc == 0 and "Traceback" not in err, err
    assert "finished and saved" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["time_final"] == pytest.approx(0.5)
    assert check_complete_folder(out) == []


def test_a_second_signal_after_the_last_step_stops_at_once_without_a_traceback(tmp_path):
    out = tmp_path / "run"
    rc, err = _signalled_at("summary", 2, out)
    assert rc == 130 and "Traceback" not in err and "interrupted" in err, err
    assert not (out / "summary.json").exists()  # nothing claims to be a complete run


def test_a_signal_during_start_up_stops_before_anything_is_written(tmp_path):
    out = tmp_path / "run"
    rc, err = _signalled_at("start-up", 1, out)
    assert rc == 130 and "Traceback" not in err and "run interrupted" in err, err
    assert not out.exists()
