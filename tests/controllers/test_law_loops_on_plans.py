"""The law on a plan in one compiled call (issue 17, "Real buildings"), and the plan's sight and coverage loops.

* :func:`meanfield.controllers._law_loops.face_law` against the numpy law (the reference): every field of
  :class:`~meanfield.interfaces.ControlState` to 1e-12 of its size, on the ``office`` plan and in
  a room with a pillar, with the paper's Step I (eq. (6)) and Hughes' (the exits'), robots in and
  out of sight, over successive calls (``∂_t v_d`` by a backward difference), and on a box with
  exits (which ran the paper's Step I in place of Hughes' before);
* its ``b_i``, ``g_i`` keep the Step II identity ``⟨ṽ, ∂_t v_r⟩ = −Σ b_i·u_i + Σ g_i ω_i`` (eq. (5))
  with the masked field, and its inputs the law's identity of eq. (8);
* it is deterministic, and ``use_compiled(False)`` runs the numpy path;
* ``FusedLaw.which`` says exactly when each compiled call applies;
* the sight table, the coverage's owners and the view's gate: compiled loops against their numpy
  twins and against the formulas they replaced.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import math

import numpy as np
import pytest

from meanfield import ClosedLoop, Domain, GaussianKernel, Grid, NavigationField
from meanfield._compiled import core as compiled
from meanfield.controllers._coverage_loops import owners
from meanfield.controllers._law_loops import face_law
from meanfield.controllers.backstepping import BacksteppingController, ConstantAlpha, SaturatingAlpha, UserBetaGamma
from meanfield.controllers.coverage import CoverageController
from meanfield.controllers.evacuation import EvacuationController, exit_distance
from meanfield.controllers.step_one import PaperStepOne
from meanfield.crowds._view_loops import in_view, turn_walkers
from meanfield.crowds.local_view import LocalView, robots_in_view
from meanfield.geometry._sight_loops import cell_index
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.plan import Plan
from meanfield.geometry.sight import SightLines
from meanfield.geometry.target import gaussian_target
from meanfield.interfaces import ControlState
from meanfield.scenarios.scenario import builtin_scenarios
from meanfield.signs.kernels import CustomKernel
from tests.conftest import smooth_density

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")

# a 4 m x 3 m room with a pillar off the grid's lines (cut cells with partial apertures) and an exit
PILLAR_WKT = "POLYGON ((0 0, 4 0, 4 3, 0 3, 0 0), (1.45 0.95, 2.55 0.95, 2.55 2.05, 1.45 2.05, 1.45 0.95))"
PILLAR = Plan(Plan.from_wkt(PILLAR_WKT).polygon, [((4.0, 1.0), (4.0, 2.0))])
# robots around the pillar: each sees part of the room only
AROUND = np.array([[0.5, 1.5], [3.5, 1.5], [2.0, 0.4], [2.0, 2.6], [0.3, 0.3], [3.7, 2.8]])
TWO_ROOMS = "POLYGON ((0 0, 0.45 0, 0.45 0.8, 0.55 0.8, 0.55 0, 1 0, 1 1, 0 1, 0 0))"

COVERAGE = {"controller.kind": "coverage", "view.memory": "none"}
"""The office as it shipped before the guide: the coverage controller, whose law these tests compile."""


def _same_state(fast: ControlState, ref: ControlState) -> None:
    """Every field of the two states: arrays to 1e-12 of the reference's largest entry, numbers to 1e-12."""
    for f in dataclasses.fields(ControlState):
        a, r = getattr(fast, f.name), getattr(ref, f.name)
        pairs = list(zip(a, r, strict=True)) if f.name in ("v_d", "v_tilde") else [(a, r)]
        for x, y in pairs:
            if isinstance(y, np.ndarray) and y.ndim:
                assert x.shape == y.shape, f.name
                assert np.max(np.abs(x - y)) <= 1e-12 * np.max(np.abs(y)), f.name
            elif isinstance(y, tuple):
                assert x == y, f.name
            else:
                assert float(x) == pytest.approx(float(y), rel=1e-12, abs=1e-300), f.name


@functools.cache
def _pillar_grid() -> Grid:
    return Grid(PILLAR, (24, 18))


