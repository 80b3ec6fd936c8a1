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

The numpy path of the controller is the reference; the two agree to round-off (tests).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.compiled import UNAVAILABLE, compiled, inner
from meanfield.interfaces import ControlState
from meanfield.robots import NavigationField

__all__ = ["paper_law", "fused_robot_inputs"]


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
    """1-D kernel factors ``c exp(-d²/η)`` (``c`` = 1 for the y factors) and their ``-2d/η`` multiples."""
    s = -2.0 / eta
    for i in range(r.shape[0]):
        for a in range(coords.shape[0]):
            d = coords[a] - r[i]
            f = c * math.exp(-(d * d) / eta)
            out_f[i, a] = f
            out_g[i, a] = s * d * f


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


def fused_robot_inputs(law: Any, rho: np.ndarray, field: NavigationField, t: float) -> ControlState | None:
    """The :class:`~meanfield.control.BacksteppingController`'s inputs by :func:`paper_law`; None when not compiled.

    The controller calls this only in the common case its ``_fusable`` checks.  The previous
    ``v_d`` is read from and stored in ``law._previous_vd``, as the numpy path does.
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
    nx, ny = g.cells
    vd = (np.empty((nx - 1, ny)), np.empty((nx, ny - 1)))
    vt = (np.empty((nx - 1, ny)), np.empty((nx, ny - 1)))
    rho_t, b, gg, u, w = np.empty((nx, ny)), np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)
    rx, ry = np.ascontiguousarray(field.positions.T)
    floor = getattr(law.alpha, "rho_floor", 0.0)  # the constant schedule: α/ρ = α₀/(ρ + 0)
    out = paper_law(
        rho, law.target, tg[0], tg[1], 1.0 / g.dx, 1.0 / g.dy, g.weight_x, g.weight_y, float(law.sigma),
        law.alpha.alpha0, floor, g.x_faces, g.x, g.y_faces, g.y,
        rx, ry, field.cos, field.sin, k.c, k.eta, cache["k_u"], cache["k_w"],
        px, py, have_prev, (t - prev[0]) if have_prev else 1.0,
        rho_t, vd[0], vd[1], vt[0], vt[1], b, gg, u, w,
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
