"""The density crowd takes the agents' ``crowd.guidance`` kinds (meanfield.crowds.guidance, ``for_density``).

Exact answers: an informed density in a corridor leaves as a front at the free speed, its exit passes
``v₀ ρ b`` while the crowd streams in and never more than its capacity ``v₀ ρ_max b / 4`` with the linear
diagram; the random walk's diffusion is ``s²/(2 D_r)``, the long-time slope of the agents' mean squared
displacement; Hughes' route is the geodesic one in an empty room and bends round the crowd in a full one
(docs page *Congestion*, "The PDE").
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario, plugins
from meanfield.capabilities import GuidanceCapabilities
from meanfield.crowds.congestion import Linear
from meanfield.crowds.guidance import DensityGuidance, route_velocity, walk_diffusion
from meanfield.geometry.domain import Domain
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.geodesic import exit_distance
from meanfield.geometry.grid import Grid
from meanfield.simulation.assembly import assemble

LENGTH, WIDTH, SPEED = 10.0, 1.0, 1.34
CELL = 0.1


def _corridor(congestion: str, n: int = 200, **extra):
    """A corridor ``LENGTH`` × ``WIDTH`` m whose east end is the exit, the density uniform in it, σ = 0."""
    room = Domain.box(LENGTH, WIDTH, exits=[((LENGTH, 0.0), (LENGTH, WIDTH))])
    sc = paper_scenario(seed=0).replace(domain=room, units="SI", dt=0.05, t_final=20.0)
    values = {
        "grid.cells": [round(LENGTH / CELL), round(WIDTH / CELL)],
        "crowd.kind": "fokker-planck",
        "crowd.n": n,
        "crowd.sigma": 0.0,
        "crowd.guidance": "geodesic",
        "crowd.free_speed": SPEED,
        "crowd.congestion": congestion,
        "robots.n": 1,
        "controller.kind": "static-signs",
        "target.center": [LENGTH - 1.0, WIDTH / 2],
        "target.std": 1.0,
        **extra,
    }
    return sc.with_values(values)


def _outflow(sc, t_end: float) -> tuple[np.ndarray, np.ndarray, ClosedLoop]:
    """The times and the mass out (a fraction of the crowd) after every control period up to ``t_end``."""
    loop = ClosedLoop(sc)
    times, out = [0.0], [0.0]
    while loop.t < t_end - 1e-9:
        loop.step()
        times.append(loop.t)
        out.append(float(loop.crowd.out_per_exit.sum()) / loop.crowd.initial_mass)
    return np.array(times), np.array(out), loop


def test_the_informed_density_walks_down_the_route_at_the_free_speed():
    """In a straight corridor the route's direction is along it: every face carries ``v₀`` towards the exit."""
    sc = _corridor("none")
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    ax, ay = crowd.guidance.velocity
    np.testing.assert_allclose(ax, SPEED, rtol=1e-12)
    assert np.all(ay == 0.0)
    assert crowd.velocity(loop.robots) is crowd.guidance.velocity and crowd.last_field is None  # no robots' field
    assert not crowd.guidance.follows_signs and crowd.guidance.diffusion == 0.0


def test_route_velocity_goes_downhill_at_most_at_the_speed_round_a_corner():
    """On the bottleneck's plan (a room and a corridor) every face's velocity points down φ, never faster than v₀."""
    from meanfield.geometry.plan import Plan

    plan = Plan.from_wkt("POLYGON ((0 0, 10 0, 10 3.5, 12 3.5, 12 4.5, 10 4.5, 10 8, 0 8, 0 0))")
    plan = Plan(plan.polygon, [((12.0, 3.5), (12.0, 4.5))])
    grid = Grid(plan, (60, 40))
    phi = exit_distance(grid, exit_segments(plan))
    ax, ay = route_velocity(grid, phi, SPEED)
    assert np.abs(ax).max() <= SPEED * (1 + 1e-12) and np.abs(ay).max() <= SPEED * (1 + 1e-12)
    finite = np.where(np.isfinite(phi), phi, 0.0)
    gx, gy = np.diff(finite, axis=0), np.diff(finite, axis=1)
    assert np.all(ax * gx <= 0) and np.all(ay * gy <= 0)  # down the distance to the exit
    assert np.all(ax[grid.aperture_x == 0] == 0) and np.all(ay[grid.aperture_y == 0] == 0)  # walls closed
    inside = grid.active[1:, :] & grid.active[:-1, :] & (grid.aperture_x > 0)
    assert (ax[inside] > 0).mean() > 0.9  # the exit is east of nearly everyone


