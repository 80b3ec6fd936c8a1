"""Finite-volume grid: cut cells, exact operators, summation by parts, interpolation."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from meanfield import Domain, Grid, ParameterError

from .conftest import PENTAGON


def _grid(domain: Domain) -> Grid:
    return Grid(domain, cells=(17, 23))


def test_summation_by_parts(domain, rng):
    """<f, div F> = -<grad f, F> for random f, F: the discrete operators are adjoint (cut cells too)."""
    g = _grid(domain)
    nx, ny = g.shape
    f = rng.normal(size=(nx, ny))
    F = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
    lhs = g.inner(f, g.divergence(F))
    rhs = -g.face_inner(g.gradient(f), F)
    scale = g.inner(np.abs(f), np.abs(g.divergence(F)))
    assert abs(lhs - rhs) <= 1e-13 * scale


def test_divergence_of_unit_field_on_box_is_the_wall_flux():
    """F = (1, 0) on interior faces, zero through the walls: div F = +1/dx in the first column
    (flux leaves through its right face), -1/dx in the last, 0 elsewhere (Gauss' theorem per cell)."""
    g = Grid(Domain.box(1.0, 1.0), (4, 3))
    F = (np.ones((3, 3)), np.zeros((4, 2)))
    div = g.divergence(F)
    expected = np.zeros((4, 3))
    expected[0] = 1.0 / g.dx
    expected[-1] = -1.0 / g.dx
    np.testing.assert_allclose(div, expected, rtol=0, atol=1e-12)


def test_divergence_matches_hand_written_box_formula(rng):
    """div F[i,j] = (F_{i+1/2,j} - F_{i-1/2,j})/dx + (F_{i,j+1/2} - F_{i,j-1/2})/dy with zero wall fluxes."""
    g = Grid(Domain.box(2.0, 1.0, origin=(0.5, -1.0)), (9, 7))
    Fx = rng.normal(size=(8, 7))
    Fy = rng.normal(size=(9, 6))
    px = np.pad(Fx, ((1, 1), (0, 0)))
    py = np.pad(Fy, ((0, 0), (1, 1)))
    expected = (px[1:] - px[:-1]) / g.dx + (py[:, 1:] - py[:, :-1]) / g.dy
    np.testing.assert_allclose(g.divergence((Fx, Fy)), expected, rtol=1e-13, atol=1e-12)


def test_divergence_conserves_mass(domain, rng):
    """Zero flux through the walls: ∫ div F = 0 exactly (to round-off) on every shape."""
    g = _grid(domain)
    nx, ny = g.shape
    F = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
    div = g.divergence(F)
    assert abs(g.integrate(div)) <= 1e-13 * g.integrate(np.abs(div))


def test_gradient_of_linear_function_is_exact(domain):
    g = _grid(domain)
    X, Y = g.centers
    gx, gy = g.gradient(3.0 * X - 2.0 * Y + 1.0)
    open_x = g.aperture_x > 0
    open_y = g.aperture_y > 0
    np.testing.assert_allclose(gx[open_x], 3.0, rtol=1e-12)
    np.testing.assert_allclose(gy[open_y], -2.0, rtol=1e-12)
    # closed faces (outside Ω) carry nothing
    assert np.all(gx[~open_x] == 0) and np.all(gy[~open_y] == 0)


def test_cell_areas_are_exact():
    box = Grid(Domain.box(1.5, 0.5, origin=(0.0, 2.0)), (7, 5))
    assert box.area == pytest.approx(0.75, rel=1e-14)
    poly = Grid(Domain.polygon(PENTAGON), (17, 23))
    assert poly.area == pytest.approx(shapely.Polygon(PENTAGON).area, rel=1e-13)
    disk = Grid(Domain.disk(0.8, center=(0.2, -0.1)), (17, 23))
    # the disk is a 4096-gon: relative area error 2π²/(3·4096²) ≈ 3.9e-7
    assert disk.area == pytest.approx(math.pi * 0.64, rel=5e-7)


def test_integrate_quadratic_on_box_midpoint_rule():
    """Midpoint rule: ∫_0^1∫_0^1 x² dx dy = 1/3 - dx²/12 exactly on n cells."""
    g = Grid(Domain.box(1.0, 1.0), (10, 4))
    X, _ = g.centers
    assert g.integrate(X**2) == pytest.approx(1 / 3 - g.dx**2 / 12, rel=1e-14)


def test_staircase_mask():
    g = Grid(Domain.disk(1.0), (20, 20), cut_cells=False)
    X, Y = g.centers
    inside = X**2 + Y**2 <= 1.0
    np.testing.assert_array_equal(g.active, inside)
    np.testing.assert_array_equal(g.volume_fraction, inside.astype(float))


def test_interpolate_is_exact_for_bilinear_functions(rng):
    g = Grid(Domain.box(1.0, 2.0), (8, 11))
    X, Y = g.centers
    f = 1.0 + 2.0 * X - 0.5 * Y + 3.0 * X * Y
    # inside the hull of the cell centres
    p = rng.uniform([g.x[0], g.y[0]], [g.x[-1], g.y[-1]], size=(200, 2))
    expected = 1.0 + 2.0 * p[:, 0] - 0.5 * p[:, 1] + 3.0 * p[:, 0] * p[:, 1]
    np.testing.assert_allclose(g.interpolate(f, p), expected, rtol=1e-13, atol=1e-13)


def test_face_inner_weights_on_box():
    """On a box every interior face weight is dx·dy: <1, 1> = dx dy (#x-faces + #y-faces)."""
    g = Grid(Domain.box(1.0, 1.0), (5, 4))
    one = (np.ones((4, 4)), np.ones((5, 3)))
    assert g.face_inner(one, one) == pytest.approx(g.dx * g.dy * (16 + 15), rel=1e-14)


def test_normalize_gives_unit_mass_and_refuses_zero(domain):
    g = _grid(domain)
    f = g.normalize(np.ones(g.shape))
    assert g.integrate(f) == pytest.approx(1.0, rel=1e-13)
    assert np.all(f[~g.active] == 0)
    with pytest.raises(ParameterError):
        g.normalize(np.zeros(g.shape))


@pytest.mark.parametrize("cells", [(1, 5), (5, 1), (2.5, 3), "ab"])
def test_bad_cells_refused(cells):
    with pytest.raises(ParameterError) as info:
        Grid(Domain.box(), cells)
    assert info.value.name == "cells"


def test_clipping_slivers_are_not_cells():
    """A polygon vertex grazing a cell leaves a round-off sliver (volume fraction ~1e-30
    on this grid); it is not a cell: every active cell holds a real share of volume."""
    g = Grid(Domain.polygon([(0.0, 0.0), (1.0, 0.0), (0.3, 0.9)]), cells=(40, 40))
    assert g.volume_fraction[g.active].min() > 1e-6
    assert abs(g.area - 0.45) < 1e-9
