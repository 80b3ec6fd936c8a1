"""Finite-volume grid: cut cells, exact operators, summation by parts, interpolation."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from meanfield import Domain, Grid, ParameterError
from tests.conftest import PENTAGON


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
    # the true circle, not a polygon: exact to round-off
    assert disk.area == pytest.approx(math.pi * 0.64, rel=1e-14)


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


# ---------------------------------------------------------------------- cut-cell geometry
HEXAGON = [(math.cos(k * math.pi / 3 + 0.2), math.sin(k * math.pi / 3 + 0.2)) for k in range(6)]
THIN_TRIANGLE = [(0.0, 0.0), (1.0, 0.0), (0.3, 0.9)]


def _clip_every_cell(domain: Domain, cells: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The brute-force reference: shapely clips every cell and every face with Ω (Grid's old method)."""
    g = Grid(domain, cells, cut_cells=False)  # only for dx, dy
    nx, ny = cells
    poly = shapely.Polygon(domain.vertices)
    x0, _, y0, _ = domain.bounds
    xe = x0 + np.arange(nx + 1) * g.dx
    ye = y0 + np.arange(ny + 1) * g.dy
    XL, YL = np.meshgrid(xe[:-1], ye[:-1], indexing="ij")
    frac = shapely.area(shapely.intersection(shapely.box(XL, YL, XL + g.dx, YL + g.dy), poly)) / (g.dx * g.dy)
    frac = np.clip(frac, 0.0, 1.0)
    frac[frac < 1e-12] = 0.0

    def apertures(xa, ya, xb, yb, length):
        seg = shapely.linestrings(np.stack([np.stack([xa, ya], -1), np.stack([xb, yb], -1)], axis=-2))
        return np.clip(shapely.length(shapely.intersection(seg, poly)) / length, 0.0, 1.0)

    XF, YF = np.meshgrid(xe[1:-1], ye[:-1], indexing="ij")
    ax = apertures(XF, YF, XF, YF + g.dy, g.dy)
    XF, YF = np.meshgrid(xe[:-1], ye[1:-1], indexing="ij")
    ay = apertures(XF, YF, XF + g.dx, YF, g.dx)
    act = frac > 0
    ax = np.where(act[1:, :] & act[:-1, :], ax, 0.0)
    ay = np.where(act[:, 1:] & act[:, :-1], ay, 0.0)
    return frac, ax, ay


@pytest.mark.parametrize("vertices", [PENTAGON, HEXAGON, THIN_TRIANGLE], ids=["pentagon", "hexagon", "thin-triangle"])
@pytest.mark.parametrize("cells", [(17, 23), (64, 64)])
def test_polygon_cut_cells_equal_clipping_every_cell(vertices, cells):
    """Clipping only the cells the wall crosses gives what clipping every cell gives."""
    dom = Domain.polygon(vertices)
    g = Grid(dom, cells)
    frac, ax, ay = _clip_every_cell(dom, cells)
    np.testing.assert_allclose(g.volume_fraction, frac, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.aperture_x, ax, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.aperture_y, ay, rtol=0, atol=1e-12)
    # the same cells and faces are open
    np.testing.assert_array_equal(g.active, frac > 0)
    np.testing.assert_array_equal(g.aperture_x > 0, ax > 0)
    np.testing.assert_array_equal(g.aperture_y > 0, ay > 0)


@pytest.mark.parametrize(
    ("radius", "center", "cells"),
    [
        (1.0, (0.0, 0.0), (128, 128)),
        (0.8, (0.2, -0.1), (17, 23)),
        (2.5, (1e3, -300.0), (90, 61)),
        (1.0, (0, 0), (3, 3)),
    ],
)
def test_disk_volume_fractions_sum_to_the_exact_area(radius, center, cells):
    """The disk is the true circle: Σ volume fractions = π r²/(dx dy) to round-off."""
    g = Grid(Domain.disk(radius, center=center), cells)
    assert g.volume_fraction.sum() == pytest.approx(math.pi * radius**2 / (g.dx * g.dy), rel=1e-13)
    assert g.area == pytest.approx(math.pi * radius**2, rel=1e-13)
    assert g.volume_fraction.min() >= 0.0 and g.volume_fraction.max() <= 1.0


