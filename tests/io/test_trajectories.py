"""JuPedSim's SQLite trajectory file, read back by PedPy (issue 16, item 10)."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from meanfield import load_scenario, run
from meanfield.io.trajectories import JUPEDSIM_SQLITE_VERSION, write_jupedsim_sqlite
from tests.optional import load

pytestmark = pytest.mark.requires("pedpy")
pedpy = load("pedpy")


@pytest.fixture(scope="module")
def unity_run():
    sc = load_scenario("paper-unity").replace(t_final=50.0)
    return sc, run(sc, progress=False)


def test_pedpy_reads_back_the_recorded_trajectories_and_the_room(unity_run, tmp_path):
    sc, result = unity_run
    ds = result.dataset
    path = write_jupedsim_sqlite(ds, sc.domain.to_shapely(), tmp_path / "t.sqlite")
    traj = pedpy.load_trajectory_from_jupedsim_sqlite(trajectory_file=path)
    spacing = float(ds["time"].values[1] - ds["time"].values[0])
    assert traj.frame_rate == pytest.approx(1.0 / spacing)
    data = traj.data.sort_values(["frame", "id"])
    frames, humans = ds.sizes["time"], ds.sizes["human"]
    assert len(data) == frames * humans
    np.testing.assert_array_equal(data["x"].to_numpy().reshape(frames, humans), ds["human_x"].values)
    np.testing.assert_array_equal(data["y"].to_numpy().reshape(frames, humans), ds["human_y"].values)
    area = pedpy.load_walkable_area_from_jupedsim_sqlite(trajectory_file=path)
    assert area.polygon.equals(sc.domain.to_shapely())


def test_the_file_has_jupedsim_s_tables_and_unit_orientations(unity_run, tmp_path):
    sc, result = unity_run
    path = write_jupedsim_sqlite(result.dataset, sc.domain.to_shapely(), tmp_path / "t.sqlite")
    with sqlite3.connect(path) as con:
        meta = dict(con.execute("select key, value from metadata").fetchall())
        assert int(meta["version"]) == JUPEDSIM_SQLITE_VERSION and meta["units"] == "SI"
        assert meta["run_id"] == result.summary["run_id"]
        ori = np.array(con.execute("select ori_x, ori_y from trajectory_data").fetchall())
        assert np.allclose(np.hypot(ori[:, 0], ori[:, 1]), 1.0)
        frames = con.execute("select count(*) from frame_data").fetchone()[0]
        assert frames == result.dataset.sizes["time"]
        assert con.execute("select count(*) from geometry").fetchone()[0] == 1


def test_meanfield_run_writes_it_beside_the_netcdf(tmp_path):
    from meanfield.cli.app import main
    from meanfield.io.atomic import check_complete_folder

    out = tmp_path / "run"
    assert main(["run", "paper-unity", "--set", "t_final=20", "--out", str(out), "--quiet", "--no-figures"]) == 0
    assert (out / "trajectories.sqlite").is_file() and check_complete_folder(out) == []