def _pillar_law(step_one: str, schedule: str = "saturating", k_u=1.5, rho_max=math.inf):
    grid = _pillar_grid()
    target = gaussian_target(grid, (3.5, 1.5), 0.6)
    alpha = SaturatingAlpha(0.2, 0.3) if schedule == "saturating" else ConstantAlpha(0.2)
    args = (grid, target, 0.01, alpha, k_u, 2.0)
    if step_one == "paper":
        return BacksteppingController(*args)
    phi = exit_distance(grid, exit_segments(PILLAR))
    return EvacuationController(*args, phi=phi, v_free=0.8, rho_max=rho_max)


def _compare_over_calls(make_law, densities, fields, dt=0.1):
    """The compiled law and the numpy law over successive calls; returns the compiled states."""
    fast, ref = make_law(), make_law()
    states = []
    for k, (rho, field) in enumerate(zip(densities, fields, strict=True)):
        assert fast.fused.which(rho, field) == ("faces", fast.compiled_step_one())
        a = fast.robot_inputs(rho, field, k * dt, dt)
        with compiled.numpy_path():
            r = ref.robot_inputs(rho, field, k * dt, dt)
        _same_state(a, r)
        states.append(a)
    assert face_law._ready and not compiled.status()["fallbacks"]  # it did run compiled
    return states


@pytest.fixture(scope="module")
def office():
    """The built-in office after a few steps: its law (Hughes' Step I), density and robots."""
    loop = ClosedLoop(builtin_scenarios()["office"](seed=1).with_values(COVERAGE))
    for _ in range(3):
        loop.step()
    return loop


def _pillar_states(grid, rng, calls=3):
    sight = SightLines(PILLAR)
    densities, fields = [], []
    for k in range(calls):
        rho = np.where(grid.active, smooth_density(grid) * rng.uniform(0.8, 1.2, grid.shape), 0.0)
        R = AROUND + 0.05 * k * rng.normal(size=AROUND.shape)
        fields.append(NavigationField(GaussianKernel(0.8, 0.5), grid, R, rng.uniform(0, 2 * np.pi, len(R)), sight))
        densities.append(rho / grid.integrate(rho))
    return densities, fields


@needs_numba
@pytest.mark.parametrize(
    "step_one, schedule, gains, rho_max",
    [
        ("paper", "saturating", "scalar", math.inf),
        ("paper", "constant", "per-robot", math.inf),
        ("hughes", "saturating", "scalar", math.inf),
        ("hughes", "saturating", "per-robot", 0.2),
    ],
)
def test_the_compiled_law_matches_the_numpy_law_round_a_pillar(step_one, schedule, gains, rho_max):
    rng = np.random.default_rng(11)
    k_u = 1.5 if gains == "scalar" else rng.uniform(0.5, 3.0, len(AROUND))
    grid = _pillar_grid()
    densities, fields = _pillar_states(grid, rng)
    seen = fields[0].cell_sight()
    assert seen is not None and not seen[:, grid.active].all(axis=1).any()  # every robot has cells out of sight
    assert (0 < grid.aperture_x).any() and ((0 < grid.aperture_x) & (grid.aperture_x < 1)).any()  # cut faces

    states = _compare_over_calls(lambda: _pillar_law(step_one, schedule, k_u, rho_max), densities, fields)
    if rho_max < math.inf:
        assert max(rho.max() for rho in densities) > rho_max  # the congested branch f = 0 is met
    st, field = states[-1], fields[-1]
    # Step II (eq. (5)): ⟨ṽ, ∂_t v_r⟩ = −Σ b_i·u_i + Σ g_i ω_i, with the field masked by the pillar
    u, w = rng.normal(size=(len(AROUND), 2)), rng.normal(size=len(AROUND))
    lhs = grid.face_inner(st.v_tilde, field.velocity_rate(u, w))
    assert lhs == pytest.approx(-(st.b * u).sum() + (st.g * w).sum(), rel=1e-12)
    # the law (eq. (8)): Σ b_i·u_i − g_i ω_i = Σ k_u |b_i|² + k_ω g_i² + A
    lhs = (st.b * st.u).sum() - (st.g * st.omega).sum()
    rhs = (np.reshape(k_u, (-1, 1)) * st.b**2).sum() + (2.0 * st.g**2).sum() + st.A
    assert st.shortfall == 0 and lhs == pytest.approx(rhs, rel=1e-12)


