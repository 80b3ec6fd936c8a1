"""Robots: single integrators carrying signs, and the navigation velocity field they make.

Robot model (paper, eq. (2))::

    dR_i/dt = u_i,   dθ_i/dt = ω_i,   ‖u_i‖ <= u_max,  |ω_i| <= ω_max  (optional limits)

Navigation field (paper, eq. (3)) and its time derivative (eq. (5))::

    v_r(x, t)   = Σ_i K(x - R_i, θ_i)
    ∂_t v_r     = Σ_i ( -K_ξ^i u_i + K_θ^i ω_i )

:class:`NavigationField` evaluates ``v_r`` on the grid faces once per step and gives
the integrals ``∫ Fᵀ K_ξ^i dx`` and ``∫ Fᵀ K_θ^i dx`` of any face field ``F`` against
each robot's kernel (the ``b_i`` and ``g_i`` of the controller).  For the separable
Gaussian kernel all of this reduces to small matrix products.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from meanfield._compiled.core import NO_BOX
from meanfield.errors import ParameterError, limit_or_inf
from meanfield.geometry.grid import FaceField, Grid
from meanfield.geometry.region import Region
from meanfield.geometry.sight import SightLines
from meanfield.signs._masked_loops import face_moments, masked_face_kernels
from meanfield.signs._robot_loops import limit_inputs, robot_euler
from meanfield.signs.kernels import NavigationKernel

__all__ = [
    "RobotTeam",
    "NavigationField",
    "navigation_velocity",
    "saturate_inputs",
    "limited_inputs",
    "AT_LIMIT_RTOL",
]

AT_LIMIT_RTOL = 1e-6
"""A command within this relative tolerance of a speed or turn-rate limit counts as at the limit."""


@dataclass
class RobotTeam:
    """States of ``n`` robots and their speed limits.

    Parameters
    ----------
    positions : ndarray, shape (n, 2)
        Robot positions ``R_i``, each inside Ω.
    headings : ndarray, shape (n,)
        Sign orientations ``θ_i`` (radians).
    u_max : float or None
        Linear speed limit ``‖u_i‖ <= u_max`` (None: unlimited).
    omega_max : float or None
        Turning-rate limit ``|ω_i| <= ω_max`` (None: unlimited).
    shows : ndarray of int, shape (n,), or None
        The exit each sign names beside its arrow ("EXIT 2, THIS WAY"), ``-1`` for an arrow alone; None: arrows
        alone (set by a controller that names exits, :attr:`meanfield.interfaces.Command.shows`; read by people who
        remember the sign's exit, :mod:`meanfield.crowds.memory`).
    """

    positions: np.ndarray
    headings: np.ndarray
    u_max: float | None = None
    omega_max: float | None = None
    shows: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.positions = np.array(self.positions, dtype=float).reshape(-1, 2)
        self.headings = np.array(self.headings, dtype=float).reshape(-1)
        if len(self.positions) < 1:
            raise ParameterError("robots.positions", "no robots", "at least one robot")
        if self.headings.shape != (len(self.positions),):
            raise ParameterError(
                "robots.headings", self.headings.shape, f"one heading per robot ({len(self.positions)})"
            )
        if not (np.all(np.isfinite(self.positions)) and np.all(np.isfinite(self.headings))):
            raise ParameterError("robots", "non-finite state", "finite positions and headings")
        self.u_max = limit_or_inf("robots.u_max", self.u_max)
        self.omega_max = limit_or_inf("robots.omega_max", self.omega_max)

    @property
    def n(self) -> int:
        """Number of robots."""
        return len(self.positions)

    def check_inside(self, domain: Region, tol: float = 1e-12) -> None:
        """Raise :class:`ParameterError` if a robot is outside Ω."""
        inside = domain.contains(self.positions[:, 0], self.positions[:, 1], tol=tol)
        if not inside.all():
            k = int(np.flatnonzero(~inside)[0])
            raise ParameterError(f"robots.positions[{k}]", self.positions[k].tolist(), "a point inside the domain")

    def at_limit(self, u: np.ndarray, omega: np.ndarray, rtol: float = AT_LIMIT_RTOL) -> np.ndarray:
        """Robots whose commanded input reaches a limit: ``‖u_i‖ >= (1 - rtol) u_max`` or
        ``|ω_i| >= (1 - rtol) ω_max`` (a saturated command counts); bool array of shape (n,)."""
        out = np.zeros(len(omega), dtype=bool)
        if math.isfinite(self.u_max):
            out |= np.hypot(u[:, 0], u[:, 1]) >= (1 - rtol) * self.u_max
        if math.isfinite(self.omega_max):
            out |= np.abs(omega) >= (1 - rtol) * self.omega_max
        return out

    def step(self, u: np.ndarray, omega: np.ndarray, dt: float, domain: Region) -> None:
        """Advance eq. (2) by one explicit Euler step, saturating and keeping robots in Ω.

        ``u`` and ``omega`` are saturated with :func:`saturate_inputs` first, then the
        positions are projected onto Ω (a robot that hits a wall slides along it).
        """
        u, omega = saturate_inputs(u, omega, self.u_max, self.omega_max)
        self.advance(u, omega, dt, domain)

    def advance(self, u: np.ndarray, omega: np.ndarray, dt: float, domain: Region) -> None:
        """Euler step of eq. (2) with inputs already within the limits; robots kept in ``domain``.

        In a plan (a region with ``slide_along_walls``) a robot whose step meets a wall or a
        pillar goes on along it with what is left of the step's component along the wall
        (a head-on step stops), never through it.
        """
        stop = getattr(domain, "slide_along_walls", None)
        start = self.positions.copy() if stop is not None else None
        u, omega = np.asarray(u, float), np.asarray(omega, float)
        headings = np.empty(self.headings.shape)  # (float: __post_init__ made it so)
        fits = u.shape == self.positions.shape and omega.shape == headings.shape  # (else numpy broadcasts)
        box = NO_BOX if stop is not None else getattr(domain, "box_walls", NO_BOX)  # a box's: clamped in the pass
        step = robot_euler if fits else robot_euler.fallback
        step(self.positions, self.headings, u, omega, float(dt), box, headings)
        if stop is not None:
            stop(start, self.positions)
        if not box.shape[0]:
            domain.project(self.positions)
        self.headings = headings


def saturate_inputs(u: np.ndarray, omega: np.ndarray, u_max: float, omega_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Scale each ``u_i`` down to ``‖u_i‖ <= u_max`` (direction kept) and clip ``ω_i`` (eq. (2)'s limits).

    Returns new arrays (the inputs are not changed): :func:`limited_inputs` without its report.
    """
    u_out, w_out, _ = limited_inputs(u, omega, u_max, omega_max)
    return u_out, w_out


_SHRINK = 1 - 4 * np.finfo(float).eps


def limited_inputs(
    u: np.ndarray, omega: np.ndarray, u_max: float, omega_max: float
) -> tuple[np.ndarray, np.ndarray, tuple[float, float, bool, int, bool]]:
    """The inputs within eq. (2)'s limits (each ``u_i`` scaled to ``‖u_i‖ <= u_max``, direction kept; ``ω_i``
    clipped) and what the limits did, ``(max ‖u_i‖, max |ω_i|, cut, at_limit, finite)``.

    The report is :func:`meanfield.signs._robot_loops.input_report`'s (``at_limit`` with
    :data:`AT_LIMIT_RTOL`), ``finite`` whether every command is finite: one compiled pass
    (:func:`meanfield.signs._robot_loops.limit_inputs`).  The closed loop's step calls this.
    """
    u, omega = np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(omega, dtype=float)
    u_out, w_out = np.empty(u.shape), np.empty(omega.shape)  # (float, as u and omega now are)
    run = limit_inputs if u.ndim == 2 and omega.ndim == 1 else limit_inputs.fallback  # (numpy says what is wrong)
    report = run(u, omega, float(u_max), float(omega_max), _SHRINK, AT_LIMIT_RTOL, u_out, w_out)
    return u_out, w_out, report


def navigation_velocity(
    kernel: NavigationKernel,
    positions: np.ndarray,
    headings: np.ndarray,
    points: np.ndarray,
    visible: np.ndarray | None = None,
) -> np.ndarray:
    """``v_r(x) = Σ_i K̄(x - R_i) e(θ_i)`` at ``points`` (N, 2) (paper, eq. (3)); shape (N, 2).

    Cost O(N n), evaluated in blocks of points so that temporaries hold at most
    ``_EXACT_BLOCK`` robot-point pairs whatever N is; for very large crowds sample the
    field on a lattice instead (:class:`~meanfield.signs.sampled_field.SampledNavigationField`).
    With ``visible`` (bool, ``(n, N)``: which robot each point sees in a floor plan,
    :meth:`meanfield.geometry.sight.SightLines.mask`), robot ``i``'s term is zero where a wall hides it.
    """
    n = len(positions)
    cos, sin = np.cos(headings), np.sin(headings)
    rx, ry = positions[:, 0][:, None], positions[:, 1][:, None]
    out = np.empty((len(points), 2), dtype=np.result_type(points, positions, headings, float))
    step = max(1, _EXACT_BLOCK // max(n, 1))
    for a in range(0, len(points), step):
        block = points[a : a + step]
        k = kernel.magnitude(block[None, :, 0] - rx, block[None, :, 1] - ry)  # (n, block)
        if visible is not None:
            k = k * visible[:, a : a + step]
        out[a : a + step, 0] = cos @ k
        out[a : a + step, 1] = sin @ k
    return out


_EXACT_BLOCK = 1 << 20
"""Robot-point pairs per block of :func:`navigation_velocity` (8 MB per temporary)."""


class NavigationField:
    """The robots' kernels sampled on the grid's faces at one instant.

    Parameters
    ----------
    kernel : NavigationKernel
    grid : Grid
    positions, headings : ndarray
        Robot states ``R_i`` (n, 2) and ``θ_i`` (n,); complex values are allowed
        (complex-step differentiation in the tests).
    sight : SightLines, optional
        A plan's walls: each robot's kernel is zero on the faces it does not see
        (:mod:`meanfield.geometry.sight`, decided between cells).  The mask is piecewise constant in ``R_i``: the
        rates and moments below differentiate the kernel where it is visible and ignore the jumps.
    """

    def __init__(
        self,
        kernel: NavigationKernel,
        grid: Grid,
        positions: np.ndarray,
        headings: np.ndarray,
        sight: SightLines | None = None,
    ):
        self.kernel = kernel
        self.grid = grid
        positions, headings = np.array(positions), np.array(headings)  # the robots it was built for (dtype kept)
        self.positions = positions if positions.ndim == 2 else positions.reshape(-1, 2)
        self.headings = headings if headings.ndim == 1 else headings.reshape(-1)
        self.cos = np.cos(headings)
        self.sin = np.sin(headings)
        self._sight = sight
        hidden = sight is not None and not sight.trivial
        self.separable = bool(getattr(kernel, "separable", False)) and not hidden
        self._built = False  # the kernels on the faces: computed on first use (_build)

    def cell_sight(self) -> np.ndarray | None:
        """Which cells each robot sees, bool ``(n, nx, ny)`` (:meth:`meanfield.geometry.sight.SightLines.cell_rows`).

        A face is seen when both its cells are (as in :meth:`_build`'s masks); None when no wall
        can hide a sign.  The compiled law (:func:`meanfield.controllers._law_loops.face_law`) reads this
        instead of the masked kernels.
        """
        sight = self._sight
        if sight is None or sight.trivial:
            return None
        return sight.cell_rows(self.grid, self.positions)

    def _build(self) -> None:
        """The kernels and their gradients on the faces (from 1-D factors when the kernel is separable)."""
        if self._built:
            return
        self._built = True
        kernel, grid, positions, sight = self.kernel, self.grid, self.positions, self._sight
        rx = positions[:, 0][:, None]
        ry = positions[:, 1][:, None]
        hidden = sight is not None and not sight.trivial
        separable = bool(getattr(kernel, "separable", False))
        if separable:
            s = -2.0 / kernel.eta
            c = kernel.c
            # one-dimensional factors (robot, coordinate)
            dxf = grid.x_faces[None, :] - rx
            dxc = grid.x[None, :] - rx
            dyf = grid.y_faces[None, :] - ry
            dyc = grid.y[None, :] - ry
            self._fxf = c * kernel.factor(dxf)  # strength folded into the x factors
            self._fxc = c * kernel.factor(dxc)
            self._fyf = kernel.factor(dyf)
            self._fyc = kernel.factor(dyc)
            self._gxf = s * dxf * self._fxf
            self._gxc = s * dxc * self._fxc
            self._gyf = s * dyf * self._fyf
            self._gyc = s * dyc * self._fyc
        if separable and hidden:  # the kernels on the faces from their 1-D factors and the masks, one pass
            sx, sy = sight.face_masks(grid, self.positions)
            n, (nx, ny) = len(positions), grid.shape
            dtype = np.result_type(self._fxf, self._fyc)
            out = tuple(np.empty((n, nx - 1, ny), dtype) for _ in range(3)) + tuple(
                np.empty((n, nx, ny - 1), dtype) for _ in range(3)
            )
            factors = (self._fxf, self._fyc, self._fxc, self._fyf, self._gxf, self._gyc, self._gxc, self._gyf)
            if dtype.kind == "f":
                masked_face_kernels(*factors, sx, sy, out)
            else:  # complex steps (the tests' derivatives): the numpy twin
                masked_face_kernels.fallback(*factors, sx, sy, out)
            self._kx, self._gx_x, self._gy_x, self._ky, self._gx_y, self._gy_y = out
            return
        if not separable:
            Xx, Yx = grid.face_points_x
            Xy, Yy = grid.face_points_y
            rx3 = positions[:, 0][:, None, None]
            ry3 = positions[:, 1][:, None, None]
            self._kx = kernel.magnitude(Xx[None] - rx3, Yx[None] - ry3)
            self._ky = kernel.magnitude(Xy[None] - rx3, Yy[None] - ry3)
            self._gx_x, self._gy_x = kernel.magnitude_gradient(Xx[None] - rx3, Yx[None] - ry3)
            self._gx_y, self._gy_y = kernel.magnitude_gradient(Xy[None] - rx3, Yy[None] - ry3)
        if hidden:  # a kernel that is not separable, masked
            sx, sy = sight.face_masks(grid, self.positions)
            self._kx, self._gx_x, self._gy_x = self._kx * sx, self._gx_x * sx, self._gy_x * sx
            self._ky, self._gx_y, self._gy_y = self._ky * sy, self._gx_y * sy, self._gy_y * sy

    # ---------------------------------------------------------------- the field itself
    def velocity(self) -> FaceField:
        """``v_r`` on the faces: x-component on x-faces, y-component on y-faces."""
        self._build()
        if self.separable:
            vx = (self.cos[:, None] * self._fxf).T @ self._fyc
            vy = (self.sin[:, None] * self._fxc).T @ self._fyf
            return vx, vy
        return np.tensordot(self.cos, self._kx, 1), np.tensordot(self.sin, self._ky, 1)

    def velocity_rate(self, u: np.ndarray, omega: np.ndarray) -> FaceField:
        """``∂_t v_r = Σ_i (-K_ξ^i u_i + K_θ^i ω_i)`` on the faces (paper, eq. (5))."""
        # -K_ξ u = -e(θ) (∇K̄ · u);  K_θ ω = K̄ e⊥(θ) ω
        self._build()
        ux, uy = u[:, 0], u[:, 1]
        if self.separable:
            ax = -self.cos * ux
            ay = -self.cos * uy
            bw = -self.sin * omega
            fx = (
                (ax[:, None] * self._gxf).T @ self._fyc
                + (ay[:, None] * self._fxf).T @ self._gyc
                + (bw[:, None] * self._fxf).T @ self._fyc
            )
            ax = -self.sin * ux
            ay = -self.sin * uy
            bw = self.cos * omega
            fy = (
                (ax[:, None] * self._gxc).T @ self._fyf
                + (ay[:, None] * self._fxc).T @ self._gyf
                + (bw[:, None] * self._fxc).T @ self._fyf
            )
            return fx, fy
        fx = np.tensordot(-self.cos * ux, self._gx_x, 1) + np.tensordot(-self.cos * uy, self._gy_x, 1)
        fx = fx + np.tensordot(-self.sin * omega, self._kx, 1)
        fy = np.tensordot(-self.sin * ux, self._gx_y, 1) + np.tensordot(-self.sin * uy, self._gy_y, 1)
        fy = fy + np.tensordot(self.cos * omega, self._ky, 1)
        return fx, fy

    # ---------------------------------------------------------------- projections
    def moments(self, F: FaceField) -> tuple[np.ndarray, np.ndarray]:
        """``b_i = ∫ Fᵀ K_ξ^i dx`` (n, 2) and ``g_i = ∫ Fᵀ K_θ^i dx`` (n,) for a face field F.

        With ``F = ṽ`` these are the ``b_i``, ``g_i`` of the robot law (paper, eq. (8)).
        Integrals use the grid's face inner product, so ``Σ_i b_i·u_i - g_i ω_i`` equals
        ``-<F, ∂_t v_r>`` exactly.
        """
        self._build()
        Wx = self.grid.weight_x * F[0]
        Wy = self.grid.weight_y * F[1]
        if self.separable:
            # x-faces: factors (x at faces, y at centres); y-faces: (x at centres, y at faces)
            Px = self._fxf @ Wx  # (n, ny)
            Gx = self._gxf @ Wx
            Py = self._fxc @ Wy  # (n, ny-1)
            Gy = self._gxc @ Wy
            s0x = (Px * self._fyc).sum(1)
            s1x = (Gx * self._fyc).sum(1)
            s2x = (Px * self._gyc).sum(1)
            s0y = (Py * self._fyf).sum(1)
            s1y = (Gy * self._fyf).sum(1)
            s2y = (Py * self._gyf).sum(1)
        else:  # the kernels on every face (masked by walls, or not separable): one pass
            arrays = (self._kx, self._gx_x, self._gy_x, self._ky, self._gx_y, self._gy_y, Wx, Wy)
            out = np.empty((6, len(self.positions)), np.result_type(*arrays))
            if out.dtype.kind == "f":
                face_moments(*arrays, out)
            else:  # complex steps (the tests' derivatives): the numpy twin
                face_moments.fallback(*arrays, out)
            s0x, s1x, s2x, s0y, s1y, s2y = out
        b = np.stack([self.cos * s1x + self.sin * s1y, self.cos * s2x + self.sin * s2y], axis=1)
        g = -self.sin * s0x + self.cos * s0y
        return b, g
