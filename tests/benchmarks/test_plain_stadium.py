"""The frozen plain stadium step (``benchmarks/plain_stadium.py``) against ``ClosedLoop`` on the same scenario.

A small crowd (2000 humans; the stadium's 64 robots, 128² grid and every other number), so
that the toolkit evaluates ``v_r`` exactly at each human (128 000 pairs, below ``"auto"``'s
2·10⁶) and its KDE term by term (``"separable"``: 2000·128² ≤ 5·10⁷).  The random draws
differ, so the comparisons are of the deterministic parts: the crowd's step with σ = 0,
the law (eqs. (6), (8)) on the same density, and the KDE against the exact sum over the
binned positions.  No speed is asserted.
"""

from __future__ import annotations

import numpy as np

from benchmarks.plain_stadium import PlainStadiumStep, stadium_numbers
from meanfield import ClosedLoop
from meanfield.scenarios.scenario import stadium_scenario

N = 2000
ROUND_OFF = 1e-12  # eqs. evaluated with the same formulas in another order: ~1e-15 relative, measured 4e-15


def _pair(sigma: float | None = None, seed: int = 3) -> tuple[ClosedLoop, PlainStadiumStep]:
    """The toolkit's loop and the plain step, from the same initial state."""
    values: dict = {"crowd.n": N, "crowd.field_evaluation": "exact"}
    if sigma is not None:
        values["crowd.sigma"] = sigma
    loop = ClosedLoop(stadium_scenario(seed=seed).with_values(values))
    numbers = stadium_numbers(N)
    if sigma is not None:
        numbers["sigma"] = sigma
    plain = PlainStadiumStep(
        seed=seed,
        positions=loop.crowd.positions.copy(),
        robots=loop.robots.positions.copy(),
        headings=loop.robots.headings.copy(),
        **numbers,
    )
    return loop, plain


def test_numbers_are_the_stadium_scenarios() -> None:
    sc = stadium_scenario()
    n = stadium_numbers()
    assert (n["n_humans"], n["n_robots"], n["cells"]) == (1_000_000, 64, 128)
    assert (n["h"], n["eta"], n["c"], n["sigma"]) == (sc.density.bandwidth, sc.kernel.eta, sc.kernel.c, sc.crowd.sigma)
    assert (n["k_u"], n["k_w"], n["rho_floor"], n["alpha0"]) == (10.0, 10.0, 2.0, 0.2)
    assert stadium_numbers(N)["n_humans"] == N


def test_crowd_step_without_noise_matches_closed_loop_to_round_off() -> None:
    """σ = 0: one step moves every human by ``v_r dt`` (eq. (3) summed exactly, eq. (1)), then the walls."""
    loop, plain = _pair(sigma=0.0)
    x0 = loop.crowd.positions.copy()
    loop.step()
    plain.step()
    ours, theirs = loop.crowd.positions - x0, plain.X - x0
    scale = np.abs(theirs).max()
    assert scale > 1e-3  # the crowd moves (c dt = 2e-3 at most per robot; 7e-3 measured)
    assert np.abs(ours - theirs).max() <= ROUND_OFF * scale
    assert np.allclose(ours.mean(0), theirs.mean(0), rtol=0, atol=ROUND_OFF * scale)


def test_navigation_velocity_at_fixed_points() -> None:
    """``v_r`` at a lattice of points, against the crowd's drift at the same points (σ = 0: drift·dt is the step)."""
    loop, plain = _pair(sigma=0.0)
    g = (np.arange(17) + 0.5) / 17
    pts = np.column_stack([a.ravel() for a in np.meshgrid(g, g, indexing="ij")])
    loop.crowd.positions[: len(pts)] = pts
    plain.X[: len(pts)] = pts
    ours = loop.crowd.drift(loop.robots, 0.0, loop.dt)[: len(pts)]
    theirs = plain.navigation_velocity(pts)
    assert np.abs(theirs).max() > 0.05  # c = 0.2: a robot's kernel is felt across the room
    assert np.abs(ours - theirs).max() <= ROUND_OFF * np.abs(theirs).max()


