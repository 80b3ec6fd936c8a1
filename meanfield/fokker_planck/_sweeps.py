"""Compiled tridiagonal sweeps of the Fokker–Planck time stepping (paper, eq. (4)).

The ``"adi"`` and ``"split"`` integrators of :mod:`meanfield.fokker_planck.stepping` solve, along each
grid line, the tridiagonal systems

    ``(V - τ A_axis) ρ' = b``                                                         (S)

where ``A_axis`` holds the Scharfetter–Gummel face coefficients along one axis
(docs/fokker_planck.md, "The scheme"): the flux through the face between cells ``k`` and
``k + 1`` of a line is ``G = lo_k ρ_k - hi_k ρ_{k+1}``, so row ``k`` of ``V - τ A`` is

    ``-τ lo_{k-1} ρ_{k-1} + (V_k + τ lo_k + τ hi_{k-1}) ρ_k - τ hi_k ρ_{k+1}``.

Its columns sum to ``V``, so it is a non-singular M-matrix, strictly diagonally dominant by
columns wherever ``V > 0`` (cells outside Ω have ``V = 0``, no open face, and an identity
row).  Gaussian elimination without pivoting (the Thomas algorithm) is therefore stable
and does exactly what LAPACK's ``gttrf``/``gttrs`` do on these matrices (partial pivoting
never swaps rows there).  Eliminating downwards, with all quantities ``>= 0``,

    ``g_k = τ lo_{k-1} r_{k-1}``,  ``r_k = 1 / (d_k - g_k τ hi_{k-1})``               (F)

(``d_k`` the diagonal, ``r_k`` the reciprocal pivot), and a solve is

    ``w_k = b_k + g_k w_{k-1}``,  ``x_k = (w_k + τ hi_k x_{k+1}) r_k``.                (T)

Every array is in the grid's natural layout (``[i, j]``, x along axis 0), whatever the
axis of the lines, so the compiled loops run along contiguous memory.

Each kernel is a pair (:func:`meanfield._compiled.core.compiled`): a plain loop compiled by numba,
and its numpy twin, the same arithmetic vectorised across the lines, which is the
reference the tests compare it with and the path taken when numba is missing.  (With
``MEANFIELD_COMPILED=0`` the solver does not call these kernels at all: it runs its numpy
path with LAPACK, see :mod:`meanfield.fokker_planck.stepping`.)

* :func:`tridiagonal_factor`: (F) for the lines along one axis;
* :func:`tridiagonal_solve`: (T), one sweep of the ``"split"`` method;
* :func:`adi_step`: one Peaceman–Rachford step,
  ``(V - h A_x) r = (V + h A_y) ρ``, ``(V - h A_y) ρ' = (V + h A_x) r`` with ``h = dt/2``,
  fused into one pass down and one pass up the grid (each row of the second half-step is
  solved as soon as the three rows of ``r`` it needs are known, while they are in cache).

The recurrences (F) and (T) along y are serial within a row; the loops run eight rows side
by side, whose independent chains keep the processor busy (about 4 ns per cell and ADI
step up to 256², against 7–11 ns row by row).
"""

from __future__ import annotations

import numpy as np

from meanfield._compiled.core import compiled, enabled

__all__ = ["tridiagonal_factor", "tridiagonal_solve", "adi_step", "enabled"]

#: rows whose recurrences along y run side by side (independent chains hide the latency of each)
_ROWS = 8


# --------------------------------------------------------------------------- (F) factorisation
def _factor_numpy(V, lo, hi, tau, axis, g, rp) -> None:
    """(F) with numpy: one vector operation per position along the lines."""
    if axis == 1:
        V, lo, hi, g, rp = V.T, lo.T, hi.T, g.T, rp.T
    n = V.shape[0]
    d = V.copy()
    d[:-1] += tau * lo
    d[1:] += tau * hi
    d[V <= 0] = 1.0  # cells outside Ω: identity rows (they have no open face)
    g[0] = 0.0
    rp[0] = 1.0 / d[0]
    for k in range(1, n):
        g[k] = tau * lo[k - 1] * rp[k - 1]
        rp[k] = 1.0 / (d[k] - g[k] * (tau * hi[k - 1]))