def test_disk_cut_cells_by_hand():
    """Fractions and apertures of the unit disk on 2², 4² and 5² cells, worked out by hand."""
    quarter = Grid(Domain.disk(1.0), (2, 2))  # four quarter disks, all faces whole
    np.testing.assert_allclose(quarter.volume_fraction, math.pi / 4, rtol=1e-15)
    assert np.all(quarter.aperture_x == 1.0) and np.all(quarter.aperture_y == 1.0)
    g = Grid(Domain.disk(1.0), (4, 4))  # edges at -1, -0.5, 0, 0.5, 1
    corner = math.pi / 3 - math.sqrt(3) + 1  # [0.5, 1]² ∩ disk, over 1/4
    for i, j in ((0, 0), (0, 3), (3, 0), (3, 3)):
        assert g.volume_fraction[i, j] == pytest.approx(corner, rel=1e-14)
    assert np.all(g.volume_fraction[1:3, 1:3] == 1.0)
    # x-face x = 0.5 over y ∈ [0.5, 1]: inside up to y = √3/2, aperture (√3/2 − 1/2)/(1/2)
    assert g.aperture_x[2, 3] == pytest.approx(math.sqrt(3) - 1, rel=1e-14)
    assert g.aperture_x[0, 0] == pytest.approx(math.sqrt(3) - 1, rel=1e-14)  # x = -0.5, y ∈ [-1, -0.5]
    assert g.aperture_y[3, 2] == pytest.approx(math.sqrt(3) - 1, rel=1e-14)  # y = 0.5, x ∈ [0.5, 1]
    assert g.aperture_x[1, 3] == 1.0  # x = 0 over y ∈ [0.5, 1]: a radius
    assert g.aperture_x[2, 1] == 1.0  # x = 0.5 over y ∈ [-0.5, 0]: whole
    # 5² cells of a disk of radius 2.5 about (1, -3): edges 1 cell apart, a 3-4-5 triangle
    g = Grid(Domain.disk(2.5, center=(1.0, -3.0)), (5, 5))
    # x-face at x - 1 = 1.5 over y + 3 ∈ [1.5, 2.5]: inside up to y + 3 = 2 → aperture 1/2
    assert g.aperture_x[3, 4] == pytest.approx(0.5, rel=1e-14)
    assert g.aperture_x[0, 0] == pytest.approx(0.5, rel=1e-14)
    assert g.aperture_y[4, 3] == pytest.approx(0.5, rel=1e-14)
    # x-face at x - 1 = 0.5 over y + 3 ∈ [1.5, 2.5]: inside up to √6 → aperture √6 − 1.5
    assert g.aperture_x[2, 4] == pytest.approx(math.sqrt(6) - 1.5, rel=1e-14)
    assert g.aperture_x[3, 3] == 1.0  # x - 1 = 1.5, y + 3 ∈ [0.5, 1.5]: whole
    # non-square cells, 4 × 5 on the unit disk: dx = 0.5, dy = 0.4
    g = Grid(Domain.disk(1.0), (4, 5))
    assert g.aperture_y[3, 3] == pytest.approx(0.6, rel=1e-14)  # y = 0.6, x ∈ [0.5, 1]: inside up to x = 0.8
    assert g.aperture_x[2, 4] == pytest.approx((math.sqrt(3) / 2 - 0.6) / 0.4, rel=1e-14)  # x = 0.5, y ∈ [0.6, 1]


@pytest.mark.parametrize(
    "domain", [Domain.disk(0.8, center=(0.2, -0.1)), Domain.polygon(HEXAGON)], ids=["disk", "hexagon"]
)
def test_cut_cell_conventions(domain):
    """Whole cells and faces are exactly 1, faces between two whole cells are whole, a face
    is open only if both neighbours hold volume, and no sliver below 1e-12 is a cell."""
    g = Grid(domain, (40, 33))
    frac = g.volume_fraction
    assert frac.min() >= 0.0 and frac.max() <= 1.0
    assert np.all(frac[frac > 0] >= 1e-12)
    assert np.all(g.aperture_x[(frac[1:, :] == 1) & (frac[:-1, :] == 1)] == 1.0)
    assert np.all(g.aperture_y[(frac[:, 1:] == 1) & (frac[:, :-1] == 1)] == 1.0)
    assert np.all(g.active[1:, :][g.aperture_x > 0]) and np.all(g.active[:-1, :][g.aperture_x > 0])
    assert np.all(g.active[:, 1:][g.aperture_y > 0]) and np.all(g.active[:, :-1][g.aperture_y > 0])
    assert (frac == 1).sum() > (0 < frac).sum() / 2  # most cells are whole
    # cells well inside Ω (within 0.3 of the middle of the bounding box) are whole
    X, Y = g.centers
    assert np.all(frac[np.hypot(X - g.x.mean(), Y - g.y.mean()) < 0.3] == 1.0)


