"""Poincaré constant: Neumann eigenvalue μ₂ against closed forms, convergence order, bounds."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull
from scipy.special import jnp_zeros

from analysis.poincare import (
    PoincareReport,
    exact_neumann_eigenvalue,
    is_convex,
    neumann_eigenvalue,
    payne_weinberger_bound,
    poincare_report,
)
from meanfield import Domain, Grid, ParameterError
from tests.conftest import PENTAGON

UNIT_DISK_MU2 = 3.389957716671890  # (j'_11)^2, j'_11 = 1.8411837813406593
EQUILATERAL = [(0.0, 0.0), (1.0, 0.0), (0.5, math.sqrt(3) / 2)]
RIGHT_ISOSCELES = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]
UNIT_SQUARE = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]


def _moved(vertices, angle: float, shift=(0.3, -0.2), scale: float = 1.0) -> list[tuple[float, float]]:
    """Rotate by ``angle``, scale and translate a vertex list."""
    c, s = math.cos(angle), math.sin(angle)
    return [(scale * (c * x - s * y) + shift[0], scale * (s * x + c * y) + shift[1]) for x, y in vertices]


@functools.cache
def _mu(domain: Domain, n: int) -> float:
    """μ₂ on an n × n grid, cached across tests (the 128² solves are shared)."""
    return neumann_eigenvalue(domain, (n, n))


def _rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


def _observed_order(domain: Domain, exact: float, ns=(32, 64, 128)) -> float:
    """Least-squares slope of log|error| against log(1/n)."""
    err = [abs(_mu(domain, n) - exact) for n in ns]
    return float(-np.polyfit(np.log(ns), np.log(err), 1)[0])


# ---------------------------------------------------------------------- closed forms
def test_exact_values():
    """The closed forms: rectangle π²/max(w,h)², disk (j'₁₁/r)², the two triangles."""
    assert jnp_zeros(1, 1)[0] == pytest.approx(1.8411837813406593, rel=1e-15)
    assert exact_neumann_eigenvalue(Domain.disk(1.0)) == pytest.approx(UNIT_DISK_MU2, rel=1e-14)
    assert exact_neumann_eigenvalue(Domain.disk(2.0, center=(5, 1))) == pytest.approx(UNIT_DISK_MU2 / 4, rel=1e-14)
    assert exact_neumann_eigenvalue(Domain.box(1.0, 1.0)) == pytest.approx(math.pi**2, rel=1e-15)
    assert exact_neumann_eigenvalue(Domain.box(0.5, 2.0, origin=(3, 3))) == pytest.approx(math.pi**2 / 4, rel=1e-15)
    eq = 16 * math.pi**2 / 9
    rt = math.pi**2
    for angle in (0.0, 0.3, 2.0):
        for shift in ((0.0, 0.0), (-4.0, 7.5)):
            for order in (slice(None), slice(None, None, -1)):
                tri = Domain.polygon(_moved(EQUILATERAL, angle, shift)[order])
                assert exact_neumann_eigenvalue(tri) == pytest.approx(eq, rel=1e-12)
                right = Domain.polygon(_moved(RIGHT_ISOSCELES, angle, shift)[order])
                assert exact_neumann_eigenvalue(right) == pytest.approx(rt, rel=1e-12)
                rect = Domain.polygon(_moved([(0, 0), (2, 0), (2, 0.5), (0, 0.5)], angle, shift)[order])
                assert exact_neumann_eigenvalue(rect) == pytest.approx(math.pi**2 / 4, rel=1e-12)
    # side a: 16π²/(9a²) and π²/a²; the right angle need not be at a grid-aligned corner
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (0.5, 0.5)])) == pytest.approx(2 * rt, rel=1e-12)
    assert exact_neumann_eigenvalue(Domain.polygon(_moved(EQUILATERAL, 1.0, scale=3.0))) == pytest.approx(
        eq / 9, rel=1e-12
    )
    assert exact_neumann_eigenvalue(Domain.polygon(_moved(RIGHT_ISOSCELES, 1.0, scale=0.5))) == pytest.approx(
        4 * rt, rel=1e-12
    )


