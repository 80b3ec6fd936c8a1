"""Local view (Unity study): view gating, the persistent random walk, the paper-unity scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, ParameterError, Scenario, paper_scenario
from meanfield.crowds.local_view import LocalView, robots_in_view
from meanfield.scenarios.scenario import paper_unity_scenario
from meanfield.simulation.loop import ClosedLoop


def _err(call) -> ParameterError:
    with pytest.raises(ParameterError) as info:
        call()
    return info.value


def test_robots_in_view_is_the_disk_of_the_view_radius():
    robots = np.array([[0.0, 0.0], [10.0, 0.0]])
    humans = np.array([[3.0, 4.0 - 1e-9], [3.0, 4.0 + 1e-9], [10.0, 5.0], [10.0, 5.0 + 1e-9], [5.0, 0.0]])
    assert robots_in_view(humans, robots, 5.0).tolist() == [True, False, True, False, True]
    assert robots_in_view(humans, robots, math.inf).all()


@pytest.mark.parametrize("radius", [0.003, 0.04, 0.3, 5.0])
def test_cell_classification_equals_the_pairwise_test(radius):
    """Large crowds skip the pairs in whole-seen and whole-unseen cells: same mask, exactly,
    including humans placed on the view circles and on the cells' edges."""
    from meanfield.crowds.local_view import _in_view_direct

    rng = np.random.default_rng(11)
    robots = rng.uniform(0.0, 1.0, (40, 2))
    humans = rng.uniform(0.0, 1.0, (30_000, 2))
    angle = rng.uniform(0, 2 * np.pi, 400)
    circle = robots[np.arange(400) % 40]
    on_circle = circle + radius * np.column_stack([np.cos(angle), np.sin(angle)])
    humans = np.vstack([humans, on_circle, np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]])])
    assert len(humans) * len(robots) > 200_000  # the classified path, not the fallback
    np.testing.assert_array_equal(robots_in_view(humans, robots, radius), _in_view_direct(humans, robots, radius))


def test_heading_correlation_decays_as_exp_minus_turning_rate_t():
    # E[cos(θ(t) − θ(0))] = exp(−D_r t) exactly for dθ = sqrt(2 D_r) dW (Gaussian increments)
    n, d_r, dt, steps = 40_000, 0.25, 0.1, 40
    view = LocalView(n, 1.0, 1.0, d_r, Domain.box(1.0, 1.0), np.random.default_rng(3))
    theta0 = view.headings.copy()
    for _ in range(steps):
        view.advance(dt)
    c = np.cos(view.headings - theta0)
    expected = math.exp(-d_r * dt * steps)
    assert abs(c.mean() - expected) < 4 * c.std() / math.sqrt(n)


