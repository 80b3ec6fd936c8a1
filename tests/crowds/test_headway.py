"""The headway door model (docs page *Congestion*, "The headway door model"; :mod:`meanfield.crowds.headway`).

* (H1) the headway is the nearest person ahead in one's lane, every pair compared as the reference; in a
  hexagonal crowd it is the lattice's spacing, so each human walks the diagram's speed at the lattice's density;
* (H2) the walk projected on the cone of the velocities that approach nobody one touches: feasible, and no
  feasible velocity is nearer (a fine polar grid of the plane as the reference);
* (H3) two people closer than ``d`` step apart at ``u (1 − r/d)`` each;
* (H5) the noise's share among one's contacts and its gradient, against their closed form and finite
  differences; with ``σ ∇φ`` in the drift, a touching pair's separation follows its exact stationary law
  (Itô's step without it packs the pair);
* the compiled loops equal their numpy twins; the point masses take the model, by default (``"auto"``), the
  density and the bodies refuse it naming ``crowd.door_model``.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest

from meanfield._compiled import core as compiled
from meanfield.crowds._cell_list import cell_list
from meanfield.crowds._contact_loops import contact_cone, contact_noise
from meanfield.crowds._headway_loops import headways
from meanfield.crowds.congestion import Linear, Weidmann
from meanfield.crowds.headway import HEADWAY_REACH, TURNS, Headway
from meanfield.errors import ParameterError
from meanfield.simulation.loop import ClosedLoop
from tests.crowds.test_agent_congestion import bottleneck

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")

JAM = math.sqrt(2.0 / (math.sqrt(3.0) * 5.4))


def direct_headways(x, e, active, lane, reach):
    """Every ordered pair compared: the reference of (H1)."""
    n = len(x)
    out = np.full(n, np.inf)
    for j in range(n):
        if not active[j] or not np.isfinite(x[j]).all() or not e[j].any():
            continue
        for k in range(n):
            if k == j or not active[k] or not np.isfinite(x[k]).all():
                continue
            dx, dy = x[k] - x[j]
            r2 = dx * dx + dy * dy
            if r2 < reach * reach and dx * e[j, 0] + dy * e[j, 1] > 0 and abs(dx * e[j, 1] - dy * e[j, 0]) < lane:
                out[j] = min(out[j], math.sqrt(r2))
    return out


def spread_crowd(n, rng, width=8.0):
    x = rng.uniform(0.0, width, (n, 2))
    e = rng.normal(size=(n, 2))
    e /= np.hypot(*e.T)[:, None]
    e[::11] = 0.0  # some stand
    active = rng.random(n) > 0.1
    x[3] = np.nan
    return x, e, active


def hexagonal(spacing, rows=9):
    a = spacing
    pts = [((i + 0.5 * (k % 2)) * a, k * a * math.sqrt(3) / 2) for k in range(rows) for i in range(rows)]
    return np.array(pts)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_headway_is_the_nearest_person_ahead_in_one_s_lane(seed):
    x, e, active = spread_crowd(300, np.random.default_rng(seed))
    out = headways(x, e, active, JAM, 2.0, cell_list(x, active, JAM), np.empty(len(x)))
    ref = direct_headways(x, e, active, JAM, 2.0)
    assert np.array_equal(out, ref)
    assert np.isfinite(out).sum() > 100 and np.isinf(out).sum() > 20


def test_who_is_in_the_lane_ahead():
    x = np.array([[0.0, 0.0], [1.0, 0.3], [0.5, -0.5], [-0.2, 0.0], [2.5, 0.0]])
    e = np.array([[1.0, 0.0]] * 5)
    s = headways(x, e, np.ones(5, bool), JAM, 3.0, cell_list(x, np.ones(5, bool), JAM), np.empty(5))
    # human 0: human 2 is off the lane (0.5 > d = 0.46), human 3 behind, human 1 in it at 1.044 m
    assert s[0] == pytest.approx(math.hypot(1.0, 0.3), abs=0)
    # beyond the reach nobody counts
    s = headways(x, e, np.ones(5, bool), JAM, 1.0, cell_list(x, np.ones(5, bool), JAM), np.empty(5))
    assert math.isinf(s[0])


@pytest.mark.parametrize("spacing", [0.5, 0.6, 0.8])
@pytest.mark.parametrize("angle", [0.0, 10.0, 30.0, 47.0])
def test_a_hexagonal_crowd_walks_the_diagram_s_speed_at_its_density(spacing, angle):
    """Spacing ``a <= 2d``: whatever the direction, a neighbour in front is less than ``a/2 <= d`` off the line
    of walk, so the headway is ``a`` and (H1) reads ``2/(√3 a²)``, the lattice's density."""
    x = hexagonal(spacing)
    t = math.radians(angle)
    e = np.tile([math.cos(t), math.sin(t)], (len(x), 1))
    active = np.ones(len(x), bool)
    inner = np.hypot(*(x - x.mean(axis=0)).T) < 1.5 * spacing
    for diagram in (Linear(), Weidmann()):
        model = Headway(diagram)
        s = headways(x, e, active, model.lane, model.reach, cell_list(x, active, model.jam_spacing), np.empty(len(x)))
        np.testing.assert_allclose(s[inner], spacing, rtol=1e-12)
        rho = 2.0 / (math.sqrt(3.0) * spacing**2)
        np.testing.assert_allclose(model.density(s[inner]), rho, rtol=1e-12)
        np.testing.assert_allclose(model.speed_factor(s[inner]), diagram.speed_factor(np.array(rho)), rtol=1e-12)


