"""``meanfield sweep`` / :func:`meanfield.workflows.sweep.run_sweep`: Dask sweeps, resuming, bad input.

A tiny scenario (12×12 grid, 50 humans, 20 steps) keeps each run well under a second.  The
external cluster is a ``dask scheduler`` and a ``dask worker`` started as separate processes
on loopback, the way a user starts a cluster and points the sweep at it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

pytest.importorskip("distributed")

from meanfield import paper_scenario, plugins  # noqa: E402
from meanfield.cli.app import main  # noqa: E402
from meanfield.errors import ParameterError  # noqa: E402
from meanfield.simulation.loop import ClosedLoop  # noqa: E402
from meanfield.workflows.sweep import parse_seeds, parse_values, run_sweep  # noqa: E402


def _tiny():
    return paper_scenario().replace(t_final=0.2).with_values({"grid.cells": [12, 12], "crowd.n": 50})


@pytest.fixture
def tiny_toml(tmp_path) -> Path:
    path = tmp_path / "tiny.toml"
    _tiny().save(path)
    return path


@pytest.fixture(scope="module")
def scheduler_address(tmp_path_factory):
    """A Dask scheduler and a worker (2 processes) started as separate processes on 127.0.0.1."""
    d = tmp_path_factory.mktemp("dask")
    sched_file = d / "scheduler.json"
    log = open(d / "cluster.log", "w")  # closed below
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
             "--no-dashboard", "--scheduler-file", str(sched_file)],
            stdout=log, stderr=subprocess.STDOUT, cwd=d,
        )
    ]
    try:
        deadline = time.monotonic() + 30
        while not sched_file.exists():
            if time.monotonic() > deadline or procs[0].poll() is not None:
                pytest.fail(f"the Dask scheduler did not start: {(d / 'cluster.log').read_text()[-2000:]}")
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        procs.append(
            subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers", "2", "--nthreads", "1",
                 "--no-dashboard", "--host", "127.0.0.1"],
                stdout=log, stderr=subprocess.STDOUT, cwd=d,
            )
        )
        from distributed import Client

        with Client(address, timeout=30, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        if len(procs) == 2 and procs[1].poll() is None:
            try:  # the graceful way: the scheduler stops its workers (terminate() alone takes ~8 s)
                with Client(address, timeout=10, set_as_default=False) as client:
                    client.shutdown()
            except Exception:
                pass
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        log.close()


# ---------------------------------------------------------------------- parsing
def test_parse_values_splits_outside_brackets_and_reads_toml():
    sets = parse_values(["robots.n=4,9", "grid.cells=[8,8],[12, 12]", "controller.beta_gamma=min-norm,bounded"])
    assert sets == {
        "robots.n": [4, 9],
        "grid.cells": [[8, 8], [12, 12]],
        "controller.beta_gamma": ["min-norm", "bounded"],
    }
    assert parse_seeds("3") == [0, 1, 2]
    assert parse_seeds("2-4") == [2, 3, 4]
    assert parse_seeds("1,5") == [1, 5]
    for bad in (["robots.n"], ["robots.n=4", "robots.n=9"], ["robots.n=4,,9"]):
        with pytest.raises(ParameterError):
            parse_values(bad)
    with pytest.raises(ParameterError):
        parse_seeds("0")


# ---------------------------------------------------------------------- local cluster
def test_sweep_on_a_local_cluster_gathers_every_run_deterministically(tiny_toml, tmp_path):
    out = tmp_path / "sweep"
    ds = run_sweep(tiny_toml, {"robots.n": [4, 9], "kernel.eta": [0.02, 0.05]}, 2, out, workers=2, progress=False)
    assert dict(ds.sizes) == {"robots.n": 2, "kernel.eta": 2, "seed": 2}
    assert list(ds["robots.n"].values) == [4, 9]
    assert list(ds["kernel.eta"].values) == [0.02, 0.05]
    assert list(ds["seed"].values) == [0, 1]
    assert (ds["status"].values == "completed").all()
    assert np.isfinite(ds["fraction_in_target"].values).all()
    assert (ds["steps"].values == 20).all()
    assert ds.attrs["status"] == "completed" and ds.attrs["runs_executed"] == 8
    assert "t_final = 0.2" in ds.attrs["scenario"]
    assert len(list((out / "runs").glob("*.json"))) == 8
    with xr.open_dataset(out / "sweep.nc", engine="h5netcdf") as saved:
        np.testing.assert_array_equal(saved["l2_error_final"].values, ds["l2_error_final"].values)
        assert (saved["status"].values == "completed").all()
    # the same seed and values give the same run as a direct closed loop
    direct = ClosedLoop(_tiny().with_values({"robots.n": 9, "kernel.eta": 0.02}).replace(seed=1)).run(progress=False)
    run = ds.sel({"robots.n": 9, "kernel.eta": 0.02, "seed": 1})
    for key in ("fraction_in_target", "l2_error_final", "w2_to_target_final", "max_robot_speed"):
        assert float(run[key]) == direct.summary[key], key


# ---------------------------------------------------------------------- external cluster
def test_interrupted_sweep_resumes_without_rerunning_finished_runs(tiny_toml, tmp_path, scheduler_address):
    """4 robot counts × 10 seeds, interrupted half-way (Ctrl-C in the collecting loop), then resumed."""
    out = tmp_path / "sweep"
    sets = {"robots.n": [4, 9, 16, 25]}
    seen = []

    def interrupt_half_way(record):
        seen.append(record["key"])
        if len(seen) == 20:
            raise KeyboardInterrupt

    ds = run_sweep(tiny_toml, sets, 10, out, scheduler=scheduler_address, progress=False, on_result=interrupt_half_way)
    assert ds.attrs["status"] == "interrupted"
    assert (ds["status"].values == "completed").sum() == 20
    assert (ds["status"].values == "not run").sum() == 20
    assert (out / "sweep.nc").is_file()
    files = {p.name: (p.stat().st_mtime_ns, p.read_text()) for p in (out / "runs").glob("*.json")}
    assert sorted(files) == sorted(f"{k}.json" for k in seen)

    ds2 = run_sweep(tiny_toml, sets, 10, out, scheduler=scheduler_address, progress=False)
    assert ds2.attrs["status"] == "completed"
    assert ds2.attrs["runs_reused"] == 20 and ds2.attrs["runs_executed"] == 20
    assert (ds2["status"].values == "completed").all()
    for name, (mtime, text) in files.items():  # the finished runs were not run again
        p = out / "runs" / name
        assert p.stat().st_mtime_ns == mtime and p.read_text() == text
    assert len(list((out / "runs").glob("*.json"))) == 40
    done = ds["status"].values == "completed"
    np.testing.assert_array_equal(ds2["wall_seconds"].values[done], ds["wall_seconds"].values[done])


def test_cli_sweep_against_a_separately_started_scheduler(tiny_toml, tmp_path, scheduler_address, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", str(tiny_toml), "--set", "robots.n=4,9", "--set", "controller.beta_gamma=min-norm,bounded",
            "--seeds", "1-2", "--scheduler", scheduler_address, "--out", str(out), "--quiet"]
    assert main(argv) == 0
    with xr.open_dataset(out / "sweep.nc", engine="h5netcdf") as ds:
        assert dict(ds.sizes) == {"robots.n": 2, "controller.beta_gamma": 2, "seed": 2}
        assert list(ds["controller.beta_gamma"].values) == ["min-norm", "bounded"]
        assert list(ds["seed"].values) == [1, 2]
        assert (ds["status"].values == "completed").all()
        assert json.loads(ds.attrs["sweep"])["scheduler"] == scheduler_address


def test_a_run_that_fails_is_recorded_and_the_sweep_goes_on(tiny_toml, tmp_path, scheduler_address, capsys):
    """NMPC refuses a crowd that interacts (``interaction.kind = "gaussian"``, not in its model) when its controller
    is built, inside the worker, after validation; the static signs, which do not model the crowd, complete."""
    if "nmpc" not in plugins.available("controller"):
        pytest.skip("the nmpc controller plugin (analysis package) is not installed")
    out = tmp_path / "sweep"
    argv = ["sweep", str(tiny_toml), "--set", "controller.kind=static-signs,nmpc",
            "--set", "interaction.strength=0.001", "--set", "interaction.kind=gaussian",
            "--scheduler", scheduler_address, "--out", str(out),
            "--quiet"]
    assert main(argv) == 1
    assert "interaction.kind" in capsys.readouterr().err
    with xr.open_dataset(out / "sweep.nc", engine="h5netcdf") as ds:
        run = ds.isel({"interaction.strength": 0, "interaction.kind": 0, "seed": 0})
        assert list(run["status"].values) == ["completed", "error"]
        assert "interaction.kind" in str(run["message"].values[1])
        assert ds.attrs["status"] == "incomplete"
    errors = [json.loads(p.read_text()) for p in (out / "runs").glob("*.json")]
    assert sorted(r["summary"]["status"] for r in errors) == ["completed", "error"]
    # on resume the completed run is reused, the failed one is run again
    ds2 = run_sweep(tiny_toml, parse_values(argv[3:8:2]), 1, out, scheduler=scheduler_address, progress=False)
    assert ds2.attrs["runs_reused"] == 1 and ds2.attrs["runs_executed"] == 1


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--set", "robots.nn=4,9"], "robots.nn"),
        (["--set", "robots.n=4,abc"], "robots.n = 'abc'"),
        (["--set", "kernel.eta=0.02,-1"], "kernel.eta"),
        (["--set", "robots.n=4,4"], "distinct"),
        (["--set", "robots.n=4", "--seeds", "0"], "at least one seed"),
        (["--set", "robots.n="], "robots.n"),
        (["--set", "seed=1,2"], "--seeds"),
        (["--set", "robots.n=4", "--workers", "0"], "--workers"),
        (["--set", "robots.n=4", "--scheduler", "tcp://127.0.0.1:1", "--connect-timeout", "1"], "could not connect"),
        (["--set", "robots.n=4", "--scheduler", "not-an-address"], "--scheduler"),
    ],
)
def test_bad_input_is_refused_before_any_run(tiny_toml, tmp_path, capsys, args, says):
    out = tmp_path / "sweep"
    assert main(["sweep", str(tiny_toml), "--out", str(out), "--quiet", *args]) == 2
    assert says in capsys.readouterr().err
    assert not out.exists()


def test_empty_sweep_is_refused_from_python(tiny_toml, tmp_path):
    with pytest.raises(ParameterError, match="at least one value"):
        run_sweep(tiny_toml, {"robots.n": []}, 1, tmp_path / "a")
    with pytest.raises(ParameterError, match="at least one seed"):
        run_sweep(tiny_toml, {"robots.n": [4]}, [], tmp_path / "b")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_ctrl_c_while_the_cluster_closes_after_100_percent_keeps_a_completed_sweep(
    tiny_toml, tmp_path, scheduler_address, monkeypatch, capsys
):
    """Issue 16, item 4: a Ctrl-C in the seconds after 100 % (closing the cluster) used to record a
    finished sweep as "interrupted" and end in an IndexError."""
    import meanfield.workflows.sweep as sweep_module

    real_connect = sweep_module._connect

    class ClosingInterrupted:
        def close(self):
            raise KeyboardInterrupt

    def connect(scheduler, workers, timeout):
        client, _ = real_connect(scheduler, workers, timeout)
        return client, ClosingInterrupted()  # as a local cluster would, closing after the last run

    monkeypatch.setattr(sweep_module, "_connect", connect)
    out = tmp_path / "sweep"
    argv = ["sweep", str(tiny_toml), "--set", "robots.n=4,9", "--scheduler", scheduler_address, "--out", str(out)]
    assert main(argv) == 0
    with xr.open_dataset(out / "sweep.nc", engine="h5netcdf") as ds:
        assert ds.attrs["status"] == "completed" and (ds["status"].values == "completed").all()
    assert "closing the Dask cluster" in capsys.readouterr().err


def test_a_sweep_leaves_dask_s_global_configuration_as_it_found_it(tiny_toml, tmp_path, scheduler_address):
    """After a sweep in the same process, xarray (which asks dask for its scheduler) still writes NetCDF."""
    import dask

    before = dask.config.get("scheduler", None)
    run_sweep(tiny_toml, {"robots.n": [4]}, 1, tmp_path / "sweep", scheduler=scheduler_address, progress=False)
    assert dask.config.get("scheduler", None) == before
    from meanfield import ClosedLoop, load_scenario

    ClosedLoop(load_scenario(tiny_toml)).run(progress=False).save(tmp_path / "run")  # to_netcdf
    assert (tmp_path / "run" / "summary.json").is_file()


def test_analyze_and_verify_jobs_go_to_a_running_scheduler(scheduler_address):
    """The fan-outs of analyze and verify (analysis.parallel.map_jobs) on the sweep's Dask machinery."""
    import math

    from analysis.parallel import jobs_on, map_jobs

    with jobs_on(scheduler_address):  # its workers import what they run: a function of an installed module
        assert map_jobs(math.factorial, [1, 2, 3, 4], workers=None, desc="t", progress=False) == [1, 2, 6, 24]