@compiled(fallback=_factor_numpy)
def tridiagonal_factor(
    V: np.ndarray, lo: np.ndarray, hi: np.ndarray, tau: float, axis: int, g: np.ndarray, rp: np.ndarray
) -> None:
    """Factor the systems (S) of every line along ``axis`` (the Thomas algorithm, eq. (F)).

    Parameters
    ----------
    V : ndarray, shape (nx, ny)
        Cell volumes (0 outside Ω).
    lo, hi : ndarray
        Face coefficients along ``axis`` (``(nx-1, ny)`` for axis 0, ``(nx, ny-1)`` for 1):
        the flux through the face after cell ``k`` is ``lo_k ρ_k - hi_k ρ_{k+1}``.
    tau : float
        The implicit weight ``τ`` of (S).
    axis : int
        0: lines along x (one per column ``j``); 1: lines along y.
    g, rp : ndarray, shape (nx, ny)
        Written: the multipliers ``g_k`` (``g_0 = 0``) and reciprocal pivots ``r_k``.
    """
    nx, ny = V.shape
    if axis == 0:
        for j in range(ny):
            d = V[0, j] + tau * lo[0, j]
            g[0, j] = 0.0
            rp[0, j] = 1.0 / (d if V[0, j] > 0 else 1.0)
        for i in range(1, nx):
            for j in range(ny):
                d = V[i, j] + tau * hi[i - 1, j]
                if i < nx - 1:
                    d += tau * lo[i, j]
                if V[i, j] <= 0:
                    d = 1.0
                gk = tau * lo[i - 1, j] * rp[i - 1, j]
                g[i, j] = gk
                rp[i, j] = 1.0 / (d - gk * (tau * hi[i - 1, j]))
    else:
        for s in range(0, nx, _ROWS):  # a block of rows at a time: independent recurrences side by side
            e = min(s + _ROWS, nx)
            for i in range(s, e):
                d = V[i, 0] + tau * lo[i, 0]
                g[i, 0] = 0.0
                rp[i, 0] = 1.0 / (d if V[i, 0] > 0 else 1.0)
            for j in range(1, ny):
                for i in range(s, e):
                    d = V[i, j] + tau * hi[i, j - 1]
                    if j < ny - 1:
                        d += tau * lo[i, j]
                    if V[i, j] <= 0:
                        d = 1.0
                    gk = tau * lo[i, j - 1] * rp[i, j - 1]
                    g[i, j] = gk
                    rp[i, j] = 1.0 / (d - gk * (tau * hi[i, j - 1]))


# --------------------------------------------------------------------------- (T) one sweep
def _solve_numpy(b, hi, tau, g, rp, axis, out) -> None:
    """(T) with numpy: one vector operation per position along the lines."""
    if axis == 1:
        b, hi, g, rp, out = b.T, hi.T, g.T, rp.T, out.T
    n = b.shape[0]
    out[0] = b[0]
    for k in range(1, n):
        out[k] = b[k] + g[k] * out[k - 1]
    out[n - 1] *= rp[n - 1]
    for k in range(n - 2, -1, -1):
        out[k] = (out[k] + (tau * hi[k]) * out[k + 1]) * rp[k]


