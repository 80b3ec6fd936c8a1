"""The paper's robot law in one compiled call, for its common case: one pass over the faces.

:class:`~meanfield.controllers.backstepping.BacksteppingController` evaluates Steps I and II (eqs. (6) and
(8); docs page *The controller*) with a few dozen numpy operations on face fields.  On a
box grid, with a constant σ, no interaction (``W = 0``), the constant or saturating α
schedule, the minimum-norm β/γ, ``∂_t v_d`` by a backward difference, the paper's units and
the separable Gaussian kernel seen everywhere (the ``paper`` scenario and its relatives),
:func:`paper_law` does the same arithmetic in one compiled call:

* the kernel's 1-D factors ``c exp(-d²/η)`` (eq. (3)) at the centres and faces along x and y,
  walked along each lattice by the recurrence (L1) of :func:`paper_law` (two exponentials per
  robot and segment, as the KDE's (K1) in :func:`meanfield.crowds._kde_loops.separable_sum`);
* Step I, per face: ``ρ_f`` (face average), ``∇ρ̃``, ``∇(σρ) = σ(∇ρ̃ + ∇ρ_*)``,
  ``α/ρ_f``, ``v_d = -(α/ρ_f) ∇ρ̃ + ∇(σρ)/ρ_f`` and ``∂_t v_d = (v_d - v_d^prev)/h``, and
  ``ṽ = v_r - v_d`` over the signs ``v_r`` (the factors' product), in flat loops that vectorise;
* Step II: ``b_i``, ``g_i`` by the factors' matrix products (as
  :meth:`~meanfield.signs.robots.NavigationField.moments`), ``A = ⟨ṽ, ρ_f ∇ρ̃ - ∂_t v_d⟩``,
  ``Z = Σ|b_i|² + Σ g_i²``, ``u_i = k_u b_i + (A/Z) b_i``, ``ω_i = -k_ω g_i - (A/Z) g_i``,
  and the dissipation ``∫ α|∇ρ̃|²``; the four products are BLAS calls (:func:`meanfield._compiled.blas.gemm`).

Any grid, line of sight, the exits' Step I: :func:`face_law` is the same law face by face on a
cut-cell grid (a floor plan: closed faces carry nothing, ``ρ_f = 1`` there as in the
controller's ``_prepare``), with each robot's sign hidden on the faces it does not see (the
sight masks of :class:`~meanfield.signs.robots.NavigationField`, decided between cells, docs page
*Buildings*), and with either the paper's Step I or Hughes' ``v_d = -f(ρ_f) ∇φ`` towards the
exits (:class:`~meanfield.controllers.evacuation.EvacuationController`, whose dissipation is
``-S = ⟨∇ρ̃, ∇(σρ) - v_d ρ_f⟩``).  One call, three passes over each family of faces (the
signs ``v_r``; Step I, ``ṽ`` and ``A``; the integrals), computes ``v_d``, ``∂_t v_d``, ``v_r``,
``ṽ``, ``A``, the dissipation and the six face integrals behind ``b_i``, ``g_i`` (as
:func:`meanfield.signs._masked_loops.face_moments`) from the kernel's 1-D factors and the cells each
robot sees, without building the ``(n, faces)`` masked kernels.
:meth:`~meanfield.controllers.fused_law.FusedLaw.which` says which call applies (docs page *Large crowds*,
"Compiled loops").

The numpy path of the controller is the reference; the two agree to round-off (tests).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.blas import gemm
from meanfield._compiled.core import compiled, empty_array, inner
from meanfield._compiled.vector_exp import exp_inplace

__all__ = ["paper_law", "face_law", "PAPER_STEP_ONE", "HUGHES_STEP_ONE"]

PAPER_STEP_ONE = 0
"""``face_law``'s ``step``: the paper's Step I, eq. (6)."""
HUGHES_STEP_ONE = 1
"""``face_law``'s ``step``: Hughes' field towards the exits, ``v_d = -f(ρ) ∇φ``."""
_SEGMENT_BANDWIDTHS = 16.0
"""(L1) restarts from exact exponentials every ``16 h`` (``η = 2h²``; 1 to 64 points), as the KDE's (K1)."""
_LANES = 64
"""Step I sums ``A`` and the dissipation in this many partial sums per family of faces (so the loop vectorises)."""
_U = np.uint64
"""paper_law indexes its flat buffers by unsigned integers: numba then adds no negative-index wrap-around, and the
loops over the robots and over the faces vectorise."""