def test_exact_values_unknown_shapes():
    """Shapes without a closed form (or slightly off one) give None."""
    assert exact_neumann_eigenvalue(Domain.polygon(PENTAGON)) is None
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (0.3, 0.8)])) is None
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (0.5, 0.6)])) is None  # isosceles, not right
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (0.5, 2.0)])) is None  # isosceles, not right
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (0.5, math.sqrt(3) / 2 + 1e-6)])) is None
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (1.2, 1), (0.2, 1)])) is None  # parallelogram
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (0.9, 1), (0.1, 1)])) is None  # trapezoid
    assert exact_neumann_eigenvalue(Domain.polygon([(0, 0), (1, 0), (1, 1), (0, 1.0001)])) is None


# ---------------------------------------------------------------------- box: exact discrete answer
def test_box_reproduces_the_discrete_eigenvalue():
    """On a box every cell is whole: μ₂ is (4/h²) sin²(πh/2L) to round-off."""
    h = 1 / 128
    discrete = 4 / h**2 * math.sin(math.pi * h / 2) ** 2
    mu = _mu(Domain.box(1.0, 1.0), 128)
    assert mu == pytest.approx(discrete, rel=1e-12)
    assert _rel(mu, math.pi**2) < 1e-3
    # the square's μ₂ is double, μ₄ = 2 μ₂ (mode cos πx cos πy)
    assert neumann_eigenvalue(Domain.box(1.0, 1.0), (32, 32), k=2) == pytest.approx(
        neumann_eigenvalue(Domain.box(1.0, 1.0), (32, 32)), rel=1e-12
    )
    h = 1 / 32
    assert neumann_eigenvalue(Domain.box(1.0, 1.0), (32, 32), k=3) == pytest.approx(
        8 / h**2 * math.sin(math.pi * h / 2) ** 2, rel=1e-12
    )


def test_rectangle():
    """w ≠ h, non-square cells, offset origin: the long side's discrete mode, near π²/w²."""
    dom = Domain.box(2.0, 0.8, origin=(-3.0, 5.0))
    dx, dy = 2.0 / 60, 0.8 / 40
    discrete = min(4 / dx**2 * math.sin(math.pi * dx / 4) ** 2, 4 / dy**2 * math.sin(math.pi * dy / 1.6) ** 2)
    mu = neumann_eigenvalue(dom, (60, 40))
    assert mu == pytest.approx(discrete, rel=1e-12)
    assert _rel(mu, exact_neumann_eigenvalue(dom)) < 1e-3
    assert _rel(neumann_eigenvalue(Domain.box(0.8, 2.0), (40, 60)), mu) < 1e-12  # transposed


# ---------------------------------------------------------------------- accuracy and order
def test_unit_square_and_disk_at_128():
    assert _rel(_mu(Domain.box(1.0, 1.0), 128), math.pi**2) < 1e-3
    assert _rel(_mu(Domain.disk(1.0), 128), UNIT_DISK_MU2) < 1e-3
    assert _rel(_mu(Domain.disk(1.0), 128), UNIT_DISK_MU2) < 1e-4  # measured 6.0e-5


@pytest.mark.parametrize(
    ("vertices", "exact"),
    [(EQUILATERAL, 16 * math.pi**2 / 9), (RIGHT_ISOSCELES, math.pi**2)],
    ids=["equilateral", "right-isosceles"],
)
def test_triangles_at_128(vertices, exact):
    """Convex polygons with known μ₂, axis-aligned and rotated (slanted walls everywhere)."""
    for angle in (0.0, 0.3):
        mu = _mu(Domain.polygon(_moved(vertices, angle)), 128)
        assert _rel(mu, exact) < 1e-2
        assert _rel(mu, exact) < 2e-4  # measured ≤ 7.8e-5