def test_an_informed_density_leaves_as_a_front_at_the_free_speed():
    """No congestion, σ = 0: the exit passes ``v₀ ρ₀ b`` (mass ``v₀/L`` per second) until the back of the
    crowd, which left the west wall at ``t = 0``, reaches the exit at ``L/v₀``.

    A first-order monotone scheme smears the back over about ``sqrt(h L)`` (its numerical diffusion
    ``v₀ h/2``), symmetrically about the exact position: the back's passage is measured at its
    middle, when the outflow has fallen to half its plateau, and must be within one cell's travel
    time ``h/v₀`` of ``L/v₀``.  The mean exit time of the mass is ``L/(2 v₀)``, up to half a cell's
    travel time (the semi-discrete upwind chain's mean is ``(x + h/2)/v₀`` from a centre at ``x``).
    """
    sc = _corridor("none")
    t, out, loop = _outflow(sc, 12.0)
    rate = np.diff(out) / np.diff(t)
    mid = 0.5 * (t[1:] + t[:-1])
    plateau = SPEED / LENGTH
    # the exit passes v0 rho0 b exactly once the exit cell's start is forgotten (1 s) and before the
    # back's smear arrives (3 s; it is 5 m from the exit then, 4 smear widths)
    steady = (mid > 2.0) & (mid < 3.0)
    np.testing.assert_allclose(rate[steady], plateau, rtol=1e-9)
    k = int(np.flatnonzero(rate >= 0.5 * plateau)[-1])
    back = mid[k] + (rate[k] - 0.5 * plateau) / (rate[k] - rate[k + 1]) * (mid[k + 1] - mid[k])
    travel = CELL / SPEED
    assert abs(back - LENGTH / SPEED) < travel, (back, LENGTH / SPEED)
    mean_exit_time = float(np.sum(0.5 * (2.0 - out[1:] - out[:-1]) * np.diff(t)))
    assert abs(mean_exit_time - LENGTH / (2 * SPEED)) < 0.5 * travel + 1e-3
    assert out[-1] > 1 - 1e-6  # everyone out by 12 s = 1.6 L/v0
    assert loop.crowd.remaining_fraction() + out[-1] == pytest.approx(1.0, abs=1e-13)  # nothing lost


def test_with_the_linear_diagram_the_exit_never_passes_more_than_its_capacity():
    """40 people in 10 m² (4 persons/m², above the 2.7 of the largest flow): the door of 1 m passes at most
    ``q_max b = v₀ ρ_max b / 4`` persons per second at every period, and the queue reaches it."""
    n = 40
    sc = _corridor("linear", n=n)
    t, out, loop = _outflow(sc, 20.0)
    q_max, _ = Linear(free_speed=SPEED, rho_max=sc.crowd.rho_max).capacity()
    assert q_max == pytest.approx(SPEED * 5.4 / 4)
    persons_per_second = n * np.diff(out) / np.diff(t)
    assert persons_per_second.max() <= q_max * WIDTH * (1 + 1e-12)
    assert persons_per_second.max() >= 0.99 * q_max * WIDTH  # the queue discharges at the capacity
    assert loop.crowd.fp.congestion is not None and loop.crowd.fp.congestion.people == n
    free = _outflow(_corridor("none", n=n), 5.0)[1]
    assert n * free[-1] > 1.2 * n * out[np.searchsorted(t, 5.0)]  # without congestion more leave


def test_the_random_walk_is_diffusion_only_with_the_walks_coefficient():
    sc = _corridor("none", **{"crowd.guidance": "random-walk", "view.walk_speed": 0.7, "view.turning_rate": 0.1})
    sc = sc.with_values({"crowd.sigma": 0.05})
    loop = ClosedLoop(sc)
    g = loop.crowd.guidance
    assert g.velocity is None and not g.follows_signs
    assert g.diffusion == pytest.approx(0.7**2 / (2 * 0.1), rel=1e-15)
    assert loop.crowd.fp.sigma == pytest.approx(0.05 + 0.7**2 / 0.2, rel=1e-15)
    assert loop.crowd.velocity(loop.robots) is None and loop.crowd.last_field is None


