"""The humans' local view: follow the signs only when a robot is near, else walk randomly.

The paper's Unity study (Section V-B) drops the assumption of eq. (1) that every human
feels every robot: a human follows the navigation field ``v_r`` (eq. (3)) only while a
robot is within its view radius ``R``, and walks randomly otherwise.  This module is that
behaviour, shared by both crowd backends (the point-mass SDE and the JuPedSim bodies), so
that the effect of view gating can be separated from the effect of bodies.

The random walk is the persistent (active Brownian) walk of speed ``s`` whose heading
diffuses with rate ``D_r`` (the scenario's ``view.turning_rate``, rad²/s)::

    dθ_j = sqrt(2 D_r) dW_j,      walking velocity  s (cos θ_j, sin θ_j),

so ``E[cos(θ(t) − θ(0))] = exp(−D_r t)``: the heading persists for ``1/D_r`` seconds and
the walk's mean squared displacement grows like ``2 s² t / D_r`` at long times.  A walker
whose next step would leave Ω turns as if reflected by the wall.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.crowds._view_loops import in_view, turn_walkers
from meanfield.errors import ParameterError
from meanfield.geometry.region import Region

__all__ = ["LocalView", "robots_in_view"]


def robots_in_view(humans: np.ndarray, robots: np.ndarray, radius: float) -> np.ndarray:
    """Boolean mask, shape (N,): which humans have some robot within ``radius``.

    Exact, in O(N + n·M) for M lattice cells rather than O(N n): the bounding box of the
    humans is cut into cells about ``radius/8`` wide (at most ``_VIEW_CELLS`` of them); a
    cell whose farthest point is within ``radius`` of some robot is seen whole, one whose
    nearest point is beyond ``radius`` of every robot is unseen whole, and only the humans
    of the remaining cells (a band about one cell wide around each view circle) are
    compared with the robots one by one.

    Parameters
    ----------
    humans : ndarray, shape (N, 2)
    robots : ndarray, shape (n, 2)
    radius : float
        View radius ``R > 0``; ``inf`` means every human sees the robots.
    """
    if math.isinf(radius):
        return np.ones(len(humans), dtype=bool)
    if len(humans) * len(robots) <= _DIRECT_PAIRS or len(robots) == 0:
        return _in_view_direct(humans, robots, radius)
    # column by column: numpy's axis-0 reduction of an (N, 2) array is ~20× slower
    lo = np.array([humans[:, 0].min(), humans[:, 1].min()])
    span = np.maximum(np.array([humans[:, 0].max(), humans[:, 1].max()]) - lo, 1e-300)
    cells = np.clip(np.ceil(8.0 * span / radius), 1, int(math.sqrt(_VIEW_CELLS))).astype(int)
    size = span / cells
    edges_x = lo[0] + size[0] * np.arange(cells[0] + 1)
    edges_y = lo[1] + size[1] * np.arange(cells[1] + 1)
    # per robot and cell, nearest and farthest squared distance, separably in x and y
    rx, ry = robots[:, 0][:, None], robots[:, 1][:, None]
    near_x = np.maximum(np.maximum(edges_x[:-1] - rx, rx - edges_x[1:]), 0.0) ** 2  # (n, cx)
    near_y = np.maximum(np.maximum(edges_y[:-1] - ry, ry - edges_y[1:]), 0.0) ** 2
    far_x = np.maximum(np.abs(edges_x[:-1] - rx), np.abs(edges_x[1:] - rx)) ** 2
    far_y = np.maximum(np.abs(edges_y[:-1] - ry), np.abs(edges_y[1:] - ry)) ** 2
    r2 = radius * radius
    some_near = ((near_x[:, :, None] + near_y[:, None, :]) <= r2).any(axis=0)  # (cx, cy)
    all_seen = ((far_x[:, :, None] + far_y[:, None, :]) <= r2).any(axis=0)
    i = np.minimum(((humans[:, 0] - lo[0]) / size[0]).astype(np.intp), cells[0] - 1)
    j = np.minimum(((humans[:, 1] - lo[1]) / size[1]).astype(np.intp), cells[1] - 1)
    flat = i * cells[1] + j
    seen = all_seen.ravel()[flat]
    unsure = np.flatnonzero(some_near.ravel()[flat] & ~seen)
    if len(unsure):
        seen[unsure] = _in_view_direct(humans[unsure], robots, radius)
    return seen


def _in_view_direct(humans: np.ndarray, robots: np.ndarray, radius: float) -> np.ndarray:
    """Every human against every robot: one compiled pass (:func:`meanfield.crowds._view_loops.in_view`)."""
    humans, robots = np.ascontiguousarray(humans, float), np.ascontiguousarray(robots, float)
    return in_view(humans, robots, radius * radius, _NOTHING_HIDDEN, False, np.empty(len(humans), dtype=bool))


_NOTHING_HIDDEN = np.ones((0, 0), dtype=bool)
_DIRECT_PAIRS = 200_000
"""Below this many human-robot pairs :func:`robots_in_view` compares every pair."""
_VIEW_CELLS = 65_536
"""At most this many lattice cells in :func:`robots_in_view` (256 a side)."""


class LocalView:
    """View gating and the persistent random walk of the humans who see no robot.

    Parameters
    ----------
    n : int
        Number of humans.
    radius : float or None
        View radius ``R > 0`` (metres of the scenario); ``None``: no gating.
    walk_speed : float
        Speed ``s >= 0`` of the random walk.
    turning_rate : float
        Heading diffusion ``D_r >= 0`` (rad²/s).
    domain : Region
        Ω, whose walls turn the walkers.
    rng : numpy.random.Generator
        Source of the initial headings (uniform) and of the heading increments.
    clearance : float
        Extra distance to the wall at which a walker turns (a body's radius).
    """

    def __init__(
        self,
        n: int,
        radius: float | None,
        walk_speed: float,
        turning_rate: float,
        domain: Region,
        rng: np.random.Generator,
        clearance: float = 0.0,
    ):
        if radius is not None and not radius > 0:
            raise ParameterError("view.radius", radius, 'a view radius > 0, or "none" (no gating)')
        if not walk_speed >= 0:
            raise ParameterError("view.walk_speed", walk_speed, "a speed >= 0")
        if not turning_rate >= 0:
            raise ParameterError("view.turning_rate", turning_rate, "a rate >= 0 (rad²/s)")
        self.radius = math.inf if radius is None else float(radius)
        self.walk_speed = float(walk_speed)
        self.turning_rate = float(turning_rate)
        self.domain = domain
        self.rng = rng
        self.clearance = float(clearance)
        self._n = int(n)
        self._headings: np.ndarray | None = None  # drawn at the first step (see headings)
        self.seen = np.ones(n, dtype=bool)

    def walls_changed(self, change: Any) -> None:
        """The walkers turn at the walls of ``change.region`` from now on (a ``block`` event)."""
        self.domain = change.region

    @classmethod
    def blind(
        cls,
        n: int,
        walk_speed: float,
        turning_rate: float,
        domain: Region,
        rng: np.random.Generator,
        clearance: float = 0.0,
    ) -> LocalView:
        """A view that sees no robot: everyone walks (the uninformed crowd, :mod:`meanfield.crowds.guidance`;
        the humans who ignore the signs, :class:`~meanfield.crowds.agent_crowd.Individuals`), turning
        ``clearance`` (a body's radius) before the walls."""
        view = cls(n, 1.0, walk_speed, turning_rate, domain, rng, clearance)
        view.radius = 0.0
        view.seen = np.zeros(n, dtype=bool)
        return view

    @property
    def headings(self) -> np.ndarray:
        """The walkers' headings θ_j (rad), uniform at the start.

        Drawn from the run's generator at the first use (the first :meth:`gate`), so that a
        crowd can be built before the robots while the draws keep the order of the model:
        humans, robots' headings, walkers' headings, then the steps' noise.
        """
        if self._headings is None:
            self._headings = self.rng.uniform(0.0, 2 * math.pi, self._n) if self.gated else np.zeros(self._n)
        return self._headings

    @headings.setter
    def headings(self, value: np.ndarray) -> None:
        self._headings = np.asarray(value, float)

    @property
    def gated(self) -> bool:
        """True when the view radius is finite (the Unity study's behaviour)."""
        return self.radius != math.inf  # (radius > 0, inf without gating, 0 when blind: never NaN)

    def advance(self, dt: float) -> None:
        """One Euler–Maruyama step of the heading diffusion ``dθ = sqrt(2 D_r) dW``."""
        if self.gated and self.turning_rate > 0:
            self.headings += math.sqrt(2.0 * self.turning_rate * dt) * self.rng.standard_normal(len(self.headings))

    def walk_velocity(self, positions: np.ndarray, dt: float, which: np.ndarray | None = None) -> np.ndarray:
        """Walking velocity at ``positions`` (rows ``which`` of the crowd), turned away from walls.

        A heading whose step of length ``s dt + clearance`` would leave Ω is replaced by
        the direction to that step's mirror image in the wall (a specular turn).  In a plan
        (a region that ``reflects_along_paths``) the step is followed from the walker and
        mirrored at the first wall it meets, a thin wall or a pillar included.

        Parameters
        ----------
        positions : ndarray, shape (M, 2)
            Positions of the humans ``which`` (all N when ``which`` is None).
        dt : float
        which : ndarray of int, optional
            Their indices in the crowd (their headings).
        """
        idx = np.arange(len(self.headings)) if which is None else np.asarray(which)
        theta = self.headings[idx]
        e = np.column_stack([np.cos(theta), np.sin(theta)])
        reach = self.walk_speed * dt + self.clearance
        if reach > 0 and len(idx):
            ahead = positions + reach * e
            if getattr(self.domain, "reflects_along_paths", False):  # a plan: each step followed, mirrored at its wall
                start = np.ascontiguousarray(positions, float)
                mirrored = self.domain.reflect(ahead.copy(), start)
                turn_walkers(start, ahead, mirrored, e, self.headings, np.ascontiguousarray(idx, np.intp))
                return self.walk_speed * e
            out = ~self.domain.contains(ahead[:, 0], ahead[:, 1])
            if out.any():
                d = self.domain.reflect(ahead[out].copy()) - positions[out]
                norm = np.hypot(d[:, 0], d[:, 1])
                ok = norm > 0
                rows = np.flatnonzero(out)[ok]
                e[rows] = d[ok] / norm[ok, None]
                self.headings[idx[rows]] = np.arctan2(d[ok, 1], d[ok, 0])
        return self.walk_speed * e

    def gate(
        self,
        v_r: np.ndarray,
        positions: np.ndarray,
        robots: np.ndarray,
        dt: float,
        visible: np.ndarray | None = None,
    ) -> np.ndarray:
        """Replace, in place, the navigation velocity of every human who sees no robot by its walk.

        Parameters
        ----------
        v_r : ndarray, shape (N, 2)
            The navigation velocity (eq. (3)) at each human.
        positions : ndarray, shape (N, 2)
        robots : ndarray, shape (n, 2)
        dt : float
            The control period (the walkers' look-ahead).
        visible : ndarray of bool, shape (n, N), optional
            In a floor plan, which robot each human sees (:meth:`meanfield.geometry.sight.SightLines.mask`):
            a robot within the radius but behind a wall is not in view.

        Returns
        -------
        ndarray
            ``v_r``, with the walkers' rows replaced; :attr:`seen` holds who sees a robot.
        """
        if not self.gated:
            return v_r
        self.headings  # noqa: B018 -- the walkers' initial headings are drawn here, at the first step
        if visible is None:
            self.seen = robots_in_view(positions, robots, self.radius)
        else:  # a robot in reach but behind a wall is not seen: one pass over the pairs (n × N, as visible)
            humans, robots = np.ascontiguousarray(positions, float), np.ascontiguousarray(robots, float)
            visible = np.ascontiguousarray(visible, bool)
            r2 = self.radius * self.radius
            self.seen = in_view(humans, robots, r2, visible, True, np.empty(len(humans), dtype=bool))
        walkers = np.flatnonzero(~self.seen)
        if len(walkers):
            v_r[walkers] = self.walk_velocity(positions[walkers], dt, walkers)
        return v_r