@pytest.mark.parametrize(
    "domain",
    [
        Domain.disk(1.0),
        Domain.polygon(_moved(EQUILATERAL, 0.3)),
        Domain.polygon(_moved(UNIT_SQUARE, math.radians(17))),
    ],
    ids=["disk", "rotated-equilateral", "rotated-square"],
)
def test_second_order_convergence(domain):
    """Cut cells on curved and slanted walls converge at second order (fit over 32², 64², 128²)."""
    exact = exact_neumann_eigenvalue(domain)
    assert exact is not None
    order = _observed_order(domain, exact)
    assert order >= 1.8, order
    assert order <= 2.3, order
    # and from below, monotonically
    mus = [_mu(domain, n) for n in (32, 64, 128)]
    assert mus[0] < mus[1] < mus[2] < exact


def test_self_convergence_on_a_generic_polygon():
    """No closed form for the pentagon: successive differences shrink fourfold."""
    dom = Domain.polygon(PENTAGON)
    m32, m64, m128 = (_mu(dom, n) for n in (32, 64, 128))
    order = math.log2((m64 - m32) / (m128 - m64))
    assert 1.8 <= order <= 2.3, order


def test_staircase_is_worse():
    """cut_cells=False (the staircase mask) is far less accurate than cut cells."""
    disk = Domain.disk(1.0)
    stair = neumann_eigenvalue(disk, (64, 64), cut_cells=False)
    assert _rel(stair, UNIT_DISK_MU2) > 10 * _rel(_mu(disk, 64), UNIT_DISK_MU2)


def test_higher_eigenvalues_of_the_disk():
    """k counts multiplicity: the disk's μ₂ is double, then (j'₂₁)² (split by the grid), then (j'₀₁)²."""
    disk = Domain.disk(1.0)
    mus = [neumann_eigenvalue(disk, (64, 64), k=k) for k in (1, 2, 3, 4, 5)]
    assert mus[1] == pytest.approx(mus[0], rel=1e-10)
    assert mus == sorted(mus)
    for mu, j in zip(mus[2:], (jnp_zeros(2, 1)[0], jnp_zeros(2, 1)[0], jnp_zeros(0, 1)[0]), strict=True):
        assert _rel(mu, j**2) < 2e-3


# ---------------------------------------------------------------------- invariances
def test_translation_invariance():
    """A shifted disk or polygon has the same μ₂ (the grid moves with the bounding box)."""
    ref = _mu(Domain.disk(1.0), 64)
    assert neumann_eigenvalue(Domain.disk(1.0, center=(3.7, -2.2)), (64, 64)) == pytest.approx(ref, rel=1e-9)
    poly = _mu(Domain.polygon(PENTAGON), 64)
    moved = Domain.polygon([(x - 10.25, y + 3.5) for x, y in PENTAGON])
    assert neumann_eigenvalue(moved, (64, 64)) == pytest.approx(poly, rel=1e-9)


@pytest.mark.parametrize("factor", [0.3, 2.5])
def test_scaling_like_one_over_length_squared(factor):
    """μ₂(sΩ) = μ₂(Ω)/s² on the same number of cells (the discretisation scales too)."""
    assert neumann_eigenvalue(Domain.disk(factor), (64, 64)) * factor**2 == pytest.approx(
        _mu(Domain.disk(1.0), 64), rel=1e-9
    )
    scaled = Domain.polygon([(factor * x, factor * y) for x, y in PENTAGON])
    pentagon = _mu(Domain.polygon(PENTAGON), 64)
    assert neumann_eigenvalue(scaled, (64, 64)) * factor**2 == pytest.approx(pentagon, rel=1e-9)
    box = Domain.box(factor * 1.5, factor * 1.0)
    assert neumann_eigenvalue(box, (48, 32)) * factor**2 == pytest.approx(
        neumann_eigenvalue(Domain.box(1.5, 1.0), (48, 32)), rel=1e-10
    )


# ---------------------------------------------------------------------- Payne–Weinberger
def test_payne_weinberger_value():
    assert payne_weinberger_bound(Domain.disk(1.0)) == pytest.approx(math.pi**2 / 4, rel=1e-15)
    assert payne_weinberger_bound(Domain.box(3.0, 4.0)) == pytest.approx(math.pi**2 / 25, rel=1e-15)
    assert payne_weinberger_bound(Grid(Domain.box(3.0, 4.0), (4, 4))) == pytest.approx(math.pi**2 / 25, rel=1e-15)


