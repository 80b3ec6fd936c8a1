"""The Fokker–Planck solver's compiled sweeps (meanfield.fokker_planck._sweeps) against the numpy path.

* each compiled loop (Thomas factorisation, one sweep, one fused Peaceman–Rachford step)
  agrees with its numpy twin to round-off on one call, on a box and on a floor plan with a
  pillar (cells outside Ω, cut cells);
* the solver on the compiled path agrees with its numpy path (LAPACK ``gtsv``/``gttrs``,
  which ``MEANFIELD_COMPILED=0`` selects) to 1e-12 relative, on one step and on a short
  solve, for ``"adi"`` and ``"split"``, with a fixed drift (factorisations reused), a
  drift that moves every step (factorised every step) and the interaction; on a plan with
  exits, with the exits' outflow applied after every step as the density crowd does;
* the accuracy step (``courant``): its size, equal steps to ``t_final``, its fallback
  without drift, and that it is refused for the other methods.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import Domain, FokkerPlanck, GaussianKernel, GaussianPotential, Grid, NavigationField
from meanfield._compiled import core as compiled
from meanfield.errors import ParameterError
from meanfield.fokker_planck import _sweeps as fpc
from meanfield.geometry.plan import Plan

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")

L_WITH_PILLAR = (
    "POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0), (0.15 0.15, 0.25 0.15, 0.25 0.25, 0.15 0.25, 0.15 0.15))"
)
RTOL = 1e-12


def _box() -> Grid:
    return Grid(Domain.box(1.0, 0.8), (24, 19))


def _plan(exits: bool = False) -> Grid:
    plan = Plan.from_wkt(L_WITH_PILLAR)
    if exits:
        plan = Plan(plan.polygon, [((1.0, 0.1), (1.0, 0.3)), ((0.1, 1.0), (0.3, 1.0))])
    return Grid(plan, (26, 26))


GRIDS = {"box": _box, "plan": _plan}


def _swirl(x, y, t):
    return 0.4 * (0.5 - y) + 0.1 * np.cos(3 * t), 0.4 * (x - 0.45) + 0.2 * np.sin(2 * x)


def _rho0(grid: Grid) -> np.ndarray:
    X, Y = grid.centers
    return grid.normalize(np.where(grid.active, 0.2 + np.exp(-((X - 0.3) ** 2 + (Y - 0.25) ** 2) / 0.02), 0.0))


def _close(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(a, b, rtol=0, atol=RTOL * np.abs(b).max())


def _coefficients(grid: Grid):
    fp = FokkerPlanck(grid, 0.02, _swirl, method="adi", time_dependent=False)
    return fp._coefficients(_rho0(grid), 0.0, None)


# ---------------------------------------------------------------------- each loop against its twin
@needs_numba
@pytest.mark.parametrize("grid", sorted(GRIDS))
@pytest.mark.parametrize("axis", [0, 1])
def test_factor_and_sweep_match_their_numpy_twins(grid, axis):
    g = GRIDS[grid]()
    c = _coefficients(g)
    lo, hi = (c.lx, c.rx) if axis == 0 else (c.ly, c.ry)
    tau = 0.03
    fast = [np.empty(g.shape) for _ in range(2)]
    ref = [np.empty(g.shape) for _ in range(2)]
    fpc.tridiagonal_factor(g.volume, lo, hi, tau, axis, *fast)
    fpc.tridiagonal_factor.fallback(g.volume, lo, hi, tau, axis, *ref)
    for a, b in zip(fast, ref, strict=True):
        _close(a, b)
    b = g.volume * _rho0(g)
    x_fast, x_ref = np.empty(g.shape), np.empty(g.shape)
    fpc.tridiagonal_solve(b, hi, tau, *fast, axis, x_fast)
    fpc.tridiagonal_solve.fallback(b, hi, tau, *ref, axis, x_ref)
    _close(x_fast, x_ref)
    # it is the solve of (V - τ A_axis) x = b: the residual, and mass conservation (columns sum to V)
    fp = FokkerPlanck(g, 0.02, _swirl, method="adi", time_dependent=False)
    residual = g.volume * x_fast - tau * fp._apply(c, x_fast, "x" if axis == 0 else "y", np.empty(g.shape)) - b
    assert np.abs(residual).max() <= 1e-13 * np.abs(b).max()
    assert (g.volume * x_fast).sum() == pytest.approx(b.sum(), rel=1e-13)


@needs_numba
@pytest.mark.parametrize("grid", sorted(GRIDS))
def test_adi_step_matches_its_numpy_twin(grid):
    g = GRIDS[grid]()
    c = _coefficients(g)
    h = 0.02
    rho = _rho0(g)

    def run(kernel, factor, sx=0.0, sy=0.0):
        """One step with the outflow coefficients ``sx``, ``sy`` in every cell (0: no exits, mass conserved)."""
        f = [np.empty(g.shape) for _ in range(4)]
        factor(g.volume + h * sx, c.lx, c.rx, h, 0, f[0], f[1])
        factor(g.volume + h * sy, c.ly, c.ry, h, 1, f[2], f[3])
        work, out = np.empty(g.shape), np.empty(g.shape)
        lowest = kernel(rho, g.volume - h * sy, g.volume - h * sx, c.lx, c.rx, c.ly, c.ry, h, *f, work, out)
        return out, lowest

    fast, low_fast = run(fpc.adi_step, fpc.tridiagonal_factor)
    ref, low_ref = run(fpc.adi_step.fallback, fpc.tridiagonal_factor.fallback)
    _close(fast, ref)
    assert low_fast == pytest.approx(low_ref, rel=RTOL) and low_fast == pytest.approx(fast.min(), rel=0, abs=0)
    assert (g.volume * fast).sum() == pytest.approx((g.volume * rho).sum(), rel=1e-14)
    sink = 0.3 * g.volume  # outflow along x and (half as much) along y: the explicit halves differ
    fast, _ = run(fpc.adi_step, fpc.tridiagonal_factor, sink, 0.5 * sink)
    ref, _ = run(fpc.adi_step.fallback, fpc.tridiagonal_factor.fallback, sink, 0.5 * sink)
    _close(fast, ref)
    assert (g.volume * fast).sum() < (g.volume * rho).sum()


# ---------------------------------------------------------------------- the solver, both paths
def _both(make, run):
    """``run(make())`` on the compiled path and on the numpy path."""
    fast = run(make())
    with compiled.numpy_path():
        ref = run(make())
    return fast, ref


@needs_numba
@pytest.mark.parametrize("grid", sorted(GRIDS))
@pytest.mark.parametrize("method", ["adi", "split"])
@pytest.mark.parametrize("drift", ["fixed", "moving", "interaction"])
def test_solver_paths_agree_on_one_step_and_a_short_solve(grid, method, drift):
    g = GRIDS[grid]()
    rho0 = _rho0(g)
    kwargs = {"time_dependent": drift != "fixed"}
    if drift == "interaction":
        kwargs["interaction"] = GaussianPotential(0.05, 0.1)

    def make():
        return FokkerPlanck(g, 0.02, _swirl, method=method, **kwargs)

    kernel = GaussianKernel(0.5, 0.05)

    def robots(t):  # a new face drift every step
        return NavigationField(kernel, g, np.array([[0.2 + 0.1 * t, 0.3], [0.2, 0.7]]), np.array([t, 1.0])).velocity()

    fv = robots if drift == "moving" else None
    dt = 0.01
    fast, ref = _both(make, lambda fp: fp.step(rho0, 0.0, dt, face_velocity=None if fv is None else fv(0.0)))
    _close(fast, ref)
    fast, ref = _both(make, lambda fp: fp.solve(rho0, 20 * dt, dt=dt, face_velocity=fv))
    _close(fast, ref)
    assert g.integrate(fast) == pytest.approx(g.integrate(rho0), rel=1e-13)
    assert fast.min() >= 0 and np.all(fast[~g.active] == 0)
    assert np.abs(fast - rho0).max() > 1e-2 * rho0.max()  # something did happen


@needs_numba
def test_paths_agree_on_a_plan_with_exits_and_the_exits_absorb():
    """The solver's own exits, integrated with each step (their outflow in the sweeps), counted in ``mass_out``:
    the compiled and numpy paths agree, and the mass in Ω plus the mass out is the initial mass."""
    g = _plan(exits=True)
    rho0 = _rho0(g)

    def run(fp):
        rho = rho0
        for k in range(30):
            rho = fp.step(rho, 0.02 * k, 0.02)
        return rho, fp.mass_out_total

    for method in ("adi", "split"):
        (fast, out_fast), (ref, out_ref) = _both(lambda m=method: FokkerPlanck(g, 0.02, _swirl, method=m), run)
        _close(fast, ref)
        assert out_fast == pytest.approx(out_ref, rel=RTOL)
        assert out_fast > 1e-3  # mass did leave through the exits
        assert g.integrate(fast) + out_fast == pytest.approx(g.integrate(rho0), rel=1e-12)  # and only there
        walls, _ = run(FokkerPlanck(g, 0.02, _swirl, method=method, exits=False))
        assert g.integrate(walls) == pytest.approx(g.integrate(rho0), rel=1e-12)  # exits=False: zero flux


@needs_numba
def test_fixed_drift_reuses_the_factorisations_and_keeps_only_a_few():
    g = _box()
    fp = FokkerPlanck(g, 0.02, _swirl, method="adi", time_dependent=False)
    rho = _rho0(g)
    for dt in np.linspace(0.001, 0.02, 12):
        rho = fp.step(rho, 0.0, float(dt))
        assert len(fp.stepper._lu_cache) <= 8
    before = dict(fp.stepper._lu_cache)
    fp.step(rho, 0.0, 0.02)  # the same step again: no new factorisation
    cache = fp.stepper._lu_cache
    assert cache.keys() == before.keys() and all(cache[k] is before[k] for k in before)


# ---------------------------------------------------------------------- the accuracy step
def test_courant_step_is_the_cell_crossing_time():
    g = Grid(Domain.box(1.0, 1.0), (32, 32))
    rho = g.normalize(np.ones(g.shape))
    fp = FokkerPlanck(g, 0.01, lambda x, y, t: (0.4 + 0 * x, -0.1 + 0 * y), method="adi", courant=2.0)
    assert fp.automatic_dt(rho) == pytest.approx(2.0 * g.dx / 0.4, rel=1e-12)
    steps = []
    out = fp.solve(rho, 1.0, callback=lambda t, r: steps.append(t))
    assert len(steps) == math.ceil(1.0 / (2.0 * g.dx / 0.4)) and steps[-1] == 1.0
    np.testing.assert_allclose(np.diff(steps), 1.0 / len(steps), rtol=1e-12)  # equal steps to t_final
    assert out.min() >= 0 and g.integrate(out) == pytest.approx(1.0, abs=1e-13)
    # without any drift there is no crossing time: the positivity step
    still = FokkerPlanck(g, 0.01, method="adi", courant=2.0)
    assert still.automatic_dt(rho) == pytest.approx(FokkerPlanck(g, 0.01, method="adi").automatic_dt(rho))


def test_courant_step_time_error_is_small():
    """A Gaussian carried by a uniform drift: the accuracy step (two cells per step) agrees
    with a 16× smaller step to a small fraction of what the solve changes."""
    g = Grid(Domain.box(1.0, 1.0), (48, 48))
    X, Y = g.centers
    rho0 = g.normalize(0.1 + np.exp(-((X - 0.3) ** 2 + (Y - 0.5) ** 2) / 0.01))
    fp = FokkerPlanck(g, 0.005, lambda x, y, t: (0.3 + 0 * x, 0 * y), method="adi", time_dependent=False, courant=2)
    coarse = fp.solve(rho0, 1.0)
    fine = fp.solve(rho0, 1.0, dt=fp.automatic_dt(rho0) / 16)
    assert np.abs(coarse - fine).max() <= 0.015 * np.abs(fine - rho0).max()  # 0.008 measured; 0.025 at courant=8


@pytest.mark.parametrize("method", ["split", "explicit", "implicit"])
def test_courant_is_refused_for_the_other_methods(method):
    with pytest.raises(ParameterError) as info:
        FokkerPlanck(_box(), 0.01, method=method, courant=2.0)
    assert info.value.name == "courant"
    with pytest.raises(ParameterError):
        FokkerPlanck(_box(), 0.01, method="adi", courant=-1.0)
