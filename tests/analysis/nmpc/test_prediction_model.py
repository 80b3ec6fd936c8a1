"""The coarse Fokker–Planck model of the NMPC (analysis.nmpc.prediction_model) against exact answers:
mass, walls, diffusion modes, positivity, the navigation field at the faces, the restriction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.nmpc import CoarseFokkerPlanck
from meanfield import Domain, Grid
from meanfield.signs.robots import navigation_velocity
from tests.analysis.nmpc.conftest import KERNEL, model, random_density, random_robots, zero_velocity


@pytest.mark.parametrize("flux", ["upwind", "central"])
def test_coarse_step_conserves_mass_to_round_off(flux, rng):
    m = model(flux=flux, step=1.0)
    rho = random_density(m, rng)
    for _ in range(3):
        vel = m.face_velocity(*random_robots(3, rng))
        assert abs(m.mass(m.rate(rho, vel))) < 1e-14
        rho = m.step_density(rho, vel)
        assert m.mass(rho) == pytest.approx(1.0, abs=1e-13)


def test_walls_carry_no_flux():
    """σ = 0 and a field pushing into the right wall: mass piled against it stays, exactly."""
    m = model(sigma=0.0, step=5.0)
    nx, ny = m.shape
    vx, vy = np.full((nx - 1, ny), 0.3), np.zeros((nx, ny - 1))
    rho = np.zeros(m.shape)
    rho[-1, :] = 1.0
    rho /= m.mass(rho)
    assert np.array_equal(m.rate(rho, (vx, vy)), np.zeros(m.shape))
    assert np.allclose(m.step_density(rho, (vx, vy)), rho, rtol=0, atol=1e-15)
    # and a uniform density is pushed against the wall without losing mass
    flat = np.full(m.shape, 1.0 / m.mass(np.ones(m.shape)))
    after = m.step_density(flat, (vx, vy))
    assert m.mass(after) == pytest.approx(1.0, abs=1e-13)
    assert after[-1].sum() > flat[-1].sum() and after[0].sum() < flat[0].sum()


def test_no_field_no_noise_is_stationary(rng):
    m = model(sigma=0.0)
    rho = random_density(m, rng)
    assert np.array_equal(m.rate(rho, zero_velocity(m)), np.zeros(m.shape))
    assert np.allclose(m.step_density(rho, zero_velocity(m)), rho, rtol=1e-15, atol=0)


@pytest.mark.parametrize(("k", "l"), [(1, 0), (2, 3), (6, 4)])
def test_diffusion_of_a_cosine_mode_has_the_exact_discrete_factor(k, l):
    """Backward Euler on the Neumann Laplacian: the mode cos(πk(i+½)/nx) cos(πl(j+½)/ny)
    is multiplied by 1 / (1 + Δt σ (4/Δx² sin²(πk/2nx) + 4/Δy² sin²(πl/2ny)))."""
    sigma, step = 0.02, 0.3
    m = model(sigma=sigma, step=step)
    nx, ny = m.shape
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    mode = np.cos(np.pi * k * (i + 0.5) / nx) * np.cos(np.pi * l * (j + 0.5) / ny)
    lam = 4 / m.dx**2 * math.sin(math.pi * k / (2 * nx)) ** 2 + 4 / m.dy**2 * math.sin(math.pi * l / (2 * ny)) ** 2
    after = m.step_density(1.0 + 0.5 * mode, zero_velocity(m))
    np.testing.assert_allclose(after - 1.0, 0.5 * mode / (1 + step * sigma * lam), rtol=0, atol=1e-13)


def test_upwind_step_keeps_the_density_positive_for_any_step(rng):
    m = model(sigma=0.001, step=50.0, n=6)
    rho = np.zeros(m.shape)
    rho[3, 2] = 1.0 / m.cell_volume  # a point mass
    vel = m.face_velocity(*random_robots(6, rng))
    assert m.step_density(rho, vel).min() >= -1e-15


def test_face_velocity_is_the_navigation_field_at_the_faces(rng):
    m = model(n=4)
    pos, heads = random_robots(4, rng)
    vx, vy = m.face_velocity(pos, heads)
    X, Y = np.meshgrid(m.x_faces, m.y, indexing="ij")
    ref = navigation_velocity(KERNEL, pos, heads, np.column_stack([X.ravel(), Y.ravel()]))
    np.testing.assert_allclose(vx.ravel(), ref[:, 0], rtol=1e-12, atol=1e-15)
    X, Y = np.meshgrid(m.x, m.y_faces, indexing="ij")
    ref = navigation_velocity(KERNEL, pos, heads, np.column_stack([X.ravel(), Y.ravel()]))
    np.testing.assert_allclose(vy.ravel(), ref[:, 1], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("cells", [(10, 10), (12, 7)])
def test_restriction_averages_and_keeps_unit_mass(cells, rng):
    fine = Grid(Domain.box(1.1, 0.9, origin=(-0.3, 0.7)), cells=(30, 30))
    m = CoarseFokkerPlanck(fine.domain.bounds, cells, 0.01, KERNEL, 1, 0.1)
    rho = fine.normalize(rng.uniform(0.5, 1.5, fine.shape))
    rc = m.restrict(rho, fine)
    assert m.mass(rc) == pytest.approx(1.0, abs=1e-13)
    if cells == (10, 10):  # whole 3×3 blocks: the block means
        np.testing.assert_allclose(rc, rho.reshape(10, 3, 10, 3).mean(axis=(1, 3)), rtol=1e-13)
