"""Target density and evacuation metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, Grid, fraction_in_disk, gaussian_target, target_region_radius
from meanfield.simulation.wasserstein import wasserstein2_to_grid_density

R95 = math.sqrt(2 * math.log(20))  # 1 - exp(-r²/(2s²)) = 0.95  =>  r = s·sqrt(2 ln 20)


def test_target_region_radius_inside():
    """A Gaussian well inside the box (5 std from every wall, mass outside < 1e-6): the
    95 % disk has radius std·sqrt(2 ln 20), within the lattice resolution diam/samples."""
    box = Domain.box(1.0, 1.0)
    r = target_region_radius(box, (0.5, 0.5), 0.1, samples=800)
    assert abs(r - 0.1 * R95) <= box.diameter / 800


def test_target_region_radius_in_a_corner():
    """Centred on a corner, Ω holds a quarter of the Gaussian and the quarter disk of radius
    std·sqrt(2 ln 20) holds 95 % of that quarter (radial symmetry)."""
    box = Domain.box(1.0, 1.0)
    r = target_region_radius(box, (0.0, 0.0), 0.1, samples=800)
    assert abs(r - 0.1 * R95) <= box.diameter / 800
    r = target_region_radius(box, (1.0, 1.0), 0.15, samples=800)
    assert abs(r - 0.15 * R95) <= box.diameter / 800


def test_fraction_in_disk():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [3.0, 3.0], [0.6, 0.8]])
    assert fraction_in_disk(pts, (0.0, 0.0), 1.0) == pytest.approx(3 / 5)  # boundary points count
    assert fraction_in_disk(pts, (0.0, 0.0), 0.5) == pytest.approx(1 / 5)
    assert fraction_in_disk(pts, (10.0, 10.0), 1.0) == 0.0
    assert fraction_in_disk(pts, (0.0, 0.0), 100.0) == 1.0


def test_gaussian_target_unit_mass_and_peak(domain):
    g = Grid(domain, (21, 19))
    t = gaussian_target(g, domain.center, 0.2)
    assert g.integrate(t) == pytest.approx(1.0, rel=1e-13)
    X, Y = g.centers
    d2 = (X - domain.center[0]) ** 2 + (Y - domain.center[1]) ** 2
    ratio = t[g.active] / np.exp(-d2[g.active] / (2 * 0.04))
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-12)  # proportional to the Gaussian


def test_w2_zero_for_points_on_the_cells():
    g = Grid(Domain.box(1.0, 1.0), (10, 10))
    cells = [(1, 2), (5, 5), (7, 3), (9, 0)]
    dens = np.zeros(g.shape)
    for i, j in cells:
        dens[i, j] = 1.0
    pts = np.array([[g.x[i], g.y[j]] for i, j in cells])
    assert wasserstein2_to_grid_density(pts, g, dens) <= 1e-7


def test_w2_of_a_shifted_point_mass_is_the_shift():
    g = Grid(Domain.box(1.0, 1.0), (10, 10))
    dens = np.zeros(g.shape)
    dens[4, 4] = 7.0
    pts = np.tile([g.x[4] + 0.03, g.y[4] - 0.04], (6, 1))
    assert wasserstein2_to_grid_density(pts, g, dens) == pytest.approx(0.05, rel=1e-10)


def test_w2_two_cells_closed_form():
    """Half the mass on each of two cells, points all on the first: W₂² = ½·distance²."""
    g = Grid(Domain.box(1.0, 1.0), (10, 10))
    dens = np.zeros(g.shape)
    dens[2, 2] = dens[6, 2] = 1.0
    pts = np.tile([g.x[2], g.y[2]], (4, 1))
    d = g.x[6] - g.x[2]
    assert wasserstein2_to_grid_density(pts, g, dens) == pytest.approx(d / math.sqrt(2), rel=1e-10)


def test_w2_coarsened_grid_keeps_point_masses_exact_and_smooth_densities_within_the_bound(rng):
    """Merging b × b cells puts each block's mass at its centre of mass: a single occupied
    cell per block is not moved at all, and a smooth density moves by at most one block
    diagonal (the documented bound)."""
    from meanfield.simulation.wasserstein import w2_block_size

    g = Grid(Domain.box(1.0, 1.0), (40, 40))
    assert w2_block_size(g, 1600) == 1 and w2_block_size(g, 100) == 4 and w2_block_size(g, 99) == 5
    dens = np.zeros(g.shape)
    dens[2, 2] = dens[26, 2] = 1.0
    pts = np.tile([g.x[2], g.y[2]], (4, 1))
    d = g.x[26] - g.x[2]
    assert wasserstein2_to_grid_density(pts, g, dens, max_cells=100) == pytest.approx(d / math.sqrt(2), rel=1e-10)
    X, Y = g.centers
    smooth = np.exp(-((X - 0.4) ** 2 + (Y - 0.6) ** 2) / 0.05)
    pts = rng.normal([0.5, 0.5], 0.15, size=(400, 2))
    fine = wasserstein2_to_grid_density(pts, g, smooth)
    coarse = wasserstein2_to_grid_density(pts, g, smooth, max_cells=100)
    assert fine != coarse
    assert abs(fine - coarse) <= 4 * math.hypot(g.dx, g.dy)


def test_a_target_narrower_than_the_cells_is_refused_naming_its_width():
    """``target.std = 1e-300`` was reported as ``density = 'mass 0.0'`` (issue "Nothing lost", item 7)."""
    from meanfield import ClosedLoop, ParameterError, paper_scenario

    with pytest.raises(ParameterError) as exc:
        ClosedLoop(paper_scenario(seed=0).with_values({"target.std": 1e-300}))
    assert exc.value.name == "target.std" and "cell" in str(exc.value)
