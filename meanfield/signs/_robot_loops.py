"""The robots' per-step loops, compiled: their inputs within the speed limits and the Euler step of eq. (2).

* :func:`limit_inputs`: the robots' inputs within their speed limits (eq. (2)), what the
  limits did to the commands (for the observers) and whether they are finite, in one pass;
  :func:`input_report`: that report alone, for commands and inputs given apart;
* :func:`robot_euler`: the Euler step of eq. (2), headings wrapped as ``np.mod`` does.

Each is paired with its numpy twin, the reference (:mod:`meanfield._compiled`).
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import compiled

__all__ = ["input_report", "limit_inputs", "robot_euler"]


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
    ``|ω_cmd,i| >= (1 - rtol) ω_max`` (as :meth:`meanfield.signs.robots.RobotTeam.at_limit`); the
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
        :meth:`meanfield.geometry.domain.Domain.project` does (``np.maximum`` then ``np.minimum``: NaN stays NaN);
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
