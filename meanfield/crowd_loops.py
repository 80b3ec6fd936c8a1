"""The crowd's per-human loops, compiled: the signs' field at each human and the Euler–Maruyama step.

Each loop here is one pass over the humans, paired with its numpy twin (the reference,
:mod:`meanfield.compiled`):

* :func:`gaussian_field_at`: ``v_r(X_j) = Σ_i K̄(X_j - R_i) e(θ_i)`` for the paper's Gaussian
  ``K̄(ξ) = c exp(-|ξ|²/η)`` (eq. (3); docs page *The model*), optionally masked by which robot
  each human sees (plans, :mod:`meanfield.sight`);
* :func:`bilinear_at`: the same field sampled on a lattice and interpolated to the humans
  (:mod:`meanfield.sampled_field`);
* :func:`euler_maruyama`: ``X_j += b_j dt + a ξ_j`` (eq. (1) discretized), with the box's
  reflecting walls folded in when Ω is a box (any number of bounces, as
  :meth:`meanfield.domain.Domain.reflect` does);
* :func:`limit_inputs`: the robots' inputs within their speed limits (eq. (2)), what the
  limits did to the commands (for the observers) and whether they are finite, in one pass;
  :func:`input_report`: that report alone, for commands and inputs given apart;
* :func:`count_in_disk`: how many humans are in the target disk (the fraction in the target).

Both field loops also flag the humans a sign *reaches* (``|v_r| >= reach``, used for the
stragglers).  The noise ``ξ_j`` is drawn by the caller from its numpy Generator, so both
paths consume the same random stream.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield.compiled import compiled
from meanfield.vector_exp import exp_inplace

__all__ = [
    "gaussian_field_at",
    "bilinear_at",
    "euler_maruyama",
    "input_report",
    "limit_inputs",
    "robot_euler",
    "NO_BOX",
    "count_in_disk",
]

_FIELD_BLOCK = 256
"""Humans per block of :func:`gaussian_field_at` (its buffers stay in L1)."""


# ----------------------------------------------------------------------------- v_r, exact
def _gaussian_field_numpy(points, robots, headings, c, inv_eta, visible, reach, out, reached):
    rx, ry = robots[:, 0], robots[:, 1]
    ex, ey = c * np.cos(headings), c * np.sin(headings)
    block = max(1, (1 << 20) // max(len(rx), 1))
    for a in range(0, len(points), block):
        p = points[a : a + block]
        dx = p[None, :, 0] - rx[:, None]
        dy = p[None, :, 1] - ry[:, None]
        k = np.exp(-(dx * dx + dy * dy) * inv_eta)
        if visible.shape[1]:
            k *= visible[:, a : a + block]
        out[a : a + block, 0] = ex @ k
        out[a : a + block, 1] = ey @ k
    np.greater_equal(out[:, 0] * out[:, 0] + out[:, 1] * out[:, 1], reach * reach, out=reached)


@compiled(fallback=_gaussian_field_numpy)
def gaussian_field_at(points, robots, headings, c, inv_eta, visible, reach, out, reached):
    """``v_r`` of eq. (3) at every human for the Gaussian kernel, into ``out`` (N, 2).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        The humans.
    robots : ndarray, shape (n, 2)
        The robots' positions ``R_i``.
    headings : ndarray, shape (n,)
        Their headings ``θ_i``.
    c : float
        The kernel's strength.
    inv_eta : float
        ``1 / η``.
    visible : ndarray of bool, shape (n, N) or (n, 0)
        Which robot each human sees; an empty second axis means every robot is seen.
    reach : float
        ``reached[j] = |v_r(X_j)| >= reach``.
    out : ndarray, shape (N, 2)
    reached : ndarray of bool, shape (N,)
    """
    n = robots.shape[0]
    rx, ry, ex, ey = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        rx[i] = robots[i, 0]
        ry[i] = robots[i, 1]
        ex[i] = c * math.cos(headings[i])
        ey[i] = c * math.sin(headings[i])
    masked = visible.shape[1] > 0
    r2 = reach * reach
    block = _FIELD_BLOCK
    xs, ys = np.empty(block), np.empty(block)
    sx, sy = np.empty(block), np.empty(block)
    k = np.empty(block)
    for first in range(0, points.shape[0], block):  # blocks of humans, robot by robot: the exp vectorises
        m = block if points.shape[0] - first > block else points.shape[0] - first
        for j in range(m):
            xs[j] = points[first + j, 0]
            ys[j] = points[first + j, 1]
            sx[j] = 0.0
            sy[j] = 0.0
        for i in range(n):
            for j in range(m):
                dx = xs[j] - rx[i]
                dy = ys[j] - ry[i]
                k[j] = -(dx * dx + dy * dy) * inv_eta
            exp_inplace(k, m)
            if masked:
                for j in range(m):
                    if not visible[i, first + j]:
                        k[j] = 0.0
            for j in range(m):
                sx[j] += ex[i] * k[j]
                sy[j] += ey[i] * k[j]
        for j in range(m):
            out[first + j, 0] = sx[j]
            out[first + j, 1] = sy[j]
            reached[first + j] = sx[j] * sx[j] + sy[j] * sy[j] >= r2


# ----------------------------------------------------------------------------- v_r, sampled
def _bilinear_numpy(vx, vy, x0, y0, inv_hx, inv_hy, points, reach, out, reached):
    mx, my = vx.shape
    s = np.clip((points[:, 0] - x0) * inv_hx, 0.0, mx - 1.0)
    t = np.clip((points[:, 1] - y0) * inv_hy, 0.0, my - 1.0)
    i = np.minimum(s, mx - 2.0).astype(np.intp)
    j = np.minimum(t, my - 2.0).astype(np.intp)
    s -= i
    t -= j
    for col, f in enumerate((vx, vy)):
        lo = f[i, j] + (f[i, j + 1] - f[i, j]) * t
        hi = f[i + 1, j] + (f[i + 1, j + 1] - f[i + 1, j]) * t
        out[:, col] = lo + (hi - lo) * s
    np.greater_equal(out[:, 0] * out[:, 0] + out[:, 1] * out[:, 1], reach * reach, out=reached)
    return out


@compiled(fallback=_bilinear_numpy)
def bilinear_at(vx, vy, x0, y0, inv_hx, inv_hy, points, reach, out, reached):
    """Bilinear interpolation of a lattice field ``(vx, vy)`` at every human, into ``out`` (N, 2).

    Node ``(a, b)`` of the lattice sits at ``(x0 + a h_x, y0 + b h_y)``; a point outside
    the lattice takes the value at its nearest edge.  The interpolation error is bounded
    in :mod:`meanfield.sampled_field`.

    Parameters
    ----------
    vx, vy : ndarray, shape (mx, my)
        The field's components at the nodes.
    x0, y0, inv_hx, inv_hy : float
        The lattice's origin and inverse spacings.
    points : ndarray, shape (N, 2)
    reach : float
        ``reached[j] = |v_r(X_j)| >= reach``.
    out : ndarray, shape (N, 2)
    reached : ndarray of bool, shape (N,)
    """
    mx, my = vx.shape
    r2 = reach * reach
    for p in range(points.shape[0]):
        s = min(max((points[p, 0] - x0) * inv_hx, 0.0), mx - 1.0)
        t = min(max((points[p, 1] - y0) * inv_hy, 0.0), my - 1.0)
        i = int(min(s, mx - 2.0))
        j = int(min(t, my - 2.0))
        s -= i
        t -= j
        lo = vx[i, j] + (vx[i, j + 1] - vx[i, j]) * t
        hi = vx[i + 1, j] + (vx[i + 1, j + 1] - vx[i + 1, j]) * t
        ux = lo + (hi - lo) * s
        lo = vy[i, j] + (vy[i, j + 1] - vy[i, j]) * t
        hi = vy[i + 1, j] + (vy[i + 1, j + 1] - vy[i + 1, j]) * t
        uy = lo + (hi - lo) * s
        out[p, 0] = ux
        out[p, 1] = uy
        reached[p] = ux * ux + uy * uy >= r2
    return out


# ----------------------------------------------------------------------------- the SDE step
def _fold_numpy(col, lo, hi):
    out = (col < lo) | (col > hi)
    if out.any():
        period = 2.0 * (hi - lo)
        s = np.mod(col[out] - lo, period)
        col[out] = lo + np.where(s > hi - lo, period - s, s)


def _euler_maruyama_numpy(x, drift, noise, dt, amp, box):
    if not np.isfinite(drift).all():
        return False
    x += drift * dt
    x += noise * amp
    if box.shape[0]:
        _fold_numpy(x[:, 0], box[0], box[1])
        _fold_numpy(x[:, 1], box[2], box[3])
    return True


@compiled(fallback=_euler_maruyama_numpy)
def euler_maruyama(x, drift, noise, dt, amp, box):
    """One Euler–Maruyama step of eq. (1), in place: ``X_j += b_j dt + a_j ξ_j``, then the box's walls;
    returns False, ``x`` untouched, when some drift is not finite (else True).

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions, updated in place.
    drift : ndarray, shape (N, 2)
        ``b_j = u_W + v_r + v_a`` at each human.
    noise : ndarray, shape (N, 2)
        Standard normal draws ``ξ_j``.
    dt : float
    amp : ndarray, shape (N, 1) or (1, 1)
        ``sqrt(2 σ dt)`` per human (one row when σ is constant).
    box : ndarray, shape (4,) or (0,)
        ``(x0, x1, y0, y1)``: fold each coordinate back into the box (reflecting walls, any
        number of bounces); empty: no walls here (the caller reflects).
    """
    for j in range(x.shape[0]):  # every drift finite, or nothing moves (the caller keeps the last good state)
        if not (math.isfinite(drift[j, 0]) and math.isfinite(drift[j, 1])):
            return False
    walls = box.shape[0] == 4
    one = amp.shape[0] == 1
    for j in range(x.shape[0]):
        a = amp[0, 0] if one else amp[j, 0]
        for k in range(2):
            v = x[j, k] + drift[j, k] * dt
            v = v + noise[j, k] * a
            if walls:
                lo = box[2 * k]
                hi = box[2 * k + 1]
                if v < lo or v > hi:
                    period = 2.0 * (hi - lo)
                    s = (v - lo) % period
                    v = lo + (period - s if s > hi - lo else s)
            x[j, k] = v
    return True


# ----------------------------------------------------------------------------- the robots' limits
def _saturate_numpy(u, omega, u_max, omega_max, shrink, u_out, w_out):
    u_out[...] = u
    if math.isfinite(u_max):
        speed = np.hypot(u[:, 0], u[:, 1])
        over = speed > u_max
        if over.any():
            # scaled a hair below the limit, so that round-off never puts ‖u_i‖ above it
            u_out[over] *= (u_max / speed[over] * shrink)[:, None]
    w_out[...] = omega
    if math.isfinite(omega_max):
        np.minimum(np.maximum(omega, -omega_max), omega_max, out=w_out)
    return u_out, w_out


def _input_report_numpy(u_cmd, w_cmd, u, w, u_max, omega_max, rtol):
    asked = np.hypot(u_cmd[:, 0], u_cmd[:, 1])
    speed = np.hypot(u[:, 0], u[:, 1])
    cut = bool((asked > speed).any() or (np.abs(w_cmd) > np.abs(w)).any())
    limit = np.zeros(len(w_cmd), dtype=bool)
    if math.isfinite(u_max):
        limit |= asked >= (1 - rtol) * u_max
    if math.isfinite(omega_max):
        limit |= np.abs(w_cmd) >= (1 - rtol) * omega_max
    return float(speed.max()), float(np.abs(w).max()), cut, int(limit.sum())


@compiled(fallback=_input_report_numpy)
def input_report(u_cmd, w_cmd, u, w, u_max, omega_max, rtol):
    """What the speed limits did to one step's commands: ``(max ‖u_i‖, max |ω_i|, cut, at_limit)``.

    ``cut``: some command was reduced (``‖u_cmd,i‖ > ‖u_i‖`` or ``|ω_cmd,i| > |ω_i|``);
    ``at_limit``: how many robots' commands reach a limit, ``‖u_cmd,i‖ >= (1 - rtol) u_max`` or
    ``|ω_cmd,i| >= (1 - rtol) ω_max`` (as :meth:`meanfield.robots.RobotTeam.at_limit`); the
    maxima are over the applied inputs ``u``, ``w`` (eq. (2)'s limits, docs page *Robots*).

    Parameters
    ----------
    u_cmd, w_cmd : ndarray, shapes (n, 2), (n,)
        The commanded inputs.
    u, w : ndarray, shapes (n, 2), (n,)
        The applied ones (as :func:`limit_inputs` makes them).
    u_max, omega_max : float
        The limits (``inf``: none).
    rtol : float
    """
    top_speed = 0.0
    top_turn = 0.0
    cut = False
    count = 0
    u_lim = (1 - rtol) * u_max
    w_lim = (1 - rtol) * omega_max
    for i in range(w_cmd.shape[0]):
        asked = math.hypot(u_cmd[i, 0], u_cmd[i, 1])
        speed = math.hypot(u[i, 0], u[i, 1])
        turn = abs(w[i])
        top_speed = speed if speed > top_speed else top_speed
        top_turn = turn if turn > top_turn else top_turn
        if asked > speed or abs(w_cmd[i]) > turn:
            cut = True
        if (math.isfinite(u_max) and asked >= u_lim) or (math.isfinite(omega_max) and abs(w_cmd[i]) >= w_lim):
            count += 1
    return top_speed, top_turn, cut, count


def _limit_numpy(u, omega, u_max, omega_max, shrink, rtol, u_out, w_out):
    finite = bool(np.isfinite(u).all() and np.isfinite(omega).all())
    _saturate_numpy(u, omega, u_max, omega_max, shrink, u_out, w_out)
    if not len(omega):
        return 0.0, 0.0, False, 0, finite
    return (*_input_report_numpy(u, omega, u_out, w_out, u_max, omega_max, rtol), finite)


@compiled(fallback=_limit_numpy)
def limit_inputs(u, omega, u_max, omega_max, shrink, rtol, u_out, w_out):
    """The robots' inputs within their limits, what the limits did, and whether the commands are finite: one pass.

    ``u_i`` is scaled to ``‖u_i‖ <= u_max`` (a hair below: ``shrink``, so that round-off never
    puts it above) and ``ω_i`` clipped to ``±ω_max`` into ``u_out``, ``w_out`` (eq. (2)'s limits,
    docs page *Robots*); the first four returned values are :func:`input_report`'s for these
    commands and outputs, the last ``True`` when every command is finite (the closed loop's
    divergence check).

    Parameters
    ----------
    u, omega : ndarray, shapes (n, 2), (n,)
        The commands.
    u_max, omega_max : float
        The limits (``inf``: none).
    shrink : float
        ``1 - 4 ε``: a saturated speed lands this fraction below the limit.
    rtol : float
        As :func:`input_report`.
    u_out, w_out : ndarray
        The applied inputs.

    Returns
    -------
    tuple
        ``(max ‖u_i‖, max |ω_i|, cut, at_limit, finite)``.
    """
    top_speed = 0.0
    top_turn = 0.0
    cut = False
    count = 0
    finite = True
    u_lim = (1 - rtol) * u_max
    w_lim = (1 - rtol) * omega_max
    for i in range(omega.shape[0]):
        ux, uy = u[i, 0], u[i, 1]
        asked = math.hypot(ux, uy)
        speed = asked
        if asked > u_max:
            s = u_max / asked * shrink
            ux, uy = ux * s, uy * s
            speed = math.hypot(ux, uy)
        u_out[i, 0], u_out[i, 1] = ux, uy
        wc = omega[i]
        w = -omega_max if wc < -omega_max else wc
        w = omega_max if w > omega_max else w
        w_out[i] = w
        finite = finite and math.isfinite(u[i, 0]) and math.isfinite(u[i, 1]) and math.isfinite(wc)
        turn = abs(w)
        top_speed = speed if speed > top_speed else top_speed
        top_turn = turn if turn > top_turn else top_turn
        if asked > speed or abs(wc) > turn:
            cut = True
        if (math.isfinite(u_max) and asked >= u_lim) or (math.isfinite(omega_max) and abs(wc) >= w_lim):
            count += 1
    return top_speed, top_turn, cut, count, finite


NO_BOX = np.empty(0)
"""The ``box`` of :func:`euler_maruyama` and :func:`robot_euler` that folds no walls into the pass."""


def _robot_euler_numpy(positions, headings, u, omega, dt, box, headings_out):
    positions += dt * u
    np.mod(headings + dt * omega, 2 * np.pi, out=headings_out)
    if box.shape[0]:
        np.maximum(positions, (box[0], box[2]), out=positions)
        np.minimum(positions, (box[1], box[3]), out=positions)


@compiled(fallback=_robot_euler_numpy)
def robot_euler(positions, headings, u, omega, dt, box, headings_out):
    """One explicit Euler step of eq. (2): ``R_i += dt u_i`` in place, ``θ_i + dt ω_i`` wrapped to ``[0, 2π)``.

    Parameters
    ----------
    positions : ndarray, shape (n, 2)
        The robots' positions, updated in place.
    headings : ndarray, shape (n,)
        Their headings (read).
    u, omega : ndarray, shapes (n, 2) and (n,)
        The applied inputs.
    dt : float
    box : ndarray, shape (4,) or (0,)
        ``(x0, x1, y0, y1)``: a box's walls, the positions then clamped into it in the same pass, as
        :meth:`meanfield.domain.Domain.project` does (``np.maximum`` then ``np.minimum``: NaN stays NaN);
        empty: no clamp.
    headings_out : ndarray, shape (n,)
        The new headings (``np.mod`` semantics, bit for bit).
    """
    two_pi = 2 * np.pi
    clamp = box.shape[0] > 0
    for i in range(positions.shape[0]):
        x = positions[i, 0] + dt * u[i, 0]
        y = positions[i, 1] + dt * u[i, 1]
        if clamp:  # (a NaN compares false: it stays, as np.maximum/np.minimum keep it)
            x = box[0] if x < box[0] else x
            x = box[1] if x > box[1] else x
            y = box[2] if y < box[2] else y
            y = box[3] if y > box[3] else y
        positions[i, 0] = x
        positions[i, 1] = y
        headings_out[i] = np.mod(headings[i] + dt * omega[i], two_pi)


def _count_in_disk_numpy(points, cx, cy, radius):
    dx = points[:, 0] - cx
    dy = points[:, 1] - cy
    return int(np.count_nonzero(dx * dx + dy * dy <= radius * radius))


@compiled(fallback=_count_in_disk_numpy)
def count_in_disk(points, cx, cy, radius):
    """How many of ``points`` (N, 2) lie within ``radius`` of ``(cx, cy)`` (NaN rows: none).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
    cx, cy, radius : float
    """
    r2 = radius * radius
    count = 0
    for j in range(points.shape[0]):
        dx = points[j, 0] - cx
        dy = points[j, 1] - cy
        if dx * dx + dy * dy <= r2:
            count += 1
    return count
