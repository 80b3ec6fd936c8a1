"""Size guards before a run and stability warnings after it (issue 16, item 6)."""

from __future__ import annotations

import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario
from meanfield.cli.app import main
from meanfield.simulation import preflight as budget
from meanfield.simulation.preflight import check_fits, estimate_run


def test_the_estimate_counts_what_a_run_holds():
    sc = paper_scenario(seed=0)
    est = estimate_run(sc)
    assert est.frames == 4000 // 10 + 2
    assert est.frame_bytes == 8 * (5 * 16 + 2 * 200 + 900 + 16)
    assert est.crowd_bytes == budget.BYTES_PER_HUMAN * 200
    big = estimate_run(sc.with_values({"crowd.n": 10**7}))
    assert big.crowd_bytes == est.crowd_bytes * 10**7 // 200  # linear in N
    assert big.frame_bytes == est.frame_bytes + 8 * 2 * (10_000 - 200)  # record_humans caps the frames


def test_a_crowd_that_cannot_fit_is_refused_before_anything_is_allocated(monkeypatch):
    monkeypatch.setattr(budget, "available_memory", lambda: 4 * 2**30)
    sc = paper_scenario(seed=0).with_values({"crowd.n": 200_000_000})
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)  # would allocate 200e6 x 2 floats in the crowd factory otherwise
    assert exc.value.name == "crowd.n" and "MB are available" in str(exc.value) and "room for about" in str(exc.value)


def test_frames_that_cannot_fit_are_refused_with_the_record_every_that_would(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(budget, "available_memory", lambda: 8 * 2**30)
    argv = ["run", "paper", "--set", "t_final=1e5", "--set", "record_every=1", "--set", "crowd.n=10000"]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "record_every = 1" in err and "record_every = " in err.split("available;")[1]
    suggested = int(err.split("record_every = ")[2].split(" ")[0])
    sc = paper_scenario(seed=0).with_values(
        {"t_final": 1e5, "record_every": suggested, "crowd.n": 10000}
    )
    assert check_fits(sc).memory_bytes <= 8 * 2**30  # the suggested fix does fit


def test_an_output_larger_than_the_disk_is_refused(monkeypatch, tmp_path):
    monkeypatch.setattr(budget, "_free_disk", lambda path: 10 * 2**20)
    sc = paper_scenario(seed=0).with_values({"t_final": 400.0, "record_every": 1})
    with pytest.raises(ParameterError) as exc:
        check_fits(sc, tmp_path)
    assert exc.value.name == "record_every" and "disk space" in str(exc.value)
    assert check_fits(paper_scenario(seed=0), tmp_path).output_bytes < 10 * 2**20


def test_a_run_that_breaks_a_condition_of_the_scheme_says_so():
    sc = paper_scenario(seed=0).replace(t_final=0.2)
    s = ClosedLoop(sc).run(progress=False).summary
    assert s["status"] == "completed"
    assert any("Step-I feedback" in w and "0.00125" in w for w in s["warnings"])  # paper: dt = 0.01 > 0.9h²/(4α₀)
    fine = ClosedLoop(sc.replace(dt=0.001, t_final=0.02)).run(progress=False).summary
    assert fine["warnings"] == []
    fast = sc.with_values({"robots.u_max": 10.0, "robots.omega_max": 100.0, "controller.k_u": 1000.0})
    s = ClosedLoop(fast).run(progress=False).summary
    assert any("more than a grid cell" in w for w in s["warnings"]) and s["max_robot_speed"] * sc.dt > 1 / 30


def test_a_grid_whose_density_estimate_cannot_fit_is_refused_naming_the_grid(monkeypatch):
    """``grid.cells = [1000000, 2]`` passed the guard, grew to 23.7 GB and was killed: the guard
    missed the density estimate's fine lattice, padding and FFTs (issue "Nothing lost", item 6)."""
    monkeypatch.setattr(budget, "available_memory", lambda: 20 * 2**30)
    sc = paper_scenario(seed=0).with_values({"grid.cells": [1_000_000, 2]})
    est = estimate_run(sc)
    assert est.kde_bytes > 10 * 2**30  # the FFT of a 8e6 x 16 fine lattice padded by 6 h
    with pytest.raises(ParameterError) as exc:
        check_fits(sc)
    assert exc.value.name == "grid.cells" and "density estimate" in str(exc.value)


def test_each_size_is_blamed_on_its_own_field(monkeypatch):
    monkeypatch.setattr(budget, "available_memory", lambda: 4 * 2**30)
    cases = {
        "robots.n": {"robots.n": 100_000_000},
        "crowd.n": {"crowd.n": 100_000_000},
        "record_every": {"t_final": 1e5, "record_every": 1, "crowd.n": 10_000},
    }
    for name, values in cases.items():
        with pytest.raises(ParameterError) as exc:
            check_fits(paper_scenario(seed=0).with_values(values))
        assert exc.value.name == name, (name, str(exc.value))
    with pytest.raises(ParameterError) as exc:
        check_fits(paper_scenario(seed=0).with_values({"dt": 1e-300}))
    assert exc.value.name == "dt" and len(str(exc.value)) < 200  # not a 600-digit frame count


def test_the_memory_available_is_the_least_of_the_system_the_cgroup_and_the_ulimit(monkeypatch):
    monkeypatch.setattr(budget, "_system_available", lambda: 20 * 2**30)
    monkeypatch.setattr(budget, "_cgroup_available", lambda: 3 * 2**30)
    monkeypatch.setattr(budget, "_rlimit_available", lambda: None)
    assert budget.available_memory() == 3 * 2**30
    monkeypatch.setattr(budget, "_rlimit_available", lambda: 2**30)
    assert budget.available_memory() == 2**30
    script = (
        "import resource; resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, resource.RLIM_INFINITY));"
        "from meanfield.simulation.preflight import available_memory; print(available_memory())"
    )
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert 0 < int(done.stdout) < 3 * 2**30  # the ulimit, less what the process already maps
