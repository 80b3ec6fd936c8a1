"""Congestion for the agents (meanfield.crowds.agent_crowd, meanfield.crowds._congestion_loops).

* :func:`neighbour_density` (the cell list, compiled) equals its numpy twin and a direct count
  over every pair, to the last bit (the counts are integers), with humans who left (NaN rows, or
  stand-ins) ignored, for crowds from 0 to 2000 humans, radii from a tenth of a crowd's spacing
  to the whole room, and a crowd far wider than the radius (the lattice's cap); the order it
  keeps between calls stays a permutation and changes no number, whoever leaves;
* :func:`local_density` is persons/m²: 0 alone, ``k / (π r²)`` with ``k`` neighbours, and beside
  a wall ``k / (π r² s)`` with ``s`` the disk's share in Ω: a uniform crowd's density is seen as
  it is up to the wall (half of it without the share);
* the directed pass counts the others ahead of each human and the excluded volume's push as a direct
  sum over every pair does (the pushes add up to nothing; a pair alone moves apart by half its overlap);
* with ``crowd.congestion = "none"`` nothing changes: no density is computed, the summary has
  the same keys; with a diagram each human's chosen velocity is multiplied by ``g(ρ_j)`` (``crowd.door_model =
  "count"``), or it walks the Godunov twin's speed (G1), ``min(D(ρ⁻), S(ρ⁺))/(v₀ ρ⁻)`` (exact values), plus the
  push without its part along the walk (``"godunov-twin"``); the density and the bodies refuse the twin;
* the run is deterministic for a seed, and the congested crowd leaves the bottleneck far slower;
* the refusals: congestion outside SI units names ``crowd.congestion``; ``crowd.rho_max <= 0``
  and ``crowd.free_speed <= 0`` name their fields.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield._compiled import core as compiled
from meanfield.crowds._congestion_loops import DensityWork, neighbour_density
from meanfield.crowds.agent_crowd import AgentCrowd
from meanfield.crowds.congestion import GodunovTwin, Linear, NoCongestion, Weidmann
from meanfield.crowds.local_density import DENSITY_RADIUS, SHARE_FLOOR, LocalDensity, local_density
from meanfield.errors import ParameterError
from meanfield.geometry.disk_share import disk_share
from meanfield.geometry.domain import Domain
from meanfield.scenarios.scenario import builtin_scenarios
from meanfield.simulation.loop import ClosedLoop

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")


def direct_counts(x: np.ndarray, active: np.ndarray, radius: float) -> np.ndarray:
    """Every pair compared, the reference of the cell list."""
    ok = active & np.isfinite(x).all(axis=1)
    dx = x[:, None, 0] - x[None, :, 0]
    dy = x[:, None, 1] - x[None, :, 1]
    with np.errstate(invalid="ignore"):
        near = (dx * dx + dy * dy < radius * radius) & ok[:, None] & ok[None, :]
    np.fill_diagonal(near, False)
    return np.where(ok, near.sum(axis=1), 0)


def crowd(n: int, rng: np.random.Generator, width: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    x = rng.uniform(0.0, width, size=(n, 2))
    active = rng.random(n) > 0.1
    x[~active & (rng.random(n) > 0.5)] = np.nan  # some who left are NaN, the others stand somewhere
    if n >= 4:
        x[1] = x[0]  # two at the same point
        x[2] = x[0] + [DENSITY_RADIUS, 0.0]  # one exactly at the radius: not a neighbour
        active[:3] = True
    return x, active


def counted(x, active, radius, work=None):
    """``neighbour_density`` without walls, times ``π r²``: the counts (exact: an integer times 1/(π r²) and back)."""
    n = len(x)
    work = DensityWork(n) if work is None else work
    out = np.full(n, -1.0)
    inv = 1.0 / (math.pi * radius * radius)
    neighbour_density(
        x, active, radius, inv, np.ones((2, 2)), 0.0, 0.0, 1.0, SHARE_FLOOR, False, np.zeros((1, 2)), False,
        0.0, *work.arrays(), out, np.empty(1), np.empty((1, 2)),
    )  # fmt: skip
    return np.rint(out / inv).astype(np.int64), out


def directed(x, active, e, radius, spacing):
    """``neighbour_density`` with directions: the densities, ahead, and the push (walls ignored)."""
    n = len(x)
    out, ahead, push = np.full(n, -1.0), np.full(n, -1.0), np.full((n, 2), -1.0)
    inv = 1.0 / (math.pi * radius * radius)
    neighbour_density(
        x, active, radius, inv, np.ones((2, 2)), 0.0, 0.0, 1.0, SHARE_FLOOR, False, e, True,
        spacing, *DensityWork(n).arrays(), out, ahead, push,
    )  # fmt: skip
    return out, ahead, push


def direct_ahead_and_push(x, active, e, radius, spacing):
    """Every pair compared: the others within ``radius`` ahead of each, and the push of those closer than
    ``spacing`` (each pair apart by half its overlap)."""
    ok = active & np.isfinite(x).all(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        dx = x[None, :, 0] - x[:, None, 0]  # X_k − X_j
        dy = x[None, :, 1] - x[:, None, 1]
        d2 = dx * dx + dy * dy
        pair = ok[:, None] & ok[None, :] & ~np.eye(len(x), dtype=bool)
        near = pair & (d2 < radius * radius)
        front = near & (dx * e[:, None, 0] + dy * e[:, None, 1] > 0)
        close = near & (d2 < spacing * spacing) & (d2 > 0)
        dist = np.sqrt(np.where(close, d2, 1.0))
        w = np.where(close, (spacing - dist) / (2 * dist), 0.0)
    push = -np.stack([(w * np.where(close, dx, 0)).sum(1), (w * np.where(close, dy, 0)).sum(1)], axis=1)
    return np.where(ok, front.sum(1), 0), np.where(ok[:, None], push, 0.0)


@pytest.mark.parametrize("n", [2, 7, 300, 1500])
def test_the_density_ahead_and_the_push_are_every_pair_s(n):
    """The directed pass: the count ahead is the direct one (integers, to the bit), the push the direct sum to
    round-off, compiled and numpy alike; the pushes add up to nothing (each pair's two are opposite); a pair
    alone at ``δ < d`` is moved apart by ``(d − δ)/2`` each, along its line."""
    rng = np.random.default_rng(n)
    x, active = crowd(n, rng, width=6.0)
    e = rng.normal(size=(n, 2))
    e[rng.random(n) < 0.1] = 0.0  # some with no direction: nobody ahead of them
    spacing = 0.46
    ahead_ref, push_ref = direct_ahead_and_push(x, active, e, DENSITY_RADIUS, spacing)
    inv = 1.0 / (math.pi * DENSITY_RADIUS**2)
    for path in ("compiled", "numpy"):
        if path == "numpy":
            with compiled.numpy_path():
                out, ahead, push = directed(x, active, e, DENSITY_RADIUS, spacing)
        else:
            out, ahead, push = directed(x, active, e, DENSITY_RADIUS, spacing)
        assert np.array_equal(out, direct_counts(x, active, DENSITY_RADIUS) * inv)
        assert np.array_equal(ahead, ahead_ref * (2 * inv))
        np.testing.assert_allclose(push, push_ref, rtol=0, atol=1e-13)
        np.testing.assert_allclose(push[active].sum(axis=0), 0.0, atol=1e-12)
    pair = np.array([[1.0, 1.0], [1.3, 1.4]])  # 0.5 apart
    _, _, push = directed(pair, np.ones(2, bool), np.zeros((2, 2)), 1.0, 0.8)
    np.testing.assert_allclose(push, [[-0.09, -0.12], [0.09, 0.12]], rtol=1e-12)  # (0.8 − 0.5)/2 along (0.6, 0.8)


@pytest.mark.parametrize("n", [0, 1, 2, 7, 300, 2000])
@pytest.mark.parametrize("radius", [0.05, DENSITY_RADIUS, 3.0, 50.0])
def test_cell_list_counts_every_pair_within_the_radius(n, radius):
    rng = np.random.default_rng(n)
    x, active = crowd(n, rng)
    counts, out = counted(x, active, radius)
    assert np.array_equal(counts, direct_counts(x, active, radius))
    assert np.array_equal(out, direct_counts(x, active, radius) * (1.0 / (math.pi * radius * radius)))
    with compiled.numpy_path():
        _, ref = counted(x, active, radius)
    assert np.array_equal(ref, out)


@needs_numba
def test_compiled_count_equals_numpy_twin_on_a_spread_crowd():
    """A crowd 1000 radii wide: the lattice's cells grow (at most 4 per human), the counts do not change."""
    rng = np.random.default_rng(5)
    x = np.vstack([rng.uniform(0, 600.0, size=(400, 2)), rng.normal(300.0, 0.5, size=(400, 2))])
    active = np.ones(len(x), dtype=bool)
    fast, _ = counted(x, active, DENSITY_RADIUS)
    with compiled.numpy_path():
        ref, _ = counted(x, active, DENSITY_RADIUS)
    assert np.array_equal(fast, ref)
    assert np.array_equal(fast, direct_counts(x, active, DENSITY_RADIUS))


def test_the_order_kept_between_calls_changes_no_number():
    """A crowd that walks and leaves: at every call the counts are the direct ones, ``order`` and ``slot``
    stay inverse permutations, and the active humans come first in ``order``, in cell order."""
    rng = np.random.default_rng(11)
    n = 1500
    x = rng.uniform(0.0, 12.0, size=(n, 2))
    active = np.ones(n, dtype=bool)
    work = DensityWork(n)
    for step in range(12):
        x += rng.normal(0.0, 0.2, size=(n, 2))
        active &= rng.random(n) > 0.05 * (step % 3)  # some leave at some steps
        if step == 7:
            active[:] = True  # and a call with everyone back changes nothing either
        counts, _ = counted(x, active, DENSITY_RADIUS, work)
        assert np.array_equal(counts, direct_counts(x, active, DENSITY_RADIUS))
        assert np.array_equal(np.sort(work.order), np.arange(n))
        assert np.array_equal(work.slot[work.order], np.arange(n))
        if compiled.enabled():  # (the numpy twin keeps no order)
            assert set(work.order[: active.sum()]) == set(np.flatnonzero(active))


def test_a_uniform_crowd_is_seen_at_its_density_up_to_the_walls():
    """``n`` people drawn uniformly in a 10 m × 8 m room: the others lie in ``B(x, r) ∩ Ω`` with
    probability ``|B ∩ Ω| / |Ω|`` each, so the clipped density has the mean ``(n − 1)/|Ω|`` at every
    point, at the wall as in the middle, and the whole disk's has ``s(x) (n − 1)/|Ω|``: about 0.6
    of it within 0.3 m of a wall.  40 rooms of 160 (2 persons/m²), pooled."""
    room = Domain.box(10.0, 8.0)
    rng = np.random.default_rng(0)
    n, rooms = 160, 40
    x = np.concatenate([room.sample_uniform(n, rng) for _ in range(rooms)])
    clipped = np.concatenate([local_density(x[i * n : (i + 1) * n], None, DENSITY_RADIUS, room) for i in range(rooms)])
    whole = np.concatenate([local_density(x[i * n : (i + 1) * n], None, DENSITY_RADIUS) for i in range(rooms)])
    exact = (n - 1) / 80.0
    d = np.minimum.reduce([x[:, 0], 10.0 - x[:, 0], x[:, 1], 8.0 - x[:, 1]])
    near, middle = d < DENSITY_RADIUS / 2, d > DENSITY_RADIUS + 0.2  # (the table's cells read beside one: 0.075 m)
    assert near.sum() > 500 and middle.sum() > 2000
    assert clipped[near].mean() == pytest.approx(exact, rel=0.1)  # about 3 % statistical error
    assert clipped[middle].mean() == pytest.approx(exact, rel=0.1)
    assert whole[near].mean() < 0.75 * exact
    assert np.array_equal(clipped[middle], whole[middle])  # away from the walls the share is 1 exactly


def test_the_share_divides_the_count_and_is_floored():
    """``ρ_j = k / (π r² max(s, s_min))``, ``s`` read from the table at the human; the twins agree to the bit."""
    room = Domain.polygon([(0.0, 0.0), (10.0, 0.0), (2.0, 0.4)])  # an acute corner at the origin: s < s_min there
    share = disk_share(room, DENSITY_RADIUS)
    rng = np.random.default_rng(3)
    x = room.sample_uniform(400, rng)
    x[0] = (0.02, 0.002)  # deep in the acute corner
    rho = LocalDensity(len(x), DENSITY_RADIUS, room)(x)
    k = direct_counts(x, np.ones(len(x), bool), DENSITY_RADIUS)
    s = share.at(x)
    assert s[0] < SHARE_FLOOR
    assert np.array_equal(rho, k * (1.0 / (math.pi * DENSITY_RADIUS**2)) / np.maximum(s, SHARE_FLOOR))
    with compiled.numpy_path():
        assert np.array_equal(LocalDensity(len(x), DENSITY_RADIUS, room)(x), rho)


def test_local_density_refuses_a_crowd_of_another_size():
    with pytest.raises(ParameterError, match="positions"):
        LocalDensity(5)(np.zeros((4, 2)))


def test_local_density_is_persons_per_square_metre():
    r = 0.5
    x = np.array([[0.0, 0.0], [0.3, 0.0], [0.0, 0.3], [5.0, 5.0], [np.nan, np.nan]])
    active = np.array([True, True, True, True, False])
    rho = local_density(x, active, r)
    area = math.pi * r * r
    assert rho[3] == 0.0 and rho[4] == 0.0  # alone; gone
    assert rho[0] == pytest.approx(2 / area) and rho[1] == pytest.approx(2 / area)  # |(0.3,0)-(0,0.3)| = 0.42 < r
    assert local_density(x[:4])[3] == 0.0  # everyone active by default
    with pytest.raises(ParameterError):
        local_density(x, active, 0.0)


def bottleneck(congestion: str = "none", b: float = 1.0, **values):
    lo, hi = 4.0 - b / 2, 4.0 + b / 2
    return builtin_scenarios()["bottleneck"](seed=3).with_values(
        {
            "domain.wkt": f"POLYGON ((0 0, 10 0, 10 {lo:g}, 12 {lo:g}, 12 {hi:g}, 10 {hi:g}, 10 8, 0 8, 0 0))",
            "domain.exits": [[[12.0, lo], [12.0, hi]]],
            "crowd.congestion": congestion,
            **values,
        }
    )


def test_no_congestion_computes_nothing_and_keeps_the_summary():
    loop = ClosedLoop(bottleneck("none", t_final=1.0))
    assert loop.crowd.congestion is None
    loop.run(progress=False)
    assert loop.crowd.local_density is None
    assert "peak_local_density" not in loop.crowd.summary()
    c = loop.crowd
    assert AgentCrowd(c.engine, c.kernel, c.kde, c.view, congestion=NoCongestion()).congestion is None


def test_the_twin_s_speed_is_the_godunov_flux_over_the_density_behind():
    """(G1) with the linear diagram (``v₀`` = 1.34 m/s, ``ρ_max`` = 5.4, ``ρ_c`` = 2.7, ``q_max`` = 1.809): an even
    crowd walks at ``g(ρ)``; the head of a queue with room in front of it at ``q_max / (v₀ ρ⁻)``; nobody walks into
    the jam; someone with nobody behind it walks free unless the room ahead is short, then at the supply's pace."""
    twin = GodunovTwin(Linear(free_speed=1.34, rho_max=5.4))
    q_max = 1.34 * 5.4 / 4
    assert (twin.q_max, twin.rho_c) == pytest.approx((q_max, 2.7), rel=1e-12)
    assert twin.jam_spacing == pytest.approx(math.sqrt(2 / (math.sqrt(3) * 5.4)), rel=1e-12)  # 0.463 m
    even = np.array([0.0, 1.0, 2.7, 4.0, 5.4])
    np.testing.assert_allclose(twin.speed_factor(even, even), 1 - even / 5.4, rtol=1e-12, atol=1e-15)
    behind, ahead = np.array([5.0, 4.0, 1.0, 0.0, 0.0, 3.0]), np.array([0.0, 2.7, 5.4, 0.0, 5.4, 5.0])
    s_ahead = 5.0 * 1.34 * (1 - 5.0 / 5.4)  # S(5) = q(5): what room at 5 persons/m² takes
    expected = [q_max / (1.34 * 5.0), q_max / (1.34 * 4.0), 0.0, 1.0, 0.0, s_ahead / (1.34 * 3.0)]
    np.testing.assert_allclose(twin.speed_factor(behind, ahead), expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("name, diagram", [("weidmann", Weidmann()), ("linear", Linear())])
def test_congestion_multiplies_the_chosen_velocity_by_g(name, diagram):
    loop = ClosedLoop(bottleneck(name, t_final=1.0, **{"crowd.door_model": "count"}))
    crowd = loop.crowd
    assert crowd.congestion == diagram
    x = crowd.positions.copy()
    chosen = crowd.guidance.velocity(x, 0.0, 0.05).copy()
    drift = crowd.drift(loop.robots, 0.0, 0.05).copy()
    rho = local_density(x, crowd.engine.active, DENSITY_RADIUS, loop.scenario.domain)  # the disk cut by the walls
    assert np.array_equal(crowd.local_density, rho)
    assert np.any(rho > local_density(x, crowd.engine.active, DENSITY_RADIUS))
    assert np.allclose(drift, chosen * diagram.speed_factor(rho)[:, None], rtol=0, atol=1e-15)
    assert rho.max() > 0 and np.all(np.hypot(*drift.T) <= 1.34 + 1e-12)
    assert crowd.peak_local_density == rho.max()


@pytest.mark.parametrize("name, diagram", [("weidmann", Weidmann()), ("linear", Linear())])
def test_a_congested_human_walks_the_twin_s_speed_and_is_pushed_aside_but_only_braked_along_its_walk(name, diagram):
    loop = ClosedLoop(bottleneck(name, t_final=1.0, **{"crowd.door_model": "godunov-twin"}))
    crowd = loop.crowd
    assert crowd.congestion == diagram
    x = crowd.positions.copy()
    chosen = crowd.guidance.velocity(x, 0.0, 0.05).copy()
    drift = crowd.drift(loop.robots, 0.0, 0.05).copy()
    e = chosen / np.hypot(*chosen.T)[:, None]
    twin = GodunovTwin(diagram)
    density = LocalDensity(len(x), DENSITY_RADIUS, loop.scenario.domain)
    rho, behind, ahead, push = density.here_and_ahead(x, e, crowd.engine.active, twin.jam_spacing)
    assert np.array_equal(crowd.local_density, rho)
    assert np.array_equal(rho, local_density(x, crowd.engine.active, DENSITY_RADIUS, loop.scenario.domain))
    walk = chosen * twin.speed_factor(behind, ahead)[:, None]
    along = (push * e).sum(1)
    aside = push - along[:, None] * e
    brake = np.minimum(np.maximum(-along, 0.0) / 0.05, (walk * e).sum(1))
    np.testing.assert_allclose(drift, walk - brake[:, None] * e + aside / 0.05, rtol=0, atol=1e-12)
    forward = (drift * e).sum(1)
    assert (brake > 0).any() and (np.hypot(*aside.T) > 0).any()  # the bottleneck's start has pairs too close
    assert np.all(forward >= -1e-12) and np.all(forward <= (walk * e).sum(1) + 1e-12)  # braked, never moved back
    assert crowd.peak_local_density == rho.max()


def test_the_halves_are_each_over_its_own_area_in_the_plan():
    """Beside a wall: a human walking into it has a whole half behind it; the density behind it is its count
    there over that half (not over half the disk's share, a quarter of it: twice the density); one walking along
    the wall has the same count behind as ahead and reads the same density in both halves."""
    room = builtin_scenarios()["rimea-9"](seed=0).domain  # 30 m × 20 m, the south wall at y = 0
    x = np.array([[10.0, 0.05], [10.0, 0.35], [10.3, 0.05], [9.7, 0.05]])  # 0 walks into the wall
    x = np.r_[x, x + [10.0, 0.0], [[15.0, 10.0], [15.2, 10.0]]]  # 4 walks along it; 8 in the middle
    e = np.zeros_like(x)
    e[0], e[4], e[8] = [0.0, -1.0], [1.0, 0.0], [1.0, 0.0]
    density = LocalDensity(len(x), DENSITY_RADIUS, room)
    rho, behind, ahead, _ = density.here_and_ahead(x, e)
    halves = density._half_share
    s, s_ahead, s_behind = halves.at(x[:1], e[:1])
    assert s_ahead[0] < 0.2 and s_behind[0] > 0.95  # the wall's smoothing over a lattice cell
    half_area = 0.5 * math.pi * DENSITY_RADIUS**2
    assert ahead[0] == 0.0
    assert behind[0] == pytest.approx(3 / (half_area * s_behind[0]), rel=1e-12)  # three behind, over a whole half
    assert rho[0] == pytest.approx(3 / (2 * half_area * s[0]), rel=1e-12)
    s, s_ahead, s_behind = halves.at(x[4:5], e[4:5])
    assert s_ahead[0] == pytest.approx(s[0], abs=0.01) and s_behind[0] == pytest.approx(s[0], abs=0.01)
    assert ahead[4] == pytest.approx(1 / (half_area * s_ahead[0]), rel=1e-12)  # one ahead, one behind, one aside
    assert behind[4] == pytest.approx(2 / (half_area * s_behind[0]), rel=1e-12)  # (at 90°: behind, (X−x)·e = 0)
    assert ahead[8] == pytest.approx(1 / half_area, rel=1e-12) and behind[8] == 0.0  # a whole disk: no table read


def test_congested_runs_are_deterministic_and_slower():
    def exits(congestion: str) -> np.ndarray:
        loop = ClosedLoop(bottleneck(congestion, t_final=12.0, **{"crowd.door_model": "count"}))
        result = loop.run(progress=False)
        if congestion != "none":
            assert result.summary["peak_local_density"] > 0 and result.summary["congestion_radius"] == DENSITY_RADIUS
        return loop.crowd.engine.exit_time.copy()

    a, b = exits("weidmann"), exits("weidmann")
    assert np.array_equal(a, b, equal_nan=True)
    free = exits("none")
    assert np.isfinite(free).sum() >= 150  # point masses pour out
    assert np.isfinite(a).sum() < 40  # Weidmann: about 1.3 persons/s through the 1 m door


def test_the_narrowest_door_is_resolved():
    """b = 0.8 m: the routes (0.1 m cells) reach the exit from every cell, and people leave."""
    loop = ClosedLoop(bottleneck("linear", b=0.8, t_final=6.0))
    loop.run(progress=False)
    assert np.isfinite(loop.crowd.engine.exit_time).sum() >= 3


def test_congestion_needs_si_units():
    with pytest.raises(ParameterError) as info:
        builtin_scenarios()["paper"](seed=0).with_values({"crowd.congestion": "weidmann"})
    assert info.value.name == "crowd.congestion"
    assert builtin_scenarios()["paper"](seed=0).with_values({"crowd.congestion": "none"}).units == "dimensionless"


@pytest.mark.parametrize("key", ["crowd.rho_max", "crowd.free_speed"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_jam_density_and_free_speed_must_be_positive(key, value):
    with pytest.raises(ParameterError) as info:
        bottleneck("weidmann", **{key: value})
    assert info.value.name == key


def test_the_local_density_radius_is_a_scenario_field():
    """``crowd.congestion_radius`` reaches the crowd; a radius <= 0 is refused naming it."""
    from meanfield.simulation.loop import ClosedLoop

    sc = builtin_scenarios()["bottleneck"](seed=0).with_values({"crowd.congestion_radius": 0.4, "crowd.n": 20})
    assert sc.congestion_model == "linear"
    loop = ClosedLoop(sc)
    assert loop.crowd.density_radius == 0.4
    for bad in (0.0, -1.0):
        with pytest.raises(ParameterError) as exc:
            sc.with_values({"crowd.congestion_radius": bad})
        assert exc.value.name == "crowd.congestion_radius"


@pytest.mark.parametrize("kind", ["fokker-planck", "jupedsim"])
def test_the_density_and_the_bodies_refuse_the_twin_naming_the_door_model(kind):
    with pytest.raises(ParameterError) as exc:
        congestion = "none" if kind == "jupedsim" else "linear"
        bottleneck(congestion, **{"crowd.kind": kind, "crowd.door_model": "godunov-twin"})
    assert exc.value.name == "crowd.door_model" and "'auto' or 'count'" in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        bottleneck("linear", **{"crowd.door_model": "push"})
    assert exc.value.name == "crowd.door_model"


def test_the_crowd_shares_the_noise_where_the_door_model_and_the_engine_declare_it():
    """(H5) reaches the engine through what the parts declare, not their classes: the headway and the forward cell
    share the noise among contacts, the Godunov twin does not; the point masses' engine takes a share, and with a
    door model that shares none (or (H5) off) its noise stays σ for all."""
    from meanfield.crowds.agent_crowd import SharesNoise, TakesNoiseShare
    from meanfield.crowds.forward_cell import ForwardCell
    from meanfield.crowds.headway import Headway

    d = Linear()
    assert isinstance(Headway(d), SharesNoise) and isinstance(ForwardCell(d), SharesNoise)
    assert not isinstance(GodunovTwin(d), SharesNoise)
    for model, shared in (("forward-cell", True), ("headway", True), ("godunov-twin", False), ("count", False)):
        loop = ClosedLoop(bottleneck("linear", **{"crowd.door_model": model}))
        for _ in range(40):
            loop.step()
        engine = loop.crowd.engine
        assert isinstance(engine, TakesNoiseShare)
        assert (engine.noise_factor is not None and (engine.noise_factor < 1.0).any()) == shared, model
