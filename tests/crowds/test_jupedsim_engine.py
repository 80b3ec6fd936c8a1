"""The JuPedSim backend: body placement, the adapter, steering targets, a short closed loop.

Tests that need JuPedSim are skipped when it is not installed; CI installs it (.ci/run),
so there they run.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from meanfield import Domain, ParameterError
from meanfield.crowds.jupedsim_engine import PEDESTRIAN_MODELS, JuPedSimOptions, max_body_overlap, place_bodies
from meanfield.scenarios.scenario import paper_unity_scenario


def _uniform(domain: Domain, seed: int = 0):
    rng = np.random.default_rng(seed)
    return lambda k: domain.sample_uniform(k, rng)


def test_placed_bodies_neither_overlap_nor_touch_the_walls():
    room = Domain.box(10.0, 6.0, (2.0, -1.0))
    pos = place_bodies(_uniform(room), 100, 0.25, room)  # 33 % of the room covered
    d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 0.5
    assert (pos[:, 0] >= 2.25).all() and (pos[:, 0] <= 11.75).all()
    assert (pos[:, 1] >= -0.75).all() and (pos[:, 1] <= 4.75).all()
    assert max_body_overlap(pos[:, 0], pos[:, 1], 0.25) == (0.0, -1)


def test_bodies_that_do_not_fit_the_initial_law_are_refused():
    room = Domain.box(3.0, 3.0)
    with pytest.raises(ParameterError) as info:
        place_bodies(_uniform(room), 60, 0.3, room)  # 60 disks of 0.3 m: 189 % of the 9 m² room
    assert info.value.name == "crowd.options.jupedsim.radius" and "could be placed" in str(info.value)


def test_max_body_overlap_measures_the_deepest_interpenetration():
    x = np.array([[0.0, 0.35, 5.0], [0.0, 0.45, 5.0]])
    y = np.zeros_like(x)
    depth, frame = max_body_overlap(x, y, 0.2)
    assert depth == pytest.approx(0.05) and frame == 0


def test_missing_jupedsim_is_refused_with_the_install_command(monkeypatch, capsys):
    from meanfield.cli.app import main

    monkeypatch.setitem(sys.modules, "jupedsim", None)  # import jupedsim -> ImportError
    code = main(["run", "paper-unity", "--crowd", "jupedsim", "--out", "/nonexistent/never-written"])
    err = capsys.readouterr().err
    assert code == 2
    assert "pip install --no-deps" in err and "jupedsim" in err


# ---------------------------------------------------------------------- with JuPedSim

from meanfield.crowds._jupedsim_api import JuPedSimAdapter  # noqa: E402
from meanfield.crowds.jupedsim_engine import JuPedSimEngine  # noqa: E402
from meanfield.simulation.loop import ClosedLoop  # noqa: E402


@pytest.mark.requires("jupedsim")
def test_a_free_agent_walks_straight_at_its_desired_speed():
    room = Domain.box(20.0, 20.0)
    ad = JuPedSimAdapter(room.to_shapely(), "collision-free-speed", 0.05)
    ad.add_agents(np.array([[5.0, 5.0]]), 0.2, 1.0)
    ad.steer(np.array([[15.0, 15.0]]), np.array([0.8]))
    ad.iterate(100)  # 5 s at 0.8 m/s along the diagonal: 4 m
    step = 4.0 / math.sqrt(2)
    np.testing.assert_allclose(ad.positions(), [[5.0 + step, 5.0 + step]], atol=1e-9)
    assert ad.elapsed_time == pytest.approx(5.0)


@pytest.mark.parametrize("model", PEDESTRIAN_MODELS)
@pytest.mark.requires("jupedsim")
def test_every_model_builds_and_walks_its_bodies(model):
    room = Domain.box(20.0, 20.0)
    pos = place_bodies(_uniform(room, 1), 20, 0.2, room)
    crowd = JuPedSimEngine(pos, room, 0.2, 1.2, 0.05, model=model, seed=1)
    v = np.tile([0.5, 0.0], (20, 1))
    for k in range(10):
        crowd.step(v, 0.25 * k, 0.25)
    moved = crowd.positions[:, 0] - pos[:, 0]
    assert np.isfinite(crowd.positions).all() and np.median(moved) > 0.5  # 2.5 s at 0.5 m/s east
    assert room.contains(crowd.positions[:, 0], crowd.positions[:, 1]).all()


@pytest.mark.requires("jupedsim")
def test_steering_targets_stay_in_the_walkable_area():
    room = Domain.box(10.0, 10.0)
    pos = np.array([[0.3, 5.0], [9.7, 9.7], [5.0, 5.0], [5.0, 0.25]])
    crowd = JuPedSimEngine(pos, room, 0.2, 1.34, 0.05)
    v = np.array([[-1.0, 0.0], [3.0, 3.0], [0.0, 0.0], [0.2, -1.0]])
    targets, speeds = crowd.steering_targets(v, 0.25)
    assert room.contains(targets[:, 0], targets[:, 1], tol=-1e-9).all()
    np.testing.assert_allclose(speeds, [1.0, 1.34, 0.0, math.hypot(0.2, 1.0)])
    for _ in range(20):  # JuPedSim raises on a target outside the walkable area
        crowd.step(v, 0.0, 0.25)


@pytest.mark.requires("jupedsim")
def test_a_body_outside_the_walkable_area_is_refused():
    room = Domain.box(10.0, 10.0)
    with pytest.raises(ParameterError) as info:
        JuPedSimEngine(np.array([[5.0, 5.0], [0.1, 5.0]]), room, 0.2, 1.34, 0.05)
    assert info.value.name == "crowd.positions[1]"


@pytest.mark.requires("jupedsim")
def test_short_closed_loop_run_with_bodies_and_view():
    sc = paper_unity_scenario(seed=1).with_values({"crowd.kind": "jupedsim", "t_final": 50.0})
    a = ClosedLoop(sc).run(progress=False)
    b = ClosedLoop(sc).run(progress=False)
    s = a.summary
    assert s["status"] == "completed" and s["backend"] == "jupedsim" and s["steps"] == 200
    # the collision-free speed model keeps bodies apart: no overlap beyond round-off
    assert s["body_overlap_max"] <= 1e-6 * JuPedSimOptions.of(sc).radius
    x, y = a.dataset["human_x"].values, a.dataset["human_y"].values
    assert ((x > 0) & (x < 150) & (y > 0) & (y < 150)).all()  # walls are soft in the model, but hold
    assert a.dataset["seen_fraction"].values.min() < 1.0  # somebody walked out of view
    np.testing.assert_array_equal(x, b.dataset["human_x"].values)  # same seed, same run


@pytest.mark.requires("jupedsim")
def test_the_adapters_per_agent_loops_restore_the_garbage_collector():
    import gc

    from meanfield.crowds._jupedsim_api import _collector_paused

    assert gc.isenabled()
    with _collector_paused():
        assert not gc.isenabled()
    assert gc.isenabled()  # restored
    gc.disable()
    try:
        with _collector_paused():
            pass
        assert not gc.isenabled()  # a caller's choice is kept
    finally:
        gc.enable()
    with pytest.raises(RuntimeError, match="inside"):
        with _collector_paused():
            raise RuntimeError("inside")
    assert gc.isenabled()  # restored after an error too
