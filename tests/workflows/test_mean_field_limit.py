"""Agents (SDE) against the Fokker–Planck PDE under the same robot trajectories:
trajectory recording, the comparison dataset, the report files and the ``compare`` command."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr

from meanfield import ClosedLoop, GaussianPotential, Grid, KernelDensityEstimator, ParameterError, paper_scenario
from meanfield.cli.app import main
from meanfield.workflows.mean_field_limit import compare_agents_pde, record_robot_trajectory, run_comparison

SIZES = (50, 200, 800)
CELLS = (24, 24)


@pytest.fixture(scope="module")
def scenario():
    return paper_scenario(seed=0)


@pytest.fixture(scope="module")
def trajectory(scenario):
    return record_robot_trajectory(scenario, t_final=0.5)


@pytest.fixture(scope="module")
def plain(scenario, trajectory):
    return compare_agents_pde(scenario, SIZES, trajectory=trajectory, t_final=0.5, cells=CELLS, record_interval=0.1)


@pytest.fixture(scope="module")
def repulsive(scenario, trajectory):
    return compare_agents_pde(
        scenario,
        SIZES,
        interaction=GaussianPotential(0.5, 0.1),
        trajectory=trajectory,
        t_final=0.5,
        cells=CELLS,
        record_interval=0.1,
    )


def test_record_robot_trajectory_shapes_times_and_limits(scenario, trajectory):
    n = scenario.robots.n
    assert trajectory.steps == 50
    assert trajectory.times.shape == (51,)
    assert trajectory.positions.shape == (51, n, 2)
    assert trajectory.headings.shape == (51, n)
    np.testing.assert_allclose(trajectory.times, np.arange(51) * scenario.dt, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(trajectory.positions[0], ClosedLoop(scenario).robots.positions)
    # each step obeys the robots' limits: |Δx| <= u_max dt, |Δθ| <= ω_max dt (mod 2π)
    step = np.linalg.norm(np.diff(trajectory.positions, axis=0), axis=-1)
    assert step.max() <= scenario.robots.u_max * scenario.dt * (1 + 1e-9)
    assert step.max() > 0  # the robots do move
    dth = np.angle(np.exp(1j * np.diff(trajectory.headings, axis=0)))
    assert np.abs(dth).max() <= scenario.robots.omega_max * scenario.dt * (1 + 1e-9)
    pts = trajectory.positions.reshape(-1, 2)
    assert np.all(scenario.domain.contains(pts[:, 0], pts[:, 1]))  # closed Ω, round-off tolerance


def test_record_robot_trajectory_stops_at_the_scenario_horizon(scenario):
    short = scenario.with_values({"t_final": 0.05})
    assert record_robot_trajectory(short, t_final=1.0).steps == 5
    assert record_robot_trajectory(short).steps == 5


def test_comparison_dataset(plain, scenario):
    ds = plain.dataset
    assert dict(ds.sizes) == {"n_agents": 3, "time": 6, "x": 24, "y": 24}
    assert list(ds["n_agents"].values) == list(SIZES)
    np.testing.assert_allclose(ds["time"].values, np.arange(6) * 0.1, atol=1e-12)
    assert set(ds.data_vars) == {"error_to_pde", "error_to_expected", "pde_density", "agents_density"}
    assert ds["error_to_pde"].dims == ("n_agents", "time")
    assert ds["agents_density"].dims == ("n_agents", "time", "x", "y")
    assert plain.summary["status"] == "completed"

    grid = Grid(scenario.domain, CELLS)
    masses = np.array([grid.integrate(f) for f in ds["pde_density"].values])
    assert np.abs(masses - masses[0]).max() <= 1e-12 * masses[0]
    assert plain.summary["pde_mass_drift"] <= 1e-12
    assert ds["pde_density"].values.min() >= 0

    # the stored errors are the L² distances between the stored fields (recomputed here)
    kde = KernelDensityEstimator(grid, ds.attrs["bandwidth"], scenario.density.boundary)
    pde = ds["pde_density"].values
    agents = ds["agents_density"].values
    for i in range(3):
        for k in range(6):
            assert ds["error_to_pde"].values[i, k] == pytest.approx(grid.norm(agents[i, k] - pde[k]), rel=1e-12)
            expected = kde.expected(pde[k])
            assert ds["error_to_expected"].values[i, k] == pytest.approx(grid.norm(agents[i, k] - expected), rel=1e-12)

    # sampling noise falls with N (like N^(-1/2): ×4 agents, ~×½ error)
    means = plain.mean_errors("error_to_expected")
    assert np.all(np.diff(means) < 0)
    assert means[-1] < 0.5 * means[0]


def test_paper_sign_is_further_from_the_agents(repulsive):
    """With a repulsive W, the agents follow the SDE's sign: the PDE run with the paper's
    written (opposite) sign is further from them at the largest N."""
    ds = repulsive.dataset
    assert "error_to_expected_paper_sign" in ds
    assert repulsive.summary["status"] == "completed"
    assert repulsive.summary["pde_mass_drift"] <= 1e-12
    same = repulsive.mean_errors("error_to_expected")[-1]
    paper = repulsive.mean_errors("error_to_expected_paper_sign")[-1]
    assert paper > same


def test_no_paper_sign_variable_without_interaction(plain):
    assert "error_to_expected_paper_sign" not in plain.dataset
    assert "error_to_expected_paper_sign_mean" not in plain.summary


def test_run_comparison_save_writes_files(scenario, tmp_path):
    report = run_comparison(scenario, (50, 200), t_final=0.3, cells=(16, 16), record_interval=0.1)
    assert [c.summary["status"] for c in report.cases] == ["completed", "completed"]
    from meanfield.plotting.figures import save_comparison_figures

    written = report.save(tmp_path, artifacts=[save_comparison_figures])
    assert list(written)[-1] == "summary"
    names = {
        "summary.json",
        "comparison_0.nc",
        "comparison_1.nc",
        "scenario.toml",
        "error_vs_n.png",
        "comparison_snapshots.png",
    }
    assert names <= {p.name for p in tmp_path.iterdir()}
    summary_time = (tmp_path / "summary.json").stat().st_mtime_ns
    assert all(p.stat().st_mtime_ns <= summary_time for p in tmp_path.iterdir())
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert len(summary["cases"]) == 2
    assert summary["cases"][1]["interaction"] == {"strength": 0.5, "length": 0.1}
    with xr.open_dataset(tmp_path / "comparison_0.nc", engine="h5netcdf") as ds:
        np.testing.assert_array_equal(
            ds["error_to_expected"].values, report.cases[0].dataset["error_to_expected"].values
        )
    for png in ("error_vs_n.png", "comparison_snapshots.png"):
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"n_agents": (1, 50)}, "n_agents"),
        ({"n_agents": (50, 50)}, "n_agents"),
        ({"n_agents": ()}, "n_agents"),
        ({"record_interval": 0.0}, "record_interval"),
        ({"record_interval": -0.1}, "record_interval"),
        ({"record_interval": math.nan}, "record_interval"),
    ],
)
def test_compare_bad_input(scenario, trajectory, kwargs, name):
    args = {"n_agents": (50, 200), "record_interval": 0.1} | kwargs
    with pytest.raises(ParameterError) as info:
        compare_agents_pde(scenario, trajectory=trajectory, t_final=0.1, cells=(16, 16), **args)
    assert info.value.name == name


@pytest.mark.parametrize("repulsion", [(-0.5, 0.1), (0.5, 0.0), (0.5, -0.1)])
def test_run_comparison_refuses_non_repulsive(scenario, repulsion):
    with pytest.raises(ParameterError) as info:
        run_comparison(scenario, (50, 200), repulsion=repulsion, t_final=0.1, cells=(16, 16))
    assert info.value.name == "repulsion"


# ---------------------------------------------------------------------- the command
def test_cli_compare_writes_outputs(tmp_path):
    out = tmp_path / "out"
    args = [
        "compare",
        "paper",
        "--out",
        str(out),
        "--n-agents",
        "50,200",
        "--t-final",
        "0.3",
        "--cells",
        "16",
        "--record-interval",
        "0.1",
        "--quiet",
    ]
    assert main(args) == 0
    for name in ("summary.json", "comparison_0.nc", "comparison_1.nc", "error_vs_n.png", "comparison_snapshots.png"):
        assert (out / name).exists(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["cases"][0]["n_agents"] == [50, 200]
    assert summary["cases"][0]["cells"] == [16, 16]
    assert summary["cases"][0]["time_final"] == pytest.approx(0.3)


@pytest.mark.parametrize(
    ("extra", "name"),
    [(["--n-agents", "abc"], "--n-agents"), (["--repulsion", "1"], "--repulsion"), (["--cells", "2"], "--cells")],
)
def test_cli_compare_bad_input_exits_2(extra, name, tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["compare", "paper", "--out", str(out), "--t-final", "0.1", "--quiet", *extra])
    assert status == 2
    assert name in capsys.readouterr().err
    assert not out.exists()