def test_payne_weinberger_below_mu2():
    """π²/diam² ≤ μ₂ for the box, the disk and convex polygons (computed and closed forms)."""
    domains = [
        Domain.box(1.0, 1.0),
        Domain.box(3.0, 0.5),
        Domain.disk(0.7, center=(1, 1)),
        Domain.polygon(PENTAGON),
        Domain.polygon(EQUILATERAL),
        Domain.polygon(RIGHT_ISOSCELES),
        Domain.polygon(_moved([(0, 0), (1, 0), (1, 0.2), (0, 0.2)], 0.5)),
        Domain.polygon([(0, 0), (1, 0), (0.5, 0.1)]),  # a needle
    ]
    for dom in domains:
        pw = payne_weinberger_bound(dom)
        assert neumann_eigenvalue(dom, (32, 32)) >= pw
        exact = exact_neumann_eigenvalue(dom)
        if exact is not None:
            assert exact >= pw


def test_payne_weinberger_random_convex_polygons():
    """A seeded family of random convex polygons (hulls of random points in random boxes)."""
    rng = np.random.default_rng(20240611)
    ratios = []
    for _ in range(25):
        m = int(rng.integers(3, 12))
        points = rng.uniform(-1.0, 1.0, (m, 2)) * rng.uniform(0.2, 3.0, 2) + rng.uniform(-5, 5, 2)
        dom = Domain.polygon(points[ConvexHull(points).vertices])
        mu = neumann_eigenvalue(dom, (24, 24))
        ratios.append(mu / payne_weinberger_bound(dom))
    assert min(ratios) >= 1.0, ratios


def test_payne_weinberger_is_sharp_for_thin_rectangles():
    """Thin domains approach the bound: rectangle L × w gives exactly 1 + (w/L)² times it."""
    for w in (0.5, 0.1, 0.01):
        dom = Domain.polygon(_moved([(0, 0), (1, 0), (1, w), (0, w)], 0.4))
        assert exact_neumann_eigenvalue(dom) / payne_weinberger_bound(dom) == pytest.approx(1 + w**2, rel=1e-9)


# ---------------------------------------------------------------------- floor plans: not convex
L_THIN = "POLYGON ((0 0, 1 0, 1 0.2, 0.2 0.2, 0.2 1, 0 1, 0 0))"  # arms 0.2 wide, diameter √2
PILLAR_ROOM = "POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0), (0.4 0.4, 0.6 0.4, 0.6 0.6, 0.4 0.6, 0.4 0.4))"


def test_convexity_of_regions():
    """Every Domain is convex; a plan is when it has no hole and its hull adds no area."""
    from meanfield.geometry.plan import Plan

    assert is_convex(Domain.disk(1.0)) and is_convex(Domain.polygon(PENTAGON)) and is_convex(Domain.box(2, 1))
    assert is_convex(Plan.from_wkt("POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0))"))
    assert is_convex(Plan.from_wkt("POLYGON ((0 0, 0.5 0, 1 0, 1 1, 0 1, 0 0))"))  # a collinear vertex
    assert is_convex(Grid(Plan.from_wkt("POLYGON ((0 0, 1 0, 0.5 0.8, 0 0))"), (8, 8)))
    assert not is_convex(Plan.from_wkt(L_THIN))
    assert not is_convex(Plan.from_wkt(PILLAR_ROOM))  # convex outline, but a hole
    dent = "POLYGON ((0 0, 1 0, 1 1, 0.5 0.999, 0 1, 0 0))"  # a re-entrant vertex 1e-3 deep
    assert not is_convex(Plan.from_wkt(dent))