@pytest.mark.parametrize(
    "record",
    [
        [],  # valid JSON, not a table: blocked every resume with AttributeError
        "done",
        {"summary": []},
        {"summary": {"status": "completed", "fraction_in_target": 5.0}},  # an impossible fraction
        {"summary": {"status": "completed", "time_to_90": -1.0}},
        {"summary": {"status": "completed", "steps": "many"}},
    ],
)
def test_a_record_that_cannot_be_a_result_is_run_again_not_reused(tiny_toml, tmp_path, record):
    """Records read back on resume are checked (issue "Nothing lost", item 5): one that is not a
    table, or whose figures are out of their ranges, is run again; a valid one is reused."""
    from meanfield.scenarios.scenario import load_scenario
    from meanfield.workflows.sweep_plan import expand_sweep, finished_runs

    plan = expand_sweep(load_scenario(tiny_toml), {"robots.n": [4]}, [0, 1])
    runs = tmp_path / "runs"
    runs.mkdir()
    bad, good = (runs / f"{r['key']}.json" for r in plan.runs)
    bad.write_text(json.dumps(record))
    good.write_text(json.dumps({"summary": {"status": "completed", "fraction_in_target": 0.9, "steps": 10}}))
    assert list(finished_runs(plan, runs)) == [plan.runs[1]["key"]]