@compiled(fallback=_solve_numpy)
def tridiagonal_solve(
    b: np.ndarray, hi: np.ndarray, tau: float, g: np.ndarray, rp: np.ndarray, axis: int, out: np.ndarray
) -> None:
    """Solve the factored systems (S) of every line along ``axis`` (eq. (T)) into ``out``.

    Parameters
    ----------
    b : ndarray, shape (nx, ny)
        Right-hand side (a mass: volume times density); may be ``out`` itself.
    hi : ndarray
        The face coefficients ``hi`` along ``axis`` (as in :func:`tridiagonal_factor`).
    tau : float
        The ``τ`` the factors were computed with.
    g, rp : ndarray, shape (nx, ny)
        The factors from :func:`tridiagonal_factor`.
    axis : int
        0 or 1, as in :func:`tridiagonal_factor`.
    out : ndarray, shape (nx, ny)
        Written: the solution.
    """
    nx, ny = b.shape
    if axis == 0:
        for j in range(ny):
            out[0, j] = b[0, j]
        for i in range(1, nx):
            for j in range(ny):
                out[i, j] = b[i, j] + g[i, j] * out[i - 1, j]
        for j in range(ny):
            out[nx - 1, j] *= rp[nx - 1, j]
        for i in range(nx - 2, -1, -1):
            for j in range(ny):
                out[i, j] = (out[i, j] + (tau * hi[i, j]) * out[i + 1, j]) * rp[i, j]
    else:
        for s in range(0, nx, _ROWS):  # a block of rows at a time: independent recurrences side by side
            e = min(s + _ROWS, nx)
            for i in range(s, e):
                out[i, 0] = b[i, 0]
            for j in range(1, ny):
                for i in range(s, e):
                    out[i, j] = b[i, j] + g[i, j] * out[i, j - 1]
            for i in range(s, e):
                out[i, ny - 1] *= rp[i, ny - 1]
            for j in range(ny - 2, -1, -1):
                for i in range(s, e):
                    out[i, j] = (out[i, j] + (tau * hi[i, j]) * out[i, j + 1]) * rp[i, j]


# --------------------------------------------------------------------------- one ADI step
def _adi_numpy(rho, V1, V2, lx, rx, ly, ry, h, gx, rpx, gy, rpy, work, out) -> float:
    """One Peaceman–Rachford step with numpy (the reference of :func:`adi_step`)."""
    b = V1 * rho
    G = ly * rho[:, :-1] - ry * rho[:, 1:]  # y-flux of ρ
    b[:, :-1] -= h * G
    b[:, 1:] += h * G
    _solve_numpy(b, rx, h, gx, rpx, 0, work)  # r: (V - h A_x) r = (V + h A_y) ρ
    c = V2 * work
    F = lx * work[:-1, :] - rx * work[1:, :]  # x-flux of r
    c[:-1, :] -= h * F
    c[1:, :] += h * F
    _solve_numpy(c, ry, h, gy, rpy, 1, out)  # ρ': (V - h A_y) ρ' = (V + h A_x) r
    return float(out.min())