def test_payne_weinberger_is_not_applicable_when_the_plan_is_not_convex():
    """On the thin L, μ₂ lies far below π²/diam²: the bound would be false, so it is None, never a number."""
    from meanfield.geometry.plan import Plan

    thin = Plan.from_wkt(L_THIN)
    assert neumann_eigenvalue(thin, (32, 32)) < 0.75 * math.pi**2 / thin.diameter**2  # 3.39 against 4.93
    assert payne_weinberger_bound(thin) is None and payne_weinberger_bound(Grid(thin, (8, 8))) is None
    for plan in (thin, Plan.from_wkt(PILLAR_ROOM)):
        rep = poincare_report(plan, (24, 24))
        assert rep.payne_weinberger is None and rep.to_dict()["payne_weinberger"] is None
        assert rep.mu2 > 0 and rep.c2 == pytest.approx(math.sqrt(rep.mu2), rel=1e-15) and rep.exact is None
    square = Plan.from_wkt("POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0))")
    assert payne_weinberger_bound(square) == pytest.approx(math.pi**2 / 2, rel=1e-15)  # a convex plan keeps it


def test_the_mode_figure_says_the_bound_is_not_applicable():
    from analysis.figures import plot_poincare_mode
    from meanfield.geometry.plan import Plan

    thin = Plan.from_wkt(L_THIN)
    grid = Grid(thin, (16, 16))
    mu, mode = neumann_eigenvalue(grid, return_mode=True)
    texts = [t.get_text() for t in plot_poincare_mode(thin, grid, mode, mu, None, None).axes[0].texts]
    assert any("not applicable (Ω not convex)" in t for t in texts)
    texts = [t.get_text() for t in plot_poincare_mode(thin, grid, mode, mu, 2.5, None).axes[0].texts]
    assert any("π²/d² = 2.5" in t for t in texts)


# ---------------------------------------------------------------------- grid pieces, the exits' rate
def test_grid_pieces_counts_what_the_open_faces_join():
    from analysis.rates import grid_pieces
    from meanfield.geometry.plan import Plan

    assert grid_pieces(Grid(Plan.from_wkt(PILLAR_ROOM), (20, 20))) == (1, 0.0)
    grid = Grid(Domain.box(1.0, 1.0), (10, 10))
    grid.aperture_x[2, :] = 0.0  # a wall the grid cannot cross: columns 0-2 apart from 3-9
    pieces, share = grid_pieces(grid)
    assert pieces == 2 and share == pytest.approx(0.3, rel=1e-12)
    with pytest.raises(ParameterError):
        grid_pieces(Domain.box(1.0, 1.0))


def test_exit_eigenvalue_of_a_strip_with_an_exit_across_one_end():
    """−αu'' = λu on (0, 1), u'(0) = 0, u(1) = 0 (the exits' outflow is Dirichlet as h → 0): λ = απ²/4,
    for any α, and no exits give λ = 0 (the constants)."""
    from analysis.rates import exit_eigenvalue
    from meanfield.geometry.exits import ExitSink, exit_segments

    strip = Domain.box(1.0, 0.2, exits=[((1.0, 0.0), (1.0, 0.2))])
    sigma = 0.3
    errors = []
    for n in (20, 40):
        grid = Grid(strip, (n, 4))
        rates = ExitSink(grid, exit_segments(strip), sigma).total_rate
        lam = exit_eigenvalue(grid, sigma, rates)
        errors.append(abs(lam - sigma * math.pi**2 / 4) / (sigma * math.pi**2 / 4))
        assert lam < sigma * math.pi**2 / 4  # from below, as the Neumann eigenvalues
    assert errors[1] < 3e-4 and errors[1] < errors[0] / 3  # second order
    grid = Grid(Domain.box(1.0, 1.0), (10, 10))
    assert exit_eigenvalue(grid, 0.2, np.zeros(grid.shape)) == pytest.approx(0.0, abs=1e-12)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ParameterError):
            exit_eigenvalue(grid, bad, np.zeros(grid.shape))
    with pytest.raises(ParameterError):
        exit_eigenvalue(grid, 0.2, -np.ones(grid.shape))


# ---------------------------------------------------------------------- grid consistency and mode
def test_fast_geometry_matches_grid():
    """A Domain gives the eigenvalue of Grid(domain, cells): both use Grid's cut cells."""
    poly = Domain.polygon(PENTAGON)
    grid = Grid(poly, (17, 23))
    assert neumann_eigenvalue(grid) == pytest.approx(neumann_eigenvalue(poly, (17, 23)), rel=1e-11)
    disk = Domain.disk(0.8, center=(0.2, -0.1))
    grid = Grid(disk, (16, 16))
    assert neumann_eigenvalue(grid) == pytest.approx(neumann_eigenvalue(disk, (16, 16)), rel=2e-6)


