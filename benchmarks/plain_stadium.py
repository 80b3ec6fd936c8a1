"""The ``stadium`` scenario's closed-loop step in plain numpy, written straight from the equations: a frozen anchor.

The step uses no module of the toolkit (its law is :mod:`benchmarks.plain_loop`'s, the paper's frozen
anchor): only :func:`stadium_numbers` imports ``meanfield``,
and only to read the scenario's numbers (counts, grid, bandwidth, gains, limits), so the
anchor does not change when the toolkit does.  It is what a careful reader of the paper
would write for a million humans, vectorized with numpy, with no trick (no lattice for the
navigation field, no compiled loop, no reuse of work arrays, no cut-off of the kernels).
One step, for ``N`` humans, ``n`` robots and an ``m × m`` grid of the unit square:

1. the density: a Gaussian KDE of the humans on the grid, **binned**: the humans are
   counted in the grid's own cells (``np.histogram2d``), and the counts, placed at the cell
   centres, are smoothed by the Gaussian of bandwidth ``h`` with the reflecting walls'
   mirror images, then normalized to unit mass.  This is the straightforward way at this
   size: the direct sum at every cell centre (``benchmarks/plain_loop.py``'s way at
   N = 200) costs ``9 N m²`` ≈ 1.5·10¹¹ exponentials at N = 10⁶, minutes per step, and
   nobody would write it; counting in cells and blurring the histogram is the textbook
   estimate (MATLAB's ``histcounts2`` then ``conv2``).  The blur is the dense
   ``m × m`` kernel matrix applied along each axis, ``ρ = G C Gᵀ`` -- the 2-D Gaussian's
   product form, ``O(m³)``, negligible beside the ``O(N n)`` of item 4.  It is not the
   exact sum: a human moves by up to half a cell to its cell's centre (the error is
   measured in ``tests/benchmarks/test_plain_stadium.py``);
2. Step I (eq. (6)): ``v_d = -(α/ρ) ∇ρ̃ + σ∇ρ/ρ`` on the faces, with the saturating schedule
   ``α/ρ = α₀ / (ρ + ρ_floor)``; ``∂_t v_d`` by a backward difference (zero at the first
   step);
3. Step II (eq. (8)): each robot's kernel ``K̄(x - R_i) = c exp(-|x - R_i|²/η)`` (eq. (3))
   and its gradient at every face (``n × faces`` exponentials), ``ṽ = Σ K̄ e(θ_i) - v_d``,
   the integrals ``b_i``, ``g_i``, ``A``, the minimum-norm β/γ,
   ``u_i = k_u b_i + A b_i / Z``, ``ω_i = -k_ω g_i - A g_i / Z``, saturated at the speed
   limits (eq. (2)'s);
4. the humans: ``v_r = Σ_i c exp(-|x - R_i|²/η) (cos θ_i, sin θ_i)`` (eq. (3)) summed
   exactly at each one (``N n`` exponentials), one robot at a time -- the sum as written,
   and the plain way's memory: ``plain_loop``'s ``(N, n, 2)`` array would be 1 GB here --
   then the Euler–Maruyama step of eq. (1) with numpy's normal draws and reflection at the
   walls of the unit box; the robots: an Euler step of eq. (2), kept in the room.

Its arithmetic is that of :class:`meanfield.ClosedLoop` on the ``stadium`` scenario with
``crowd.field_evaluation = "exact"`` (same parameters), except the KDE's binning and the
random draws, so the two steps' costs compare implementations, not problems.  Frozen:
change it only to fix a mistake, and say so where its figures are quoted (docs/scale.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from benchmarks.plain_loop import PlainPaperLoop

__all__ = ["PlainStadiumStep", "stadium_numbers"]


def stadium_numbers(n_humans: int | None = None, seed: int = 0) -> dict[str, Any]:
    """The ``stadium`` scenario's numbers, read from the toolkit (the only use of ``meanfield`` here).

    Parameters
    ----------
    n_humans : int, optional
        Replaces the scenario's ``crowd.n`` (10⁶).
    seed : int
        The scenario's seed (only read; the plain step draws with its own generator).

    Returns
    -------
    dict
        The keyword arguments of :class:`PlainStadiumStep` but ``seed`` and the state.
    """
    from meanfield.scenarios.scenario import stadium_scenario

    sc = stadium_scenario(seed=seed)
    c = sc.controller
    return {
        "n_humans": int(sc.crowd.n if n_humans is None else n_humans),
        "n_robots": int(sc.robots.n),
        "cells": int(sc.grid.cells[0]),
        "dt": float(sc.dt),
        "c": float(sc.kernel.c),
        "eta": float(sc.kernel.eta),
        "sigma": float(sc.crowd.sigma),
        "h": float(sc.density.bandwidth),
        "alpha0": float(c.alpha),
        "rho_floor": float(c.rho_floor),
        "k_u": float(c.k_u),
        "k_w": float(c.k_omega),
        "u_max": float(sc.robots.u_max),
        "w_max": float(sc.robots.omega_max),
        "target_center": tuple(float(v) for v in sc.target.center),
        "target_std": float(sc.target.std),
    }


class PlainStadiumStep:
    """The ``stadium`` scenario's closed loop in plain numpy (see the module's doc).

    Parameters
    ----------
    seed : int
        Seed of the generator of the initial state and of the noise.
    n_humans, n_robots, cells : int
        ``N``, ``n``, and ``m`` of the ``m × m`` grid of the unit square.
    dt : float
        The time step.
    c, eta : float
        The kernel ``K̄(ξ) = c exp(-|ξ|²/η)`` (eq. (3)).
    sigma : float
        The humans' diffusion (eq. (1): ``dX = v_r dt + sqrt(2σ) dB``).
    h : float
        The KDE's bandwidth.
    alpha0, rho_floor : float
        Step I's saturating gain ``α(ρ) = α₀ ρ / (ρ + ρ_floor)`` (eq. (6)).
    k_u, k_w : float
        Step II's gains (eq. (8)).
    u_max, w_max : float
        The robots' speed limits (eq. (2)).
    target_center, target_std : tuple of float, float
        The Gaussian target ``ρ_*``, normalized to unit mass on the grid.
    positions, robots, headings : ndarray, optional
        The initial state ``(N, 2)``, ``(n, 2)``, ``(n,)``; by default humans uniform, robots
        on a square lattice, headings uniform (the scenario's layout).
    """

    def __init__(
        self,
        seed: int = 0,
        n_humans: int = 1_000_000,
        n_robots: int = 64,
        cells: int = 128,
        dt: float = 0.01,
        c: float = 0.2,
        eta: float = 0.05,
        sigma: float = 0.015,
        h: float = 0.03,
        alpha0: float = 0.2,
        rho_floor: float = 2.0,
        k_u: float = 10.0,
        k_w: float = 10.0,
        u_max: float = 0.2,
        w_max: float = 3.0,
        target_center: tuple[float, float] = (1.0, 1.0),
        target_std: float = 0.15,
        positions: np.ndarray | None = None,
        robots: np.ndarray | None = None,
        headings: np.ndarray | None = None,
    ):
        rng = np.random.default_rng(seed)
        self.rng, self.dt, self.m = rng, dt, cells
        self.c, self.eta, self.sigma, self.h = c, eta, sigma, h
        self.alpha0, self.rho_floor, self.k_u, self.k_w = alpha0, rho_floor, k_u, k_w
        self.u_max, self.w_max = u_max, w_max
        self.X = rng.uniform(0, 1, (n_humans, 2)) if positions is None else np.array(positions, float)
        if robots is None:
            side = int(np.ceil(np.sqrt(n_robots)))
            lattice = (np.arange(side) + 0.5) / side
            gx, gy = np.meshgrid(lattice, lattice, indexing="ij")
            robots = np.column_stack([gx.ravel(), gy.ravel()])[:n_robots]
        self.R = np.array(robots, float)
        self.theta = rng.uniform(0, 2 * np.pi, n_robots) if headings is None else np.array(headings, float)
        d = 1.0 / cells
        self.d = d
        centres = (np.arange(cells) + 0.5) * d
        self.centres = centres
        self.xc, self.yc = np.meshgrid(centres, centres, indexing="ij")
        faces = np.arange(1, cells) * d
        self.fx = np.meshgrid(faces, centres, indexing="ij")  # x-faces (between cells along x)
        self.fy = np.meshgrid(centres, faces, indexing="ij")  # y-faces
        cx, cy = target_center
        target = np.exp(-((self.xc - cx) ** 2 + (self.yc - cy) ** 2) / (2 * target_std**2))
        self.target = target / (target.sum() * d * d)
        self.previous_vd: list[np.ndarray] | None = None

    def density(self) -> np.ndarray:
        """The binned Gaussian KDE at the cell centres, with the walls' mirror images; unit mass on the grid.

        Returns
        -------
        ndarray, shape (m, m)
        """
        edges = np.linspace(0.0, 1.0, self.m + 1)
        counts, _, _ = np.histogram2d(self.X[:, 0], self.X[:, 1], bins=(edges, edges))
        x = self.centres
        g = np.zeros((self.m, self.m))  # g[a, b]: weight of the cell b's count at the centre a, images included
        for image in (x, -x, 2 - x):
            g += np.exp(-((x[:, None] - image[None, :]) ** 2) / (2 * self.h**2))
        rho = g @ counts @ g.T
        return rho / (rho.sum() * self.d * self.d)

    def robot_inputs(self, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Steps I and II (eqs. (6) and (8)) with the minimum-norm β/γ, saturated (eq. (2)).

        The paper loop's own law (:meth:`benchmarks.plain_loop.PlainPaperLoop.robot_inputs`, another
        frozen anchor), run on this step's fields of the same names: one copy of the law.

        Parameters
        ----------
        rho : ndarray, shape (m, m)
            The density at the cell centres.

        Returns
        -------
        u : ndarray, shape (n, 2)
        omega : ndarray, shape (n,)
        """
        return PlainPaperLoop.robot_inputs(self, rho, 0.0)  # type: ignore[arg-type]  # the same law, the same fields

    def navigation_velocity(self, points: np.ndarray) -> np.ndarray:
        """``v_r(x) = Σ_i c exp(-|x - R_i|²/η) (cos θ_i, sin θ_i)`` (eq. (3)) at each point, exactly.

        Parameters
        ----------
        points : ndarray, shape (P, 2)

        Returns
        -------
        ndarray, shape (P, 2)
        """
        v = np.zeros_like(points)
        for (rx, ry), th in zip(self.R, self.theta, strict=True):
            k = self.c * np.exp(-((points[:, 0] - rx) ** 2 + (points[:, 1] - ry) ** 2) / self.eta)
            v[:, 0] += k * np.cos(th)
            v[:, 1] += k * np.sin(th)
        return v

    def step(self) -> None:
        """One closed-loop step: observe (KDE), act (eqs. (6), (8)), move the humans (eqs. (1), (3)) and robots."""
        u, omega = self.robot_inputs(self.density())
        v = self.navigation_velocity(self.X)
        self.X = self.X + v * self.dt + np.sqrt(2 * self.sigma * self.dt) * self.rng.standard_normal(self.X.shape)
        self.X = np.abs(self.X)
        self.X = np.where(self.X > 1, 2 - self.X, self.X)
        self.R = np.clip(self.R + u * self.dt, 0, 1)
        self.theta = np.mod(self.theta + omega * self.dt, 2 * np.pi)

    def run(self, steps: int) -> PlainStadiumStep:
        """``steps`` closed-loop steps."""
        for _ in range(steps):
            self.step()
        return self
