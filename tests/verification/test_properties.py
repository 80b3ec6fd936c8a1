"""Property-based tests (hypothesis) of the paper's claims on the semi-discrete system.

Every claim is checked over random densities, targets, robot states, kernels, gains,
diffusions, α schedules, interaction potentials and domains, on the finite-volume
operators of :class:`~meanfield.geometry.grid.Grid` (where the Lyapunov identities are exact):

* Theorem 1 (Step I): with ``v_r = v_d``, ``dV₁/dt = -2∫α|∇ρ̃|² <= -k_p V₁``,
  ``V₁ = ∫ρ̃²`` (no ½), ``k_p = 2 α_inf μ₂`` with μ₂ the *discrete* Neumann eigenvalue of
  the same grid and ``α_inf`` the smallest α over the open faces;
* Theorem 3 (Step II): along the closed loop ``ρ̇ = density_rate(ρ, v_r)``, ``Ṙ = u``,
  ``θ̇ = ω``, ``dV₂/dt = -∫α|∇ρ̃|² - Σ k_u|b_i|² - Σ k_ω g_i² + shortfall`` (an identity),
  for the minimum-norm β/γ (shortfall 0) and the speed-limited program
  (:class:`analysis.bounded.BoundedBetaGamma`, whose total inputs respect the limits);
* ``∂_t v_d`` by finite differences (the scenarios' default) is the backward difference of
  ``v_d`` and tends to the model-based ``∂_t v_d`` as the step shrinks;
* the Fokker–Planck solver conserves mass and keeps ``ρ >= 0`` (``"split"`` and
  ``"implicit"`` at any ``dt``, ``"explicit"`` and ``"adi"`` at their automatic step), and
  its Scharfetter–Gummel flux is the model's central flux plus a non-negative numerical
  diffusion of at most the upwind amount ``|a|h/2``;
* the bounded β/γ program: limits, the sign convention of the shortfall and the algebraic
  form of the ``dV₂/dt`` identity, with per-robot gains and zero integrals (and, as a strict
  xfail, a measured limitation of its Clarabel path with tiny limits).

``dV/dt`` is computed independently of the controller's own terms by complex-step
differentiation along the closed-loop vector field: ``Im V(x + iεẋ)/ε = V'(x)ẋ`` with no
cancellation error, so identities hold to round-off and inequalities are genuine.

The number of examples comes from the hypothesis profile (``HYPOTHESIS_PROFILE``:
``ci`` by default, ``dev``, ``release``; see ``tests/conftest.py``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import event, given, note
from hypothesis import strategies as st

from analysis.bounded import BoundedBetaGamma, achievable_range, bounded_inputs_exact
from analysis.poincare import _assemble, neumann_eigenvalue
from meanfield import (
    BacksteppingController,
    ConstantAlpha,
    Domain,
    FokkerPlanck,
    GaussianKernel,
    GaussianPotential,
    Grid,
    InteractionField,
    MinimumNormBetaGamma,
    NavigationField,
    SaturatingAlpha,
)
from tests.conftest import all_domains

EPS = 1e-30  # complex step
TWO_PI = 2 * math.pi

# ---------------------------------------------------------------------- grids (μ₂ cached per grid)
_GRID_SPECS = {
    "box": (lambda: Domain.box(1.0, 1.2), (12, 14)),
    "box-offset": (lambda: all_domains()[0], (11, 9)),
    "disk": (lambda: all_domains()[1], (14, 14)),
    "polygon": (lambda: all_domains()[2], (14, 13)),
}
BOXES = ["box", "box-offset"]
CUT = ["disk", "polygon"]


@functools.cache
def grid_named(name: str) -> Grid:
    """One fixed grid per name (built once per session)."""
    make, cells = _GRID_SPECS[name]
    return Grid(make(), cells)


@functools.cache
def mu2_of(name: str) -> float:
    """The discrete Neumann eigenvalue μ₂ of ``grid_named(name)`` (the grid's own operator).

    Also checks the precondition of the discrete Poincaré inequality used by Theorem 1:
    every active cell is an unknown of the eigenproblem (the open faces connect them all),
    so a ρ̃ of zero cell-volume mean is orthogonal to the constants of that operator.
    """
    grid = grid_named(name)
    _, _, unknown = _assemble(grid)
    assert np.array_equal(unknown, grid.active), f"{name}: active cells not connected by open faces"
    return float(neumann_eigenvalue(grid))


def _open_faces(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    return grid.aperture_x > 0, grid.aperture_y > 0


# ---------------------------------------------------------------------- strategies
unit = st.floats(0.0, 1.0)


@st.composite
def densities(draw, grid: Grid, floor_min: float = 0.02) -> np.ndarray:
    """A smooth unit-mass density: a positive floor plus 1-3 random Gaussian bumps."""
    x0, x1, y0, y1 = grid.domain.bounds
    w, h = x1 - x0, y1 - y0
    X, Y = grid.centers
    f = np.full(grid.shape, draw(st.floats(floor_min, 0.5)))
    for _ in range(draw(st.integers(1, 3))):
        cx, cy = x0 + w * draw(unit), y0 + h * draw(unit)
        width = max(w, h) * draw(st.floats(0.08, 0.4))
        f = f + draw(st.floats(0.2, 2.0)) * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * width**2))
    return grid.normalize(f)


alphas = st.one_of(
    st.builds(ConstantAlpha, st.floats(0.01, 0.5)),
    st.builds(SaturatingAlpha, st.floats(0.01, 0.5), st.floats(0.02, 2.0)),
)
sigmas = st.one_of(st.just(0.0), st.floats(1e-6, 0.03))
kernels = st.builds(GaussianKernel, st.floats(0.05, 1.0), st.floats(0.005, 0.2))
potentials = st.one_of(
    st.none(),
    st.builds(
        GaussianPotential,
        st.floats(0.005, 0.1).flatmap(lambda s: st.sampled_from([s, -s])),
        st.floats(0.05, 0.4),
    ),
)


@st.composite
def robots(draw, grid: Grid, n_max: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Positions (n, 2) over the grid's bounding box and headings (n,)."""
    n = draw(st.integers(1, n_max))
    x0, x1, y0, y1 = grid.domain.bounds
    R = np.array([[x0 + (x1 - x0) * draw(unit), y0 + (y1 - y0) * draw(unit)] for _ in range(n)])
    th = np.array([draw(st.floats(0.0, TWO_PI)) for _ in range(n)])
    return R, th


def gains(n: int):
    """A scalar gain or one gain per robot, each in [0, 5] (zeros included)."""
    g = st.floats(0.0, 5.0)
    return st.one_of(g, st.lists(g, min_size=n, max_size=n).map(np.array))


@dataclass
class Case:
    """One random closed-loop configuration."""

    name: str
    grid: Grid
    rho: np.ndarray
    target: np.ndarray
    sigma: float
    alpha: ConstantAlpha | SaturatingAlpha
    potential: GaussianPotential | None
    kernel: GaussianKernel
    R: np.ndarray
    th: np.ndarray
    k_u: float | np.ndarray
    k_omega: float | np.ndarray

    @property
    def n(self) -> int:
        return len(self.th)

    def interaction(self) -> InteractionField | None:
        return None if self.potential is None else InteractionField(self.grid, self.potential)

    def controller(self, strategy=None, dvd_dt: str = "model") -> BacksteppingController:
        return BacksteppingController(
            self.grid, self.target, self.sigma, self.alpha, self.k_u, self.k_omega,
            strategy or MinimumNormBetaGamma(), self.interaction(), dvd_dt,
        )  # fmt: skip

    def field(self, R=None, th=None) -> NavigationField:
        return NavigationField(self.kernel, self.grid, self.R if R is None else R, self.th if th is None else th)


@st.composite
def cases(draw, names=("box", "box", "box-offset", "disk", "polygon")) -> Case:
    """A random configuration on one of the fixed grids (boxes drawn most often)."""
    name = draw(st.sampled_from(names))
    grid = grid_named(name)
    R, th = draw(robots(grid))
    n = len(th)
    return Case(
        name, grid, draw(densities(grid)), draw(densities(grid)), draw(sigmas), draw(alphas), draw(potentials),
        draw(kernels), R, th, draw(gains(n)), draw(gains(n)),
    )  # fmt: skip


def _per_robot(k: float | np.ndarray, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(k, float), (n,))


# ---------------------------------------------------------------------- Theorem 1
def alpha_inf(grid: Grid, alpha, rho: np.ndarray) -> float:
    """``min α(ρ_f)`` over the open faces, α as the controller forms it (``(α/ρ)(ρ_f)·ρ_f``)."""
    rf = [r[m] for r, m in zip(grid.face_average(rho), _open_faces(grid), strict=True)]
    return float(min((alpha.over_rho(r) * r).min() for r in rf))


@given(name=st.sampled_from(list(_GRID_SPECS)), data=st.data())
def test_discrete_poincare_inequality(name, data):
    """``‖∇_h f‖² >= μ₂ ‖f - f̄‖²`` on the grid's own operators (face_inner of grid.gradient),
    with μ₂ from analysis.poincare: the constant Theorem 1 uses is the one of this operator."""
    grid = grid_named(name)
    mu2 = mu2_of(name)
    f = data.draw(densities(grid, floor_min=0.0)) * data.draw(st.floats(-3.0, 3.0))
    f = f + data.draw(st.floats(-1.0, 1.0)) * np.where(grid.active, grid.centers[0] ** 2, 0.0)
    fm = np.where(grid.active, f - grid.integrate(f) / grid.area, 0.0)
    energy = grid.face_inner(grid.gradient(f), grid.gradient(f))
    assert energy >= mu2 * grid.inner(fm, fm) * (1 - 1e-9)


def test_poincare_mode_attains_the_bound():
    """The eigenfunction of μ₂ makes the discrete Poincaré inequality an equality: μ₂ is the
    sharp constant of ``grid.face_inner ∘ grid.gradient`` (same operator, same weights)."""
    for name in _GRID_SPECS:
        grid = grid_named(name)
        mu2, mode = neumann_eigenvalue(grid, return_mode=True)
        u = np.where(grid.active, mode, 0.0)
        assert abs(grid.integrate(u)) <= 1e-10 * grid.norm(u)
        ratio = grid.face_inner(grid.gradient(u), grid.gradient(u)) / grid.inner(u, u)
        assert abs(ratio - mu2) <= 1e-9 * mu2, name


@given(case=cases())
def test_theorem1_exponential_decay_of_V1(case: Case):
    """With v_r = v_d: dV₁/dt = -2∫α|∇ρ̃|² <= -2 α_inf μ₂ V₁ (V₁ = ∫ρ̃², ρ̃ of zero mean)."""
    g = case.grid
    ctrl = case.controller()
    rho, rt = case.rho, case.rho - case.target
    assert abs(g.integrate(rt)) <= 1e-12
    rho_dot = ctrl.density_rate(rho, ctrl.virtual_velocity(rho))
    z = rho + 1j * EPS * rho_dot - case.target
    dV1 = g.inner(z, z).imag / EPS
    V1 = g.inner(rt, rt)
    diss = ctrl.dissipation(rho)
    k_p = 2 * alpha_inf(g, case.alpha, rho) * mu2_of(case.name)
    event(f"grid {case.name}, {type(case.alpha).__name__}, W {'on' if case.potential else 'off'}")
    note(f"dV1={dV1:.6g} -2diss={-2 * diss:.6g} -k_p V1={-k_p * V1:.6g}")
    assert (diss > 0) == (V1 > 0)  # ρ̃ has zero mean: it is constant only where it vanishes
    assert abs(dV1 + 2 * diss) <= 1e-9 * diss
    assert dV1 <= -k_p * V1 + 1e-9 * (abs(dV1) + k_p * V1)


# ---------------------------------------------------------------------- Theorem 3
def _V2(ctrl: BacksteppingController, case: Case, rho, R, th) -> complex:
    """``V₂ = ∫½ρ̃² + ½|ṽ|²`` (complex inputs allowed)."""
    g = ctrl.grid
    v_r = case.field(R, th).velocity()
    v_d = ctrl.virtual_velocity(rho)
    vt = (v_r[0] - v_d[0], v_r[1] - v_d[1])
    rt = rho - ctrl.target
    return 0.5 * g.inner(rt, rt) + 0.5 * g.face_inner(vt, vt)


def _robot_term_magnitude(case: Case, vt, u: np.ndarray, omega: np.ndarray) -> float:
    """``Σ_i ‖u_i‖₁ ∫|ṽ||K_ξ^i| + |ω_i| ∫|ṽ||K_θ^i|``: the size of the terms that make
    ``Σ b_i·u_i - Σ g_i ω_i``, whose round-off matters when a robot sees almost nothing
    (``b_i`` tiny, so the minimum-norm ``u_i = A b_i / Z`` is huge)."""
    g = case.grid
    c, s = np.abs(np.cos(case.th)), np.abs(np.sin(case.th))
    total = 0.0
    # x-faces carry the x-components (factor cos θ of e, sin θ of e⊥), y-faces the y-components
    for (X, Y), w, v, e, e_perp in (
        (g.face_points_x, g.weight_x, np.abs(vt[0]), c, s),
        (g.face_points_y, g.weight_y, np.abs(vt[1]), s, c),
    ):
        for i in range(case.n):
            k = case.kernel.magnitude(X - case.R[i, 0], Y - case.R[i, 1])
            gx, gy = case.kernel.magnitude_gradient(X - case.R[i, 0], Y - case.R[i, 1])
            wv = w * v
            total += e[i] * (abs(u[i, 0]) * (wv * np.abs(gx)).sum() + abs(u[i, 1]) * (wv * np.abs(gy)).sum())
            total += e_perp[i] * abs(omega[i]) * (wv * k).sum()
    return float(total)


def _check_lyapunov(ctrl: BacksteppingController, case: Case):
    """Compute the law, differentiate V₂ along the closed loop, check the identity; returns the state."""
    g = case.grid
    field = case.field()
    st_ = ctrl.robot_inputs(case.rho, field)
    rho_dot = ctrl.density_rate(case.rho, field.velocity())
    # the step must stay tiny against the kernels' length scale even when u_i is huge
    # (complex step: error O(h²) in the displacement h·u_i, none from cancellation)
    h = EPS / max(1.0, np.abs(rho_dot).max(), np.abs(st_.u).max(), np.abs(st_.omega).max())
    dV = _V2(ctrl, case, case.rho + 1j * h * rho_dot, case.R + 1j * h * st_.u, case.th + 1j * h * st_.omega).imag / h
    n = case.n
    ku, kw = _per_robot(case.k_u, n), _per_robot(case.k_omega, n)
    gain_b = (ku * (st_.b**2).sum(1)).sum()
    gain_g = (kw * st_.g**2).sum()
    bound = -st_.dissipation - gain_b - gain_g + st_.shortfall
    # the size of the terms dV₂/dt is made of: round-off is relative to these
    vd_rate = ctrl.virtual_velocity_rate(case.rho, rho_dot)
    abs_vt = (np.abs(st_.v_tilde[0]), np.abs(st_.v_tilde[1]))
    scale = (
        st_.dissipation + abs(st_.A) + gain_b + gain_g + abs(st_.shortfall)
        + g.inner(np.abs(st_.rho_tilde), np.abs(rho_dot))
        + g.face_inner(abs_vt, (np.abs(vd_rate[0]), np.abs(vd_rate[1])))
        + _robot_term_magnitude(case, st_.v_tilde, st_.u, st_.omega)
    )  # fmt: skip
    note(f"dV2={dV:.6g} bound={bound:.6g} diff={dV - bound:.3g} A={st_.A:.4g}")
    note(f"shortfall={st_.shortfall:.4g} scale={scale:.4g} max|u|={np.abs(st_.u).max():.3g}")
    assert abs(dV - bound) <= 1e-8 * scale, (dV, bound)
    assert dV <= bound + 1e-8 * scale
    return st_


@given(case=cases())
def test_theorem3_identity_minimum_norm(case: Case):
    """Minimum-norm β/γ: dV₂/dt = -∫α|∇ρ̃|² - Σ k_u|b_i|² - Σ k_ω g_i² (shortfall 0 when Z > 0)."""
    st_ = _check_lyapunov(case.controller(), case)
    if (st_.b**2).sum() + (st_.g**2).sum() > 0:
        assert st_.shortfall == 0


@given(
    case=cases(),
    u_frac=st.one_of(st.none(), st.floats(0.02, 3.0)),
    w_frac=st.one_of(st.none(), st.floats(0.02, 3.0)),
    condition=st.sampled_from(["inequality", "equality"]),
    method=st.sampled_from(["exact", "clarabel"]),
)
def test_theorem3_identity_bounded(case: Case, u_frac, w_frac, condition, method):
    """Speed-limited β/γ: the identity with the reported shortfall, and every robot's total
    input within ``u_max`` and ``ω_max``.  The limits are drawn as a fraction of what the
    minimum-norm law asks for, so that they often bind."""
    free = case.controller().robot_inputs(case.rho, case.field())
    need_u = float(np.hypot(free.u[:, 0], free.u[:, 1]).max())
    need_w = float(np.abs(free.omega).max())
    u_max = None if u_frac is None else u_frac * need_u + 1e-12
    omega_max = None if w_frac is None else w_frac * need_w + 1e-12
    strategy = BoundedBetaGamma(case.n, case.k_u, case.k_omega, u_max, omega_max, condition, method)
    st_ = _check_lyapunov(case.controller(strategy), case)
    out = strategy.last
    assert out is not None and out.shortfall == st_.shortfall
    if u_max is not None:
        assert np.all(np.hypot(st_.u[:, 0], st_.u[:, 1]) <= u_max * (1 + 1e-9))
    if omega_max is not None:
        assert np.all(np.abs(st_.omega) <= omega_max * (1 + 1e-9))
    _check_shortfall_convention(out, st_.A, condition)
    small = 1e-9 * (abs(st_.A) + 1e-12)
    event(f"shortfall {'> 0' if out.shortfall > small else '< 0' if out.shortfall < -small else '~ 0'}")
    event(f"limit binding: {bool(np.any(out.speed_binding) or np.any(out.turn_binding))}")


@given(case=cases(), log_step=st.floats(-8.0, -5.0))
def test_finite_difference_dvd_dt_is_the_backward_difference_and_tends_to_the_model(case: Case, log_step):
    """``dvd_dt="finite-difference"`` (the scenarios' default): the first call uses
    ``∂_t v_d = 0``; the next one the backward difference ``(v_d(t) - v_d(t-h))/h`` in
    ``A = ∫ṽᵀ(ρ∇ρ̃ - ∂_t v_d)``, and along one Euler step of the closed loop its ``A``
    tends to the model-based (chain-rule) ``A`` as ``h → 0``."""
    g = case.grid
    fd = case.controller(dvd_dt="finite-difference")
    model = case.controller()
    f0 = case.field()
    s0 = fd.robot_inputs(case.rho, f0, t=0.0)
    rf0 = g.face_average(case.rho)
    a0 = g.face_inner(s0.v_tilde, (rf0[0] * g.gradient(s0.rho_tilde)[0], rf0[1] * g.gradient(s0.rho_tilde)[1]))
    assert abs(s0.A - a0) <= 1e-12 * (abs(a0) + g.face_norm(s0.v_tilde) * g.norm(case.rho))
    # one explicit Euler step of the closed loop, of a size relative to its fastest rate
    rho_dot = model.density_rate(case.rho, f0.velocity())
    h_min = min(g.dx, g.dy)
    v_max = max(np.abs(c).max() for c in f0.velocity())
    rate = max(
        1.0,
        np.abs(rho_dot).max() / case.rho[g.active].min(),
        v_max / h_min + case.sigma / h_min**2,
        np.abs(s0.u).max() / math.sqrt(case.kernel.eta),
        np.abs(s0.omega).max(),
    )
    h = 10.0**log_step / rate
    rho1 = case.rho + h * rho_dot
    R1, th1 = case.R + h * s0.u, case.th + h * s0.omega
    f1 = case.field(R1, th1)
    s1 = fd.robot_inputs(rho1, f1, t=h)
    vd0, vd1 = fd.virtual_velocity(case.rho), fd.virtual_velocity(rho1)
    dvd = ((vd1[0] - vd0[0]) / h, (vd1[1] - vd0[1]) / h)
    rf1, gr1 = g.face_average(rho1), g.gradient(s1.rho_tilde)
    A_def = g.face_inner(s1.v_tilde, (rf1[0] * gr1[0] - dvd[0], rf1[1] * gr1[1] - dvd[1]))
    abs_vt = (np.abs(s1.v_tilde[0]), np.abs(s1.v_tilde[1]))
    size = g.face_inner(abs_vt, (np.abs(rf1[0] * gr1[0]) + np.abs(dvd[0]), np.abs(rf1[1] * gr1[1]) + np.abs(dvd[1])))
    assert abs(s1.A - A_def) <= 1e-9 * size, (s1.A, A_def)
    A_model = model.robot_inputs(rho1, f1, t=h).A
    # the difference quotient's own round-off (ρ may barely move in h): the rounding of ρ
    # (~eps ρ per cell) moves v_d by ~eps (α + σ)/h_min, plus ~eps |v_d| from its evaluation
    alpha_f = [
        np.where(o, case.alpha.over_rho(np.where(o, r, 1.0)) * r, 0.0) for r, o in zip(rf1, _open_faces(g), strict=True)
    ]
    m = [(alpha_f[k] + case.sigma) / h_min + np.abs(vd0[k]) + np.abs(vd1[k]) for k in range(2)]
    roundoff = 1e-13 * g.face_inner(abs_vt, (m[0], m[1])) / h
    note(f"h={h:.3g} A_fd={s1.A:.8g} A_model={A_model:.8g} size={size:.3g} roundoff={roundoff:.3g}")
    assert abs(s1.A - A_model) <= 1e-3 * size + roundoff


def _check_shortfall_convention(out, A: float, condition: str) -> None:
    """The documented sign of the shortfall: > 0 only when ``A`` is above the reachable range;
    with ``"equality"`` < 0 only when below it; else ~0 (or < 0 with ``"inequality"``)."""
    lo, hi = out.achievable
    tol = 1e-6 * (abs(A) + 1e-3 * (abs(lo) + abs(hi))) + 1e-300
    if out.feasible:
        assert out.shortfall <= tol
        if condition == "equality":
            assert out.shortfall >= -tol
    else:
        assert A > hi or (condition == "equality" and A < lo)
        assert (out.shortfall > 0) == (A > hi)


# ---------------------------------------------------------------------- the bounded program
@st.composite
def programs(draw):
    """Random integrals (some exactly zero), per-robot or scalar gains, limits or none."""
    n = draw(st.integers(1, 6))
    scale = 10 ** draw(st.floats(-3.0, 0.0))
    # entries within a factor 20 of the scale (or exactly zero, below): well-conditioned for
    # the interior-point solver, whose tolerances are absolute (see the xfail test below)
    vals = st.floats(0.05, 1.0).flatmap(lambda v: st.sampled_from([v, -v]))
    b = scale * np.array([[draw(vals), draw(vals)] for _ in range(n)])
    g = scale * np.array([draw(vals) for _ in range(n)])
    zero_b = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    zero_g = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    b[zero_b & (np.arange(n) % 2 == 0)] = 0.0
    g[zero_g & (np.arange(n) % 3 == 0)] = 0.0
    A = draw(st.floats(-1.0, 1.0)) * scale**2 * n * 3
    limit = st.one_of(st.none(), st.floats(1e-3, 2.0))
    return b, g, A, draw(gains(n)), draw(gains(n)), draw(limit), draw(limit)


@given(
    problem=programs(),
    condition=st.sampled_from(["inequality", "equality"]),
    method=st.sampled_from(["exact", "clarabel"]),
)
def test_bounded_program_constraints_and_shortfall(problem, condition, method):
    """Per-robot gains, zero integrals, both solvers: the totals never exceed the limits (not
    even by round-off), the shortfall is ``A`` minus what the inputs achieve with the
    documented sign, the achieved value is within the reachable range, and the algebraic
    form of the dV₂/dt identity holds: ``A - Σ b·u + Σ g ω = -Σ k_u|b|² - Σ k_ω g² + shortfall``."""
    b, g, A, k_u, k_omega, u_max, omega_max = problem
    n = len(g)
    out = BoundedBetaGamma(n, k_u, k_omega, u_max, omega_max, condition, method)(b, g, A)
    ku, kw = _per_robot(k_u, n), _per_robot(k_omega, n)
    u = ku[:, None] * b + out.du
    w = -kw * g + out.domega
    if u_max is not None:
        assert np.all(np.hypot(u[:, 0], u[:, 1]) <= u_max)
    if omega_max is not None:
        assert np.all(np.abs(w) <= omega_max)
    done = float((b * out.du).sum() - (g * out.domega).sum())
    mag = float(np.abs(b * out.du).sum() + np.abs(g * out.domega).sum()) + abs(A)
    assert abs(out.shortfall - (A - done)) <= 1e-12 * mag + 1e-300
    lo, hi = achievable_range(b, g, ku, kw, math.inf if u_max is None else u_max,
                              math.inf if omega_max is None else omega_max)  # fmt: skip
    assert (lo, hi) == out.achievable
    assert lo - 1e-9 * (abs(lo) + 1e-12) <= done <= hi + 1e-9 * (abs(hi) + 1e-12)
    lhs = A - (b * u).sum() + (g * w).sum()
    rhs = -(ku * (b**2).sum(1)).sum() - (kw * g**2).sum() + out.shortfall
    assert abs(lhs - rhs) <= 1e-12 * (mag + np.abs(b * u).sum() + np.abs(g * w).sum()) + 1e-300
    _check_shortfall_convention(out, A, condition)
    if method == "clarabel":  # no more effort than the exact optimum of the same program
        ex = bounded_inputs_exact(b, g, A, k_u, k_omega, u_max, omega_max, condition)
        effort = lambda o: float((o.du**2).sum() + (o.domega**2).sum())  # noqa: E731
        assert effort(ex) <= effort(out) * (1 + 1e-6) + 1e-14
        assert out.feasible == ex.feasible


@pytest.mark.xfail(
    strict=True,
    reason="finding: the cvxpy path meets A only to the interior-point solver's absolute "
    "tolerance; with limits of ~1e-7 and integrals of ~1e-10 it reports feasible=True with a "
    "shortfall up to ~1e3 A (the exact dual: ~1e-15 relative). Realistic limits (0.1 m/s, "
    "1 rad/s) are accurate at every integral scale down to 1e-10 (measured)",
)
def test_the_cvxpy_path_meets_A_relative_to_its_size_with_tiny_limits():
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(20):
        n = int(rng.integers(1, 7))
        b, g = 1e-10 * rng.normal(size=(n, 2)), 1e-10 * rng.normal(size=n)
        A = abs(rng.normal()) * 1e-20 * n
        out = BoundedBetaGamma(n, 10.0, 10.0, 1e-7, 1e-7, method="cvxpy")(b, g, A)
        exact = bounded_inputs_exact(b, g, A, 10.0, 10.0, 1e-7, 1e-7)
        assert out.feasible and exact.feasible and exact.shortfall <= 1e-12 * A
        worst = max(worst, out.shortfall / A)
    assert worst <= 1e-6, worst


# ---------------------------------------------------------------------- Fokker–Planck solver
fp_sigmas = st.one_of(st.just(0.0), st.floats(1e-12, 1e-6), st.floats(1e-4, 0.05))  # tiny σ: high Péclet


@st.composite
def fp_cases(draw, names=("box", "box-offset", "disk", "polygon")):
    """Grid, density, σ, robots' face drift (strength up to 2) and an optional interaction."""
    name = draw(st.sampled_from(names))
    grid = grid_named(name)
    R, th = draw(robots(grid))
    kernel = GaussianKernel(draw(st.floats(0.05, 2.0)), draw(st.floats(0.005, 0.2)))
    fv = NavigationField(kernel, grid, R, th).velocity()
    return grid, draw(densities(grid, floor_min=0.0)), draw(fp_sigmas), fv, draw(potentials)


def _check_mass_and_sign(grid: Grid, rho0: np.ndarray, rho: np.ndarray, what: str) -> None:
    m0, m1 = grid.integrate(rho0), grid.integrate(rho)
    assert abs(m1 - m0) <= 1e-12 * m0, (what, m1 - m0)
    assert np.all(np.isfinite(rho))
    assert rho.min() >= -1e-14 * rho.max(), (what, rho.min())


@given(
    case=fp_cases(),
    method=st.sampled_from(["split", "implicit"]),
    log_dts=st.lists(st.floats(-4.0, 3.0), min_size=1, max_size=4),
)
def test_fokker_planck_mass_and_positivity_at_any_dt(case, method, log_dts):
    """Split and implicit steps (M-matrices): mass to round-off and ρ >= 0 for any dt, up to 1e3."""
    grid, rho0, sigma, fv, pot = case
    fp = FokkerPlanck(grid, sigma, interaction=pot, method=method)
    rho, t = rho0, 0.0
    for e in log_dts:
        dt = 10.0**e
        rho = fp.step(rho, t, dt, face_velocity=fv)
        t += dt
        _check_mass_and_sign(grid, rho0, rho, f"{method} dt={dt:.3g}")
    event(f"largest dt >= 1: {max(log_dts) >= 0}")
    event(f"grid {grid.domain.kind}")


@given(case=fp_cases(), method=st.sampled_from(["explicit", "adi"]), steps=st.integers(1, 6))
def test_fokker_planck_mass_and_positivity_automatic_step(case, method, steps):
    """Explicit (Heun) and ADI at their automatic step: mass to round-off and ρ >= 0."""
    grid, rho0, sigma, fv, pot = case
    fp = FokkerPlanck(grid, sigma, interaction=pot, method=method)
    dt = fp.automatic_dt(rho0, 0.0, fv)
    if not math.isfinite(dt):
        return  # nothing moves
    rho = fp.solve(rho0, steps * dt, face_velocity=fv)
    _check_mass_and_sign(grid, rho0, rho, method)


@given(case=fp_cases(), sigma=st.one_of(st.just(0.0), st.floats(-9.0, 1.0).map(lambda e: 10.0**e)))
def test_scharfetter_gummel_is_central_flux_plus_bounded_upwind_diffusion(case, sigma):
    """The solver's flux and the controller's model (central fluxes, the ``density_rate`` that
    Theorems 1-3 are proved on) discretise the same equation: on every open face
    ``J_SG - J_central = κ (ρ_L - ρ_R)/h`` with ``0 <= κ <= min(|a|h/2, a²h²/(12σ))``
    (``J_SG = (σ/h)·(P/2)coth(P/2)·(ρ_L - ρ_R) + a ρ̄``, ``P = a h/σ``): non-negative
    numerical diffusion, at most the upwind amount, O(P²) at low Péclet."""
    grid, rho, _, fv, pot = case
    fp = FokkerPlanck(grid, sigma, interaction=pot)
    J = fp.flux(rho, 0.0, fv)
    a = fp.drift(rho, 0.0, fv)
    peclet = max(np.abs(a[0]).max() * grid.dx, np.abs(a[1]).max() * grid.dy) / sigma if sigma > 0 else math.inf
    event(f"max grid Péclet {'< 0.1' if peclet < 0.1 else '< 10' if peclet < 10 else '>= 10'}")
    rf = grid.face_average(rho)
    for k, (h, m) in enumerate(zip((grid.dx, grid.dy), _open_faces(grid), strict=True)):
        left = rho[:-1, :] if k == 0 else rho[:, :-1]
        right = rho[1:, :] if k == 0 else rho[:, 1:]
        jump = (left - right)[m]
        central = a[k][m] * rf[k][m] - sigma * (-jump) / h
        D = J[k][m] - central
        tol = 1e-11 * (np.abs(a[k][m]) + sigma / h) * (left + right)[m] + 1e-300
        assert np.all(D * jump >= -tol * np.abs(jump))
        assert np.all(np.abs(D) <= 0.5 * np.abs(a[k][m]) * np.abs(jump) + tol)
        if sigma > 0:
            assert np.all(np.abs(D) <= a[k][m] ** 2 * h / (12 * sigma) * np.abs(jump) + tol)