@pytest.mark.parametrize("domain", [Domain.box(1.1, 0.9), Domain.disk(0.8), Domain.polygon(PENTAGON)])
def test_mode_is_an_eigenfunction_of_the_grid_operator(domain):
    """With a Grid, -div(grad u) = μ u for the returned mode, in the grid's own operators."""
    grid = Grid(domain, (20, 16))
    mu, mode = neumann_eigenvalue(grid, return_mode=True)
    assert mode.shape == grid.shape
    assert np.array_equal(np.isnan(mode), ~grid.active)
    u = np.nan_to_num(mode)
    lap = -grid.divergence(grid.gradient(u))
    assert np.max(np.abs(lap - mu * u)[grid.active]) <= 1e-8 * mu * np.max(np.abs(u))
    assert grid.integrate(u) == pytest.approx(0.0, abs=1e-10)  # orthogonal to constants
    assert grid.inner(u, u) == pytest.approx(1.0, rel=1e-10)
    assert grid.face_inner(grid.gradient(u), grid.gradient(u)) == pytest.approx(mu, rel=1e-10)
    assert u.max() == np.abs(u).max()  # sign fixed


def test_mode_of_the_disk_looks_like_the_first_bessel_mode():
    """The disk's μ₂ mode is J₁(j'₁₁ r/R)·cos(θ − θ₀): zero at the centre, extreme on the wall."""
    mu, mode = neumann_eigenvalue(Domain.disk(1.0), (32, 32), return_mode=True)
    grid = Grid(Domain.box(2.0, 2.0, origin=(-1, -1)), (32, 32))
    X, Y = grid.centers
    r = np.hypot(X, Y)
    inside = ~np.isnan(mode)
    assert abs(np.nanmean(mode[r < 0.2])) < 0.05 * np.nanmax(np.abs(mode))
    assert np.nanmax(np.abs(mode[inside & (r > 0.85)])) == pytest.approx(np.nanmax(np.abs(mode)))


def test_isolated_cells_are_dropped():
    """A cell no open face reaches (a sliver cut at a vertex) would add a second zero eigenvalue."""
    grid = Grid(Domain.box(1.0, 1.0), (8, 8))
    ref = neumann_eigenvalue(grid)
    grid.aperture_x[0, 0] = 0.0
    grid.aperture_y[0, 0] = 0.0
    mu, mode = neumann_eigenvalue(grid, return_mode=True)
    assert mu > 0.5 * ref
    assert np.isnan(mode[0, 0]) and np.isnan(mode).sum() == 1


def test_arpack_fallback_agrees(monkeypatch):
    """Should the block iteration stall, ARPACK on the same factorisation gives the same answer."""
    import analysis.poincare as poincare

    ref = _mu(Domain.polygon(PENTAGON), 32)
    monkeypatch.setattr(poincare, "_MAX_ITERATIONS", 1)
    assert neumann_eigenvalue(Domain.polygon(PENTAGON), (32, 32)) == pytest.approx(ref, rel=1e-10)
    assert neumann_eigenvalue(Domain.disk(1.0), (32, 32), k=2) == pytest.approx(_mu(Domain.disk(1.0), 32), rel=1e-10)
    grid = Grid(Domain.polygon(PENTAGON), (32, 32))
    mu, mode = neumann_eigenvalue(grid, k=2, return_mode=True)
    u = np.nan_to_num(mode)
    assert grid.integrate(u) == pytest.approx(0.0, abs=1e-10)
    assert grid.face_inner(grid.gradient(u), grid.gradient(u)) == pytest.approx(mu, rel=1e-10)