@compiled(fallback=_adi_numpy)
def adi_step(
    rho: np.ndarray,
    V1: np.ndarray,
    V2: np.ndarray,
    lx: np.ndarray,
    rx: np.ndarray,
    ly: np.ndarray,
    ry: np.ndarray,
    h: float,
    gx: np.ndarray,
    rpx: np.ndarray,
    gy: np.ndarray,
    rpy: np.ndarray,
    work: np.ndarray,
    out: np.ndarray,
) -> float:
    """One Peaceman–Rachford ADI step of ``V dρ/dt = (A_x + A_y) ρ`` (paper, eq. (4)).

    ``(V - h A_x) r = (V + h A_y) ρ`` then ``(V - h A_y) ρ' = (V + h A_x) r``, ``h = dt/2``,
    each a set of factored tridiagonal solves (T).  Down the grid: the explicit y-half and
    the elimination of the x-systems, row by row; up the grid, eight rows at a time: the
    back-substitution of the x-systems and, for every row ``k`` whose rows ``k-1 … k+1``
    of ``r`` are then known, the explicit x-half and the y-system (the eight rows'
    recurrences interleaved, so that the latency of one hides behind the others).

    Parameters
    ----------
    rho : ndarray, shape (nx, ny)
        The density at the start of the step (not modified).
    V1, V2 : ndarray, shape (nx, ny)
        The diagonal of the explicit halves, ``V + h A_y`` and ``V + h A_x``: the cell volumes, less ``h s`` where an
        exit along that axis takes mass at the rate ``s ρ`` (:func:`meanfield.fokker_planck.stepping._with_sink`).
    lx, rx, ly, ry : ndarray
        Face coefficients along x (``(nx-1, ny)``) and y (``(nx, ny-1)``), see
        :func:`tridiagonal_factor`.
    h : float
        Half the time step.
    gx, rpx, gy, rpy : ndarray, shape (nx, ny)
        Factors of ``V - h A_x`` (axis 0) and ``V - h A_y`` (axis 1) from
        :func:`tridiagonal_factor` with ``τ = h``.
    work : ndarray, shape (nx, ny)
        Scratch (holds ``r`` on return).
    out : ndarray, shape (nx, ny)
        Written: the density at the end of the step (must not be ``rho``).

    Returns
    -------
    float
        ``min(out)`` (a negative value means the step was above the positivity bound).
    """
    nx, ny = rho.shape
    # down: b = V ρ + h A_y ρ (row-local; each cell from its two y-faces), eliminated along x into work
    for i in range(nx):
        work[i, 0] = V1[i, 0] * rho[i, 0] - h * (ly[i, 0] * rho[i, 0] - ry[i, 0] * rho[i, 1])
        for j in range(1, ny - 1):
            work[i, j] = V1[i, j] * rho[i, j] + h * (
                (ly[i, j - 1] * rho[i, j - 1] - ry[i, j - 1] * rho[i, j])
                - (ly[i, j] * rho[i, j] - ry[i, j] * rho[i, j + 1])
            )
        m = ny - 1
        work[i, m] = V1[i, m] * rho[i, m] + h * (ly[i, m - 1] * rho[i, m - 1] - ry[i, m - 1] * rho[i, m])
        if i > 0:
            for j in range(ny):
                work[i, j] += gx[i, j] * work[i - 1, j]
    # up, a block of rows s..e at a time: back-substitute r there, then solve the second
    # half-step on the rows whose three rows of r are now known (s+1 .. e+1; row 0 last)
    lowest = np.inf
    e = nx - 1
    while e >= 0:
        s = max(e - _ROWS + 1, 0)
        for i in range(e, s - 1, -1):
            if i == nx - 1:
                for j in range(ny):
                    work[i, j] *= rpx[i, j]
            else:
                for j in range(ny):
                    work[i, j] = (work[i, j] + (h * rx[i, j]) * work[i + 1, j]) * rpx[i, j]
        k0, k1 = (s + 1 if s > 0 else 0), min(e + 1, nx - 1)
        for k in range(k0, k1 + 1):  # c = V r + h A_x r, into out
            if k == 0:
                for j in range(ny):
                    out[k, j] = V2[k, j] * work[k, j] - h * (lx[k, j] * work[k, j] - rx[k, j] * work[k + 1, j])
            elif k == nx - 1:
                for j in range(ny):
                    out[k, j] = V2[k, j] * work[k, j] + h * (lx[k - 1, j] * work[k - 1, j] - rx[k - 1, j] * work[k, j])
            else:
                for j in range(ny):
                    out[k, j] = V2[k, j] * work[k, j] + h * (
                        (lx[k - 1, j] * work[k - 1, j] - rx[k - 1, j] * work[k, j])
                        - (lx[k, j] * work[k, j] - rx[k, j] * work[k + 1, j])
                    )
        # (V - h A_y) ρ' = c on those rows, their recurrences side by side
        for j in range(1, ny):
            for k in range(k0, k1 + 1):
                out[k, j] += gy[k, j] * out[k, j - 1]
        for k in range(k0, k1 + 1):
            out[k, ny - 1] *= rpy[k, ny - 1]
        for j in range(ny - 2, -1, -1):
            for k in range(k0, k1 + 1):
                out[k, j] = (out[k, j] + (h * ry[k, j]) * out[k, j + 1]) * rpy[k, j]
        for k in range(k0, k1 + 1):
            for j in range(ny):
                lowest = min(lowest, out[k, j])
        e = s - 1
    return lowest
