"""Units: scenarios state theirs, NetCDF variables carry CF units and long names (issue 16, item 9)."""

from __future__ import annotations

import pytest

from meanfield import ParameterError, load_scenario, paper_scenario, run
from meanfield.trajectories import write_pedpy_trajectories


def test_the_built_in_scenarios_state_their_units():
    assert paper_scenario(seed=0).units == "dimensionless"
    assert load_scenario("stadium").units == "dimensionless"
    assert load_scenario("paper-unity").units == "SI"
    assert "units" in paper_scenario(seed=0).to_dict()
    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({"units": "furlongs"})
    assert exc.value.name == "units" and "SI" in str(exc.value)


@pytest.mark.parametrize(("name", "length", "speed"), [("paper-unity", "m", "m s-1"), ("paper", "1", "1")])
def test_netcdf_variables_carry_cf_units_and_long_names(name, length, speed):
    sc = load_scenario(name)
    ds = run(sc.replace(t_final=5 * sc.dt), progress=False).dataset
    assert ds.attrs["units_system"] == sc.units and ds.attrs["Conventions"].startswith("CF-")
    assert ds["robot_x"].attrs["units"] == length and ds["human_x"].attrs["units"] == length
    assert ds["robot_speed"].attrs["units"] == speed
    assert ds["density"].attrs["units"] == ("m-2" if length == "m" else "1")
    assert "units" not in ds["V2"].attrs and "mixes" in ds["V2"].attrs["long_name"]
    assert all("long_name" in ds[v].attrs for v in ds.data_vars)


def test_bodies_need_a_scenario_in_metres():
    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({"pedestrians.backend": "jupedsim"})
    assert exc.value.name == "pedestrians.backend" and "paper-unity" in str(exc.value)


def test_a_trajectory_file_claims_metres_only_for_a_scenario_in_metres(tmp_path):
    for name, metres in (("paper", False), ("paper-unity", True)):
        sc = load_scenario(name)
        ds = run(sc.replace(t_final=30 * sc.dt), progress=False).dataset
        header = write_pedpy_trajectories(ds, tmp_path / f"{name}.txt").read_text().splitlines()[:5]
        assert ("# id frame x/m y/m" in header) == metres
        assert any("dimensionless" in line for line in header) == (not metres)