@inner
def _factors(coords, r, c, eta, out_f, out_g):
    """1-D kernel factors ``c exp(-d²/η)`` (``c`` = 1 for the y factors) and their ``-2d/η`` multiples
    (the exponentials vectorised, :func:`meanfield._compiled.vector_exp.exp_inplace`)."""
    s = -2.0 / eta
    m = coords.shape[0]
    vals = np.empty(m)
    for i in range(r.shape[0]):
        for a in range(m):
            d = coords[a] - r[i]
            vals[a] = -(d * d) / eta
        exp_inplace(vals, m)
        for a in range(m):
            f = c * vals[a]
            out_f[i, a] = f
            out_g[i, a] = s * (coords[a] - r[i]) * f


@compiled(fallback=None)
def paper_law(nx, ny, rho, target, cst, pos, cos, sin, prev_x, prev_y, have_prev, h, rho_t, vdx, vdy, vtx, vty, b, g, u,
              omega):  # fmt: skip
    """Steps I and II of the paper's law (eqs. (6), (8)) in one pass; returns ``(A, shortfall, dissipation)``.

    The kernel's 1-D factors: on a lattice ``x_k = x_0 + kΔ`` (the centres or the faces along an axis), robot
    ``i``'s factor ``f_k = c exp(-d_k²/η)`` (``d_k = x_k - r_i``; ``c`` = 1 along y) obeys::

        f_{k+1} = f_k q_k,   q_k = exp(-(2 d_k Δ + Δ²)/η) = q_{k0} C[k - k0],   C[j] = exp(-2jΔ²/η)      (L1)

    ((K1) of :func:`meanfield.crowds._kde_loops.separable_sum` with ``η = 2h²``): per segment of ``S = ⌊16 h/Δ⌋``
    points (1 to 64) the start ``f_{k0}`` and ratio ``q_{k0}`` are exponentials (within 1 ulp), then each point
    takes two multiplications.  The relative round-off grows along a segment from the start's (``d²/η`` ulps, as
    ``exp(-d²/η)`` evaluated directly): a few hundred ulps where the factors matter (tests: a product of two within
    1,024 ulps above ``1e-20 c``, within ``2⁻⁴² c`` everywhere).  A start below ``e^{-708}`` is 0 (the segment's points
    are then more than 21 h away, ``f < c e^{-233}``; a ratio's exponent beyond 700, clamped by
    :func:`~meanfield._compiled.vector_exp.exp_inplace`, only occurs in such segments).  The derivatives
    are ``-2 d_k/η f_k``.

    Every field is passed flat, row after row (a C-ordered ``(nx, ny)`` array's ``reshape(-1)``; numba compiles
    a ``reshape`` into each caller, about 0.2 s of this loop's first compile).

    Parameters
    ----------
    nx, ny : int
        The grid's cells along x and y.
    rho, target : ndarray, shape (nx ny,)
        The density (positive) and ``ρ_*``.
    cst : ndarray
        The run's constants, flat (``FusedLaw._paper_constants``): ``∇ρ_*`` on the x-faces (nx-1, ny) and on the y-faces
        (nx, ny-1), the face weights of the grid's face inner product (the same shapes), the centre and face
        coordinates along x (nx, nx-1) and along y (ny, ny-1), uniform; the gains ``k_u``, ``k_ω`` (n each); then
        ``1/Δx``, ``1/Δy``, the constant σ, ``α₀`` and ``floor`` (α/ρ_f = α₀ / (ρ_f + floor); floor 0: the constant
        schedule), the Gaussian kernel's strength ``c`` and range ``η``.
    pos, cos, sin : ndarray, shape (n, 2), (n,), (n,)
        The robots' positions and headings' cosines and sines.
    prev_x, prev_y : ndarray, shapes ((nx-1) ny,), (nx (ny-1),)
        The previous call's ``v_d`` on the x- and y-faces (used when ``have_prev``), ``h`` the time since.
    rho_t, vdx, vdy, vtx, vty, b, g, u, omega : ndarray
        Outputs: ``ρ̃`` (nx ny,), ``v_d`` and ``ṽ`` on the x- and y-faces (as ``prev_x``, ``prev_y``), ``b`` (n, 2),
        ``g`` (n,), ``u`` (n, 2), ``ω`` (n,).
    """
    n = pos.shape[0]
    nfx, nfy = (nx - 1) * ny, nx * (ny - 1)
    oxc = 2 * (nfx + nfy)  # cst: the coordinates (x centres, x faces, y centres, y faces), the gains, the numbers
    oyc, oku = oxc + 2 * nx - 1, oxc + 2 * (nx + ny - 1)
    oc = oku + 2 * n
    inv_dx, inv_dy, sigma, alpha0, floor, c, eta = cst[oc], cst[oc + 1], cst[oc + 2], cst[oc + 3], cst[oc + 4], \
        cst[oc + 5], cst[oc + 6]  # fmt: skip
    nr, nxr = 2 * (nx + ny - 1), 2 * nx - 1  # the points of the four lattices, those along x
    # the buffer w: the kernel's 1-D factors f = c exp(-d²/η) (c = 1 along y) and their -2d/η multiples g at the
    # x centres, x faces, y centres, y faces, [f | g] per point (the robot index last); the signs' x factors
    # (sin_i f at the x centres, cos_i f at the x faces); the robots' x and y; the six moments; Wᵀ [f | g] of x
    # per family of faces; the exponents; then per family ρ_f, ∇ρ̃ and W = w ṽ
    oax = 2 * nr * n
    orr = oax + nxr * n
    oq = orr + 8 * n
    ov = oq + 2 * (2 * ny - 1) * n
    ofam = ov + 2 * nr * n + 2 * 64 + n
    w = empty_array(ofam + 3 * (nfx + nfy), np.float64)
    for i in range(n):
        w[_U(orr + i)] = pos[i, 0]
        w[_U(orr + n + i)] = pos[i, 1]
    # (L1) on each lattice: per segment, the start g = c e^{-d²/η} and the ratio q = e^{-(2dΔ + Δ²)/η} (d = x - r_i at
    # the segment's first point; c = 1 along y), then the tables C of x and y, exponentiated at once; then the walk
    dx = (cst[oxc + nx - 1] - cst[oxc]) / (nx - 1) if nx > 1 else 0.0
    dy = (cst[oyc + ny - 1] - cst[oyc]) / (ny - 1) if ny > 1 else 0.0
    reach = _SEGMENT_BANDWIDTHS * math.sqrt(0.5 * eta)  # 16 h, with η = 2h²
    seg = 64
    for d in (dx, dy):
        if d > 0.0 and reach < seg * d:
            fit = np.int64(reach / d)  # (not max and int: numba compiles their overloads in every process)
            seg = fit if fit > 1 else 1
    ns = 0  # segments so far
    for k in range(nr):
        lat = (k >= nx) + (k >= nxr) + (k >= nxr + ny)  # x centres, x faces, y centres, y faces
        p = k - (k >= nx) * nx - (k >= nxr) * (nx - 1) - (k >= nxr + ny) * ny  # the point on its lattice
        if p % seg == 0:
            x = cst[_U(oxc + k)]
            d = dx if lat < 2 else dy
            ro = orr if lat < 2 else orr + n
            for i in range(n):
                r = x - w[_U(ro + i)]
                w[_U(ov + 2 * ns * n + i)] = -(r * r) / eta
                w[_U(ov + (2 * ns + 1) * n + i)] = -(2.0 * r * d + d * d) / eta
            ns += 1
    otab = ov + 2 * ns * n
    for j in range(seg):
        w[_U(otab + j)] = -(2.0 * j * dx * dx) / eta
        w[_U(otab + seg + j)] = -(2.0 * j * dy * dy) / eta
    exp_inplace(w[ov:], 2 * ns * n + 2 * seg)
    one = otab + 2 * seg  # a row of ones: a segment's start is f = g × (1 × c)
    for i in range(n):
        w[_U(one + i)] = 1.0
    s = -2.0 / eta
    ns = -1
    for k in range(nr):
        lat = (k >= nx) + (k >= nxr) + (k >= nxr + ny)
        p = (k - (k >= nx) * nx - (k >= nxr) * (nx - 1) - (k >= nxr + ny) * ny) % seg
        x = cst[_U(oxc + k)]
        ro = orr if lat < 2 else orr + n
        if p == 0:
            ns += 1
            fa, fb, mult = ov + 2 * ns * n, one, c if lat < 2 else 1.0
        else:
            fa, fb, mult = 2 * (k - 1) * n, ov + (2 * ns + 1) * n, w[_U(otab + (lat // 2) * seg + p - 1)]
        for i in range(n):
            v = w[_U(fa + i)] * (w[_U(fb + i)] * mult)
            w[_U(2 * k * n + i)] = v
            w[_U(2 * k * n + n + i)] = s * (x - w[_U(ro + i)]) * v
    for k in range(nxr):
        e = sin if k < nx else cos
        for i in range(n):
            w[_U(oax + k * n + i)] = e[i] * w[_U(2 * k * n + i)]
    # v_r on the faces (x-faces: factors x at faces, y at centres; y-faces: the converse), into vtx, vty (dgemm)
    n2, yc, yf = 2 * n, 2 * nxr * n, 2 * (nxr + ny) * n
    no, yes = nx < 0, nx > 0  # (not literals: one compilation of gemm)
    gemm(no, yes, nx - 1, ny, n, w[oax + nx * n :], n, w[yc:], n2, vtx, ny, no)
    gemm(no, yes, nx, ny - 1, n, w[oax:], n, w[yf:], n2, vty, ny - 1, no)
    for k in range(nx * ny):
        rho_t[k] = rho[k] - target[k]
    rr, rt = rho, rho_t
    A = 0.0
    diss = 0.0
    inv_h = 1.0 / h
    for fam in range(2):  # Step I (eq. (6)), one family of faces at a time, flat: face (a, b) is entry a n1 + b and
        if fam == 0:  # lies between the cells a rs + b and a rs + b + off (x-faces: one row, off = ny; y-faces: nx
            n0, n1, rs, off, inv_d, prv, vd, vt = 1, nfx, 0, ny, inv_dx, prev_x, vdx, vtx  # rows, off = 1)
        else:
            n0, n1, rs, off, inv_d, prv, vd, vt = nx, ny - 1, ny, 1, inv_dy, prev_y, vdy, vty
        N = n0 * n1
        otg = fam * nfx  # cst: ∇ρ_* and the weights of this family; w: ρ_f, ∇ρ̃, W
        ot = ofam + 3 * otg
        ow = otg + nfx + nfy
        for a in range(n0):
            for bb in range(n1):
                lo = a * rs + bb
                w[_U(ot + a * n1 + bb)] = 0.5 * (rr[_U(lo + off)] + rr[_U(lo)])
                w[_U(ot + N + a * n1 + bb)] = (rt[_U(lo + off)] - rt[_U(lo)]) * inv_d
        p1, d1, t1 = prv, vd, vt
        lanes = empty_array((2, _LANES), np.float64)
        for j in range(_LANES):
            lanes[0, j] = 0.0
            lanes[1, j] = 0.0
        for k0 in range(0, N, _LANES):
            for j in range(N - k0 if N - k0 < _LANES else _LANES):
                k = _U(k0 + j)
                f = w[_U(ot) + k]
                gr = w[_U(ot + N) + k]
                gs = sigma * (gr + cst[_U(otg) + k])
                q = alpha0 / (f + floor)
                v = -q * gr + gs / f
                dv = (v - p1[k]) * inv_h if have_prev else 0.0
                tv = t1[k] - v
                wk = cst[_U(ow) + k]
                d1[k] = v
                t1[k] = tv
                w[_U(ot + 2 * N) + k] = wk * tv
                lanes[0, j] += wk * tv * (f * gr - dv)
                lanes[1, j] += wk * (q * f * gr) * gr
        for j in range(_LANES):
            A += lanes[0, j]
            diss += lanes[1, j]
    # the moments b_i, g_i (NavigationField.moments, separable): Wᵀ f and Wᵀ g of x, against y's f and g
    qy = oq + 2 * ny * n
    gemm(yes, no, ny, n2, nx - 1, w[ofam + 2 * nfx :], ny, w[2 * nx * n :], n2, w[oq:], n2, no)
    gemm(yes, no, ny - 1, n2, nx, w[ofam + 3 * nfx + 2 * nfy :], ny - 1, w[0:], n2, w[qy:], n2, no)
    for fam in range(2):
        qf = oq if fam == 0 else qy  # Wᵀ [f | g] of x (m rows of 2n)
        yo = yc if fam == 0 else yf  # y's [f | g] at the centres (x-faces) or the faces (y-faces)
        for i in range(n):
            s0 = s1 = s2 = 0.0
            for bb in range(ny - fam):
                iq = _U(qf + n2 * bb + i)
                iy = _U(yo + n2 * bb + i)
                s0 += w[iq] * w[iy]
                s1 += w[iq + _U(n)] * w[iy]
                s2 += w[iq] * w[iy + _U(n)]
            w[_U(orr + (2 + 3 * fam) * n + i)] = s0
            w[_U(orr + (3 + 3 * fam) * n + i)] = s1
            w[_U(orr + (4 + 3 * fam) * n + i)] = s2
    Z = 0.0
    for i in range(n):
        sm = orr + 2 * n + i
        b[i, 0] = cos[i] * w[_U(sm + n)] + sin[i] * w[_U(sm + 4 * n)]
        b[i, 1] = cos[i] * w[_U(sm + 2 * n)] + sin[i] * w[_U(sm + 5 * n)]
        g[i] = -sin[i] * w[_U(sm)] + cos[i] * w[_U(sm + 3 * n)]
        Z += b[i, 0] * b[i, 0] + b[i, 1] * b[i, 1] + g[i] * g[i]
    s = A / Z if Z != 0.0 else 0.0
    for i in range(n):
        u[i, 0] = cst[_U(oku + i)] * b[i, 0] + s * b[i, 0]
        u[i, 1] = cst[_U(oku + i)] * b[i, 1] + s * b[i, 1]
        omega[i] = -cst[_U(oku + n + i)] * g[i] + (-s * g[i])
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
