"""``timeseries.nc`` is written with h5netcdf directly, and xarray reads it as the dataset it would have written
(issue 45, "Small crowds fast": importing xarray and pandas cost more than a small run)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr

from meanfield import paper_scenario, run
from meanfield.io.netcdf import NetCDFDataset, NetCDFVariable
from meanfield.scenarios.scenario import builtin_scenarios


def _value(v) -> object:
    """An attribute's value as comparable text: its HDF5 type, shape and contents (NaN equal to NaN)."""
    if isinstance(v, np.ndarray):
        return f"{v.dtype}{v.shape}{v.tolist()!r}"
    return f"{type(v).__name__}:{v!r}"


def _raw(path: Path) -> dict:
    """Everything a NetCDF-4 reader sees of the file, as HDF5 holds it: each variable's dtype, shape, fill value,
    chunking, compression, data and attributes (each with its stored type), the dimension scales by name."""
    out: dict = {}
    with h5py.File(path, "r") as f:

        def attrs(obj) -> list:
            items = []
            for key in obj.attrs:
                v = obj.attrs[key]
                if key == "DIMENSION_LIST":
                    v = [f[r[0]].name for r in v]
                elif key == "REFERENCE_LIST":
                    v = [(f[r[0]].name, int(r[1])) for r in v]
                else:
                    v = (str(obj.attrs.get_id(key).dtype), _value(v))
                items.append((key, v))
            return items

        out["/"] = attrs(f)

        def visit(name: str, obj) -> None:
            if isinstance(obj, h5py.Dataset):
                data = obj[()]
                out[name] = (str(obj.dtype), obj.shape, _value(np.asarray(obj.fillvalue)), obj.chunks,
                             obj.compression, _value(data), attrs(obj))  # fmt: skip

        f.visititems(visit)
    return out


def _assert_as_xarray_writes_it(result, folder: Path) -> xr.Dataset:
    """The ``timeseries.nc`` that ``save`` wrote is what xarray writes of ``result.dataset`` and reads back as it."""
    result.save(folder)
    direct = folder / "timeseries.nc"
    by_xarray = folder.parent / f"{folder.name}-xarray.nc"
    result.dataset.to_netcdf(by_xarray, engine="h5netcdf")
    assert _raw(direct) == _raw(by_xarray)
    with xr.open_dataset(direct, engine="h5netcdf") as ds, xr.open_dataset(by_xarray, engine="h5netcdf") as other:
        ds.load()
        xr.testing.assert_identical(ds, other.load())
    xr.testing.assert_identical(ds, result.dataset)
    for name in ds.coords:
        assert "_FillValue" not in ds[name].encoding  # CF 2.5.1, as before
    return ds


@pytest.fixture(scope="module")
def paper_result():
    return run(paper_scenario(seed=0).replace(t_final=0.05), progress=False)


@pytest.fixture(scope="module")
def hall_result():
    return run(builtin_scenarios()["hall"](seed=1).replace(t_final=2.0), progress=False)


def test_the_paper_s_file_reads_as_its_dataset(paper_result, tmp_path):
    """(a) The paper's dimensionless scenario: every unit "1", the run's id and status in the attributes."""
    ds = _assert_as_xarray_writes_it(paper_result, tmp_path / "paper")
    assert ds.attrs["units_system"] == "dimensionless" and ds["robot_x"].attrs["units"] == "1"
    assert ds.attrs["run_id"] == paper_result.summary["run_id"] and ds.attrs["status"] == "completed"
    assert "fraction_evacuated" not in ds and ds["saturated"].dtype == np.int8


def test_a_plan_with_exits_s_file_reads_as_its_dataset(hall_result, tmp_path):
    """(b) A plan with agents and exits: SI units, the humans recorded, the fraction out."""
    ds = _assert_as_xarray_writes_it(hall_result, tmp_path / "hall")
    assert ds.attrs["units_system"] == "SI" and ds.sizes["human"] == 200
    assert ds["human_x"].dims == ("time", "human") and ds["human_y"].attrs["units"] == "m"
    assert ds["fraction_evacuated"].attrs["units"] == "1" and ds["robot_speed"].attrs["units"] == "m s-1"
    assert ds["robots_at_limit"].dtype == np.int16 and ds["human"].attrs["units"] == "1"