def test_walker_turns_specularly_at_a_wall():
    view = LocalView(2, 0.1, 0.5, 0.0, Domain.box(1.0, 1.0), np.random.default_rng(0))
    view.headings[:] = [0.0, math.pi / 4]  # into the right wall; diagonally into the top-right corner
    pos = np.array([[0.99, 0.5], [0.99, 0.99]])
    v = view.walk_velocity(pos, dt=0.1)
    np.testing.assert_allclose(v[0], [-0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(v[1], [-0.5 / math.sqrt(2), -0.5 / math.sqrt(2)], atol=1e-12)
    np.testing.assert_allclose(view.headings, [math.pi, -3 * math.pi / 4], atol=1e-12)


def test_gate_replaces_only_the_humans_who_see_no_robot():
    view = LocalView(3, 0.2, 0.3, 0.0, Domain.box(1.0, 1.0), np.random.default_rng(1))
    view.headings[:] = [0.0, math.pi / 2, math.pi]
    pos = np.array([[0.5, 0.5], [0.1, 0.1], [0.9, 0.5]])
    v_r = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    view.gate(v_r, pos, np.array([[0.55, 0.5]]), dt=0.01)
    assert view.seen.tolist() == [True, False, False]
    np.testing.assert_allclose(v_r, [[1.0, 2.0], [0.0, 0.3], [-0.3, 0.0]], atol=1e-12)


def test_no_gating_draws_nothing_and_changes_nothing():
    view = LocalView(4, None, 1.0, 1.0, Domain.box(1.0, 1.0), np.random.default_rng(0))
    v_r = np.ones((4, 2))
    assert view.gate(v_r, np.full((4, 2), 0.5), np.array([[5.0, 5.0]]), 0.1) is v_r
    assert (v_r == 1).all() and view.seen.all()


@pytest.mark.parametrize(
    ("key", "value", "named"),
    [
        ("view.radius", 0.0, "view.radius"),
        ("view.radius", -30.0, "view.radius"),
        ("view.walk_speed", -1.0, "view.walk_speed"),
        ("view.turning_rate", -0.1, "view.turning_rate"),
        ("crowd.kind", "unity", "crowd.kind"),
        ("crowd.options.jupedsim.model", "magic", "crowd.options.jupedsim.model"),
        ("crowd.options.jupedsim.radius", 0.0, "crowd.options.jupedsim.radius"),
        ("crowd.options.jupedsim.time_step", 0.1, "crowd.options.jupedsim.time_step"),  # 0.25 is not a whole number
    ],
)
def test_bad_view_and_pedestrian_values_are_refused_naming_the_field(key, value, named):
    sc = paper_unity_scenario().with_values({"crowd.kind": "jupedsim"})
    err = _err(lambda: sc.with_values({key: value}))
    assert err.name == named


def test_bodies_that_cannot_fit_are_refused_before_the_run():
    sc = paper_unity_scenario().with_values({"crowd.kind": "jupedsim"})
    err = _err(lambda: sc.with_values({"crowd.options.jupedsim.radius": 5.0}))  # 200 disks of 5 m: 70 % of the room
    assert err.name == "crowd.options.jupedsim.radius" and "half of the room" in str(err)


def test_paper_unity_round_trips_through_toml():
    sc = paper_unity_scenario(seed=3)
    assert Scenario.from_toml(sc.to_toml()).to_dict() == sc.to_dict()
    assert sc.view.radius == 30.0 and sc.domain.bounds == (0.0, 150.0, 0.0, 150.0)
    assert sc.crowd.n == 200 and sc.robots.n == 16 and sc.target.center == (150.0, 150.0)


def test_paper_unity_carries_the_paper_scenario_by_similarity_up_to_the_robot_law():
    # paper-unity is paper under x -> L x, t -> T t (σ aside).  With σ scaled too and no
    # gating, everything up to the Step-I law must scale exactly: the crowd, the KDE density
    # (1/L²), the desired velocity v_d and the velocity error ṽ (L/T).  The robot law does
    # not: V₂ = ∫ρ̃²/2 + ∫|ṽ|²/2 adds terms that scale as 1/L² and L⁴/T² (asserted below),
    # so the backstepping inputs depend on the unit of length (docs/findings.md).
    from meanfield.scenarios.scenario import UNITY_LENGTH as L
    from meanfield.scenarios.scenario import UNITY_TIME as T

    base = paper_scenario(seed=5)
    unity = paper_unity_scenario(seed=5).with_values(
        {"view.radius": "none", "crowd.sigma": base.crowd.sigma * L * L / T}
    )
    a, b = ClosedLoop(base), ClosedLoop(unity)
    np.testing.assert_allclose(b.crowd.positions / L, a.crowd.positions, rtol=0, atol=1e-14)
    np.testing.assert_allclose(b.density * L * L, a.density, rtol=1e-10, atol=1e-12)
    sa, sb = a.controller.act(a.observe()).state, b.controller.act(b.observe()).state
    for k in (0, 1):  # x and y faces
        for field in ("v_d", "v_tilde"):
            fa, fb = getattr(sa, field)[k], getattr(sb, field)[k]
            np.testing.assert_allclose(fb * T / L, fa, rtol=1e-9, atol=1e-9 * np.abs(fa).max())
    ga, gb = a.grid, b.grid
    assert gb.norm(sb.rho_tilde) ** 2 == pytest.approx(ga.norm(sa.rho_tilde) ** 2 / L**2, rel=1e-10)
    assert gb.face_norm(sb.v_tilde) ** 2 == pytest.approx(ga.face_norm(sa.v_tilde) ** 2 * L**4 / T**2, rel=1e-9)
    assert np.abs(sb.u * T / L - sa.u).max() > 0.1 * np.abs(sa.u).max()  # the law is not similar


def test_point_mass_gating_changes_only_the_walkers():
    # (uncongested: a congested walker is slowed by its door model, by the forward cell's g(1/(4 R²)) = 0.995 alone)
    values = {"view.radius": 12.0, "crowd.congestion": "none"}
    sc = paper_unity_scenario(seed=2).replace(t_final=2.5).with_values(values)
    loop = ClosedLoop(sc)
    drift = loop.crowd.drift(loop.robots, loop.t, loop.dt)
    seen = loop.crowd.view.seen
    assert 0 < seen.sum() < len(seen)  # a 12 m view on the 37.5 m robot lattice leaves gaps
    np.testing.assert_allclose(np.hypot(*drift[~seen].T), sc.view.walk_speed, rtol=1e-12)
    result = loop.run(progress=False)
    assert result.summary["backend"] == "point-mass" and result.summary["view_radius"] == 12.0
    assert 0 < result.dataset["seen_fraction"].values[0] < 1