@pytest.mark.parametrize("seeds", ["100000000", "0-99999999"])
def test_a_sweep_of_more_runs_than_the_cap_is_refused_before_it_is_spelt_out(tiny_toml, tmp_path, capsys, seeds):
    """``--seeds 100000000`` had no guard (issue "Nothing lost", item 6): refused at once, naming --seeds."""
    assert main(["sweep", str(tiny_toml), "--seeds", seeds, "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "--seeds" in err and "1,000,000" in err and not (tmp_path / "s").exists()


# ---------------------------------------------------------------------- plugins (issue "Nothing lost", item 9)
def _signs_plugin(folder: Path, name: str) -> Path:
    """A module registering the controller ``name`` (static signs), leaving a marker when imported."""
    module = folder / f"{name.replace('-', '_')}.py"
    module.write_text(
        "from pathlib import Path\n"
        "from meanfield import plugins\n"
        "from meanfield.controllers.static_signs import StaticSigns\n"
        "Path(__file__).with_suffix('.imported').write_text('ran')\n"
        f"plugins.register('controller', {name!r}, StaticSigns.from_parts)\n"
    )
    return module


def _listing(folder: Path, module: Path, controller: str) -> Path:
    path = folder / "listing.toml"
    d = _tiny().to_dict()
    d["plugins"] = [module.name]  # relative to the file
    d["controller"]["kind"] = controller
    import tomli_w

    path.write_text(tomli_w.dumps(d))
    return path


def test_a_worker_imports_a_scenario_s_plugins_only_with_the_job_s_permission(tmp_path):
    from meanfield.workflows.sweep import _run_one

    name = "sweep-worker-signs"
    module = _signs_plugin(tmp_path, name)
    toml = f'plugins = ["{module}"]\nt_final = 0.05\n[controller]\nkind = "{name}"\n'
    try:
        refused = _run_one(toml)
        assert refused["status"] == "error" and "invalid plugins" in refused["message"]
        assert not module.with_suffix(".imported").exists()
        done = _run_one(toml, allow_plugins=True)
        assert done["status"] == "completed" and done["controller"] == name
        assert module.with_suffix(".imported").exists()
    finally:
        plugins.unregister("controller", name)


def test_a_sweep_of_a_scenario_with_plugins_runs_on_separate_workers_once_allowed(tmp_path, scheduler_address):
    """The workers (other processes, started apart) have no command line: the job carries the permission."""
    name = "sweep-external-signs"
    module = _signs_plugin(tmp_path, name)
    path = _listing(tmp_path, module, name)
    try:
        with pytest.raises(ParameterError) as exc:
            run_sweep(path, {"robots.n": [4, 9]}, 1, tmp_path / "refused", scheduler=scheduler_address, progress=False)
        assert exc.value.name == "plugins" and not (tmp_path / "refused").exists()
        assert not module.with_suffix(".imported").exists()
        ds = run_sweep(
            path, {"robots.n": [4, 9]}, 1, tmp_path / "sweep", scheduler=scheduler_address, progress=False,
            allow_plugins=True,
        )
        assert (ds["status"].values == "completed").all(), ds["message"].values
    finally:
        plugins.unregister("controller", name)


def test_map_jobs_carries_the_permission_to_separate_workers(tmp_path, scheduler_address):
    """analyze's and verify's fan-outs: a job checks a scenario's plugins under the submitting process's permission."""
    from meanfield.workflows.dask_cluster import jobs_on, map_jobs

    module = str(tmp_path / "some_plugin.py")
    jobs = [[module], [module]]  # two jobs: they go to the cluster
    check = plugins.check_scenario_plugins
    with jobs_on(scheduler_address):
        with pytest.raises(ParameterError):  # the job's own refusal, raised here
            map_jobs(check, jobs, workers=None, desc="t", progress=False)
        with plugins.allow_scenario_plugins([module]):
            assert map_jobs(check, jobs, workers=None, desc="t", progress=False) == [None, None]


def test_the_sweeps_of_one_command_share_its_cluster(tiny_toml, tmp_path, monkeypatch):
    """Inside ``jobs_on`` (a study's several sweeps) every sweep runs on the one cluster, started once and
    closed at the end, with the same runs as a sweep on a cluster of its own."""
    from meanfield.workflows import dask_cluster, sweep

    started = []
    real = dask_cluster.connect

    def counting(*args):
        started.append(args)
        return real(*args)

    monkeypatch.setattr(dask_cluster, "connect", counting)
    monkeypatch.setattr(sweep, "_connect", counting)
    with dask_cluster.jobs_on(None, 2):
        a = run_sweep(tiny_toml, {"robots.n": [4]}, 2, tmp_path / "a", workers=2, progress=False)
        b = run_sweep(tiny_toml, {"robots.n": [9]}, 2, tmp_path / "b", workers=2, progress=False)
        assert len(started) == 1  # one cluster for both sweeps, still open
        assert dask_cluster._CURRENT.get().client.status == "running"
    assert a.attrs["status"] == b.attrs["status"] == "completed"
    alone = run_sweep(tiny_toml, {"robots.n": [9]}, 2, tmp_path / "c", workers=2, progress=False)
    assert len(started) == 2  # outside: a cluster of its own
    np.testing.assert_array_equal(alone["l2_error_final"].values, b["l2_error_final"].values)
