"""Exits that absorb (issue 17, part): exact survival in a strip, mass accounted, agents leave once."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, FokkerPlanck, Grid, ParameterError, paper_scenario
from meanfield._compiled import core as compiled
from meanfield.crowds.jupedsim_engine import JuPedSimOptions
from meanfield.crowds.point_mass import PointMassEngine
from meanfield.geometry.exits import ExitSink, exit_segments, leaving

L, W, D = 1.0, 0.25, 0.1


def survival(t: float, terms: int = 400) -> float:
    """Pure diffusion on [0, L], closed at 0, absorbing at L, uniform start: the cosine series
    S(t) = Σ 8/((2n+1)²π²) exp(−((2n+1)π/(2L))² D t)."""
    n = np.arange(terms)
    k = (2 * n + 1) * math.pi / (2 * L)
    return float(np.sum(8 / ((2 * n + 1) ** 2 * math.pi**2) * np.exp(-(k**2) * D * t)))


STRIP = Domain.box(L, W, exits=[((L, 0.0), (L, W))])


def test_the_density_s_survival_is_the_cosine_series_and_its_mass_is_accounted():
    grid = Grid(STRIP, (64, 4))
    fp = FokkerPlanck(grid, D, time_dependent=False, exits=False)  # wired by hand below
    sink = ExitSink(grid, exit_segments(STRIP), D)
    rho = grid.normalize(np.ones(grid.shape))
    t, dt, out = 0.0, 2e-4, 0.0
    for target in (0.5, 1.0, 2.0):
        while t < target - 1e-12:
            rho = fp.step(rho, t, dt)
            rho, lost = sink.apply(rho, dt)
            out += lost.sum()
            t += dt
        # second-order space (h = 1/64) and first-order splitting in time: measured 1.1e-4 to 1.3e-4
        assert grid.integrate(rho) == pytest.approx(survival(target), rel=5e-4)
        assert grid.integrate(rho) + out == pytest.approx(1.0, abs=1e-11)  # in Ω + out = initial


def test_agents_survive_as_the_series_says_within_their_sampling_noise():
    rng = np.random.default_rng(1)
    n = 10_000
    x = np.column_stack([rng.uniform(0, L, n), rng.uniform(0, W, n)])
    crowd = PointMassEngine(x, STRIP, D, rng)
    t, dt = 0.0, 1e-3
    for target in (0.5, 1.0, 2.0):
        while t < target - 1e-12:
            crowd.step(np.zeros((n, 2)), t, dt)
            t += dt
        s = survival(target)
        z = (crowd.remaining() / n - s) / math.sqrt(s * (1 - s) / n)
        assert abs(z) < 4, (target, z)
    gone = ~crowd.active
    assert np.isnan(crowd.positions[gone]).all() and np.isfinite(crowd.positions[~gone]).all()
    assert (crowd.exit_index[gone] == 0).all() and (crowd.exit_time[gone] <= t + 1e-12).all()
    assert STRIP.contains(*crowd.positions[~gone].T).all()


def test_a_step_through_an_exit_leaves_and_a_step_near_it_may():
    segs = exit_segments(STRIP)
    rng = np.random.default_rng(0)
    start = np.array([[0.9, 0.1], [0.5, 0.1], [0.999, 0.1]])
    end = np.array([[1.1, 0.1], [0.6, 0.1], [0.999, 0.1]])
    who = leaving(start, end, segs, sigma=0.0, dt=0.01, rng=rng)
    np.testing.assert_array_equal(who, [0, -1, -1])  # without noise only a crossing leaves
    # with noise, a human 1 mm from the exit at both ends leaves with probability exp(-d0 d1/(σ dt))
    many = np.tile([[0.999, 0.1]], (20_000, 1))
    left = leaving(many, many, segs, sigma=D, dt=0.01, rng=rng)
    p = math.exp(-(0.001**2) / (D * 0.01))
    assert abs((left == 0).mean() - p) < 4 * math.sqrt(p * (1 - p) / 20_000)


def test_the_closed_loop_evacuates_through_a_door_on_agents_and_on_the_density():
    room = Domain.box(1.0, 1.0, exits=[((1.0, 0.8), (1.0, 1.0))])
    sc = paper_scenario(seed=0).replace(domain=room, t_final=5.0)
    agents = ClosedLoop(sc).run(progress=False)
    s = agents.summary
    assert s["status"] == "completed" and 0 < s["fraction_evacuated"] <= 1
    assert s["evacuated_per_exit"] == [round(s["fraction_evacuated"] * 200)]
    out = agents.dataset["fraction_evacuated"].values
    assert out[0] == 0 and np.all(np.diff(out) >= 0) and out[-1] == pytest.approx(s["fraction_evacuated"])
    pde = ClosedLoop(sc, crowd="fokker-planck").run(progress=False).summary
    assert pde["mass_final"] + pde["fraction_evacuated"] == pytest.approx(1.0, abs=1e-11)


@pytest.mark.requires("jupedsim")
def test_jupedsim_bodies_leave_through_a_door_in_the_closed_loop():
    from meanfield import load_scenario

    sc = load_scenario("paper-unity")
    side = sc.domain.bounds[1]
    room = Domain.box(side, side, exits=[((side, 0.0), (side, 10.0))])
    sc = sc.replace(domain=room).with_values({"crowd.kind": "jupedsim", "t_final": 40.0, "record_every": 1})

    def to_the_door(x, y, t):  # a disturbance towards the door (150 m, 5 m) at walking speed
        dx, dy = side - x, 5.0 - y
        d = np.maximum(np.hypot(dx, dy), 1e-9)
        return 1.34 * dx / d, 1.34 * dy / d

    a = ClosedLoop(sc, disturbance=to_the_door).run(progress=False)
    b = ClosedLoop(sc, disturbance=to_the_door).run(progress=False)
    s, n = a.summary, sc.crowd.n
    assert s["status"] == "completed" and s["backend"] == "jupedsim"
    left = round(s["fraction_evacuated"] * n)
    assert left > 0 and s["evacuated_per_exit"] == [left] and s["last_exit_time"] <= 40.0
    out = a.dataset["fraction_evacuated"].values
    here = np.isfinite(a.dataset["human_x"].values).sum(axis=1)
    assert out[0] == 0 and np.all(np.diff(out) >= 0) and out[-1] == pytest.approx(s["fraction_evacuated"])
    np.testing.assert_array_equal(here + np.round(out * n), n)  # at every step: remaining + left = N
    assert s["body_overlap_max"] <= 1e-6 * JuPedSimOptions.of(sc).radius
    np.testing.assert_array_equal(a.dataset["human_x"].values, b.dataset["human_x"].values)  # same seed, same run
    assert b.summary["evacuated_per_exit"] == s["evacuated_per_exit"]


def test_a_plan_with_a_door_evacuates_and_refuses_a_door_off_its_walls():
    from meanfield.geometry.plan import Plan

    plan = Plan(Plan.from_wkt("POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0))").polygon, [((1, 0.1), (1, 0.3))])
    assert [p.kind for p in plan.boundary_parts()].count("exit") == 1
    sc = paper_scenario(seed=1).replace(domain=plan, t_final=3.0).with_values({"target.center": [0.9, 0.2]})
    s = ClosedLoop(sc).run(progress=False).summary
    assert s["fraction_evacuated"] > 0
    with pytest.raises(ParameterError) as exc:
        Plan(plan.polygon, [((0.5, 0.1), (0.6, 0.1))])  # inside the room, not on a wall
    assert exc.value.name == "exits[0]"


@pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")
def test_the_compiled_exit_passes_match_their_numpy_twins():
    from meanfield.geometry._exit_loops import bridge_exits, first_exit_crossed

    rng = np.random.default_rng(5)
    segs = np.array(
        [[[1.0, 0.2], [1.0, 0.4]], [[0.3, 1.0], [0.6, 1.0]], [[1.0, 0.4], [1.0, 0.5]], [[0.0, 0.0], [0.0, 0.3]]]
    )
    start = rng.uniform(-0.05, 1.05, (4000, 2))
    end = start + rng.normal(0, 0.08, (4000, 2))
    end[:10] = start[:10]  # steps of length 0 cross nothing
    start[10], end[10] = (0.9, 0.4), (1.1, 0.4)  # through the end point exits 0 and 2 share
    fast = first_exit_crossed(start, end, segs, np.full(4000, -1, np.intp))
    assert first_exit_crossed._ready
    with compiled.numpy_path():
        ref = first_exit_crossed(start, end, segs, np.full(4000, -1, np.intp))
    np.testing.assert_array_equal(fast, ref)
    assert 100 < np.count_nonzero(ref >= 0) < 3990 and ref[10] in (0, 2) and (ref[:10] == -1).all()
    near = np.flatnonzero(ref < 0)
    draws = rng.random(len(near))
    fast = bridge_exits(start, end, segs, near, draws, 0.05 * 0.01, ref.copy())
    with compiled.numpy_path():
        slow = bridge_exits(start, end, segs, near, draws, 0.05 * 0.01, ref.copy())
    np.testing.assert_array_equal(fast, slow)
    assert np.count_nonzero(slow != ref) > 10  # the bridge test took some who crossed nothing