def test_law_on_the_same_densities_matches_to_round_off() -> None:
    """Steps I and II (eqs. (6), (8)), minimum-norm β/γ, saturated: two steps, so ``∂_t v_d`` is a difference."""
    loop, plain = _pair()
    for _ in range(2):
        record = loop.step()
        u, omega = plain.robot_inputs(record.observation.density)
        plain.R, plain.theta = loop.robots.positions.copy(), loop.robots.headings.copy()
        assert np.abs(record.u).max() > 0.1 and np.abs(record.omega).max() > 0.1  # (a real command)
        assert np.abs(u - record.u).max() <= ROUND_OFF
        assert np.abs(omega - record.omega).max() <= ROUND_OFF * 10  # |ω| up to 3, |u| up to 0.2


def test_binned_kde_is_the_exact_kde_of_the_binned_crowd() -> None:
    """The plain KDE moves each human to its cell's centre, and is otherwise the exact sum with wall images."""
    loop, plain = _pair()
    d = 1.0 / plain.m
    snapped = (np.minimum(np.floor(plain.X / d), plain.m - 1) + 0.5) * d
    exact = loop.crowd.kde(snapped)  # the toolkit's term-by-term KDE (2000 · 128² ≤ 5e7: "separable")
    binned = plain.density()
    assert np.abs(binned - exact).max() <= ROUND_OFF * exact.max()
    # and against the unbinned crowd, the binning's error: each human moves by up to d/2 = h/7.7
    err = np.abs(binned - loop.density).max() / loop.density.max()
    assert 1e-4 < err < 0.06  # measured 0.029 at N = 2000 (it falls like N^-1/2: the offsets' mean is 0)


def test_one_step_agrees_with_closed_loop_within_the_binning() -> None:
    """One full step with σ = 0: the crowd's mean to round-off, the robots within the KDE's binning."""
    loop, plain = _pair(sigma=0.0)
    x0, r0 = loop.crowd.positions.copy(), loop.robots.positions.copy()
    loop.step()
    plain.step()
    mean_ours, mean_theirs = (loop.crowd.positions - x0).mean(0), (plain.X - x0).mean(0)
    assert np.abs(mean_theirs).max() > 1e-4
    assert np.abs(mean_ours - mean_theirs).max() <= ROUND_OFF
    # the law differs only through the density (previous test: 3 % at most); allowed: a tenth of the
    # largest step u_max dt = 2e-3 and ω_max dt = 3e-2 (measured 5.6e-5 and 4.1e-5)
    moved = np.abs(loop.robots.positions - r0).max()
    assert moved > 1e-3
    assert np.abs(loop.robots.positions - plain.R).max() <= 0.1 * 0.2 * loop.dt
    turn = np.angle(np.exp(1j * (loop.robots.headings - plain.theta)))
    assert np.abs(turn).max() <= 0.1 * 3.0 * loop.dt


def test_noise_and_walls() -> None:
    """Euler–Maruyama (eq. (1)): the step minus ``v_r dt`` has the spread ``sqrt(2σ dt)``; all stay in the box."""
    sigma = 0.015  # the stadium's
    _, plain = _pair(sigma=sigma)
    plain.X = np.random.default_rng(1).uniform(0.2, 0.8, (20_000, 2))  # away from the walls: no reflection
    plain.X[:1000] = (1e-4, 1 - 1e-4)  # at a corner: half of them would step out
    drift = plain.navigation_velocity(plain.X) * plain.dt
    before = plain.X.copy()
    plain.step()
    noise = (plain.X - before - drift)[1000:]
    assert abs(noise.std() / np.sqrt(2 * sigma * plain.dt) - 1) < 0.03  # 38 000 draws: the std's error 0.4 %
    assert abs(noise.mean()) < 0.03 * np.sqrt(2 * sigma * plain.dt)
    corner = plain.X[:1000]
    assert corner.min() >= 0 and corner.max() <= 1 and (corner[:, 0] < 0.1).all() and (corner[:, 1] > 0.9).all()