@needs_numba
@pytest.mark.parametrize("step_one", ["hughes", "paper"])
def test_the_compiled_law_matches_the_numpy_law_on_the_office(office, step_one):
    grid, field0 = office.grid, office.observe().field
    rng = np.random.default_rng(5)
    hughes = office.controller.law
    assert type(hughes) is EvacuationController and field0.cell_sight() is not None

    def make():
        if step_one == "hughes":  # the office's own law, without its previous v_d
            law = copy.copy(hughes)
            law.previous_vd = None
            law.fused.reset()
            return law
        return BacksteppingController(grid, hughes.target, hughes.sigma, SaturatingAlpha(0.5, 0.1), 1.0, 1.0)

    densities, fields = [], []
    for k in range(3):  # the robots move, some into and out of the rooms' doors
        rho = office.density * rng.uniform(0.9, 1.1, grid.shape)
        R = field0.positions + 0.4 * k * rng.normal(size=field0.positions.shape)
        R = office.domain.project(R)
        fields.append(NavigationField(field0.kernel, grid, R, field0.headings + 0.3 * k, office.parts.sight))
        densities.append(rho)
    _compare_over_calls(make, densities, fields)


@needs_numba
def test_on_a_box_with_exits_the_fused_law_follows_hughes_field_not_the_paper_s():
    """The box anchor of bench_plan: the coverage's law is Hughes'; it once ran the paper's Step I compiled."""
    box = Domain.box(3.0, 2.0, exits=[((3.0, 0.5), (3.0, 1.5))])
    grid = Grid(box, (18, 12))
    rng = np.random.default_rng(2)
    phi = exit_distance(grid, exit_segments(box))
    target = gaussian_target(grid, (2.5, 1.0), 0.4)

    def make():
        return EvacuationController(grid, target, 0.01, SaturatingAlpha(0.2, 0.3), 1.0, 1.0, phi=phi, v_free=1.0)

    kernel = GaussianKernel(0.8, 0.4)
    densities = [smooth_density(grid) * rng.uniform(0.9, 1.1, grid.shape) for _ in range(2)]
    fields = [NavigationField(kernel, grid, rng.uniform(0, 2, (4, 2)), rng.uniform(0, 6, 4)) for _ in range(2)]
    states = _compare_over_calls(make, densities, fields)
    assert make().fused.which(densities[0], fields[0])[1][0] == 1  # Hughes', on the box
    hughes_vd = -1.0 * make().grad_phi[0]  # f(ρ) = v_free without congestion
    np.testing.assert_allclose(states[0].v_d[0], hughes_vd, rtol=1e-15, atol=1e-15)


@needs_numba
def test_the_compiled_law_is_deterministic_and_use_compiled_false_runs_numpy():
    rng = np.random.default_rng(3)
    (rho,), (field,) = _pillar_states(_pillar_grid(), rng, calls=1)

    def make():
        return _pillar_law("hughes")

    one, two = make().robot_inputs(rho, field, 0.0, 0.1), make().robot_inputs(rho, field, 0.0, 0.1)
    for f in dataclasses.fields(ControlState):
        a, b = getattr(one, f.name), getattr(two, f.name)
        assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True)) if f.name in ("v_d", "v_tilde") else (
            np.array_equal(a, b))  # fmt: skip
    with compiled.numpy_path():
        ref = make().robot_inputs(rho, field, 0.0, 0.1)
    law = make()
    compiled.use_compiled(False)
    try:
        assert law.fused.inputs(rho, field, 0.0, law.compiled_step_one()) is None  # the loop does not run
        off = make().robot_inputs(rho, field, 0.0, 0.1)
    finally:
        compiled.use_compiled(None)
    assert np.array_equal(off.u, ref.u) and np.array_equal(off.omega, ref.omega) and off.A == ref.A


