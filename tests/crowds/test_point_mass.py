"""The human crowd: Euler–Maruyama step of eq. (1) with reflecting walls."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from meanfield import Domain, ParameterError, PointMassEngine
from meanfield._compiled.philox import standard_normals


def test_step_is_euler_maruyama(rng):
    """X' = X + dt·drift + sqrt(2σ dt)·ξ with ξ the counter-based draws of (noise seed, step, human), the
    noise seed drawn from a child of the run's generator (which leaves the generator's own stream alone)."""
    box = Domain.box(10.0, 10.0)
    x = rng.uniform(4.0, 6.0, size=(100, 2))
    drift = rng.normal(size=(100, 2))
    sigma, dt = 0.3, 0.01
    crowd = PointMassEngine(x, box, sigma, np.random.default_rng(5))
    gen = np.random.default_rng(5)
    assert crowd.noise_seed == int(gen.spawn(1)[0].integers(0, 2**64, dtype=np.uint64))
    assert crowd.rng.random() == gen.random()  # the run's own stream untouched
    crowd.step(drift, 0.0, dt)
    xi = standard_normals(crowd.noise_seed, 0, np.empty((100, 2)))
    np.testing.assert_allclose(crowd.positions, x + dt * drift + math.sqrt(2 * sigma * dt) * xi, rtol=1e-15)
    y = crowd.positions.copy()
    crowd.step(drift, dt, dt)  # the next step: the next counter
    xi = standard_normals(crowd.noise_seed, 1, np.empty((100, 2)))
    np.testing.assert_allclose(crowd.positions, y + dt * drift + math.sqrt(2 * sigma * dt) * xi, rtol=1e-15)


def test_callable_sigma(rng):
    box = Domain.box(10.0, 10.0)
    x = rng.uniform(4.0, 6.0, size=(50, 2))
    crowd = PointMassEngine(x, box, lambda X, Y, t: 0.1 * X, np.random.default_rng(9))
    crowd.step(np.zeros((50, 2)), 0.0, 0.01)
    xi = standard_normals(crowd.noise_seed, 0, np.empty((50, 2)))
    np.testing.assert_allclose(crowd.positions, x + np.sqrt(2 * 0.1 * x[:, :1] * 0.01) * xi, rtol=1e-14)
    bad = PointMassEngine(x, box, lambda X, Y, t: -1.0 + 0 * X, rng)
    with pytest.raises(ParameterError) as info:
        bad.step(np.zeros((50, 2)), 0.0, 0.01)
    assert info.value.name == "crowd.sigma"


def test_no_agent_ever_leaves(domain, rng):
    """Huge random drifts and noise (steps many times the domain's size): always inside Ω."""
    x = domain.sample_uniform(2000, rng)
    crowd = PointMassEngine(x, domain, 1.0, rng)
    for k in range(40):
        scale = 10.0 ** (k % 4)  # drifts of 1 to 1000 per unit time
        crowd.step(rng.normal(scale=scale, size=x.shape), 0.1 * k, 0.1)
        p = crowd.positions
        assert np.isfinite(p).all()
        assert domain.contains(p[:, 0], p[:, 1]).all()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"sigma": -0.1}, "crowd.sigma"),
        ({"sigma": float("nan")}, "crowd.sigma"),
        ({"positions": np.zeros((0, 2))}, "crowd.positions"),
        ({"positions": np.array([[0.5, 0.5], [1.5, 0.5]])}, "crowd.positions"),
        ({"positions": np.array([[0.5, np.nan]])}, "crowd.positions"),
    ],
)
def test_bad_input_refused(kwargs, name, rng):
    args = {"positions": np.array([[0.5, 0.5]]), "domain": Domain.box(), "sigma": 0.1, "rng": rng}
    args.update(kwargs)
    with pytest.raises(ParameterError) as info:
        PointMassEngine(**args)
    assert info.value.name == name


# ---------------------------------------------------------------------- uniformity
ALPHA = 1e-3  # false-alarm rate of the chi-square test below
CELLS = 8


def _chi_square_uniform(points: np.ndarray) -> tuple[float, float]:
    """Pearson's statistic of the counts on a CELLS×CELLS partition of the unit box, and
    the critical value at level ALPHA (chi-square with CELLS² - 1 degrees of freedom)."""
    counts, _, _ = np.histogram2d(points[:, 0], points[:, 1], bins=CELLS, range=[[0, 1], [0, 1]])
    expected = len(points) / CELLS**2
    stat = float(((counts - expected) ** 2 / expected).sum())
    return stat, float(stats.chi2.ppf(1 - ALPHA, CELLS**2 - 1))


def _diffuse(domain, drift, dt=0.01, steps=200, n=4000, seed=11):
    rng = np.random.default_rng(seed)
    crowd = PointMassEngine(rng.uniform(size=(n, 2)), domain, 0.01, rng)
    d = np.broadcast_to(np.asarray(drift, float), (n, 2))
    for k in range(steps):
        crowd.step(d, dt * k, dt)
    return crowd.positions


def test_reflecting_walls_keep_a_uniform_crowd_uniform():
    """4000 uniform humans, pure diffusion (σ = 0.01, dt = 0.01, 200 steps: each human
    diffuses about 0.2, well across the walls), then Pearson's chi-square test of the
    8×8 cell counts against the uniform law at level α = 0.001.

    Uniform is the stationary law of reflected Brownian motion, so under a correct wall
    rule this test fails with probability 0.001 for a random seed; the seed is fixed, so
    the test is deterministic.
    """
    p = _diffuse(Domain.box(1.0, 1.0), (0.0, 0.0))
    stat, critical = _chi_square_uniform(p)
    assert stat < critical


class _ClippingWalls:
    """A deliberately wrong wall rule: clip to the box instead of reflecting."""

    def __init__(self, domain: Domain):
        self.domain = domain

    def contains(self, x, y, tol=0.0):
        return self.domain.contains(x, y, tol)

    def reflect(self, points):
        return self.domain.project(points)


def test_chi_square_has_power_against_a_wrong_wall_rule():
    """The same statistic rejects a crowd whose walls clip, pushed toward the left wall
    by a drift of 0.05 (humans pile up on the wall)."""
    p = _diffuse(_ClippingWalls(Domain.box(1.0, 1.0)), (-0.05, 0.0))
    stat, critical = _chi_square_uniform(p)
    assert stat > critical


def test_chi_square_separates_reflecting_from_clipping_walls():
    """Pure diffusion with coarse steps (dt = 0.25, step std sqrt(2σ dt) ≈ 0.07, 8 steps):
    only the wall rule differs.  Reflection passes (again at false-alarm rate 0.001, fixed
    seed); clipping piles humans on the walls and the statistic rejects it.

    16 000 humans: with 4 000 the test had about even odds against clipping (over seeds 0-19
    its statistic was 82-128 against the critical 103.4, rejected on 10); with 16 000 it was
    222-333 on every one of those seeds, and reflection at most 79."""
    box = Domain.box(1.0, 1.0)
    stat, critical = _chi_square_uniform(_diffuse(box, (0.0, 0.0), dt=0.25, steps=8, n=16000))
    assert stat < critical
    stat, critical = _chi_square_uniform(_diffuse(_ClippingWalls(box), (0.0, 0.0), dt=0.25, steps=8, n=16000))
    assert stat > critical