@pytest.mark.parametrize("spacing", [0.5, 0.6, 0.8])
@pytest.mark.parametrize("angle", [0.0, 10.0, 30.0, 47.0])
def test_in_a_hexagonal_crowd_no_turn_makes_more_progress(spacing, angle):
    """(H4): with ``a <= 2d`` every turned lane holds a neighbour at ``a`` too, so its progress ``f cos θ`` is less
    than the route's own, which each keeps, at the diagram's speed."""
    x = hexagonal(spacing)
    t = math.radians(angle)
    e = np.tile([math.cos(t), math.sin(t)], (len(x), 1))
    active = np.ones(len(x), bool)
    inner = np.hypot(*(x - x.mean(axis=0)).T) < 1.5 * spacing
    model = Headway(Linear())
    s, f, walk = model.choose_direction(x, e, active, cell_list(x, active, model.jam_spacing))
    np.testing.assert_array_equal(walk[inner], e[inner])
    rho = 2.0 / (math.sqrt(3.0) * spacing**2)
    np.testing.assert_allclose(f[inner], Linear().speed_factor(np.array(rho)), rtol=1e-12)


def test_a_human_blocked_ahead_turns_to_the_direction_of_most_progress():
    """One person 0.54 m away, 0.2 m right of the route (east), nobody else: a lane along ``θ`` holds it when its
    centre is less than ``d`` off that line; the turns whose lanes hold it are as slow as the route's own, times
    ``cos θ``, the others free.  The walk is the turn of largest ``f cos θ``: here 45° left, ``cos 45° = 0.71``
    against ``f = 0.26`` straight on."""
    model = Headway(Linear())
    x = np.array([[0.0, 0.0], [0.5, -0.2]])
    e = np.array([[1.0, 0.0], [1.0, 0.0]])
    active = np.ones(2, bool)
    s, f, walk = model.choose_direction(x, e, active, cell_list(x, active, model.jam_spacing))
    ahead = x[1] - x[0]
    blocked = model.speed_factor(np.array([np.hypot(*ahead)]))[0]
    gains = []
    for theta in TURNS:
        line = np.array([math.cos(theta), math.sin(theta)])
        in_lane = ahead @ line > 0 and abs(ahead[0] * line[1] - ahead[1] * line[0]) < model.lane
        gains.append((blocked if in_lane else 1.0) * math.cos(theta))
    best = TURNS[int(np.argmax(gains))]  # the first of equal gains, as the model settles ties
    assert best == pytest.approx(math.radians(45.0)) and blocked < 0.3
    np.testing.assert_allclose(walk[0], [math.cos(best), math.sin(best)], rtol=0, atol=1e-15)
    assert f[0] == 1.0 and f[1] == 1.0 and np.array_equal(walk[1], e[1])  # the one ahead walks on, unturned