def test_the_fused_law_applies_exactly_where_it_computes_the_same_law():
    box = Grid(Domain.box(1.0, 1.0), (8, 8))
    plan = _pillar_grid()
    kernel = GaussianKernel(0.5, 0.1)
    rho = np.ones((8, 8))

    class Mine(BacksteppingController):  # a subclass that changes how the law computes Step I: never fused
        def _virtual_velocity(self, p):
            return super()._virtual_velocity(p)

    class Same(BacksteppingController):  # a subclass that changes nothing of Step I computes the same law
        pass

    class NoCompiledForm(PaperStepOne):  # a Step I with no compiled form
        def compiled(self, law):
            return None

    def law(grid=box, cls=BacksteppingController, **kw):
        return cls(grid, np.ones(grid.shape) / grid.area, 0.01, SaturatingAlpha(0.2, 0.3), **kw)

    field = NavigationField(kernel, box, [[0.5, 0.5]], [0.0])
    assert law().fused.which(rho, field) == ("paper", None)
    assert law(cls=Same).fused.which(rho, field) == ("paper", None)
    sight = SightLines(PILLAR)
    on_plan = NavigationField(kernel, plan, AROUND, np.zeros(len(AROUND)), sight)
    assert law(plan).fused.which(np.ones(plan.shape), on_plan)[0] == "faces"
    assert law(plan).fused.which(np.ones(plan.shape), NavigationField(kernel, plan, AROUND, np.zeros(6)))[0] == "faces"
    refused = [
        (law(cls=Mine), field),
        (law(step_one=NoCompiledForm()), field),
        (law(dvd_dt="model"), field),
        (law(strategy=UserBetaGamma(lambda b, g, A: None)), field),
        (law(scales=(2.0, 1.0)), field),
        (law(), NavigationField(kernel, Grid(Domain.box(1.0, 1.0), (8, 8)), [[0.5, 0.5]], [0.0])),  # another grid
        (law(), NavigationField(kernel, box, [[0.5 + 1e-30j, 0.5]], [0.0])),  # complex steps
        (law(), NavigationField(CustomKernel(lambda x, y: 0 * x, lambda x, y: (x, y)), box, [[0.5, 0.5]], [0.0])),
    ]
    for controller, f in refused:
        assert controller.fused.which(rho, f) is None
    sigma = law()
    sigma.sigma = lambda x, y, t: 0.01 + 0 * x
    assert sigma.fused.which(rho, field) is None
    assert law().fused.which(rho.astype(complex), field) is None
    assert law().fused.which(np.asfortranarray(rho), field) is None  # not C-ordered


