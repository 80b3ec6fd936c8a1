"""The examples of docs/examples/: a baseline controller and a toy crowd, each one module plus one
registration line, selected by name from a TOML scenario."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from meanfield import ClosedLoop, ParameterError, load_scenario, navigation_velocity
from meanfield.interfaces import Controller, Crowd

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def test_parked_robots_come_from_the_toml_and_park_with_signs_on_the_target():
    # robots start away from their stations; at u_max = 0.2 the farthest needs ~6 time units
    # to arrive, then both errors decay like e^{-t}
    sc = load_scenario(EXAMPLES / "parked_robots.toml", allow_plugins=True).replace(t_final=12.0)
    sc = sc.with_values({"robots.layout": "random"})
    assert sc.controller.kind == "parked"
    loop = ClosedLoop(sc)
    ctrl = loop.controller
    assert type(ctrl).__name__ == "ParkedRobots" and isinstance(ctrl, Controller)
    start = np.hypot(*(loop.robots.positions - ctrl.stations).T).max()
    assert start > 0.1  # the test is not vacuous: the robots have somewhere to go
    result = loop.run(progress=False)
    s = result.summary
    assert s["status"] == "completed" and s["controller"] == "parked"
    assert np.hypot(*(loop.robots.positions - ctrl.stations).T).max() < 1e-2 * start
    miss = np.angle(np.exp(1j * (ctrl.bearings(loop.robots.positions) - loop.robots.headings)))
    assert np.abs(miss).max() < 1e-3
    assert s["max_robot_speed"] <= sc.robots.u_max * (1 + 1e-12)
    # no law, no Lyapunov quantities: the recorder writes NaN rather than inventing them
    assert np.isnan(result.dataset["V2"].values).all() and s["V2_final"] is not None


def test_parked_robots_refuse_an_unknown_option():
    sc = load_scenario(EXAMPLES / "parked_robots.toml", allow_plugins=True)
    with pytest.raises(ParameterError) as exc:  # refused as the scenario is read
        sc.with_values({"controller.options.parked.k_speed": 1.0})
    assert exc.value.name == "controller.options.parked.k_speed" and "k_position" in str(exc.value)


def test_obedient_walkers_come_from_the_toml_and_walk_only_where_a_sign_is_strong():
    # 4 robots on the unit square leave humans beyond every sign's reach
    sc = load_scenario(EXAMPLES / "obedient_walkers.toml", allow_plugins=True)
    sc = sc.replace(t_final=1.0).with_values({"robots.n": 4})
    assert sc.crowd.kind == "obedient-walkers"
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    assert type(crowd).__name__ == "ObedientWalkers" and isinstance(crowd, Crowd)
    c, dt = sc.kernel.c, sc.dt
    x0 = crowd.positions.copy()
    v = navigation_velocity(loop.kernel, loop.robots.positions, loop.robots.headings, x0)
    strong = np.hypot(v[:, 0], v[:, 1]) > 0.1 * c
    assert 0 < strong.sum() < len(strong)  # some walk, some stand
    loop.step()
    moved = np.hypot(*(crowd.positions - x0).T)
    assert (moved[~strong] == 0).all()
    inside = strong & (np.abs(x0 - 0.5).max(axis=1) < 0.5 - 2 * c * dt)  # no wall within reach
    np.testing.assert_allclose(moved[inside], c * dt, rtol=1e-12)
    assert (moved <= c * dt * (1 + 1e-12)).all()
    s = loop.run(progress=False).summary
    assert s["status"] == "completed" and s["backend"] == "obedient-walkers"
    assert 0 <= s["walking_fraction_final"] <= 1
    assert sc.domain.contains(*crowd.positions.T).all()


def test_the_command_line_runs_an_example_and_its_saved_scenario_runs_again(tmp_path):
    from meanfield.cli.app import main

    out = tmp_path / "run"
    argv = ["run", str(EXAMPLES / "parked_robots.toml"), "--set", "t_final=0.2", "--out", str(out), "--quiet"]
    argv.append("--allow-plugins")  # the example lists its module in plugins: a file runs no code without it
    assert main([*argv, "--no-figures"]) == 0
    again = load_scenario(out / "scenario.toml", allow_plugins=True)  # the plugin path is kept absolute
    assert again.controller.kind == "parked" and again.plugins[0].endswith("parked_robots.py")
    assert ClosedLoop(again.replace(t_final=0.05)).run(progress=False).summary["status"] == "completed"
