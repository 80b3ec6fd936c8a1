"""BLAS threads chosen by the toolkit (meanfield._compiled.threads): one by default while a run steps,
MEANFIELD_BLAS_THREADS or ``--threads`` for another count, the previous count back afterwards."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_info

from meanfield import ClosedLoop, ParameterError, paper_scenario
from meanfield._compiled.threads import ENV, blas_threads, limited_blas


def _blas_threads_now() -> set[int]:
    return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}


def test_a_run_steps_with_blas_on_one_thread_and_gives_the_count_back(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    before = _blas_threads_now()
    seen: list[set[int]] = []
    ClosedLoop(paper_scenario(seed=0).replace(t_final=0.03)).run(
        progress=False, callback=lambda loop: seen.append(_blas_threads_now())
    )
    assert seen and all(s == {1} for s in seen)
    assert _blas_threads_now() == before


def test_the_environment_chooses_another_count_and_a_bad_one_is_refused_by_name(monkeypatch):
    monkeypatch.setenv(ENV, "2")
    assert blas_threads() == 2
    with limited_blas() as n:
        assert n == 2 and _blas_threads_now() <= {1, 2}  # a BLAS built for one core stays at 1
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv(ENV, bad)
        with pytest.raises(ParameterError) as exc:
            blas_threads()
        assert exc.value.name == ENV


def test_nmpc_reports_its_real_time_factor():
    pytest.importorskip("casadi")
    sc = paper_scenario(seed=0).replace(t_final=0.2).with_values({"controller.kind": "nmpc"})
    s = ClosedLoop(sc).run(progress=False).summary
    assert 0 < s["realtime_factor_mean"] <= s["realtime_factor_worst"]


def test_the_command_line_sets_the_count_and_refuses_a_bad_one(tmp_path, capsys, monkeypatch):
    from meanfield.cli.app import main

    # unset for the test, and unset again after it (a bare delenv of an unset variable records nothing to undo: when
    # the command left the variable set, every later test ran its BLAS on two threads, RiMEA 12's runs 5x slower)
    monkeypatch.setenv(ENV, "1")
    monkeypatch.delenv(ENV)
    from meanfield.cli.run import available_cores

    argv = ["run", "paper", "--set", "t_final=0.02", "--quiet", "--no-figures"]
    cores = available_cores()
    for bad in ("0", str(cores + 1)):  # none, more than the cores available
        assert main([*argv, "--threads", bad, "--out", str(tmp_path / bad)]) == 2
        assert "--threads" in capsys.readouterr().err
    for bad in ("two", "1.5"):  # not an integer: refused by the parser, exit status 2
        with pytest.raises(SystemExit) as exc:
            main([*argv, "--threads", bad, "--out", str(tmp_path / bad)])
        assert exc.value.code == 2 and "--threads" in capsys.readouterr().err
    import json
    import os

    from meanfield._compiled import threads

    seen = []
    blas_threads = threads.blas_threads

    def counted() -> int:  # what the run's limited_blas reads
        seen.append(blas_threads())
        return seen[-1]

    monkeypatch.setattr(threads, "blas_threads", counted)
    assert main([*argv, "--threads", str(cores), "--out", str(tmp_path / "b")]) == 0
    assert seen and set(seen) == {cores}  # the run held BLAS to the count asked for
    assert ENV not in os.environ  # and the command's count ended with it: the caller's (unset) is back
    monkeypatch.setenv(ENV, "1")
    assert main([*argv, "--threads", str(cores), "--out", str(tmp_path / "c")]) == 0
    assert os.environ[ENV] == "1"  # a caller's own value, too
    assert json.loads((tmp_path / "c" / "summary.json").read_text())["status"] == "completed"


def test_the_crowds_threads_are_set_from_the_command_line_and_a_bad_count_is_refused(tmp_path, capsys):
    numba = pytest.importorskip("numba")
    import json

    from meanfield.cli.app import main
    from meanfield.cli.run import available_cores

    argv = ["run", "paper", "--set", "t_final=0.02", "--quiet", "--no-figures"]
    cores = available_cores()
    for bad in ("0", str(cores + 1)):
        assert main([*argv, "--crowd-threads", bad, "--out", str(tmp_path / bad)]) == 2
        assert "--crowd-threads" in capsys.readouterr().err
    for bad in ("two", "1.5"):
        with pytest.raises(SystemExit) as exc:
            main([*argv, "--crowd-threads", bad, "--out", str(tmp_path / bad)])
        assert exc.value.code == 2 and "--crowd-threads" in capsys.readouterr().err
    before = numba.get_num_threads()
    try:
        assert main([*argv, "--crowd-threads", "1", "--out", str(tmp_path / "one")]) == 0
        summary = json.loads((tmp_path / "one" / "summary.json").read_text())
        assert summary["compiled_loops"]["threads"] == 1  # the run's loops ran on the count asked for
        assert numba.get_num_threads() == before  # and the caller's count is back after the command
    finally:
        numba.set_num_threads(before)