def test_the_density_refuses_a_walk_that_never_turns_and_a_guidance_that_declares_nothing():
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(_corridor("none", **{"crowd.guidance": "random-walk", "view.walk_speed": 0.7}))
    assert exc.value.name == "view.turning_rate"
    assert walk_diffusion(0.0, 0.0) == 0.0  # nobody walks: nothing to diffuse

    def follow_the_leader(ctx, positions):  # a plug-in's guidance: agents only
        return None

    plugins.register("guidance", "follow-the-leader", follow_the_leader, capabilities=GuidanceCapabilities())
    try:
        sc = _corridor("none", **{"crowd.guidance": "follow-the-leader"})
        with pytest.raises(ParameterError) as exc:
            ClosedLoop(sc)
        assert exc.value.name == "crowd.guidance" and exc.value.value == "follow-the-leader"
        for name in ("'geodesic'", "'random-walk'", "'signs'"):
            assert name in str(exc.value)
    finally:
        plugins.unregister("guidance", "follow-the-leader")
    field = GuidanceCapabilities(for_density=lambda ctx: "a field")  # declares, but not a DensityGuidance
    plugins.register("guidance", "follow-the-leader", follow_the_leader, capabilities=field)
    try:
        with pytest.raises(ParameterError) as exc:
            ClosedLoop(sc)
        assert exc.value.name == "crowd.guidance"
    finally:
        plugins.unregister("guidance", "follow-the-leader")
    with pytest.raises(ParameterError) as exc:  # the informed crowd needs exits
        ClosedLoop(paper_scenario(seed=0).with_values({"crowd.guidance": "geodesic"}), crowd="fokker-planck")
    assert exc.value.name == "crowd.guidance"
    with pytest.raises(ParameterError) as exc:
        DensityGuidance(diffusion=-1.0)
    assert exc.value.name == "diffusion"


def test_the_signs_still_drive_the_density_as_before():
    """``signs`` (the paper): the robots' field on the faces, the exits once per control period, as ever."""
    loop = ClosedLoop(paper_scenario(seed=0).replace(t_final=0.02), crowd="fokker-planck")
    crowd = loop.crowd
    assert crowd.guidance.follows_signs and crowd.fp.sigma == loop.scenario.crowd.sigma
    v = crowd.velocity(loop.robots)
    np.testing.assert_array_equal(v[0], crowd.last_field.velocity()[0])


def _discrete_walk_msd(s: float, rate: float, dt: float, k: int) -> float:
    """``E|X_k − X_0|²`` of the agents' walk: ``k`` steps ``s dt e(θ_i)``, ``θ_{i+1} = θ_i + sqrt(2 D_r dt) ξ_i``.

    ``E[e_i · e_j] = E cos(θ_i − θ_j) = q^{|i−j|}``, ``q = exp(−D_r dt)`` (a Gaussian angle of variance
    ``2 D_r dt |i−j|``), so the sum over the pairs is ``k (1+q)/(1−q) − 2q (1−q^k)/(1−q)²``.
    """
    q = math.exp(-rate * dt)
    return (s * dt) ** 2 * (k * (1 + q) / (1 - q) - 2 * q * (1 - q**k) / (1 - q) ** 2)


