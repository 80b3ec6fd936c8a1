"""The closed loop behind its three interfaces: one step for agents and for the density, parts built once."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from meanfield import BacksteppingController, ClosedLoop, Domain, ParameterError, paper_scenario
from meanfield.crowds.agent_crowd import AgentCrowd
from meanfield.crowds.density_crowd import DensityCrowd
from meanfield.interfaces import Controller, Crowd, Region
from meanfield.simulation.assembly import assemble


def _short(t_final: float = 0.3):
    return paper_scenario(seed=4).replace(t_final=t_final)


def test_the_built_in_parts_implement_the_interfaces():
    for region in (Domain.box(2, 1), Domain.disk(1.0), Domain.polygon([(0, 0), (1, 0), (0, 1)])):
        assert isinstance(region, Region)
    agents = assemble(_short())
    density = assemble(_short(), crowd="fokker-planck")
    assert isinstance(agents.crowd, AgentCrowd) and isinstance(agents.crowd, Crowd)
    assert isinstance(density.crowd, DensityCrowd) and isinstance(density.crowd, Crowd)
    assert isinstance(agents.controller, BacksteppingController) and isinstance(agents.controller, Controller)


def test_a_seed_gives_the_same_robots_for_agents_and_for_their_density():
    a = assemble(_short(), crowd="point-mass")
    b = assemble(_short(), crowd="fokker-planck")
    np.testing.assert_array_equal(a.robots.positions, b.robots.positions)
    np.testing.assert_array_equal(a.robots.headings, b.robots.headings)


def test_the_same_loop_runs_on_the_fokker_planck_crowd_and_keeps_its_mass():
    loop = ClosedLoop(_short(), crowd="fokker-planck")
    grid = loop.grid
    mass0 = grid.integrate(loop.density)
    result = loop.run(progress=False)
    s = result.summary
    assert s["status"] == "completed" and s["steps"] == 30
    assert abs(s["mass_final"] - mass0) < 1e-12  # zero-flux walls: mass to round-off
    assert s["w2_to_target_final"] is None  # no agents to transport
    assert "human_x" not in result.dataset and np.isfinite(result.dataset["V2"].values).all()
    # the robots observed the density itself: the recorded frame is the solver's state
    np.testing.assert_array_equal(result.dataset["density"].values[-1], loop.crowd.rho)
    # the law acted on it: V2 decreased (paper scenario, unsaturated start)
    assert result.dataset["V2"].values[-1] < result.dataset["V2"].values[0]


def test_one_step_is_observe_act_advance():
    parts = assemble(_short())
    seen = []

    class Spy:
        def start(self, loop):
            seen.append(("start", loop.t))

        def step(self, loop, record):
            seen.append(("step", record.index, record.observation.t, loop.t))

    loop = ClosedLoop(parts, observers=[Spy()])
    r0 = loop.robots.positions.copy()
    rec = loop.step()
    assert seen == [("start", 0.0), ("step", 0, 0.0, loop.dt)]
    np.testing.assert_array_equal(rec.observation.field.positions, r0)  # observed before moving
    np.testing.assert_allclose(loop.robots.positions, r0 + loop.dt * rec.u, atol=1e-15)
    assert np.all(np.hypot(*rec.u.T) <= loop.robots.u_max * (1 + 1e-12))
    assert rec.saturated  # the paper's law asks for more than u_max at the start


def test_a_controller_that_diverges_leaves_the_state_at_the_last_good_step():
    parts = assemble(_short())

    class Broken:
        calls = 0

        def act(self, observation):
            from meanfield.interfaces import Command

            Broken.calls += 1
            u = np.zeros((16, 2)) + (np.nan if Broken.calls > 3 else 0.0)
            return Command(u, np.zeros(16))

        def reset(self):
            pass

    loop = ClosedLoop(dataclasses.replace(parts, controller=Broken()))
    s = loop.run(progress=False).summary
    assert s["status"] == "diverged" and s["steps"] == 3 and "non-finite robot inputs" in s["message"]
    assert math.isclose(loop.t, 0.03) and np.isfinite(loop.crowd.positions).all()


def test_bad_input_names_what_is_wrong():
    with pytest.raises(ParameterError) as exc:
        ClosedLoop("paper")  # a name is not a scenario
    assert exc.value.name == "scenario"
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(assemble(_short()), sigma=0.1)
    assert exc.value.name == "overrides"
    with pytest.raises(ParameterError) as exc:
        assemble(_short(), crowd="ghosts")
    assert exc.value.name == "crowd" and "point-mass" in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        assemble(_short(), controller="magic")
    assert exc.value.name == "controller" and "backstepping" in str(exc.value)


def test_exits_are_carried_by_the_region_and_reach_the_crowd():
    room = Domain.box(1.0, 1.0, exits=[((1.0, 0.4), (1.0, 0.6))])
    parts = {p.kind: p.length for p in room.boundary_parts()}
    assert parts["exit"] == pytest.approx(0.2) and parts["wall"] == pytest.approx(3.8, rel=1e-8)
    assert Domain.from_dict(room.to_dict()) == room
    with pytest.raises(ParameterError) as exc:
        Domain.box(1.0, 1.0, exits=[((0.5, 0.5), (0.6, 0.5))])  # inside, not on the boundary
    assert exc.value.name == "domain.exits[0]"
    crowd = assemble(_short().replace(domain=room)).crowd
    assert crowd.models_exits and len(crowd.engine.exits) == 1


def test_the_grid_reads_the_shape_from_the_region():
    from meanfield import Grid

    assert Grid(Domain.box(2, 1), (8, 4)).is_box
    assert Grid(Domain.polygon([(0, 0), (2, 0), (2, 1), (0, 1)]), (8, 4)).is_box  # a rectangle is a rectangle
    disk = Grid(Domain.disk(1.0), (16, 16))
    assert not disk.is_box and disk.area == pytest.approx(math.pi, rel=1e-12)


def test_a_new_region_is_one_class_and_one_registration_line(tmp_path):
    """A region that is not a Domain: the scenario, the assembly and the loop take any Region."""
    from meanfield import load_scenario, plugins
    from meanfield.capabilities import RegionCapabilities

    class SquareRoom:
        """A square room of side ``side`` (its geometry delegated to a box)."""

        def __init__(self, side: float = 1.0):
            self.side = float(side)
            self._box = Domain.box(self.side, self.side)

        kind = "square-room"
        capabilities = RegionCapabilities()  # what it declares beyond the Region protocol: nothing

        def __getattr__(self, name):
            return getattr(self._box, name)

        def robot_region(self, margin):
            return self if margin <= 0 else self._box.robot_region(margin)

        def to_dict(self):
            return {"kind": "square-room", "side": self.side}

    plugins.register("region", "square-room", SquareRoom)
    try:
        import tomli_w

        table = _short(0.05).to_dict()
        table["domain"] = {"kind": "square-room", "side": 2.0}
        table["target"]["center"] = [1.8, 1.8]
        path = tmp_path / "square.toml"
        path.write_text(tomli_w.dumps(table))
        sc = load_scenario(path)  # [domain] kind = "square-room", side = 2.0
        assert isinstance(sc.domain, SquareRoom) and isinstance(sc.domain, Region)
        loop = ClosedLoop(sc)
        s = loop.run(progress=False).summary
        assert s["status"] == "completed" and s["scenario"]["domain"] == {"kind": "square-room", "side": 2.0}
        assert loop.grid.x[-1] > 1.9  # the grid spans the 2 m room
    finally:
        plugins.unregister("region", "square-room")


def test_an_interrupt_inside_a_frame_leaves_a_whole_dataset(monkeypatch):
    """Ctrl-C between two appends of a frame (the recorder's record_state) still gives a dataset."""
    from meanfield import ClosedLoop, paper_scenario
    from meanfield.simulation.observers import Recorder

    real = Recorder.record_state
    calls = {"n": 0}

    def cut_short(self):
        calls["n"] += 1
        if calls["n"] == 4:  # the fourth frame: half written, then the interrupt
            self.frames["time"].append(self.loop.t)
            self.frames["robot_x"].append(self.loop.robots.positions[:, 0].copy())
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(Recorder, "record_state", cut_short)
    result = ClosedLoop(paper_scenario(seed=0).replace(t_final=1.0)).run(progress=False)
    ds = result.dataset
    assert result.summary["status"] == "interrupted"
    assert ds.sizes["time"] == 4 and float(ds["time"][-1]) == result.summary["time_final"]  # 3 frames + the final state
    assert len({ds[v].sizes.get("time") for v in ds.data_vars if "time" in ds[v].dims}) == 1


def test_a_signal_during_a_run_stops_it_between_two_steps():
    import os
    import signal

    from meanfield import ClosedLoop, paper_scenario

    before = signal.getsignal(signal.SIGINT)

    def ctrl_c_after_the_fifth_step(loop):
        if loop.step_index == 5:
            os.kill(os.getpid(), signal.SIGINT)

    result = ClosedLoop(paper_scenario(seed=0).replace(t_final=1.0)).run(
        progress=False, callback=ctrl_c_after_the_fifth_step
    )
    assert result.summary["status"] == "interrupted" and result.summary["steps"] == 5
    assert result.dataset.sizes["time"] == 2  # the initial state and the state after step 5, whole
    assert signal.getsignal(signal.SIGINT) is before  # the handler is restored