def test_small_grid_and_report():
    """4 × 4 cells work; the report bundles μ₂, c₂ = √μ₂, the bound and the closed form."""
    assert 0 < neumann_eigenvalue(Domain.disk(1.0), (4, 4)) < UNIT_DISK_MU2
    rep = poincare_report(Domain.disk(1.0), (64, 64))
    assert isinstance(rep, PoincareReport)
    assert rep.c2 == pytest.approx(math.sqrt(rep.mu2), rel=1e-15)
    assert rep.payne_weinberger <= rep.mu2
    assert rep.exact == pytest.approx(UNIT_DISK_MU2)
    assert rep.relative_error == pytest.approx(abs(rep.mu2 - UNIT_DISK_MU2) / UNIT_DISK_MU2)
    assert rep.cells == (64, 64)
    d = rep.to_dict()
    assert d["cells"] == [64, 64] and set(d) == {"mu2", "c2", "payne_weinberger", "exact", "relative_error", "cells"}
    pent = poincare_report(Domain.polygon(PENTAGON), (16, 16)).to_dict()
    assert pent["exact"] is None and pent["relative_error"] is None
    assert poincare_report(Grid(Domain.box(1, 1), (8, 8))).cells == (8, 8)


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize("cells", [(3, 64), (64, 2), (64,), (8, 8, 8), 64, "64", (4.5, 8), (True, 8), ("a", 8)])
def test_bad_cells(cells):
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(Domain.disk(1.0), cells)
    assert exc.value.name == "cells"
    assert ">= 4" in str(exc.value)


@pytest.mark.parametrize("domain", ["disk", None, 1.0, {"kind": "disk", "radius": 1.0}])
def test_bad_domain(domain):
    for func in (neumann_eigenvalue, payne_weinberger_bound, exact_neumann_eigenvalue, poincare_report):
        with pytest.raises(ParameterError) as exc:
            func(domain)
        assert exc.value.name == "domain"
        assert "Domain" in exc.value.allowed


@pytest.mark.parametrize("k", [0, -1, 1.5, True, "1"])
def test_bad_k(k):
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(Domain.box(1, 1), (8, 8), k=k)
    assert exc.value.name == "k"
    assert ">= 1" in exc.value.allowed


def test_other_bad_arguments():
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(Domain.box(1, 1), (4, 4), k=16)  # 16 cells: at most 15 non-zero eigenvalues
    assert exc.value.name == "k"
    assert neumann_eigenvalue(Domain.box(1, 1), (4, 4), k=15) > 0
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(Domain.box(1, 1), (8, 8), cut_cells="yes")
    assert exc.value.name == "cut_cells"
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(Domain.box(1, 1), (8, 8), return_mode=1)
    assert exc.value.name == "return_mode"
    grid = Grid(Domain.disk(1.0), (12, 12))
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(grid, (16, 16))
    assert exc.value.name == "cells"
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(grid, cut_cells=False)
    assert exc.value.name == "cut_cells"
    assert neumann_eigenvalue(grid, (12, 12), cut_cells=True) > 0
    with pytest.raises(ParameterError) as exc:
        neumann_eigenvalue(Grid(Domain.box(1, 1), (3, 8)))
    assert exc.value.name == "cells"


@pytest.mark.parametrize(
    "vertices",
    [
        [(0, 0), (2, 2), (2, 0), (0, 2)],  # a bow tie: crosses itself
        [(0, 0), (1, 0)],  # fewer than 3 vertices
        [(0, 0), (1, 0), (1, 0), (0, 1)],  # repeated vertex
        [(0, 0), (1, 1), (2, 2)],  # zero area: all collinear
        [(0, 0), (1, 0), (2, 0), (3, 0)],  # zero area: all collinear
        [(0, 0), (1, 0), (0.5, 0), (0.2, 0)],  # zero area, doubling back
    ],
    ids=["self-intersecting", "two-vertices", "repeated", "collinear-3", "collinear-4", "collinear-back"],
)
def test_domain_refuses_degenerate_polygons(vertices):
    """Domain.polygon refuses what no region can be (a crossing outline, no area); a polygon that is
    merely not convex is a plan, with no Payne–Weinberger bound (tests/geometry/test_region_family.py)."""
    with pytest.raises(ParameterError) as exc:
        Domain.polygon(vertices)
    assert exc.value.name == "vertices"