def test_the_agents_random_walk_spreads_with_the_densitys_diffusion():
    """10⁴ random-walk point masses, σ = 0, in a box 200 m wide (they spread ±10 m: no wall is reached):
    the mean squared displacement after ``T`` is the walk's exact one, and its growth from ``T₁`` to ``T``
    (``D_r T₁ = 20``: the start forgotten to ``e⁻²⁰``) is ``4 D (T − T₁)`` with the density's ``D``, each
    within four standard errors of the mean over the walkers (their sample standard deviation over √M)."""
    s, rate, dt, box, m = 1.0, 2.0, 0.05, 200.0, 10_000
    t1_steps, t_steps = 200, 2000  # T1 = 10 s, T = 100 s
    room = Domain.box(box, box)
    sc = paper_scenario(seed=7).replace(domain=room, units="SI", dt=dt, t_final=t_steps * dt)
    sc = sc.with_values(
        {
            "crowd.n": m,
            "crowd.sigma": 0.0,
            "crowd.guidance": "random-walk",
            "crowd.congestion": "none",
            "crowd.initial": "gaussian",
            "crowd.initial_center": [box / 2, box / 2],
            "crowd.initial_std": 1.0,
            "view.walk_speed": s,
            "view.turning_rate": rate,
            "grid.cells": [20, 20],
            "robots.n": 1,
            "controller.kind": "static-signs",
            "target.center": [box / 2, box / 2],
            "target.std": 30.0,
        }
    )
    density = assemble(sc, crowd="fokker-planck").crowd
    d = float(density.fp.sigma)  # σ = 0: all of it is the walk's
    assert d == pytest.approx(s**2 / (2 * rate), rel=1e-15)
    parts = assemble(sc)
    crowd, robots = parts.crowd, parts.robots
    x0 = crowd.positions.copy()
    for k in range(t_steps):
        if k == t1_steps:
            x1 = crowd.positions.copy()
        crowd.advance(robots, k * dt, dt)
    x = crowd.positions
    assert np.abs(x - box / 2).max() < 0.4 * box  # far from the walls: nobody turned at one
    r2 = ((x - x0) ** 2).sum(axis=1)
    se = r2.std(ddof=1) / math.sqrt(m)
    exact = _discrete_walk_msd(s, rate, dt, t_steps)
    assert abs(r2.mean() - exact) < 4 * se, (r2.mean(), exact, se)
    growth = r2 - ((x1 - x0) ** 2).sum(axis=1)
    se_growth = growth.std(ddof=1) / math.sqrt(m)
    span = (t_steps - t1_steps) * dt
    assert abs(growth.mean() - 4 * d * span) < 4 * se_growth, (growth.mean(), 4 * d * span, se_growth)
    # what "equals 4 D t" leaves out is below a tenth of the statistical error: the start (e^-20) and the
    # steps of dt ((D_r dt)²/12 = 8.3e-4 of the growth: 0.075 m² of 90 m², the error being about 1 m²)
    exact_growth = _discrete_walk_msd(s, rate, dt, t_steps) - _discrete_walk_msd(s, rate, dt, t1_steps)
    assert abs(exact_growth - 4 * d * span) < 0.1 * se_growth
    assert se_growth < 0.03 * 4 * d * span  # the test tells D from 0.88 D or 1.12 D (four errors at most)


# ---------------------------------------------------------------------------------------------- Hughes' route


def _two_doors(guidance: str, congestion: str = "linear", n: int = 60):
    """A room 12 m × 4 m with a door of 1 m in the middle of each end wall, equally far from the room's middle;
    the crowd a normal law about 1.5 m east of the middle (std 1.5 m, at most 5.2 persons/m² with n = 60)."""
    length, width = 12.0, 4.0
    room = Domain.box(length, width, exits=[((0.0, 1.5), (0.0, 2.5)), ((length, 1.5), (length, 2.5))])
    sc = paper_scenario(seed=0).replace(domain=room, units="SI", dt=0.05, t_final=30.0)
    return sc.with_values(
        {
            "grid.cells": [60, 20],
            "crowd.kind": "fokker-planck",
            "crowd.n": n,
            "crowd.sigma": 0.0,
            "crowd.guidance": guidance,
            "crowd.congestion": congestion,
            "crowd.initial": "gaussian",
            "crowd.initial_center": [length / 2 + 1.5, width / 2],
            "crowd.initial_std": 1.5,
            "robots.n": 1,
            "controller.kind": "static-signs",
            "target.center": [length / 2, width / 2],
            "target.std": 1.0,
        }
    )


def _run(sc, t_end: float) -> tuple[ClosedLoop, float]:
    """Run to ``t_end``; the largest density (persons/m²) on any cell at any control period."""
    loop = ClosedLoop(sc)
    crowd, n = loop.crowd, sc.crowd.n
    peak = n * float(crowd.rho[loop.grid.active].max())
    while loop.t < t_end - 1e-9:
        loop.step()
        peak = max(peak, n * float(crowd.rho[loop.grid.active].max()))
    return loop, peak


