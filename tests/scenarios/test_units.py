"""Units: scenarios state theirs, NetCDF variables carry CF units and long names (issue 16, item 9)."""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ParameterError, load_scenario, paper_scenario, run
from meanfield.io.trajectories import write_pedpy_trajectories


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
    # every variable has a unit, or says in its comment why it has none (issue "Nothing lost", item 10)
    unitless = {v for v in ds.data_vars if "units" not in ds[v].attrs}
    assert unitless == {"V2", "A", "shortfall", "shortfall_applied"}
    assert all("no single unit" in ds[v].attrs["comment"] for v in unitless)
    assert ds["dissipation"].attrs["units"] == ("m-2 s-1" if length == "m" else "1")
    assert ds["robots_at_limit"].attrs["units"] == "1"
    flag = ds["saturated"].attrs
    assert flag["units"] == "1" and list(flag["flag_values"]) == [0, 1] and len(flag["flag_meanings"].split()) == 2


def test_bodies_need_a_scenario_in_metres():
    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({"crowd.kind": "jupedsim"})
    assert exc.value.name == "crowd.kind" and "paper-unity" in str(exc.value)


def test_a_trajectory_file_claims_metres_only_for_a_scenario_in_metres(tmp_path):
    for name, metres in (("paper", False), ("paper-unity", True)):
        sc = load_scenario(name)
        ds = run(sc.replace(t_final=30 * sc.dt), progress=False).dataset
        header = write_pedpy_trajectories(ds, tmp_path / f"{name}.txt").read_text().splitlines()[:5]
        assert ("# id frame x/m y/m" in header) == metres
        assert any("dimensionless" in line for line in header) == (not metres)


def _first_inputs(scaling: str, s: float):
    """The robots' first inputs on paper-unity with every length multiplied by ``s`` (metres → 1/s m)."""
    from meanfield import ClosedLoop
    from meanfield.scenarios.scenario import builtin_scenarios

    sc = builtin_scenarios()["paper-unity"](seed=4)
    values = {
        "units": "dimensionless",  # a unit of length other than the metre
        "domain.width": 150.0 * s,
        "domain.height": 150.0 * s,
        "crowd.sigma": 0.5 * s * s,
        "robots.u_max": "none",
        "robots.omega_max": "none",
        "kernel.c": 1.2 * s,
        "kernel.eta": 1125.0 * s * s,
        "target.center": [150.0 * s, 150.0 * s],
        "target.std": 22.5 * s,
        "density.bandwidth": 12.0 * s,
        "controller.alpha": 180.0 * s * s,
        "controller.rho_floor": 8.888888888888889e-05 / (s * s),
        "controller.scaling": scaling,
        "view.radius": "none",
        "view.walk_speed": 0.0,
    }
    loop = ClosedLoop(sc.with_values(values))
    command = loop.controller.act(loop.observe())
    return loop.robots.positions.copy(), command.u, command.omega


def test_the_law_in_the_kernel_s_units_gives_the_same_inputs_in_metres_and_in_centimetres():
    """The same room in metres and in centimetres: positions and speeds ×100, turn rates equal.
    The paper's law changes its inputs by far more than 10 %; the scaled law only by round-off."""
    for scaling, same in (("kernel", True), ("paper", False)):
        x_m, u_m, w_m = _first_inputs(scaling, 1.0)
        x_cm, u_cm, w_cm = _first_inputs(scaling, 100.0)
        np.testing.assert_allclose(x_cm, 100.0 * x_m, rtol=1e-12)  # the same robots
        du = np.abs(u_cm - 100.0 * u_m).max() / np.abs(100.0 * u_m).max()
        dw = np.abs(w_cm - w_m).max() / np.abs(w_m).max()
        if same:
            assert du < 1e-8 and dw < 1e-8
        else:
            assert du > 0.1 or dw > 0.1