def test_disk_cut_cells_move_with_the_disk():
    """Translating a disk and its grid leaves the cut cells unchanged (to round-off)."""
    a = Grid(Domain.disk(0.7), (31, 31))
    b = Grid(Domain.disk(0.7, center=(12.5, -3.25)), (31, 31))
    np.testing.assert_allclose(b.volume_fraction, a.volume_fraction, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.aperture_x, a.aperture_x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.aperture_y, a.aperture_y, rtol=0, atol=1e-12)
    # and the disk is symmetric under x → -x and x ↔ y
    np.testing.assert_allclose(a.volume_fraction, a.volume_fraction[::-1, :], rtol=0, atol=1e-13)
    np.testing.assert_allclose(a.volume_fraction, a.volume_fraction.T, rtol=0, atol=1e-13)
    np.testing.assert_allclose(a.aperture_x, a.aperture_y.T, rtol=0, atol=1e-13)


@pytest.mark.parametrize(
    "domain",
    [Domain.disk(1.0), Domain.disk(0.3, center=(5.0, 5.0)), Domain.polygon(HEXAGON), Domain.polygon(THIN_TRIANGLE)],
    ids=["unit-disk", "small-disk", "hexagon", "thin-triangle"],
)
def test_summation_by_parts_on_finer_cut_cells(domain, rng):
    """divergence = -gradientᵀ also on finer grids and more shapes than the fixture's."""
    g = Grid(domain, (64, 48))
    nx, ny = g.shape
    f = rng.normal(size=(nx, ny))
    F = (rng.normal(size=(nx - 1, ny)), rng.normal(size=(nx, ny - 1)))
    lhs = g.inner(f, g.divergence(F))
    rhs = -g.face_inner(g.gradient(f), F)
    assert abs(lhs - rhs) <= 1e-13 * g.inner(np.abs(f), np.abs(g.divergence(F)))


def test_linear_binning_keeps_mass_and_mean_position_exactly(rng):
    """Cloud-in-cell weights are bilinear: each point's weights sum to ``weight`` and their
    centre of mass is the point itself (for points between the outer centres)."""
    from meanfield.geometry.grid import linear_binning

    origin, spacing, shape = (-0.3, 0.2), (0.05, 0.08), (17, 11)
    lo = np.array(origin) + 0.5 * np.array(spacing)
    hi = np.array(origin) + (np.array(shape) - 0.5) * np.array(spacing)
    pts = rng.uniform(lo, hi, size=(5000, 2))
    counts = linear_binning(pts, origin, spacing, shape, weight=0.25)
    cx = origin[0] + (np.arange(shape[0]) + 0.5) * spacing[0]
    cy = origin[1] + (np.arange(shape[1]) + 0.5) * spacing[1]
    assert counts.sum() == pytest.approx(0.25 * len(pts), rel=1e-13)
    assert (counts * cx[:, None]).sum() == pytest.approx(0.25 * pts[:, 0].sum(), rel=1e-12)
    assert (counts * cy[None, :]).sum() == pytest.approx(0.25 * pts[:, 1].sum(), rel=1e-12)
    # one point on a lattice centre lands there whole; one beyond the edge goes to the edge
    one = linear_binning(np.array([[cx[3], cy[4]], [10.0, -10.0]]), origin, spacing, shape)
    assert one[3, 4] == pytest.approx(1.0) and one[-1, 0] == pytest.approx(1.0)
    assert one.sum() == pytest.approx(2.0)


def test_a_grid_of_a_plan_seen_before_is_the_grid_clipped_afresh() -> None:
    """The clipped cells are remembered per process (``grid._FRACTIONS``): a second grid of the same plan gets the
    same fractions to the last bit as a grid clipped afresh, in arrays of its own; a plan one ulp apart is not
    taken for it."""
    import meanfield.geometry.grid as grid_module
    from meanfield.geometry.plan import Plan

    wkt = "POLYGON ((0 0, 10 0, 10 4, 6 4, 6 8, 0 8, 0 0))"
    grid_module._FRACTIONS.clear()
    fresh = Grid(Plan.from_wkt(wkt), cells=(40, 32))
    again = Grid(Plan.from_wkt(wkt), cells=(40, 32))
    assert len(grid_module._FRACTIONS) == 1
    for name in ("volume_fraction", "aperture_x", "aperture_y", "volume", "active"):
        np.testing.assert_array_equal(getattr(again, name), getattr(fresh, name))
    again.volume_fraction[0, 0] = -1.0  # its own arrays
    assert Grid(Plan.from_wkt(wkt), cells=(40, 32)).volume_fraction[0, 0] == fresh.volume_fraction[0, 0]
    nudged = Plan.from_wkt(f"POLYGON ((0 0, 10 0, 10 4, {float(np.nextafter(6.0, 7.0))!r} 4, 6 8, 0 8, 0 0))")
    assert grid_module.exact_key(nudged) != grid_module.exact_key(Plan.from_wkt(wkt))
    Grid(nudged, cells=(40, 32))
    assert len(grid_module._FRACTIONS) == 2
