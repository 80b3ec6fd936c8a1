"""The paper's robot law in one compiled call, for its common case: one pass over the faces.

:class:`~meanfield.control.BacksteppingController` evaluates Steps I and II (eqs. (6) and
(8); docs page *The controller*) with a few dozen numpy operations on face fields.  On a
box grid, with a constant σ, no interaction (``W = 0``), the constant or saturating α
schedule, the minimum-norm β/γ, ``∂_t v_d`` by a backward difference, the paper's units and
the separable Gaussian kernel seen everywhere (the ``paper`` scenario and its relatives),
:func:`paper_law` does the same arithmetic in one compiled call with no temporaries:

* Step I, per face: ``ρ_f`` (face average), ``∇ρ̃``, ``∇(σρ) = σ(∇ρ̃ + ∇ρ_*)``,
  ``α/ρ_f``, ``v_d = -(α/ρ_f) ∇ρ̃ + ∇(σρ)/ρ_f`` and ``∂_t v_d = (v_d - v_d^prev)/h``;
* the signs on the faces from the kernel's 1-D factors ``c exp(-d²/η)`` (eq. (3)),
  ``ṽ = v_r - v_d``;
* Step II: ``b_i``, ``g_i`` by the factors' matrix products (as
  :meth:`~meanfield.robots.NavigationField.moments`), ``A = ⟨ṽ, ρ_f ∇ρ̃ - ∂_t v_d⟩``,
  ``Z = Σ|b_i|² + Σ g_i²``, ``u_i = k_u b_i + (A/Z) b_i``, ``ω_i = -k_ω g_i - (A/Z) g_i``,
  and the dissipation ``∫ α|∇ρ̃|²``.

Any grid, line of sight, the exits' Step I: :func:`face_law` is the same law face by face on a
cut-cell grid (a floor plan: closed faces carry nothing, ``ρ_f = 1`` there as in the
controller's ``_prepare``), with each robot's sign hidden on the faces it does not see (the
sight masks of :class:`~meanfield.robots.NavigationField`, decided between cells, docs page
*Buildings*), and with either the paper's Step I or Hughes' ``v_d = -f(ρ_f) ∇φ`` towards the
exits (:class:`~meanfield.evacuation.EvacuationController`, whose dissipation is
``-S = ⟨∇ρ̃, ∇(σρ) - v_d ρ_f⟩``).  One call, three passes over each family of faces (the
signs ``v_r``; Step I, ``ṽ`` and ``A``; the integrals), computes ``v_d``, ``∂_t v_d``, ``v_r``,
``ṽ``, ``A``, the dissipation and the six face integrals behind ``b_i``, ``g_i`` (as
:func:`meanfield.plan_loops.face_moments`) from the kernel's 1-D factors and the cells each
robot sees, without building the ``(n, faces)`` masked kernels.  The controller's
``_fused_law`` says which call applies (docs page *Large crowds*, "Compiled loops").

The numpy path of the controller is the reference; the two agree to round-off (tests).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.compiled import UNAVAILABLE, compiled, inner
from meanfield.interfaces import ControlState
from meanfield.robots import NavigationField
from meanfield.vector_exp import exp_inplace

__all__ = ["paper_law", "face_law", "fused_robot_inputs", "PAPER_STEP_ONE", "HUGHES_STEP_ONE"]

PAPER_STEP_ONE = 0
"""``face_law``'s ``step``: the paper's Step I, eq. (6)."""
HUGHES_STEP_ONE = 1
"""``face_law``'s ``step``: Hughes' field towards the exits, ``v_d = -f(ρ) ∇φ``."""


@inner
def _faces(rho, rho_t, tg, inv_h, sigma, alpha0, floor, prev, have_prev, h, vd, rf, grt, dvd, q_out, axis):
    """Step I on the faces normal to ``axis`` (0: x-faces, 1: y-faces), into the given arrays."""
    n0, n1 = vd.shape
    for a in range(n0):
        for b in range(n1):
            if axis == 0:
                lo, hi = rho[a, b], rho[a + 1, b]
                dlo, dhi = rho_t[a, b], rho_t[a + 1, b]
            else:
                lo, hi = rho[a, b], rho[a, b + 1]
                dlo, dhi = rho_t[a, b], rho_t[a, b + 1]
            f = 0.5 * (hi + lo)
            gr = (dhi - dlo) * inv_h
            gs = sigma * (gr + tg[a, b])
            q = alpha0 / (f + floor)
            v = -q * gr + gs / f
            rf[a, b] = f
            grt[a, b] = gr
            q_out[a, b] = q
            vd[a, b] = v
            dvd[a, b] = (v - prev[a, b]) / h if have_prev else 0.0


@inner
def _factors(coords, r, c, eta, out_f, out_g):
    """1-D kernel factors ``c exp(-d²/η)`` (``c`` = 1 for the y factors) and their ``-2d/η`` multiples
    (the exponentials vectorised, :func:`meanfield.vector_exp.exp_inplace`)."""
    s = -2.0 / eta
    m = coords.shape[0]
    vals, bits = np.empty(m), np.empty(m, np.int64)
    for i in range(r.shape[0]):
        for a in range(m):
            d = coords[a] - r[i]
            vals[a] = -(d * d) / eta
        exp_inplace(vals, bits, m)
        for a in range(m):
            f = c * vals[a]
            out_f[i, a] = f
            out_g[i, a] = s * (coords[a] - r[i]) * f


@compiled(fallback=None)
def paper_law(
    rho, target, tgx, tgy, inv_dx, inv_dy, wx, wy, sigma, alpha0, floor,
    xf, xc, yf, yc, rx, ry, cos, sin, c, eta, k_u, k_w,
    prev_x, prev_y, have_prev, h,
    rho_t, vdx, vdy, vtx, vty, b, g, u, omega,
):  # fmt: skip
    """Steps I and II of the paper's law (eqs. (6), (8)) in one pass; returns ``(A, shortfall, dissipation)``.

    Parameters
    ----------
    rho, target : ndarray, shape (nx, ny)
        The density (positive) and ``ρ_*``.
    tgx, tgy : ndarray
        ``∇ρ_*`` on the x-faces (nx-1, ny) and the y-faces (nx, ny-1).
    inv_dx, inv_dy : float
        Inverse cell sizes.
    wx, wy : ndarray
        The face weights of the grid's face inner product.
    sigma, alpha0, floor : float
        Constant σ; α/ρ_f = α₀ / (ρ_f + floor) (floor 0: the constant schedule).
    xf, xc, yf, yc : ndarray
        Face and centre coordinates along x and y.
    rx, ry, cos, sin : ndarray, shape (n,)
        The robots' positions and headings' cosines and sines.
    c, eta : float
        The Gaussian kernel's strength and range.
    k_u, k_w : ndarray, shape (n,)
        The gains.
    prev_x, prev_y : ndarray
        The previous call's ``v_d`` (used when ``have_prev``), ``h`` the time since.
    rho_t, vdx, vdy, vtx, vty, b, g, u, omega : ndarray
        Outputs: ``ρ̃``, ``v_d``, ``ṽ``, ``b`` (n, 2), ``g`` (n,), ``u`` (n, 2), ``ω`` (n,).
    """
    nx, ny = rho.shape
    n = rx.shape[0]
    for a in range(nx):
        for bb in range(ny):
            rho_t[a, bb] = rho[a, bb] - target[a, bb]
    rfx, grx, dvx, qx = np.empty((nx - 1, ny)), np.empty((nx - 1, ny)), np.empty((nx - 1, ny)), np.empty((nx - 1, ny))
    rfy, gry, dvy, qy = np.empty((nx, ny - 1)), np.empty((nx, ny - 1)), np.empty((nx, ny - 1)), np.empty((nx, ny - 1))
    for axis in range(2):  # (a loop variable: one compiled _faces, where literal 0 and 1 would make two)
        if axis == 0:
            _faces(rho, rho_t, tgx, inv_dx, sigma, alpha0, floor, prev_x, have_prev, h, vdx, rfx, grx, dvx, qx, axis)
        else:
            _faces(rho, rho_t, tgy, inv_dy, sigma, alpha0, floor, prev_y, have_prev, h, vdy, rfy, gry, dvy, qy, axis)
    fxf, gxf = np.empty((n, nx - 1)), np.empty((n, nx - 1))
    fxc, gxc = np.empty((n, nx)), np.empty((n, nx))
    fyf, gyf = np.empty((n, ny - 1)), np.empty((n, ny - 1))
    fyc, gyc = np.empty((n, ny)), np.empty((n, ny))
    _factors(xf, rx, c, eta, fxf, gxf)
    _factors(xc, rx, c, eta, fxc, gxc)
    _factors(yf, ry, 1.0, eta, fyf, gyf)
    _factors(yc, ry, 1.0, eta, fyc, gyc)
    # v_r on the faces (x-faces: factors x at faces, y at centres; y-faces: the converse), ṽ
    ax = np.empty((n, nx - 1))
    ay = np.empty((n, nx))
    for i in range(n):
        for a in range(nx - 1):
            ax[i, a] = cos[i] * fxf[i, a]
        for a in range(nx):
            ay[i, a] = sin[i] * fxc[i, a]
    vrx = ax.T.copy() @ fyc
    vry = ay.T.copy() @ fyf
    A = 0.0
    diss = 0.0
    Wx = np.empty((nx - 1, ny))
    for a in range(nx - 1):
        for bb in range(ny):
            vt = vrx[a, bb] - vdx[a, bb]
            vtx[a, bb] = vt
            Wx[a, bb] = wx[a, bb] * vt
            A += wx[a, bb] * vt * (rfx[a, bb] * grx[a, bb] - dvx[a, bb])
            diss += wx[a, bb] * (qx[a, bb] * rfx[a, bb] * grx[a, bb]) * grx[a, bb]
    Wy = np.empty((nx, ny - 1))
    for a in range(nx):
        for bb in range(ny - 1):
            vt = vry[a, bb] - vdy[a, bb]
            vty[a, bb] = vt
            Wy[a, bb] = wy[a, bb] * vt
            A += wy[a, bb] * vt * (rfy[a, bb] * gry[a, bb] - dvy[a, bb])
            diss += wy[a, bb] * (qy[a, bb] * rfy[a, bb] * gry[a, bb]) * gry[a, bb]
    # the moments b_i, g_i (NavigationField.moments, separable)
    Px = fxf @ Wx
    Gx = gxf @ Wx
    Py = fxc @ Wy
    Gy = gxc @ Wy
    Z = 0.0
    for i in range(n):
        s0x = s1x = s2x = 0.0
        for bb in range(ny):
            s0x += Px[i, bb] * fyc[i, bb]
            s1x += Gx[i, bb] * fyc[i, bb]
            s2x += Px[i, bb] * gyc[i, bb]
        s0y = s1y = s2y = 0.0
        for bb in range(ny - 1):
            s0y += Py[i, bb] * fyf[i, bb]
            s1y += Gy[i, bb] * fyf[i, bb]
            s2y += Py[i, bb] * gyf[i, bb]
        b[i, 0] = cos[i] * s1x + sin[i] * s1y
        b[i, 1] = cos[i] * s2x + sin[i] * s2y
        g[i] = -sin[i] * s0x + cos[i] * s0y
        Z += b[i, 0] * b[i, 0] + b[i, 1] * b[i, 1] + g[i] * g[i]
    s = A / Z if Z != 0.0 else 0.0
    for i in range(n):
        u[i, 0] = k_u[i] * b[i, 0] + s * b[i, 0]
        u[i, 1] = k_u[i] * b[i, 1] + s * b[i, 1]
        omega[i] = -k_w[i] * g[i] + (-s * g[i])
    shortfall = A if Z == 0.0 else 0.0
    return A, shortfall, diss


@inner
def _signs(fa, fb, e, seen, hidden, vr, axis):
    """``v_r = Σ_i s_i K̄_i e(θ_i)`` (eq. (3), ``s_i``: the faces robot ``i`` sees) on one family of faces."""
    da, db = 1 - axis, axis
    n0, n1 = vr.shape
    for a in range(n0):
        for b in range(n1):
            vr[a, b] = 0.0
    for i in range(e.shape[0]):
        for a in range(n0):
            ea = e[i] * fa[i, a]
            if hidden:
                for b in range(n1):
                    if seen[i, a, b] and seen[i, a + da, b + db]:
                        vr[a, b] += ea * fb[i, b]
            else:
                for b in range(n1):
                    vr[a, b] += ea * fb[i, b]


@inner
def _step_one(rho, rho_t, ap, w, tg, ph, prev, have_prev, h, inv_h, step, sigma, alpha0, floor, v_free, rho_max,
              vd, vt, axis):  # fmt: skip
    """Step I on one family of faces into ``vd``, ``ṽ = v_r - v_d`` over ``v_r`` in ``vt``; returns (A, D) shares.

    ``step`` 0: the paper's ``v_d`` (eq. (6)) and ``D = ∫ α|∇ρ̃|²``; 1: Hughes' ``v_d = -f(ρ) ∇φ`` and
    ``D = -S = ⟨∇ρ̃, ∇(σρ) - v_d ρ⟩``.  A closed face (aperture 0) has ``ρ_f = 1`` and ``∇ρ̃ = 0``.
    """
    da, db = 1 - axis, axis
    A = 0.0
    diss = 0.0
    for a in range(vd.shape[0]):
        for b in range(vd.shape[1]):
            opened = ap[a, b] > 0.0
            f = 0.5 * (rho[a + da, b + db] + rho[a, b]) if opened else 1.0
            gr = (rho_t[a + da, b + db] - rho_t[a, b]) * inv_h if opened else 0.0
            gs = sigma * (gr + tg[a, b])
            if step == 0:
                q = alpha0 / (f + floor)
                v = -q * gr + gs / f
                diss += w[a, b] * (q * f * gr) * gr
            else:
                speed = v_free * (1.0 - f / rho_max) if f < rho_max else 0.0
                v = -speed * ph[a, b]
                diss += w[a, b] * gr * (gs - v * f)
            dv = (v - prev[a, b]) / h if have_prev else 0.0
            t = vt[a, b] - v
            vd[a, b] = v
            vt[a, b] = t
            A += w[a, b] * t * (f * gr - dv)
    return A, diss


@inner
def _integrals(fa, ga, fb, gb, w, vt, seen, hidden, mom, axis):
    """``Σ K W``, ``Σ ∂ₓK W``, ``Σ ∂ᵧK W`` per robot (``W`` = weight × ``ṽ``, ``K`` masked) into ``mom[3 axis:]``."""
    da, db = 1 - axis, axis
    n0, n1 = vt.shape
    for i in range(fa.shape[0]):
        s0 = s1 = s2 = 0.0
        for a in range(n0):
            t0 = t1 = 0.0
            if hidden:
                for b in range(n1):
                    if seen[i, a, b] and seen[i, a + da, b + db]:
                        W = w[a, b] * vt[a, b]
                        t0 += fb[i, b] * W
                        t1 += gb[i, b] * W
            else:
                for b in range(n1):
                    W = w[a, b] * vt[a, b]
                    t0 += fb[i, b] * W
                    t1 += gb[i, b] * W
            s0 += fa[i, a] * t0
            s1 += ga[i, a] * t0
            s2 += fa[i, a] * t1
        mom[3 * axis, i], mom[3 * axis + 1, i], mom[3 * axis + 2, i] = s0, s1, s2


@compiled(fallback=None)
def face_law(
    rho, target, tgx, tgy, inv_dx, inv_dy, apx, apy, wx, wy, step, sigma, alpha0, floor, v_free, rho_max, phx, phy,
    xf, xc, yf, yc, rx, ry, cos, sin, c, eta, seen, hidden, k_u, k_w,
    prev_x, prev_y, have_prev, h,
    rho_t, vdx, vdy, vtx, vty, b, g, u, omega,
):  # fmt: skip
    """Steps I and II (eqs. (6) or Hughes', and (8)) on any grid, signs masked by walls; returns ``(A, shortfall, D)``.

    The arguments of :func:`paper_law`, and:

    Parameters
    ----------
    apx, apy : ndarray
        The faces' apertures (a closed face, aperture 0, carries nothing).
    step : int
        :data:`PAPER_STEP_ONE` (``sigma``, ``alpha0``, ``floor``, ``∇ρ_*`` = ``tgx, tgy``) or
        :data:`HUGHES_STEP_ONE` (``f(ρ) = v_free (1 - ρ/ρ_max)``, 0 beyond ``rho_max``, ``∇φ`` = ``phx, phy``).
    seen : ndarray of bool, shape (n, nx, ny)
        The cells each robot sees; a face is seen when both its cells are (used when ``hidden``).
    hidden : bool
        Whether a wall may hide a sign (else every face is seen).
    """
    nx, ny = rho.shape
    n = rx.shape[0]
    for a in range(nx):
        for bb in range(ny):
            rho_t[a, bb] = rho[a, bb] - target[a, bb]
    # (as in paper_law; a shared helper returning the eight arrays cost 0.3-0.5 s more compilation)
    fxf, gxf = np.empty((n, nx - 1)), np.empty((n, nx - 1))
    fxc, gxc = np.empty((n, nx)), np.empty((n, nx))
    fyf, gyf = np.empty((n, ny - 1)), np.empty((n, ny - 1))
    fyc, gyc = np.empty((n, ny)), np.empty((n, ny))
    _factors(xf, rx, c, eta, fxf, gxf)
    _factors(xc, rx, c, eta, fxc, gxc)
    _factors(yf, ry, 1.0, eta, fyf, gyf)
    _factors(yc, ry, 1.0, eta, fyc, gyc)
    mom = np.empty((6, n))
    A = 0.0
    diss = 0.0
    for axis in range(2):  # (a loop variable: one compilation of each helper, where literal 0 and 1 would make two)
        if axis == 0:
            _signs(fxf, fyc, cos, seen, hidden, vtx, axis)
            s = _step_one(rho, rho_t, apx, wx, tgx, phx, prev_x, have_prev, h, inv_dx, step, sigma, alpha0, floor,
                          v_free, rho_max, vdx, vtx, axis)  # fmt: skip
            _integrals(fxf, gxf, fyc, gyc, wx, vtx, seen, hidden, mom, axis)
        else:
            _signs(fxc, fyf, sin, seen, hidden, vty, axis)
            s = _step_one(rho, rho_t, apy, wy, tgy, phy, prev_y, have_prev, h, inv_dy, step, sigma, alpha0, floor,
                          v_free, rho_max, vdy, vty, axis)  # fmt: skip
            _integrals(fxc, gxc, fyf, gyf, wy, vty, seen, hidden, mom, axis)
        A += s[0]
        diss += s[1]
    Z = 0.0
    for i in range(n):  # b_i, g_i as NavigationField.moments; then the minimum-norm inputs
        b[i, 0] = cos[i] * mom[1, i] + sin[i] * mom[4, i]
        b[i, 1] = cos[i] * mom[2, i] + sin[i] * mom[5, i]
        g[i] = -sin[i] * mom[0, i] + cos[i] * mom[3, i]
        Z += b[i, 0] * b[i, 0] + b[i, 1] * b[i, 1] + g[i] * g[i]
    s = A / Z if Z != 0.0 else 0.0
    for i in range(n):
        u[i, 0] = k_u[i] * b[i, 0] + s * b[i, 0]
        u[i, 1] = k_u[i] * b[i, 1] + s * b[i, 1]
        omega[i] = -k_w[i] * g[i] + (-s * g[i])
    shortfall = A if Z == 0.0 else 0.0
    return A, shortfall, diss


_NOTHING_HIDDEN = np.ones((0, 0, 0), dtype=bool)


def fused_robot_inputs(
    law: Any, rho: np.ndarray, field: NavigationField, t: float, step_one: tuple | None = None
) -> ControlState | None:
    """The :class:`~meanfield.control.BacksteppingController`'s inputs in one compiled call; None when not compiled.

    The controller calls this only in the cases its ``_fused_law`` checks: ``step_one`` None is
    the paper's law on a box with the signs seen everywhere (:func:`paper_law`); otherwise it is
    ``(step, v_free, rho_max, ∇φ)`` for :func:`face_law` (``step`` :data:`PAPER_STEP_ONE` or
    :data:`HUGHES_STEP_ONE`; ``∇φ`` None for the paper's).  The previous ``v_d`` is read from
    and stored in ``law._previous_vd``, as the numpy path does.
    """
    g, k = law.grid, field.kernel
    n = len(field.positions)
    cache = law._fused_state
    source = cache.get("source", (None, None, None))  # the gains per robot, once per team size and gain arrays
    if source[0] != n or source[1] is not law.k_u or source[2] is not law.k_omega:
        cache.update(source=(n, law.k_u, law.k_omega), k_u=np.broadcast_to(law.k_u, (n,)).astype(float))
        cache["k_w"] = np.broadcast_to(law.k_omega, (n,)).astype(float)
    prev = law._previous_vd
    have_prev = prev is not None and t > prev[0]
    tg = law._target_gradient
    px, py = prev[1] if have_prev else tg  # (unused without a previous v_d)
    h = (t - prev[0]) if have_prev else 1.0
    nx, ny = g.cells
    vd = (np.empty((nx - 1, ny)), np.empty((nx, ny - 1)))
    vt = (np.empty((nx - 1, ny)), np.empty((nx, ny - 1)))
    rho_t, b, gg, u, w = np.empty((nx, ny)), np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)
    rx, ry = np.ascontiguousarray(field.positions.T)
    alpha = getattr(law.alpha, "alpha0", 1.0)
    floor = getattr(law.alpha, "rho_floor", 0.0)  # the constant schedule: α/ρ = α₀/(ρ + 0)
    outputs = (rho_t, vd[0], vd[1], vt[0], vt[1], b, gg, u, w)
    if step_one is None:
        out = paper_law(
            rho, law.target, tg[0], tg[1], 1.0 / g.dx, 1.0 / g.dy, g.weight_x, g.weight_y, float(law.sigma),
            alpha, floor, g.x_faces, g.x, g.y_faces, g.y,
            rx, ry, field.cos, field.sin, k.c, k.eta, cache["k_u"], cache["k_w"], px, py, have_prev, h, *outputs,
        )  # fmt: skip
    else:
        step, v_free, rho_max, phi = step_one
        ph = tg if phi is None else phi  # (unused by the paper's Step I)
        seen = field.cell_sight()
        out = face_law(
            rho, law.target, tg[0], tg[1], 1.0 / g.dx, 1.0 / g.dy, g.aperture_x, g.aperture_y, g.weight_x,
            g.weight_y, step, float(law.sigma), alpha, floor, v_free, rho_max, ph[0], ph[1],
            g.x_faces, g.x, g.y_faces, g.y, rx, ry, field.cos, field.sin, k.c, k.eta,
            _NOTHING_HIDDEN if seen is None else seen, seen is not None, cache["k_u"], cache["k_w"],
            px, py, have_prev, h, *outputs,
        )  # fmt: skip
    if out is UNAVAILABLE:
        return None
    law._previous_vd = (t, vd)
    A, shortfall, dissipation = out
    return ControlState(
        v_d=vd,
        v_tilde=vt,
        rho_tilde=rho_t,
        b=b,
        g=gg,
        A=A,
        u=u,
        omega=w,
        shortfall=shortfall,
        dissipation=dissipation,
        k_u=law.k_u,
        k_omega=law.k_omega,
    )
