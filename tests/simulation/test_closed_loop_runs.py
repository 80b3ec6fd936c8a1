"""The closed loop: determinism, invariants, outputs on disk, and divergence handling."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr

from meanfield import ClosedLoop, Domain, paper_scenario, run
from meanfield.scenarios.scenario import CrowdSpec, GridSpec, RobotSpec, TargetSpec
from tests.conftest import PENTAGON

SUMMARY_KEYS = {
    "fraction_in_target",
    "l2_error_initial",
    "l2_error_final",
    "w2_to_target_final",
    "time_to_90",
    "max_robot_speed",
    "speed_limit",
    "steps",
    "wall_seconds",
    "seed",
    "scenario",
}
DATA_VARS = {
    "robot_x",
    "robot_y",
    "robot_heading",
    "robot_speed",
    "robot_turn_rate",
    "human_x",
    "human_y",
    "density",
    "target_density",
    "V1",
    "V2",
    "rho_error_l2",
    "v_error_l2",
    "fraction_in_target",
    "A",
    "shortfall",
    "dissipation",
    "saturated",
}


def _short(seed=3, t_final=0.2):
    return paper_scenario(seed=seed).replace(t_final=t_final)


@pytest.fixture(scope="module")
def result():
    return ClosedLoop(_short()).run(progress=False)


def test_same_seed_identical_different_seed_differs(result):
    again = ClosedLoop(_short()).run(progress=False)
    xr.testing.assert_identical(result.dataset, again.dataset)
    for k in ("fraction_in_target", "l2_error_final", "w2_to_target_final", "max_robot_speed"):
        assert result.summary[k] == again.summary[k]
    other = ClosedLoop(_short(seed=4)).run(progress=False)
    assert not np.array_equal(other.dataset["human_x"].values, result.dataset["human_x"].values)
    assert not np.array_equal(other.dataset["robot_heading"].values, result.dataset["robot_heading"].values)
    # run() with a seed override is the same as building the loop with that seed
    via_run = run(_short(seed=0), seed=3, progress=False)
    xr.testing.assert_identical(via_run.dataset, result.dataset)


def test_run_invariants(result):
    sc = result.scenario
    s = result.summary
    ds = result.dataset
    assert s["status"] == "completed"
    assert s["steps"] == sc.steps == 20
    assert ds.sizes["time"] == sc.steps // sc.record_every + 1
    np.testing.assert_allclose(ds["time"].values, [0.0, 0.1, 0.2], rtol=1e-12)
    assert s["max_robot_speed"] <= sc.robots.u_max * (1 + 1e-12)
    assert s["speed_limit"] == sc.robots.u_max
    assert np.nanmax(np.abs(ds["robot_turn_rate"].values)) <= sc.robots.omega_max * (1 + 1e-12)
    hx, hy = ds["human_x"].values, ds["human_y"].values
    assert sc.domain.contains(hx, hy).all()
    assert sc.domain.contains(ds["robot_x"].values, ds["robot_y"].values).all()
    # every density frame has unit mass on the grid (cells are 1/30 × 1/30)
    masses = ds["density"].values.sum(axis=(1, 2)) / 900
    np.testing.assert_allclose(masses, 1.0, rtol=1e-12)
    # V₂ = ½ V₁ + ½‖ṽ‖² per frame
    np.testing.assert_allclose(ds["V2"], 0.5 * ds["V1"] + 0.5 * ds["v_error_l2"] ** 2, rtol=1e-12)
    np.testing.assert_allclose(ds["V1"], ds["rho_error_l2"] ** 2, rtol=1e-12)
    assert 0.0 <= s["fraction_in_target"] <= 1.0


@pytest.mark.parametrize("domain", [Domain.disk(0.5, (0.5, 0.5)), Domain.polygon(PENTAGON)])
def test_short_runs_on_other_shapes(domain):
    sc = paper_scenario(seed=1).replace(
        domain=domain,
        t_final=0.1,
        grid=GridSpec((16, 16)),
        crowd=CrowdSpec(n=60, sigma=1e-3),
        robots=RobotSpec(n=4, layout="grid", u_max=0.2, omega_max=2.0),
        target=TargetSpec(domain.center, 0.2),
    )
    res = ClosedLoop(sc).run(progress=False)
    assert res.summary["status"] == "completed"
    ds = res.dataset
    assert domain.contains(ds["human_x"].values, ds["human_y"].values).all()
    assert domain.contains(ds["robot_x"].values, ds["robot_y"].values).all()


def test_save_writes_documented_outputs(result, tmp_path):
    from meanfield.plotting.figures import save_run_figures

    paths = result.save(tmp_path / "out", artifacts=[save_run_figures])
    out = tmp_path / "out"
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["seed"] == 3 and summary["steps"] == 20
    assert summary["scenario"] == result.scenario.to_dict()
    with xr.open_dataset(out / "timeseries.nc", engine="h5netcdf") as ds:
        assert DATA_VARS <= set(ds.data_vars)
        for v in DATA_VARS:
            np.testing.assert_array_equal(ds[v].values, result.dataset[v].values)
    toml = (out / "scenario.toml").read_text()
    assert toml.endswith(result.scenario.to_toml()) and summary["run_id"] in toml.splitlines()[0]
    with xr.open_dataset(out / "timeseries.nc", engine="h5netcdf") as ds:
        assert ds.attrs["run_id"] == summary["run_id"] and ds.attrs["status"] == "completed"
    from PIL import Image

    assert summary["run_id"] in Image.open(out / "snapshots.png").text["Comment"]
    assert set(summary["files"]) == {p.name for p in out.iterdir() if p.name != "summary.json"}
    for name in ("target_and_error.png", "snapshots.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(paths) >= {"timeseries", "scenario", "summary"}
    # nothing half-written left behind
    assert not [p for p in out.iterdir() if ".part" in p.name]


def test_blow_up_stops_with_status_diverged():
    """A disturbance that turns NaN at t >= 0.05 stops the run at the last good state."""

    def bad(x, y, t):
        v = np.nan if t >= 0.05 - 1e-12 else 0.0
        return np.full_like(x, v), np.full_like(y, v)

    loop = ClosedLoop(_short(), disturbance=bad)
    res = loop.run(progress=False)
    s = res.summary
    assert s["status"] == "diverged"
    assert "non-finite" in s["message"]
    assert s["steps"] == 5 and math.isclose(loop.t, 0.05)
    assert np.isfinite(loop.crowd.positions).all()
    assert np.isfinite(loop.robots.positions).all() and np.isfinite(loop.robots.headings).all()
    assert np.isfinite(loop.density).all()
    ds = res.dataset
    for v in ("human_x", "human_y", "robot_x", "robot_y", "density"):
        assert np.isfinite(ds[v].values).all()
    assert ds["time"].values[-1] == pytest.approx(0.05)
    # the last frame is the last good state
    np.testing.assert_array_equal(ds["human_x"].values[-1], loop.crowd.positions[:, 0])
    assert np.isfinite(s["l2_error_final"]) and np.isfinite(s["w2_to_target_final"])


def test_record_humans_keeps_a_spaced_subset_and_every_figure_uses_the_whole_crowd(result):
    from meanfield.simulation.observers import recorded_humans

    sub = ClosedLoop(_short().replace(record_humans=50)).run(progress=False)
    ds, full = sub.dataset, result.dataset
    n = result.scenario.crowd.n
    idx = ds["human"].values
    assert len(idx) == 50 and idx[0] == 0 and idx[-1] == n - 1 and np.all(np.diff(idx) > 0)
    assert ds.attrs["humans_recorded"] == 50 and ds.attrs["humans_total"] == n
    # the same seed gives the same crowd: the subset is those humans' recorded positions
    np.testing.assert_array_equal(ds["human_x"].values, full["human_x"].values[:, idx])
    np.testing.assert_array_equal(ds["density"].values, full["density"].values)
    np.testing.assert_array_equal(ds["fraction_in_target"].values, full["fraction_in_target"].values)
    assert sub.summary["fraction_in_target"] == result.summary["fraction_in_target"]
    assert full.attrs["humans_recorded"] == n  # default 10 000 keeps everyone here
    np.testing.assert_array_equal(recorded_humans(7, "all"), np.arange(7))
    np.testing.assert_array_equal(recorded_humans(7, 100), np.arange(7))
    assert len(recorded_humans(10**6, 0)) == 0
    np.testing.assert_array_equal(recorded_humans(10, 4), [0, 3, 6, 9])


@pytest.mark.parametrize("bad", [-1, 2.5, "some", True])
def test_record_humans_bad_value_refused(bad):
    from meanfield import ParameterError

    with pytest.raises(ParameterError) as info:
        paper_scenario().replace(record_humans=bad)
    assert info.value.name == "record_humans"