# ---------------------------------------------------------------------- sight, owners, view
@needs_numba
def test_cell_index_owners_in_view_and_turn_walkers_match_their_numpy_twins():
    rng = np.random.default_rng(9)
    nx, ny = 12, 9
    ii, jj = np.indices((nx, ny))
    ii, jj = np.ascontiguousarray(ii[::-1]), np.ascontiguousarray(jj)  # any table of stand-in cells
    pts = rng.uniform(-1, 5, (400, 2))
    pts[:3] = [[np.nan, 1.0], [0.0, 0.0], [1e300, -1e300]]
    args = (pts, 0.0, 0.0, 0.4, 0.5, ii, jj)
    fast = cell_index(*args, np.empty((400, 2), np.intp))
    with compiled.numpy_path():
        ref = cell_index(*args, np.empty((400, 2), np.intp))
    assert cell_index._ready and np.array_equal(fast, ref)
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < 4.8) & (pts[:, 1] >= 0) & (pts[:, 1] < 4.5)
    i, j = (pts[inside, 0] // 0.4).astype(int), (pts[inside, 1] // 0.5).astype(int)
    assert np.array_equal(fast[inside, 0], ii[i, j]) and np.array_equal(fast[inside, 1], jj[i, j])
    assert np.array_equal(fast[2], [ii[nx - 1, 0], jj[nx - 1, 0]])  # beyond the grid: the nearest edge cell

    xy, robots = rng.uniform(0, 1, (300, 2)), rng.uniform(0, 1, (7, 2))
    robots[3] = robots[1]  # a tie: the first robot wins
    cells = rng.permutation(500)[:300]
    seen = rng.uniform(size=(7, 500)) < 0.2
    seen[3] = seen[1]
    d2 = ((xy[None] - robots[:, None]) ** 2).sum(-1)
    out = {}
    for hidden in (True, False):
        out[hidden] = owners(xy, robots, seen, cells, hidden, np.empty(300, np.intp))
        with compiled.numpy_path():
            ref = owners(xy, robots, seen, cells, hidden, np.empty(300, np.intp))
        assert np.array_equal(out[hidden], ref) and 3 not in out[hidden]
    nobody = ~seen[:, cells].any(axis=0)
    assert nobody.any() and np.array_equal(out[True][nobody], np.argmin(d2[:, nobody], axis=0))  # seen by none
    hidden_d2 = np.where(seen[:, cells], d2, np.inf)
    assert np.array_equal(out[True][~nobody], np.argmin(hidden_d2[:, ~nobody], axis=0))  # the nearest that sees it
    assert np.array_equal(out[False], np.argmin(d2, axis=0))  # nothing hidden: the nearest robot

    humans = rng.uniform(0, 1, (500, 2))
    visible = rng.uniform(size=(7, 500)) < 0.5
    near = ((humans[None] - robots[:, None]) ** 2).sum(-1) <= 0.2**2
    for hidden, expected in ((True, (near & visible).any(axis=0)), (False, near.any(axis=0))):
        fast = in_view(humans, robots, 0.2**2, visible, hidden, np.empty(500, bool))
        with compiled.numpy_path():
            ref = in_view(humans, robots, 0.2**2, visible, hidden, np.empty(500, bool))
        assert np.array_equal(fast, ref) and np.array_equal(fast, expected)
    assert np.array_equal(robots_in_view(humans, robots, 0.2), near.any(axis=0))

    start = rng.uniform(0, 1, (60, 2))
    ahead = start + 0.1 * rng.normal(size=(60, 2))
    mirrored = ahead.copy()
    mirrored[::3] = start[::3] + 0.1 * rng.normal(size=(20, 2))  # a wall turned every third walker
    mirrored[3] = start[3]  # mirrored onto the start: no direction, no turn
    mirrored[6, 0] = np.nan
    idx = rng.permutation(100)[:60]
    e0 = rng.normal(size=(60, 2))
    turned = []
    for path in ("compiled", "numpy"):
        e, headings = e0.copy(), np.zeros(100)
        with compiled.numpy_path() if path == "numpy" else contextlib.nullcontext():
            turn_walkers(start, ahead, mirrored, e, headings, idx)
        turned.append((e, headings))
    assert turn_walkers._ready
    np.testing.assert_allclose(turned[0][0], turned[1][0], rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(turned[0][1], turned[1][1], rtol=1e-15, atol=1e-15)
    moved = np.zeros(60, bool)
    moved[::3] = True
    moved[[3, 6]] = False
    assert np.array_equal((turned[0][0] != e0).any(axis=1), moved)
    d = mirrored[9] - start[9]
    np.testing.assert_allclose(turned[0][0][9], d / np.hypot(*d), rtol=1e-15)
    assert turned[0][1][idx[9]] == pytest.approx(math.atan2(d[1], d[0]), rel=1e-15)
    assert not np.array_equal(near.any(axis=0), (near & visible).any(axis=0))


@needs_numba
def test_a_sight_row_is_every_segment_tested_against_every_wall(office):
    """The compiled row (nearest walls first, walls with both ends on one side skipped) against the numpy twin."""
    from meanfield.geometry._sight_loops import sight_row

    rng = np.random.default_rng(6)
    cases = []
    for sight, grid in ((SightLines(PILLAR), _pillar_grid()), (office.parts.sight, office.grid)):
        pts = np.ascontiguousarray(sight._cells_of(grid).points.reshape(-1, 2))
        cases += [(p, pts, sight._a, sight._e) for p in pts[rng.permutation(len(pts))[:60]]]
    walls = rng.uniform(0, 1, (30, 2, 2))
    walls[:10] = np.round(walls[:10] * 4) / 4  # walls on a lattice: collinear walls, shared ends
    a, e = np.ascontiguousarray(walls[:, 0]), np.ascontiguousarray(walls[:, 1] - walls[:, 0])
    lattice = np.stack(np.meshgrid(np.arange(5) / 4, np.arange(5) / 4), -1).reshape(-1, 2)
    length = np.hypot(e[:, 0], e[:, 1])  # (a wall on the lattice may have shrunk to a point)
    normal = np.column_stack([-e[:, 1], e[:, 0]]) / np.where(length > 0, length, 1.0)[:, None]
    beyond = [a + 0.5 * e + s * normal for s in (-1e-4, -1e-7, 1e-7, 1e-4)]  # a hair either side of each wall
    ends = np.concatenate([rng.uniform(0, 1, (500, 2)), lattice, a, a + e, a + 0.5 * e, *beyond])  # on walls, ends
    cases += [(p, ends, a, e) for p in np.concatenate([rng.uniform(0, 1, (20, 2)), lattice, a[:5], a[:5] + e[:5]])]
    hidden = 0
    for p, q, a, e in cases:
        work = np.empty(len(a), np.intp), np.empty((len(a), 7))
        fast = sight_row(p, q, a, e, *work, np.empty(len(q), bool))
        with compiled.numpy_path():
            ref = sight_row(p, q, a, e, *work, np.empty(len(q), bool))
        assert np.array_equal(fast, ref)
        hidden += (~fast).sum()
    assert sight_row._ready and hidden > 0


def test_the_sight_table_s_rows_are_the_segments_tested_against_every_wall():
    grid = _pillar_grid()
    sight = SightLines(PILLAR)
    cells = sight._cells_of(grid)
    for key in map(tuple, np.argwhere(grid.active)[::5]):
        row = cells._row(key)
        exact = sight.visible(cells.points[key], cells.points) & grid.active
        exact[key] = True
        assert np.array_equal(row, exact)
        assert np.array_equal(sight.visible_from(cells.points[key], cells.points.reshape(-1, 2)),
                              sight.visible(cells.points[key], cells.points).ravel())  # fmt: skip
    R = AROUND.copy()
    first = sight.cell_rows(grid, R)
    assert sight.cell_rows(grid, R.copy()) is first  # the same robots: the same answer, no look-up
    R[0] += 0.01  # the same cells: the same rows
    assert np.array_equal(sight.cell_rows(grid, R), first)
    R[0] = [3.0, 0.3]  # another cell: its row
    assert np.array_equal(sight.cell_rows(grid, R)[0], cells._row(tuple(cells.cells(R[:1])[0])))


def test_the_coverage_owners_are_the_nearest_robot_in_sight(office):
    c = office.controller
    assert isinstance(c, CoverageController) and c.sight is not None
    R = office.robots.positions
    d2 = ((c._xy[None, :, :] - R[:, None, :]) ** 2).sum(-1)  # the formula the compiled loop replaced
    seen = c.sight.cell_rows(c.grid, R).reshape(len(R), -1)[:, c._cells]
    expected = np.where(seen.any(axis=0), np.argmin(np.where(seen, d2, np.inf), axis=0), np.argmin(d2, axis=0))
    assert np.array_equal(c.owners(R), expected)
    assert (expected != np.argmin(d2, axis=0)).any()  # the walls matter here
    with compiled.numpy_path():
        assert np.array_equal(c.owners(R), expected)


def test_the_gate_hides_robots_behind_walls_and_a_walker_turns_at_a_thin_wall():
    plan = Plan.from_wkt(TWO_ROOMS)
    rng = np.random.default_rng(4)
    view = LocalView(3, 0.5, 1.0, 0.0, plan, rng)
    view.headings = np.array([0.0, 0.0, math.pi / 2])
    humans = np.array([[0.3, 0.3], [0.8, 0.3], [0.8, 0.5]])  # the left room; the right room (x2)
    robots = np.array([[0.2, 0.5]])
    sight = SightLines(plan)
    visible = sight.mask(robots, humans)
    v = np.zeros((3, 2))
    view.gate(v, humans, robots, 0.2, visible)
    assert view.seen.tolist() == [True, False, False]  # within 0.5 m, but behind the wall
    # walking east from (0.4, 0.3), a step of 0.2 m would end in the other room, through the wall
    e = view.walk_velocity(np.array([[0.4, 0.3]]), 0.2, np.array([0]))
    np.testing.assert_allclose(e, [[-1.0, 0.0]], atol=1e-12)  # the mirror image across x = 0.45
    assert view.headings[0] == pytest.approx(math.pi)


@needs_numba
def test_the_office_s_closed_loop_is_deterministic_on_the_compiled_path():
    runs = []
    for _ in range(2):
        loop = ClosedLoop(builtin_scenarios()["office"](seed=2).with_values(COVERAGE))
        for _ in range(15):
            loop.step()
        runs.append((loop.robots.positions.copy(), loop.robots.headings.copy(), loop.crowd.positions.copy()))
    for a, b in zip(*runs, strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    assert face_law._ready and owners._ready and in_view._ready
