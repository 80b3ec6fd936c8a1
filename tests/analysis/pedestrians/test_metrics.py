"""PedPy trajectories and measurements (analysis.pedestrians.metrics): exact counts on synthetic
crowds, round trip, refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meanfield.errors import ParameterError
from meanfield.io.trajectories import frame_spacing, write_pedpy_trajectories
from tests.analysis.pedestrians.conftest import CELLS, N, crowd_positions, run_dataset


def _read(path):
    rows = np.loadtxt(path, comments="#", ndmin=2)
    return rows[:, 0].astype(int), rows[:, 1].astype(int), rows[:, 2], rows[:, 3]


# ------------------------------------------------------------------ writer (no PedPy)
def test_file_has_header_and_one_line_per_human_and_frame(tmp_path):
    x, y = crowd_positions([0, 3, 5])
    path = write_pedpy_trajectories(run_dataset(x, y, [0.0, 0.1, 0.2]), tmp_path / "t.txt")
    text = path.read_text()
    assert "# framerate: 10.0\n" in text  # 1/0.1 written as 10, not 10.000000000000002
    assert "x/m" in text
    pid, frame, px, py = _read(path)
    assert pid.size == 3 * N
    order = np.lexsort((frame, pid))
    np.testing.assert_array_equal(pid[order], np.repeat(np.arange(N), 3))
    np.testing.assert_array_equal(frame[order], np.tile(np.arange(3), N))
    np.testing.assert_array_equal(px[order], x.T.ravel())  # %.17g: exact
    np.testing.assert_array_equal(py[order], y.T.ravel())
    assert [p.name for p in tmp_path.iterdir()] == ["t.txt"]  # no temporary file left


def test_short_last_frame_is_dropped(tmp_path):
    x, y = crowd_positions([1, 2, 3, 4])
    path = write_pedpy_trajectories(run_dataset(x, y, [0.0, 2.0, 4.0, 5.0]), tmp_path / "t.txt")
    _, frame, _, _ = _read(path)
    assert set(frame) == {0, 1, 2}
    assert "# framerate: 0.5\n" in path.read_text()
    assert frame_spacing([0.0, 2.0, 4.0, 5.0]) == (2.0, 3)
    assert frame_spacing([0.0, 2.0, 4.0, 6.0]) == (2.0, 4)
    assert frame_spacing([3.0, 4.0]) == (1.0, 2)


def test_missing_positions_are_left_out(tmp_path):
    x, y = crowd_positions([0, 0])
    x[1, 4] = np.nan
    pid, frame, _, _ = _read(write_pedpy_trajectories(run_dataset(x, y, [0.0, 1.0]), tmp_path / "t.txt"))
    assert pid.size == 2 * N - 1 and not np.any((pid == 4) & (frame == 1))


@pytest.mark.parametrize(
    "times, what",
    [
        ([], "no recorded frame"),
        ([0.0], "1 recorded frame"),
        ([0.0, 1.0, 3.0, 4.0], "frame spacings"),
        ([0.0, 1.0, 2.0, 3.5], "last frame spacing"),
        ([0.0, 1.0, 1.0], "not strictly increasing"),
    ],
)
def test_bad_frames_are_refused_by_name(tmp_path, times, what):
    T = len(times)
    ds = run_dataset(np.zeros((T, N)), np.zeros((T, N)), times)
    with pytest.raises(ParameterError) as exc:
        write_pedpy_trajectories(ds, tmp_path / "t.txt")
    assert exc.value.name == "dataset" and what in str(exc.value)
    assert not (tmp_path / "t.txt").exists()


def test_dataset_without_humans_is_refused(tmp_path):
    x, y = crowd_positions([0, 0])
    ds = run_dataset(x, y, [0.0, 1.0])
    with pytest.raises(ParameterError, match="human_y") as exc:
        write_pedpy_trajectories(ds.drop_vars("human_y"), tmp_path / "t.txt")
    assert exc.value.name == "dataset"
    with pytest.raises(ParameterError, match="dims") as exc:
        write_pedpy_trajectories(ds.assign(human_x=ds.human_x.T), tmp_path / "t.txt")


# ------------------------------------------------------------------ PedPy
@pytest.mark.requires("pedpy")
def test_round_trip_through_pedpy_gives_the_same_frames_and_positions(tmp_path):
    x, y = crowd_positions([0, 4, 9, 2])
    path = write_pedpy_trajectories(run_dataset(x, y, [10.0, 12.5, 15.0, 17.5]), tmp_path / "t.txt")
    import pedpy

    traj = pedpy.load_trajectory_from_txt(trajectory_file=path)
    assert traj.frame_rate == 0.4
    d = traj.data.sort_values(["frame", "id"])
    np.testing.assert_array_equal(d["frame"].to_numpy(), np.repeat(np.arange(4), N))
    np.testing.assert_array_equal(d["id"].to_numpy(), np.tile(np.arange(N), 4))
    np.testing.assert_allclose(d["x"].to_numpy(), x.ravel(), rtol=1e-15, atol=0)
    np.testing.assert_allclose(d["y"].to_numpy(), y.ravel(), rtol=1e-15, atol=0)


@pytest.mark.parametrize("center, radius", [((1.0, 1.0), 0.3), ((0.5, 0.45), 0.2), ((0.0, 0.6), 0.25)])
@pytest.mark.requires("pedpy")
def test_pedpy_count_in_target_is_exactly_k(tmp_path, center, radius):
    from analysis.pedestrians.metrics import count_in_target, load_pedpy_trajectories, target_measurement_area

    ks = [0, 1, 7, N, 13]
    x, y = crowd_positions(ks, center, radius, seed=1)
    ds = run_dataset(x, y, np.arange(len(ks)) * 0.5, center=center, radius=radius)
    traj = load_pedpy_trajectories(ds, tmp_path / "t.txt")
    area = target_measurement_area(ds)
    counts = count_in_target(traj, area)
    np.testing.assert_array_equal(counts, ks)
    np.testing.assert_array_equal(np.rint(ds.fraction_in_target.values * N), ks)  # the synthetic data is right
    # the measurement area is the disk ∩ room, polygonised from inside
    full = np.pi * radius**2
    assert area.area <= full
    if center == (0.5, 0.45):  # the whole disk is in the room
        assert area.area > full * (1 - 1e-4)


@pytest.mark.requires("pedpy")
def test_pedestrian_metrics_end_to_end(tmp_path):
    from analysis.pedestrians.metrics import pedestrian_metrics

    ks = [2, 5, 9, 12, 15]
    x, y = crowd_positions(ks, seed=2)
    run = tmp_path / "run"
    run.mkdir()
    run_dataset(x, y, np.arange(5) * 0.1).to_netcdf(run / "timeseries.nc", engine="h5netcdf")
    m = pedestrian_metrics(run, tmp_path / "out", window_fraction=0.5, voronoi_frames=2)
    np.testing.assert_array_equal(m.n_in_target, ks)
    assert m.max_fraction_difference == 0 and m.differences_explained
    np.testing.assert_array_equal(m.window_frames, [2, 3, 4])
    assert m.density_classic.shape == (CELLS, CELLS) == m.density_toolkit.shape
    # every map holds the N humans (the grid is stretched by 1e-9 to get exactly CELLS cells)
    assert np.sum(m.density_classic) * m.grid_size**2 == pytest.approx(N, rel=1e-8)
    assert np.sum(m.density_toolkit) * m.grid_size**2 == pytest.approx(N, rel=1e-12)
    assert m.voronoi_error is None and m.voronoi_frames == [2, 4]
    assert np.sum(m.density_voronoi) * m.grid_size**2 == pytest.approx(N, rel=1e-6)
    # classic map: the humans of a cell, averaged over the window frames
    in_window = np.stack([x[2:].ravel(), y[2:].ravel()], axis=1)
    hist, _, _ = np.histogram2d(in_window[:, 0], in_window[:, 1], bins=CELLS, range=[[0, 1], [0, 1]])
    np.testing.assert_allclose(m.density_classic * m.grid_size**2, hist / 3, rtol=1e-8)
    for p in m.figures.values():
        assert p.endswith(".png") and (tmp_path / "out" / p.split("/")[-1]).stat().st_size > 0
    assert json.loads(json.dumps(m.to_dict()))["fraction_final_pedpy"] == ks[-1] / N
