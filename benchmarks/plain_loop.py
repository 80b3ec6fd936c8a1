"""The paper's closed loop in plain numpy, written straight from the equations: the speed anchor.

No module of the toolkit is used: this is what a careful reader of the paper would write
in an afternoon, vectorized with numpy, with no trick (no separable kernels, no binning,
no compiled loop, no reuse of work arrays).  One step, for ``N`` humans, ``n`` robots and
an ``m × m`` grid of the unit square:

1. the density: a Gaussian KDE of the humans summed at every cell centre (``N m²``
   exponentials), with the reflecting walls' mirror images, normalized to unit mass;
2. Step I (eq. (6)): ``v_d = -(α/ρ) ∇ρ̃ + σ∇ρ/ρ`` on the faces, with the saturating schedule
   ``α/ρ = α₀ / (ρ + ρ_floor)``; ``∂_t v_d`` by a backward difference;
3. Step II (eq. (8)): each robot's kernel ``K̄(x - R_i)`` and its gradient at every face
   (``n × faces`` exponentials), ``ṽ = Σ K̄ e(θ_i) - v_d``, the integrals ``b_i``, ``g_i``,
   ``A``, the minimum-norm β/γ, ``u_i = k_u b_i + A b_i / Z``, ``ω_i = -k_ω g_i - A g_i / Z``,
   saturated at the speed limits;
4. the humans: ``v_r`` at each one (``N n`` exponentials), the Euler–Maruyama step,
   reflection at the walls; the robots: an Euler step, kept in the room.

Its arithmetic is that of :class:`meanfield.ClosedLoop` on the ``paper`` scenario (same
parameters), so their steps per second compare the implementations, not the problems.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PlainPaperLoop"]


class PlainPaperLoop:
    """The ``paper`` scenario's closed loop in plain numpy (see the module's doc)."""

    def __init__(self, seed: int = 0, n_humans: int = 200, n_robots: int = 16, cells: int = 30, dt: float = 0.01):
        rng = np.random.default_rng(seed)
        self.rng, self.dt, self.m = rng, dt, cells
        self.c, self.eta, self.sigma, self.h = 0.2, 0.05, 0.015, 0.08
        self.alpha0, self.rho_floor, self.k_u, self.k_w = 0.2, 2.0, 10.0, 10.0
        self.u_max, self.w_max = 0.2, 3.0
        self.X = rng.uniform(0, 1, (n_humans, 2))
        side = int(np.ceil(np.sqrt(n_robots)))
        lattice = (np.arange(side) + 0.5) / side
        gx, gy = np.meshgrid(lattice, lattice, indexing="ij")
        self.R = np.column_stack([gx.ravel(), gy.ravel()])[:n_robots].copy()
        self.theta = rng.uniform(0, 2 * np.pi, n_robots)
        d = 1.0 / cells
        self.d = d
        centres = (np.arange(cells) + 0.5) * d
        self.xc, self.yc = np.meshgrid(centres, centres, indexing="ij")
        faces = np.arange(1, cells) * d
        self.fx = np.meshgrid(faces, centres, indexing="ij")  # x-faces (between cells along x)
        self.fy = np.meshgrid(centres, faces, indexing="ij")  # y-faces
        target = np.exp(-((self.xc - 1.0) ** 2 + (self.yc - 1.0) ** 2) / (2 * 0.15**2))
        self.target = target / (target.sum() * d * d)
        self.previous_vd = None

    def density(self) -> np.ndarray:
        """Gaussian KDE at the cell centres, with the walls' mirror images; unit mass on the grid."""
        rho = np.zeros((self.m, self.m))
        for mx in (lambda x: x, lambda x: -x, lambda x: 2 - x):
            for my in (lambda y: y, lambda y: -y, lambda y: 2 - y):
                px, py = mx(self.X[:, 0]), my(self.X[:, 1])
                r2 = (self.xc[..., None] - px) ** 2 + (self.yc[..., None] - py) ** 2
                rho += np.exp(-r2 / (2 * self.h**2)).sum(-1)
        return rho / (rho.sum() * self.d * self.d)

    def robot_inputs(self, rho: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Steps I and II (eqs. (6) and (8)) with the minimum-norm β/γ."""
        d = self.d
        rt = rho - self.target
        rf = (0.5 * (rho[1:] + rho[:-1]), 0.5 * (rho[:, 1:] + rho[:, :-1]))
        grad_t = ((rt[1:] - rt[:-1]) / d, (rt[:, 1:] - rt[:, :-1]) / d)
        grad_r = ((rho[1:] - rho[:-1]) / d, (rho[:, 1:] - rho[:, :-1]) / d)
        vd = [-(self.alpha0 / (rf[k] + self.rho_floor)) * grad_t[k] + self.sigma * grad_r[k] / rf[k] for k in (0, 1)]
        if self.previous_vd is None:
            dvd = [np.zeros_like(vd[0]), np.zeros_like(vd[1])]
        else:
            dvd = [(vd[k] - self.previous_vd[k]) / self.dt for k in (0, 1)]
        self.previous_vd = vd
        e = np.column_stack([np.cos(self.theta), np.sin(self.theta)])
        kern, grad = [], []
        for px, py in (self.fx, self.fy):
            xi_x = px[None] - self.R[:, 0, None, None]
            xi_y = py[None] - self.R[:, 1, None, None]
            k = self.c * np.exp(-(xi_x**2 + xi_y**2) / self.eta)
            kern.append(k)
            grad.append((-2 / self.eta * xi_x * k, -2 / self.eta * xi_y * k))
        vr = [np.einsum("i,ijk->jk", e[:, k], kern[k]) for k in (0, 1)]
        vt = [vr[k] - vd[k] for k in (0, 1)]
        w = d * d
        # b_i = ∫ ṽᵀ K_ξ^i = ∫ (ṽ·e_i) ∇K̄_i ; g_i = ∫ ṽᵀ K_θ^i = ∫ K̄_i (ṽ·e⊥_i)
        b = np.zeros((len(self.R), 2))
        g = np.zeros(len(self.R))
        for k in (0, 1):
            proj = e[:, k, None, None] * vt[k][None]
            b[:, 0] += (proj * grad[k][0]).sum((1, 2)) * w
            b[:, 1] += (proj * grad[k][1]).sum((1, 2)) * w
            perp = -e[:, 1] if k == 0 else e[:, 0]
            g += (perp[:, None, None] * kern[k] * vt[k][None]).sum((1, 2)) * w
        A = sum((vt[k] * (rf[k] * grad_t[k] - dvd[k])).sum() * w for k in (0, 1))
        Z = (b**2).sum() + (g**2).sum()
        u = self.k_u * b + (A / Z) * b
        omega = -self.k_w * g - (A / Z) * g
        speed = np.hypot(u[:, 0], u[:, 1])
        u = np.where((speed > self.u_max)[:, None], u * (self.u_max / np.maximum(speed, 1e-300))[:, None], u)
        return u, np.clip(omega, -self.w_max, self.w_max)

    def step(self, t: float) -> None:
        """One closed-loop step: observe, act, move the humans and the robots."""
        u, omega = self.robot_inputs(self.density(), t)
        e = np.column_stack([np.cos(self.theta), np.sin(self.theta)])
        dx = self.X[:, None, :] - self.R[None]
        k = self.c * np.exp(-(dx**2).sum(-1) / self.eta)
        v = k @ e
        self.X = self.X + v * self.dt + np.sqrt(2 * self.sigma * self.dt) * self.rng.standard_normal(self.X.shape)
        self.X = np.abs(self.X)
        self.X = np.where(self.X > 1, 2 - self.X, self.X)
        self.R = np.clip(self.R + u * self.dt, 0, 1)
        self.theta = np.mod(self.theta + omega * self.dt, 2 * np.pi)

    def run(self, steps: int) -> PlainPaperLoop:
        for k in range(steps):
            self.step(k * self.dt)
        return self