def test_a_wall_along_a_turned_direction_counts_as_a_person_half_a_spacing_beyond_it():
    """In a corridor 1 m wide (walls at y = 0 and y = 1), a human at y = 0.1 with a person 0.7 m straight ahead:
    straight on it walks at ``f = g(ρ(0.7))`` = 0.56; the turns of 45° free its lane (the person is 0.49 m off
    them, beyond ``d``).  Without walls it takes the first of the two, 45° right.  With them, 45° right meets the
    wall at ``0.1/sin 45°``, a headway of ``0.14 + d/2 < d`` (it stops), and 45° left meets the far wall at
    ``0.9/sin 45°``, a headway of 1.50 m, ``f = 0.90``, so it turns left: ``0.90 cos 45° = 0.64 > 0.56``."""
    from meanfield.geometry.domain import Domain

    x = np.array([[2.0, 0.1], [2.7, 0.1]])
    e = np.array([[1.0, 0.0], [1.0, 0.0]])
    active = np.ones(2, bool)
    free = Headway(Linear())
    cells = cell_list(x, active, free.jam_spacing)
    _, _, walk = free.choose_direction(x, e, active, cells)
    np.testing.assert_allclose(walk[0], [math.sqrt(0.5), -math.sqrt(0.5)], rtol=0, atol=1e-15)
    walled = Headway(Linear(), region=Domain.box(10.0, 1.0))
    s, f, walk = walled.choose_direction(x, e, active, cells)
    np.testing.assert_allclose(walk[0], [math.sqrt(0.5), math.sqrt(0.5)], rtol=0, atol=1e-15)
    far = 0.9 / math.sqrt(0.5) + walled.jam_spacing / 2
    assert s[0] == pytest.approx(far, rel=1e-12)
    assert f[0] * math.sqrt(0.5) > walled.speed_factor(np.array([0.7]))[0]
    near = 0.1 / math.sqrt(0.5) + walled.jam_spacing / 2
    assert near < walled.jam_spacing and walled.speed_factor(np.array([near]))[0] == 0.0


def test_without_turns_the_model_is_h1_to_h3():
    rng = np.random.default_rng(3)
    x = rng.uniform(0.0, 4.0, (300, 2))
    v = np.tile([1.34, 0.0], (300, 1))
    active = np.ones(300, bool)
    model = Headway(Linear(), turns=(0.0,))
    out = v.copy()
    model.slow_down(out, x, active)
    cells = cell_list(x, active, model.jam_spacing)
    s = headways(x, v / 1.34, active, model.lane, model.reach, cells, np.empty(300))
    expected = v * model.speed_factor(s)[:, None]
    contact_cone(expected, x, active, model.jam_spacing, model.separation, cells)
    np.testing.assert_array_equal(out, expected)
    with pytest.raises(ValueError, match="route's own direction"):
        Headway(Linear(), turns=(0.3, 0.0))


def test_nobody_ahead_walks_free_and_nobody_walks_on_at_the_jam_spacing():
    model = Headway(Linear())
    assert model.speed_factor(np.array([np.inf]))[0] == 1.0
    assert model.speed_factor(np.array([model.jam_spacing]))[0] == pytest.approx(0.0, abs=1e-12)
    assert model.speed_factor(np.array([0.3]))[0] == 0.0
    assert model.jam_spacing == pytest.approx(JAM)
    assert 1.0 - model.speed_factor(np.array([HEADWAY_REACH]))[0] < 0.025


