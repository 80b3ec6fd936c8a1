"""``meanfield study controllers``: every controller on the same seeds, a table, a figure, resumable."""

from __future__ import annotations

import csv
import subprocess
import sys

import pytest
import xarray as xr

from meanfield import ParameterError, paper_scenario
from meanfield.scenarios.scenario import builtin_scenarios
from meanfield.workflows.controller_study import candidates, study_controllers


def test_the_candidates_are_the_installed_controllers_that_apply():
    paper = candidates(paper_scenario(seed=0))
    assert {"backstepping", "coverage", "static-signs"} <= set(paper) and "evacuation" not in paper
    assert paper["coverage"] == {"controller.kind": "coverage"}
    assert "evacuation" in candidates(builtin_scenarios()["l-room"](seed=0))  # a room with exits


def test_every_candidate_builds_on_its_scenario():
    """A controller that needs exits says so in its record (``requires_exits``): the guide did not, so the paper's
    candidates named it and ``meanfield bench``'s controllers record failed on it (found 2026-12-07)."""
    from meanfield import ClosedLoop

    paper = paper_scenario(seed=0)
    found = candidates(paper)
    assert "guide" not in found and "guide" in candidates(builtin_scenarios()["l-room"](seed=0))
    for overrides in found.values():
        ClosedLoop(paper.with_values(overrides))  # builds (a ParameterError here: a record that does not tell)


def test_a_small_study_writes_its_table_and_figure_and_resumes(tmp_path):
    sc = paper_scenario(seed=0).replace(t_final=0.2)
    rows = study_controllers(sc, 2, tmp_path, controllers=["backstepping", "coverage"], workers=1, progress=False)
    assert [r["controller"] for r in rows] == ["backstepping", "coverage"]
    assert all(r["seeds"] == 2 and 0.0 <= r["objective_worst"] <= r["objective_median"] <= 1.0 for r in rows)
    assert rows[0]["compute_vs_law"] == 1.0 and rows[1]["compute_vs_law"] > 0
    with open(tmp_path / "controllers.csv") as f:
        assert [r["controller"] for r in csv.DictReader(f)] == ["backstepping", "coverage"]
    assert "| coverage | 2 |" in (tmp_path / "controllers.md").read_text()
    assert (tmp_path / "controllers.png").stat().st_size > 10_000
    again = study_controllers(sc, 2, tmp_path, controllers=["backstepping", "coverage"], workers=1, progress=False)
    for name in ("backstepping", "coverage"):
        with xr.open_dataset(tmp_path / name / "sweep.nc", engine="h5netcdf") as ds:
            assert ds.attrs["runs_reused"] == 2 and ds.attrs["runs_executed"] == 0
    assert [r["objective_median"] for r in again] == [r["objective_median"] for r in rows]


def test_an_unknown_controller_is_refused_before_anything_runs(tmp_path):
    with pytest.raises(ParameterError) as exc:
        study_controllers(paper_scenario(seed=0), 1, tmp_path / "out", controllers=["coverage", "telepathy"])
    assert exc.value.name == "--controllers" and "coverage" in str(exc.value)
    assert not (tmp_path / "out").exists()
    cmd = [sys.executable, "-m", "meanfield.cli.app", "study", "controllers", "paper", "--out", str(tmp_path / "cli")]
    done = subprocess.run([*cmd, "--controllers", "telepathy"], capture_output=True, text=True)
    assert done.returncode == 2 and "--controllers" in done.stderr and not (tmp_path / "cli").exists()


def test_a_sensing_radius_adds_each_local_controller_s_twin(tmp_path):
    twins = candidates(paper_scenario(seed=0), 0.2)
    assert twins["coverage@0.2"] == {"controller.kind": "coverage", "sensing.radius": 0.2, "sensing.comm_radius": 0.4}
    assert "backstepping@0.2" in twins and "static-signs@0.2" not in twins  # parked signs need no knowledge
    sc = paper_scenario(seed=0).replace(t_final=0.05)
    (row,) = study_controllers(sc, 1, tmp_path, controllers=["coverage@0.2"], sensing=0.2, workers=1, progress=False)
    assert row["controller"] == "coverage@0.2" and row["seeds"] == 1
    with pytest.raises(ParameterError) as exc:
        study_controllers(sc, 1, tmp_path / "bad", sensing=-0.1)
    assert exc.value.name == "--sensing"