def test_the_frames_answer_as_the_dataset_does(hall_result):
    """What the summary, the figures and the trajectory writers read of the frames, they read alike of both."""
    frames, ds = hall_result.timeseries, hall_result.dataset
    assert dict(frames.sizes) == dict(ds.sizes) and frames.attrs == ds.attrs
    assert set(frames.data_vars) == set(ds.data_vars) and set(frames.coords) == set(ds.coords)
    for name in frames:
        assert name in ds and frames[name].dims == ds[name].dims and frames[name].dtype == ds[name].dtype
        np.testing.assert_array_equal(frames[name].values, ds[name].values)
    assert "no_such_variable" not in frames


def test_a_small_dataset_is_written_as_xarray_writes_it(tmp_path):
    """Floats (a NaN fill value), small integers (none), coordinates (none), attributes of every kind."""
    ds = NetCDFDataset(
        data_vars={
            "a": NetCDFVariable(("t", "k"), np.array([[1.0, np.nan], [3.0, 4.0]]), {"units": "m", "n": 3}),
            "flag": NetCDFVariable(("t",), np.array([0, 1], np.int8), {"flag_values": np.array([0, 1], np.int8)}),
        },
        coords={"t": NetCDFVariable(("t",), [0.0, 0.5], {"units": "s"}), "k": NetCDFVariable(("k",), [4, 7])},
        attrs={"title": "x", "seed": 2, "r": 0.25, "empty": ""},
    )
    ds.write_netcdf(tmp_path / "direct.nc")
    ds.to_xarray().to_netcdf(tmp_path / "xarray.nc", engine="h5netcdf")
    assert _raw(tmp_path / "direct.nc") == _raw(tmp_path / "xarray.nc")
    with xr.open_dataset(tmp_path / "direct.nc", engine="h5netcdf") as read:
        xr.testing.assert_identical(read.load(), ds.to_xarray())


def test_a_dataset_refuses_what_it_cannot_write():
    with pytest.raises(ValueError, match="dimension 't'"):
        NetCDFDataset({"a": NetCDFVariable(("t",), [1.0, 2.0])}, {"t": NetCDFVariable(("t",), [0.0])})
    with pytest.raises(ValueError, match="named after"):
        NetCDFDataset({}, {"t": NetCDFVariable(("s",), [0.0])})
    with pytest.raises(TypeError, match="integers or floats"):
        NetCDFVariable(("t",), np.array(["a"]))
    with pytest.raises(ValueError, match="shape"):
        NetCDFVariable(("t", "k"), [1.0])


_NO_XARRAY = r"""
import sys
from meanfield import paper_scenario, run
from meanfield.cli.app import main

def heavy():
    return sorted({m.split(".")[0] for m in sys.modules} & {"xarray", "pandas"})

out = sys.argv[1]
result = run(paper_scenario(seed=0).replace(t_final=0.05), progress=False)  # the run and its summary
assert result.summary["status"] == "completed"
result.save(out + "/api")
assert not heavy(), f"run, summary and save imported {heavy()}"
assert main(["run", "hall", "--set", "t_final=2", "--out", out + "/cli", "--quiet"]) == 0  # figures, trajectories
assert not heavy(), f"meanfield run imported {heavy()}"
print("no xarray")
"""


def test_a_run_its_summary_and_its_save_import_no_xarray(tmp_path):
    """A run, its summary and its folder (``meanfield run`` with its figures and trajectories included) never
    import xarray or pandas: their imports cost more than a small crowd's run."""
    done = subprocess.run([sys.executable, "-c", _NO_XARRAY, str(tmp_path)], capture_output=True, text=True)
    assert done.returncode == 0 and "no xarray" in done.stdout, done.stderr
    assert (tmp_path / "cli" / "trajectories.sqlite").is_file() and (tmp_path / "api" / "timeseries.nc").is_file()
    with xr.open_dataset(tmp_path / "cli" / "timeseries.nc", engine="h5netcdf") as ds:
        assert ds.sizes["time"] == 3 and "fraction_evacuated" in ds
