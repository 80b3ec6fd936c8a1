"""The robot count × η study: medians, never-reached times, smallest counts, coverage, figure."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

from analysis.figures import plot_robot_count_sweep, save_figure
from analysis.robot_count import coverage_estimate
from analysis.robot_count_sweep import run_robot_count_sweep, summarize_robot_count_sweep
from meanfield import ParameterError, paper_scenario

NAN = float("nan")


def _sweep(frac, t90, status) -> xr.Dataset:
    """A sweep Dataset shaped like meanfield.workflows.sweep's: (robots.n, kernel.eta, seed)."""
    dims = ("robots.n", "kernel.eta", "seed")
    return xr.Dataset(
        {
            "fraction_in_target": (dims, np.array(frac, float)),
            "time_to_90": (dims, np.array(t90, float)),
            "status": (dims, np.array(status, dtype=object)),
        },
        coords={"robots.n": [9, 1], "kernel.eta": [0.05, 0.01], "seed": [0, 1, 2]},
        attrs={"scenario": paper_scenario().to_toml()},
    )


def test_medians_count_never_as_later_than_any_time_and_skip_failed_runs():
    ok = ["completed"] * 3
    frac = [[[0.95, 0.91, 0.80], [0.5, 0.6, 0.7]], [[0.2, 0.3, 0.1], [0.92, 0.93, 0.1]]]
    t90 = [[[10.0, 20.0, NAN], [NAN, NAN, NAN]], [[NAN, NAN, NAN], [5.0, 7.0, NAN]]]
    status = [[ok, ok], [ok, ["completed", "completed", "diverged"]]]
    study = summarize_robot_count_sweep(_sweep(frac, t90, status), threshold=0.9, eps_fractions=(0.2,))
    assert study.counts == [9, 1] and study.etas == [0.05, 0.01] and study.seeds == [0, 1, 2]
    np.testing.assert_allclose(study.fraction, [[0.91, 0.6], [0.2, 0.925]])
    # n=9, η=0.05: 10, 20, never -> 20; n=9, η=0.01: never ×3 -> inf; n=1, η=0.01: 5, 7 (diverged run dropped) -> 6
    assert study.time_to_90[0, 0] == 20.0 and math.isinf(study.time_to_90[0, 1]) and math.isinf(study.time_to_90[1, 0])
    assert study.time_to_90[1, 1] == 6.0
    np.testing.assert_allclose(study.reached_90, [[2 / 3, 0.0], [0.0, 1.0]])
    np.testing.assert_array_equal(study.failed, [[0, 0], [0, 1]])
    assert study.minimum == {0.05: 9, 0.01: 1}
    sc = paper_scenario()
    expected = [coverage_estimate(sc.domain, sc.kernel.c, eta, 0.2 * sc.kernel.c).n for eta in (0.05, 0.01)]
    assert study.coverage == {0.2: expected} and expected[1] > expected[0]
    d = study.to_dict()
    assert d["median_time_to_90"][0][1] == "never" and d["minimum_count"] == {"0.05": 9, "0.01": 1}


def test_a_count_that_never_succeeds_has_no_minimum_and_the_figure_is_drawn(tmp_path):
    ok = [["completed"] * 3] * 2
    frac = np.full((2, 2, 3), 0.5)
    t90 = np.full((2, 2, 3), NAN)
    study = summarize_robot_count_sweep(_sweep(frac, t90, [ok, ok]))
    assert study.minimum == {0.05: None, 0.01: None}
    path = save_figure(plot_robot_count_sweep(study), tmp_path / "f.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_input_refused_before_any_run(tmp_path):
    with pytest.raises(ParameterError) as info:
        run_robot_count_sweep(paper_scenario(), [], [0.05], 1, tmp_path / "a")
    assert info.value.name == "counts"
    with pytest.raises(ParameterError) as info:
        run_robot_count_sweep(paper_scenario(), [4], [0.0], 1, tmp_path / "b")
    assert info.value.name == "etas"
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    ds = _sweep(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), [[["completed"] * 3] * 2] * 2)
    with pytest.raises(ParameterError):
        summarize_robot_count_sweep(ds.rename({"kernel.eta": "kernel.c"}))
    with pytest.raises(ParameterError):
        summarize_robot_count_sweep(ds, eps_fractions=(1.5,))