def test_hughes_route_sends_the_crowd_to_the_emptier_door():
    """Two doors equally far from the room's middle, the crowd mostly on the east side.  The geodesic route
    sends everyone to the nearer door: the west door passes the mass west of the middle, ``Φ(−1)`` = 0.159 of
    it, while the east door jams.  Hughes' route, the travel time at the crowd's speed, sends the crowd round
    the queue to the west door: it passes more than twice the geodesic's share, and everyone is out by 30 s,
    where the geodesic crowd is not."""
    west, out = {}, {}
    for guidance in ("geodesic", "hughes"):
        loop, peak = _run(_two_doors(guidance), 30.0)
        crowd = loop.crowd
        per_exit = crowd.out_per_exit / crowd.initial_mass
        west[guidance], out[guidance] = float(per_exit[0]), float(per_exit.sum())
        assert peak <= 5.4 * (1 + 1e-12)  # the jam density, never exceeded
        assert crowd.remaining_fraction() + out[guidance] == pytest.approx(1.0, abs=1e-12)
    assert west["geodesic"] == pytest.approx(0.5 * math.erfc(1 / math.sqrt(2)), abs=0.005)  # Φ(−1)
    assert west["hughes"] > 2 * west["geodesic"]  # measured 0.52 against 0.16
    assert out["hughes"] > 0.999 and out["geodesic"] < 0.9  # measured 1.000 and 0.55


def test_hughes_density_never_exceeds_the_jam_density_in_front_of_a_narrow_door():
    """60 people (3 persons/m²) in a room 5 m × 4 m with a door of 0.5 m, σ = 0.05 m²/s: the queue in front of
    the door packs close to the jam density (above 90 % of it) and never beyond it; the door passes at most its
    capacity ``q_max b``; no mass is lost."""
    for congestion in ("linear", "weidmann"):
        room = Domain.box(5.0, 4.0, exits=[((5.0, 1.75), (5.0, 2.25))])
        sc = paper_scenario(seed=0).replace(domain=room, units="SI", dt=0.05, t_final=15.0)
        sc = sc.with_values(
            {
                "grid.cells": [50, 40],
                "crowd.kind": "fokker-planck",
                "crowd.n": 60,
                "crowd.sigma": 0.05,
                "crowd.guidance": "hughes",
                "crowd.congestion": congestion,
                "robots.n": 1,
                "controller.kind": "static-signs",
                "target.center": [2.5, 2.0],
                "target.std": 1.0,
            }
        )
        loop, peak = _run(sc, 15.0)
        crowd = loop.crowd
        assert 0.9 * 5.4 < peak <= 5.4 * (1 + 1e-12), (congestion, peak)  # measured 5.31 (linear), 5.18
        q_max = crowd.fp.congestion.door * 60  # persons/(m·s)
        persons_out = 60 * float(crowd.out_per_exit.sum()) / crowd.initial_mass
        assert persons_out <= q_max * 0.5 * 15.0 * (1 + 1e-12)
        assert crowd.remaining_fraction() + persons_out / 60 == pytest.approx(1.0, abs=1e-12)


def test_hughes_without_congestion_is_the_geodesic_crowd_exactly():
    """``crowd.congestion = "none"``: ``f ≡ v₀``, Hughes' potential is the distance over ``v₀`` whatever the
    density, and the density-dependent drift (asked every period, its exits' rates refreshed from it) leaves
    the corridor exactly as the geodesic crowd does."""
    t_h, out_h, loop = _outflow(_corridor("none", **{"crowd.guidance": "hughes"}), 8.0)
    t_g, out_g, _ = _outflow(_corridor("none"), 8.0)
    assert loop.crowd.guidance.velocity_of is not None and loop.crowd.guidance.velocity is None
    np.testing.assert_array_equal(t_h, t_g)
    np.testing.assert_allclose(out_h, out_g, rtol=1e-13, atol=1e-15)
    assert out_h[-1] > 0.7  # the drift's outflow, not the diffusion's (σ = 0)