def nearest_in_cone(v, normals, samples=20000):
    """The reference of (H2): the feasible velocity nearest ``v`` on a fine polar grid of the plane."""
    speed = np.linspace(0.0, 1.5 * np.hypot(*v), 301)
    angle = np.linspace(0.0, 2 * math.pi, samples // 100, endpoint=False)
    u = (speed[:, None, None] * np.stack([np.cos(angle), np.sin(angle)], -1)[None]).reshape(-1, 2)
    ok = (u @ normals.T <= 1e-12).all(axis=1)
    return np.min(np.hypot(*(u[ok] - v).T))


@pytest.mark.parametrize("seed", range(6))
def test_the_walk_is_the_nearest_that_approaches_nobody_it_touches(seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 2.0, (40, 2))
    v = rng.normal(size=(40, 2))
    active = np.ones(40, bool)
    out = contact_cone(v.copy(), x, active, JAM, 0.0, cell_list(x, active, JAM))
    touched = 0
    for j in range(40):
        d = x - x[j]
        r = np.hypot(*d.T)
        near = (r > 0) & (r < JAM)
        if not near.any():
            assert np.array_equal(out[j], v[j])
            continue
        n = d[near] / r[near, None]
        assert np.all(n @ out[j] <= 1e-12)  # feasible
        if np.any(n @ v[j] > 0):
            touched += 1
            # no feasible velocity nearer (to the polar grid's resolution)
            assert np.hypot(*(out[j] - v[j])) <= nearest_in_cone(v[j], n) + 1e-9
        else:
            assert np.array_equal(out[j], v[j])
    assert touched >= 5


def test_a_head_on_contact_stops_the_approach_and_a_wedge_stops_the_walk():
    x = np.array([[0.0, 0.0], [0.4, 0.0], [0.3, 0.3], [0.3, -0.3]])
    active = np.array([True, True, False, False])
    v = np.array([[1.0, 0.5], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    out = contact_cone(v.copy(), x, active, JAM, 0.0, cell_list(x, active, JAM))
    np.testing.assert_allclose(out[0], [0.0, 0.5], atol=1e-15)  # slides past, its part towards human 1 gone
    active = np.array([True, False, True, True])
    v = np.array([[1.0, 0.2], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    out = contact_cone(v.copy(), x, active, JAM, 0.0, cell_list(x, active, JAM))
    np.testing.assert_allclose(out[0], [0.0, 0.0], atol=1e-15)  # the two at ±45° close the way
    v = np.array([[-1.0, 0.2], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    out = contact_cone(v.copy(), x, active, JAM, 0.0, cell_list(x, active, JAM))
    np.testing.assert_array_equal(out[0], v[0])  # walking away: untouched


def test_the_soft_core_steps_two_people_apart_by_their_overlap():
    r = 0.3
    x = np.array([[0.0, 0.0], [r, 0.0], [5.0, 5.0]])
    active = np.ones(3, bool)
    out = contact_cone(np.zeros((3, 2)), x, active, JAM, 1.34, cell_list(x, active, JAM))
    step = 1.34 * (1.0 - r / JAM)
    np.testing.assert_allclose(out, [[-step, 0.0], [step, 0.0], [0.0, 0.0]], atol=1e-15)


def test_the_noise_s_share_is_the_product_of_the_contacts_and_its_gradient_the_exact_one():
    """(H5): ``φ_j = Π (r_jk/d)^m`` over the contacts, 1 and no gradient without; ``∇_j φ_j`` its derivative."""
    x = np.array([[0.0, 0.0], [0.3, 0.0], [0.0, 0.4], [5.0, 5.0], [np.nan, np.nan], [0.1, 0.1]])
    active = np.array([True, True, True, True, True, False])
    phi, grad = np.empty(6), np.empty((6, 2))
    contact_noise(x, active, JAM, cell_list(x, active, JAM), phi, grad, 4.0)
    expected = [(0.3 / JAM) ** 4 * (0.4 / JAM) ** 4, (0.3 / JAM) ** 4, (0.4 / JAM) ** 4, 1.0, 1.0, 1.0]
    np.testing.assert_allclose(phi, expected, rtol=1e-14)
    np.testing.assert_allclose(grad[0], [-expected[0] * 4 / 0.3, -expected[0] * 4 / 0.4], rtol=1e-14)  # away from both
    np.testing.assert_allclose(grad[1], [expected[1] * 4 / 0.3, 0.0], rtol=1e-14, atol=1e-15)
    assert np.all(grad[3:] == 0.0)
    rng = np.random.default_rng(4)
    x = rng.uniform(0.0, 3.0, (200, 2))
    active = np.ones(200, bool)
    phi, grad = np.empty(200), np.empty((200, 2))
    contact_noise(x, active, JAM, cell_list(x, active, JAM), phi, grad)
    h = 1e-6
    for j in np.flatnonzero(phi < 1.0)[:20]:
        for a in range(2):
            ends = []
            for sign in (1.0, -1.0):
                y = x.copy()
                y[j, a] += sign * h
                p, g = np.empty(200), np.empty((200, 2))
                ends.append(contact_noise(y, active, JAM, cell_list(y, active, JAM), p, g)[j])
            assert grad[j, a] == pytest.approx((ends[0] - ends[1]) / (2 * h), rel=1e-5, abs=1e-9)


def _pair_separations(sigma, u, correct, pairs=400, steps=1600, dt=0.002, seed=0):
    """Independent touching pairs under (H3) and (H5), no walk, by Euler–Maruyama; the separation reflected at
    ``d``: the separations of the second half, every 20th step."""
    rng = np.random.default_rng(seed)
    side = int(math.ceil(math.sqrt(pairs)))
    centre = 3.0 * np.stack(np.divmod(np.arange(pairs), side), axis=1).astype(float)
    x = np.concatenate([centre - [0.2, 0.0], centre + [0.2, 0.0]])
    active = np.ones(len(x), bool)
    phi, grad, out = np.empty(len(x)), np.empty((len(x), 2)), []
    for step in range(steps):
        cells = cell_list(x, active, JAM)
        v = contact_cone(np.zeros_like(x), x, active, JAM, u, cells)
        contact_noise(x, active, JAM, cells, phi, grad)
        if correct:
            v += sigma * grad
        x = x + v * dt + np.sqrt(2.0 * sigma * phi * dt)[:, None] * rng.standard_normal(x.shape)
        rel = x[pairs:] - x[:pairs]
        r = np.hypot(*rel.T)
        far = r > JAM  # r -> 2d - r
        shift = np.where(far, r - JAM, 0.0)[:, None] * rel / r[:, None]
        x[:pairs] += shift
        x[pairs:] -= shift
        if step >= steps // 2 and step % 20 == 0:
            out.append(np.hypot(*(x[pairs:] - x[:pairs]).T))
    return np.concatenate(out)


def test_a_touching_pair_keeps_the_stationary_separation_of_h5():
    """Two people who touch, step apart by (H3) at ``u (1 − r/d)`` each and diffuse at ``σ φ`` with ``σ ∇φ`` in the
    drift: their separation ``r < d`` has the density ``r p(r)``, ``p(r) ∝ exp(−∫_r^d u (1 − s/d) / (σ (s/d)^m) ds)``
    (zero flux of ``∂p = ∇·(2σφ ∇p) − ∇·(2u (1 − r/d) r̂ p)``), whatever ``φ``'s steepness; without ``σ ∇φ``
    the Itô step packs the pair (its law is ``p / φ``, piled where the noise is weakest)."""
    from meanfield.crowds._contact_loops import CONTACT_NOISE_POWER as m

    sigma, u = 0.1, 1.34
    s = np.linspace(1e-3, JAM, 4001)
    rate = u * (1.0 - s / JAM) / (sigma * (s / JAM) ** m)
    log_p = -np.concatenate([np.cumsum(((rate[1:] + rate[:-1]) / 2 * np.diff(s))[::-1])[::-1], [0.0]])
    cdf = np.cumsum(s * np.exp(log_p))
    cdf /= cdf[-1]
    q = np.array([0.30, 0.35, 0.38, 0.40, 0.42, 0.44])
    exact = np.interp(q, s, cdf)
    r = _pair_separations(sigma, u, correct=True)
    np.testing.assert_allclose((r[:, None] < q).mean(axis=0), exact, atol=0.025)
    ito = _pair_separations(sigma, u, correct=False, steps=800)
    assert np.max((ito[:, None] < q).mean(axis=0) - exact) > 0.1


@needs_numba
def test_compiled_loops_equal_their_numpy_twins():
    from meanfield.crowds._contact_loops import _cone_compiled, _contact_noise_compiled
    from meanfield.crowds._headway_loops import _headways_compiled

    if not compiled.enabled():
        pytest.skip("the compiled path is off (MEANFIELD_COMPILED=0): nothing to compare")

    x, e, active = spread_crowd(3000, np.random.default_rng(7), width=25.0)
    cells = cell_list(x, active, JAM)
    fast = headways(x, e, active, JAM, 3.0, cells, np.empty(len(x)))
    assert _headways_compiled._ready  # the compiled loop ran (else both sides would be numpy)
    with compiled.numpy_path():
        ref = headways(x, e, active, JAM, 3.0, cells, np.empty(len(x)))
    assert np.array_equal(fast, ref)
    v = np.random.default_rng(8).normal(size=x.shape)
    fast = contact_cone(v.copy(), x, active, JAM, 1.34, cells)
    assert _cone_compiled._ready
    with compiled.numpy_path():
        ref = contact_cone(v.copy(), x, active, JAM, 1.34, cells)
    np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-13)
    assert np.sum(np.any(fast != v, axis=1)) > 1000
    phi, grad = np.empty(len(x)), np.empty((len(x), 2))
    contact_noise(x, active, JAM, cells, phi, grad)
    assert _contact_noise_compiled._ready
    with compiled.numpy_path():
        ref_phi, ref_grad = np.empty(len(x)), np.empty((len(x), 2))
        contact_noise(x, active, JAM, cells, ref_phi, ref_grad)
    np.testing.assert_allclose(phi, ref_phi, rtol=1e-13, atol=0)
    np.testing.assert_allclose(grad, ref_grad, rtol=1e-12, atol=1e-12)
    assert np.sum(phi < 1.0) > 1000


def test_cells_narrower_than_the_jam_spacing_are_refused():
    x = np.zeros((2, 2))
    with pytest.raises(ValueError, match="cells at least"):
        contact_cone(np.zeros((2, 2)), x, np.ones(2, bool), JAM, 0.0, cell_list(x, np.ones(2, bool), JAM / 2))


def test_the_point_masses_walk_the_headway_model():
    loop = ClosedLoop(bottleneck("linear", t_final=1.0, **{"crowd.door_model": "headway"}))
    crowd = loop.crowd
    x = crowd.positions.copy()
    chosen = crowd.guidance.velocity(x, 0.0, 0.05).copy()
    drift = crowd.drift(loop.robots, 0.0, 0.05).copy()
    expected = chosen.copy()
    model = Headway(Linear(), region=loop.scenario.domain)
    model.slow_down(expected, x, crowd.engine.active)
    expected += crowd.engine.sigma * model.noise_gradient  # (H5): σ ∇φ
    np.testing.assert_array_equal(drift, expected)
    np.testing.assert_array_equal(crowd.engine.noise_factor, model.noise_factor)
    assert np.any(np.hypot(*drift.T) < 0.9 * np.hypot(*chosen.T))  # somebody is slowed at the start
    assert crowd.peak_local_density > 0
    loop.run(progress=False)
    assert loop.crowd.remaining() < crowd.n


@pytest.mark.parametrize("kind", ["fokker-planck", "jupedsim"])
def test_the_density_and_the_bodies_refuse_the_headway_naming_the_door_model(kind):
    congestion = "none" if kind == "jupedsim" else "linear"
    with pytest.raises(ParameterError) as exc:
        bottleneck(congestion, **{"crowd.kind": kind, "crowd.door_model": "headway"})
    assert exc.value.name == "crowd.door_model"


def exit_queue(capacity, n=60, sigma=0.0):
    """A 4 m × 2 m box whose right side (2 m) is an exit, ``n`` people walking at it at 1 m/s, capped."""
    from meanfield import Domain
    from meanfield.crowds.point_mass import PointMassEngine

    room = Domain.box(4.0, 2.0, exits=[((4.0, 0.0), (4.0, 2.0))])
    rng = np.random.default_rng(0)
    engine = PointMassEngine(np.column_stack([rng.uniform(2.0, 3.99, n), rng.uniform(0.1, 1.9, n)]), room, sigma, rng)
    engine.cap_exits(np.array([capacity]))
    return engine


@pytest.mark.parametrize("capacity", [3.0, 1.2, 0.5, 25.0])
@pytest.mark.parametrize("sigma", [0.0, 0.05])
def test_an_exit_passes_its_capacity_and_at_most_one_person_more(capacity, sigma):
    """Over every window of steps the exit passes at most ``1 + capacity τ``; with a queue always at the door,
    exactly its capacity (within one person), noise or not.  25 persons/s is more than one a step (dt = 0.05 s),
    which a credit capped at one person would starve."""
    n = 400 if capacity > 10 else 60
    engine = exit_queue(capacity, n=n, sigma=sigma)
    drift = np.tile([1.0, 0.0], (engine.n, 1))
    dt, out = 0.05, [0]
    steps = 160 if capacity <= 10 else 12
    for step in range(1, steps + 1):
        engine.step(drift, (step - 1) * dt, dt)
        out.append(engine.n - engine.remaining())
        assert np.all(engine.positions[engine.active, 0] <= 4.0)  # the waiting stay in the room
    out = np.asarray(out)
    for a in range(steps):  # every window [a, b] of whole steps
        passed = out[a + 1 :] - out[a]
        tau = dt * np.arange(1, steps - a + 1)
        assert np.all(passed <= 1.0 + capacity * tau + 1e-9)
    first, last = (40, 160) if capacity <= 10 else (2, 12)
    assert abs((out[last] - out[first]) - capacity * dt * (last - first)) <= 1.0 + 1e-9


def test_the_nearest_to_the_exit_leaves_first_and_the_held_wait_where_they_were():
    from meanfield import Domain
    from meanfield.crowds.point_mass import PointMassEngine

    room = Domain.box(4.0, 2.0, exits=[((4.0, 0.0), (4.0, 2.0))])
    x = np.array([[3.9, 1.0], [3.95, 0.5], [3.8, 1.5]])
    engine = PointMassEngine(x.copy(), room, 0.0, np.random.default_rng(0))
    engine.cap_exits(np.array([0.5]))  # one person now, the next 2 s later
    engine.step(np.tile([10.0, 0.0], (3, 1)), 0.0, 0.05)  # all three reach the exit
    assert engine.active.tolist() == [True, False, True]  # human 1 was nearest
    np.testing.assert_array_equal(engine.positions[[0, 2]], x[[0, 2]])
    # those waiting in the doorway are served first, whatever their step: a step that falls short does not lose
    # the turn (a door that dropped its credit whenever nobody reached it passed 1.62 of 1.81 persons/s at
    # rimea-9's doors, the front of the queue one noisy step away from the door)
    for step in range(1, 39):  # 1.9 s later: not yet a whole credit
        engine.step(np.tile([-0.1, 0.0], (3, 1)), step * 0.05, 0.05)
    assert engine.active.tolist() == [True, False, True]
    np.testing.assert_array_equal(engine.positions[[0, 2]], x[[0, 2]])  # they wait where they stood
    for step in (39, 40):  # 2 s after the first: the next one, the nearest of the two
        engine.step(np.tile([-0.1, 0.0], (3, 1)), step * 0.05, 0.05)
    assert engine.active.tolist() == [False, False, True]


def test_those_waiting_at_an_exit_that_closes_do_not_leave_by_it():
    from meanfield import Domain
    from meanfield.crowds.point_mass import PointMassEngine

    room = Domain.box(4.0, 2.0, exits=[((4.0, 0.0), (4.0, 2.0)), ((0.0, 0.0), (0.0, 2.0))])
    x = np.array([[3.9, 1.0], [3.95, 0.5]])
    engine = PointMassEngine(x.copy(), room, 0.0, np.random.default_rng(0))
    engine.cap_exits(np.array([0.5, 0.5]))
    engine.step(np.tile([10.0, 0.0], (2, 1)), 0.0, 0.05)  # one leaves, one waits at exit 0
    assert engine.remaining() == 1
    engine.exits_closed(np.array([False, True]))
    for step in range(1, 81):  # 4 s: exit 0 would have served it twice over
        engine.step(np.zeros((2, 2)), step * 0.05, 0.05)
    assert engine.remaining() == 1
    np.testing.assert_array_equal(engine.positions[0], x[0])


def test_an_idle_exit_keeps_one_person_s_credit():
    """Nobody at the door for 10 s, then three at once: one passes, the next two 1/capacity apart."""
    from meanfield import Domain
    from meanfield.crowds.point_mass import PointMassEngine

    room = Domain.box(4.0, 2.0, exits=[((4.0, 0.0), (4.0, 2.0))])
    x = np.array([[1.0, 1.0], [1.0, 0.5], [1.0, 1.5]])
    engine = PointMassEngine(x.copy(), room, 0.0, np.random.default_rng(0))
    engine.cap_exits(np.array([1.0]))
    still = np.zeros((3, 2))
    for step in range(200):
        engine.step(still, step * 0.05, 0.05)
    engine.step(np.tile([100.0, 0.0], (3, 1)), 10.0, 0.05)
    assert engine.remaining() == 2
    for step in range(1, 21):  # the next second: exactly one more
        engine.step(still, 10.0 + step * 0.05, 0.05)
    assert engine.remaining() == 1


def queue_step(seed):
    """One step's state of the exits' queues: three exits (one closed), people reaching them, some waiting in their
    doorways, credits below and above one person."""
    rng = np.random.default_rng(seed)
    n = 80
    exits = np.array([[[4.0, 0.0], [4.0, 2.0]], [[0.0, 0.0], [0.0, 2.0]], [[1.0, 2.0], [2.0, 2.0]]])
    previous = np.column_stack([rng.uniform(0.0, 4.0, n), rng.uniform(0.0, 2.0, n)])
    x = previous + rng.normal(0.0, 0.1, (n, 2))
    idx = np.flatnonzero(rng.random(n) > 0.2)  # who stepped (sorted)
    gone = np.where(rng.random(len(idx)) < 0.4, rng.integers(0, 3, len(idx)), -1).astype(np.intp)
    waiting = np.sort(rng.choice(n, 12, replace=False)).astype(np.intp)  # some of them no longer stepping
    waiting_at = rng.integers(0, 3, 12).astype(np.intp)
    credit = np.array([0.4, 2.7, 1.0]) * rng.uniform(0.5, 1.5, 3)
    is_open = np.array([True, True, seed % 2 == 0])
    previous[idx[3]] = previous[idx[4]]  # two equally near: the first of them first
    return gone, idx, previous, x, exits, np.array([1.8, 3.6, 0.9]), credit, waiting, waiting_at, is_open, 0.05


@pytest.mark.parametrize("seed", range(8))
def test_the_compiled_queues_are_their_numpy_twin_s(seed):
    """The exits' queues (:func:`~meanfield.crowds._point_mass_loops.hold_at_capacity`), compiled and in numpy:
    the same credits, the same held, to the last bit."""
    from meanfield.crowds._point_mass_loops import hold_at_capacity

    runs = []
    for path in ("compiled", "numpy"):
        gone, idx, previous, x, *rest = queue_step(seed)
        with compiled.numpy_path() if path == "numpy" else contextlib.nullcontext():
            credit, waiting, waiting_at = hold_at_capacity(gone, idx, previous, x, *rest)
        runs.append((gone, x, credit, waiting, waiting_at))
    assert hold_at_capacity._ready or not compiled.enabled()  # (the compiled path ran)
    assert len(runs[0][3]) > 0  # (some were held)
    for a, b in zip(*runs, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)


def test_an_exit_capacity_that_means_nothing_is_refused():
    engine = exit_queue(1.0)
    for bad in ([0.0], [-1.0], [np.inf], [1.0, 2.0]):
        with pytest.raises(ParameterError) as exc:
            engine.cap_exits(np.array(bad))
        assert exc.value.name == "exit capacity"


def test_the_headway_model_caps_the_exits_at_the_diagram_s_capacity():
    loop = ClosedLoop(bottleneck("linear", b=1.0, t_final=1.0, **{"crowd.door_model": "headway"}))
    engine = loop.crowd.engine
    q_max = Linear().capacity()[0]
    np.testing.assert_allclose(engine._capacity, [q_max * 1.0])
    other = ClosedLoop(bottleneck("linear", b=1.0, t_final=1.0, **{"crowd.door_model": "godunov-twin"}))
    assert other.crowd.engine._capacity is None
