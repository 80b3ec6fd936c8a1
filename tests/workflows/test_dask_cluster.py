"""One Dask machinery for sweep, analyze and verify (issue 16, item 13)."""

from __future__ import annotations

import pytest

from meanfield.workflows.dask_cluster import _CURRENT, jobs_on, map_jobs


def _square(x: int) -> int:
    return x * x


def _fail(x: int) -> int:
    if x == 2:
        raise ValueError("job 2 failed")
    return x


def test_map_jobs_runs_on_a_local_dask_cluster_and_keeps_the_order():
    assert map_jobs(_square, list(range(6)), workers=2, desc="t", progress=False) == [0, 1, 4, 9, 16, 25]
    assert _CURRENT.get() is None  # the temporary cluster was closed with its context


def test_one_worker_runs_here_and_a_job_s_exception_reaches_the_caller():
    assert map_jobs(_square, [3], workers=None, desc="t", progress=False) == [9]
    with pytest.raises(ValueError, match="job 2 failed"):
        map_jobs(_fail, [1, 2, 3], workers=2, desc="t", progress=False)


def test_the_fan_outs_of_one_command_share_one_cluster():
    with jobs_on(None, 2):
        jobs = _CURRENT.get()
        assert map_jobs(_square, [1, 2], workers=None, desc="t", progress=False) == [1, 4]
        first = jobs.client
        assert map_jobs(_square, [3, 4], workers=None, desc="t", progress=False) == [9, 16]
        assert jobs.client is first is not None  # not a second cluster
    assert _CURRENT.get() is None


def test_verify_and_analyze_take_a_scheduler(capsys):
    from meanfield.cli.app import main

    for command in ("verify", "analyze"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        assert "--scheduler" in capsys.readouterr().out


@pytest.mark.parametrize("workers", [1, 2])
def test_each_result_is_handed_over_as_its_job_finishes(workers):
    """``on_result(k, result)``: once per job, with the job's index, before map_jobs returns (a study writes each row
    at once, so that an interrupted study resumes): here in this process, and from a cluster."""
    seen = []
    out = map_jobs(_square, [5, 6, 7], workers, "t", False, on_result=lambda k, r: seen.append((k, r)))
    assert out == [25, 36, 49] and sorted(seen) == [(0, 25), (1, 36), (2, 49)]
