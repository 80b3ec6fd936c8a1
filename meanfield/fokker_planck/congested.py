"""Congestion in the crowd's Fokker–Planck equation: the LWR flux on the faces and its two steppers.

With a fundamental diagram ``g`` (the speed factor of :mod:`meanfield.crowds.congestion`, taken
here as any object with ``speed_factor``, ``capacity``, ``free_speed`` and ``rho_max``) and a
crowd of ``N`` people, eq. (4) becomes the nonlinear equation (docs/fokker_planck.md,
"Congestion")::

    ∂_t ρ + ∇·( ρ g(Nρ) v ) = ∇·( σ∇ρ + ρ∇σ )        (C)

with ``v`` the total drift (prescribed velocity, robots, disturbance, ``-∇U``, interaction) and
``Nρ`` the density in persons per m².  Along each face the advective flux is the flux
``a f(ρ)``, ``f(ρ) = ρ g(Nρ)``, of the Lighthill–Whitham–Richards (LWR) model with the face's
normal velocity ``a``, discretised by Godunov's flux in its supply–demand form (Daganzo's cell
transmission model)::

    F = a⁺ min(D(ρ_L), S(ρ_R)) − a⁻ min(D(ρ_R), S(ρ_L)),
    D(ρ) = f(min(ρ, ρ_c)),   S(ρ) = f(max(ρ, ρ_c)),                  (G)

``ρ_c`` the density of the largest flow (the diagram's capacity).  No flux enters a cell at
the jam density ``ρ_max / N`` (``S = 0`` there).  An exit is a face to an empty outside,
whose supply is the capacity: the outflow per metre of door is
``min(a_n⁺ D(ρ) + σρ/d, q_max / N)`` (``a_n`` the drift's outward normal component in the
cell, ``σρ/d`` the Dirichlet exit's diffusive outflow of :class:`~meanfield.geometry.exits.ExitSink`),
so that a door of width ``b`` never passes more than ``q_max b`` persons per second.

The diffusion keeps the Scharfetter–Gummel coefficients of :mod:`~meanfield.fokker_planck.solver`
with the drift ``−∇σ`` only (central differences for a constant σ).  Two methods:

``"explicit"`` (:class:`CongestedExplicitStepper`)
    Heun's method (SSP Runge–Kutta 2) on the whole right-hand side.  Monotone, hence
    ``0 <= ρ <= ρ_max/N`` (for a constant σ), when
    ``dt <= min_c V_c / (Σ_faces L |a| ℓ + Σ_faces c_diff + Σ_exits (L a_n⁺ ℓ + k V))`` (B),
    ``L = max |f'|`` (1 for Greenshields' and Weidmann's diagrams).
``"split"`` (:class:`CongestedSplitStepper`)
    Lie splitting: a Heun step of the advection and the exits (bound (B) without the diffusion
    terms), then the backward-Euler diffusion sweeps along x and y of ``"split"`` (M-matrices
    whose discrete maximum principle keeps ``ρ <= ρ_max/N`` for a constant σ, any ``dt``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from meanfield.errors import ParameterError, positive_number
from meanfield.fokker_planck.stepping import Stepper, _Coefficients, _LineStepper, _StepTooLarge
from meanfield.geometry.grid import FaceField, Grid

if TYPE_CHECKING:
    from meanfield.geometry.exits import ExitSink

__all__ = [
    "CongestedFlux",
    "door_lengths",
    "exit_normals",
    "CongestedExplicitStepper",
    "CongestedSplitStepper",
    "CONGESTED_STEPPERS",
]


class CongestedFlux:
    """The LWR flux ``f(ρ) = ρ g(Nρ)`` of a fundamental diagram, for unit-mass densities, and Godunov's flux (G).

    Parameters
    ----------
    diagram : FundamentalDiagram
        Any object with ``speed_factor(rho)`` (``g`` at persons/m²), ``capacity() -> (q_max, ρ_c)``,
        ``free_speed`` and a finite ``rho_max`` (duck-typed: :mod:`meanfield.crowds.congestion`).
    people : float
        ``N``, the number of people: a unit-mass density ``ρ`` has ``Nρ`` persons per m².

    Attributes
    ----------
    rho_max, rho_c : float
        The jam density and the density of the capacity, as unit-mass densities (``/N``).
    q_c : float
        ``f(ρ_c)``, the largest ``f`` (``q_max / (N v₀)``).
    door : float
        ``q_max / N``: the largest outflow per metre of door (unit mass per second).
    lipschitz : float
        ``L = max |f'|`` on ``[0, ρ_max]`` (measured on a lattice; at least ``g(0) = 1``).
    """

    def __init__(self, diagram: Any, people: float):
        for attr in ("speed_factor", "capacity", "free_speed", "rho_max"):
            if not hasattr(diagram, attr):
                raise ParameterError(
                    "congestion", type(diagram).__name__, "a fundamental diagram (speed_factor, capacity, rho_max)"
                )
        self.diagram = diagram
        self.people = positive_number("people", people)
        rho_max = float(diagram.rho_max)
        v0 = positive_number("congestion.free_speed", diagram.free_speed)
        if not (math.isfinite(rho_max) and rho_max > 0):
            raise ParameterError("congestion.rho_max", rho_max, "a finite jam density > 0 (persons/m²)")
        q_max, rho_c = (float(v) for v in diagram.capacity())
        n = self.people
        self.rho_max = rho_max / n
        self.rho_c = rho_c / n
        self.q_c = float(self.f(np.array(self.rho_c)))
        self.door = q_max / n
        self.free_speed = v0
        r = np.linspace(0.0, rho_max, 20001)
        q = r * np.asarray(diagram.speed_factor(r), float)
        self.lipschitz = max(1.0, float(np.max(np.abs(np.diff(q) / np.diff(r)))))

    def f(self, rho: np.ndarray) -> np.ndarray:
        """``f(ρ) = ρ g(Nρ)`` (unit-mass density times the speed factor)."""
        rho = np.asarray(rho, float)
        return rho * np.asarray(self.diagram.speed_factor(self.people * rho), float)

    def demand(self, rho: np.ndarray) -> np.ndarray:
        """``D(ρ) = f(min(ρ, ρ_c))``: what a cell can send (nondecreasing)."""
        return self.f(np.minimum(rho, self.rho_c))

    def supply(self, rho: np.ndarray) -> np.ndarray:
        """``S(ρ) = f(max(ρ, ρ_c))``: what a cell can receive (nonincreasing, 0 at the jam density)."""
        return self.f(np.maximum(rho, self.rho_c))

    def godunov(self, a: np.ndarray, rho_l: np.ndarray, rho_r: np.ndarray) -> np.ndarray:
        """Godunov's flux (G) per unit face length, positive from the left cell to the right one.

        Parameters
        ----------
        a : ndarray
            The normal velocity on each face (left to right).
        rho_l, rho_r : ndarray
            The densities of the cells on either side.
        """
        d_l, d_r = self.demand(rho_l), self.demand(rho_r)
        s_l, s_r = self.supply(rho_l), self.supply(rho_r)
        return np.maximum(a, 0.0) * np.minimum(d_l, s_r) - np.maximum(-a, 0.0) * np.minimum(d_r, s_l)


def _cell_velocity(grid: Grid, ax: np.ndarray, ay: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The drift at the cells: the face-length-weighted mean of each cell's open faces, per axis."""
    nx, ny = grid.shape
    out = []
    for axis, (a, w) in enumerate(((ax, grid._len_x), (ay, grid._len_y))):
        s = np.zeros((nx, ny))
        m = np.zeros((nx, ny))
        if axis == 0:
            s[:-1, :] += w * a
            s[1:, :] += w * a
            m[:-1, :] += w
            m[1:, :] += w
        else:
            s[:, :-1] += w * a
            s[:, 1:] += w * a
            m[:, :-1] += w
            m[:, 1:] += w
        out.append(np.divide(s, m, out=np.zeros_like(s), where=m > 0))
    return out[0], out[1]


def exit_normals(grid: Grid, segs: np.ndarray) -> np.ndarray:
    """The outward unit normal ``(E, 2)`` of each exit segment (pointing out of Ω).

    Parameters
    ----------
    grid : Grid
        The grid (its domain tells inside from outside, a quarter cell off the exit's midpoint).
    segs : ndarray, shape (E, 2, 2)
        The exits' end points (:func:`~meanfield.geometry.exits.exit_segments`).
    """
    normals = np.zeros((len(segs), 2))
    h = 0.25 * min(grid.dx, grid.dy)
    for j, (p, q) in enumerate(np.asarray(segs, float)):
        e = q - p
        n = np.array([e[1], -e[0]]) / max(float(np.hypot(*e)), 1e-300)
        mid = 0.5 * (p + q)
        inside = bool(np.asarray(grid.domain.contains(mid[0] + h * n[0], mid[1] + h * n[1])))
        normals[j] = -n if inside else n
    return normals


def door_lengths(sink: ExitSink) -> np.ndarray:
    """The exits' lengths per cell ``(E, nx, ny)``, scaled so that each exit's add up to its length.

    :class:`~meanfield.geometry.exits.ExitSink` intersects the exits with cells widened by a
    round-off tolerance (an exit on a cell's edge is found), which counts the shared corners
    twice: a door's capacity ``q_max b`` needs its width ``b`` exactly.

    Parameters
    ----------
    sink : ExitSink
        The exits on the grid (their ``lengths`` per cell and ``segments``).
    """
    ell = np.array(sink.lengths, float)
    seg = sink.segments
    width = np.hypot(*(seg[:, 1] - seg[:, 0]).T)
    total = ell.sum(axis=(1, 2))
    scale = np.divide(width, total, out=np.zeros_like(total), where=total > 0)
    return ell * scale[:, None, None]


class _State:
    """The congested operator at ``(ρ, t)``: advective face velocities, diffusion coefficients, exits."""

    __slots__ = ("ax", "ay", "diffusion", "exit_speed", "bounds")

    def __init__(self, ax, ay, diffusion: _Coefficients, exit_speed: np.ndarray | None):
        self.ax, self.ay = ax, ay
        self.diffusion = diffusion
        self.exit_speed = exit_speed  # a_n⁺ per exit and cell, or None without exits
        self.bounds: dict[str, float] = {}


class _CongestedMixin:
    """The congested right-hand side of (C) and the bound (B), shared by both congested methods."""

    operator: Any

    def state(self, rho: np.ndarray, t: float, face_velocity: FaceField | None) -> _State:
        """Face velocities ``a`` (the total drift without ``−∇σ``), diffusion coefficients and exit speeds."""
        op = self.operator
        ax, ay = op.drift(rho, t, face_velocity)
        grad = op._sigma_fields(t)[1] if callable(op.sigma) else None
        if grad is not None:  # −∇σ belongs to the diffusion Δ(σρ), not to the congested drift
            ax, ay = ax + grad[0], ay + grad[1]
        sink = op.sink if op.absorbing else None
        speed = None
        if sink is not None:
            vx, vy = _cell_velocity(op.grid, ax, ay)
            nrm = op._exit_normals
            speed = np.maximum(nrm[:, 0, None, None] * vx[None] + nrm[:, 1, None, None] * vy[None], 0.0)
        return _State(ax, ay, op._diffusion_coefficients(t), speed)

    def _lengths(self) -> tuple[Any, Any]:
        g = self.operator.grid
        return (g.dy, g.dx) if g.is_box else (g._len_x, g._len_y)

    def advective_rate(self, s: _State, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mass rate per cell of the advection and the exits (not divided by volume), and the exits' outflow.

        Returns
        -------
        rate : ndarray
            ``−Σ_faces F ℓ − Σ_exits E`` per cell.
        out : ndarray, shape (E,)
            The mass per unit time leaving through each exit.
        """
        op = self.operator
        flux = op.congestion
        lx, ly = self._lengths()
        rate = np.zeros(rho.shape)
        fx = flux.godunov(s.ax, rho[:-1, :], rho[1:, :]) * lx
        rate[:-1, :] -= fx
        rate[1:, :] += fx
        fy = flux.godunov(s.ay, rho[:, :-1], rho[:, 1:]) * ly
        rate[:, :-1] -= fy
        rate[:, 1:] += fy
        n_exits = 0 if s.exit_speed is None else len(s.exit_speed)
        out = np.zeros(n_exits)
        if n_exits:
            sink: ExitSink = op.sink
            ell = op._door_lengths
            diffusive = sink.rates * (op.grid.volume * rho)[None]  # σ ℓ ρ / d
            e = np.minimum(s.exit_speed * flux.demand(rho)[None] * ell + diffusive, flux.door * ell)
            rate -= e.sum(axis=0)
            out = e.sum(axis=(1, 2))
        return rate, out

    def bound_of(self, s: _State, diffusion: bool) -> float:
        """The bound (B): ``min_c V_c / Σ_out(c)`` with the advective, exit and (if ``diffusion``) diffusive rates."""
        key = "with-diffusion" if diffusion else "advection"
        if key in s.bounds:
            return s.bounds[key]
        op = self.operator
        g = op.grid
        L = op.congestion.lipschitz
        lx, ly = self._lengths()
        out = np.zeros(g.shape)
        cx = L * np.abs(s.ax) * lx
        cy = L * np.abs(s.ay) * ly
        out[:-1, :] += cx
        out[1:, :] += cx
        out[:, :-1] += cy
        out[:, 1:] += cy
        if s.exit_speed is not None:
            sink = op.sink
            out += (L * s.exit_speed * op._door_lengths).sum(axis=0) + sink.total_rate * g.volume
        if diffusion:
            ox, oy = s.diffusion.outflow(g.shape)
            out += ox + oy
        mask = g.active & (out > 0)
        b = float(np.min(g.volume[mask] / out[mask])) if np.any(mask) else math.inf
        s.bounds[key] = b
        return b

    def _too_large(self, dt: float, bound: float, what: str) -> ParameterError:
        return _StepTooLarge(
            bound,
            "dt",
            dt,
            f"dt <= {bound:.6g}, the {what} bound (B) of method={self.name!r} with congestion at this state "
            "(or dt=None for an automatic step)",
        )

    def _heun(
        self, rho: np.ndarray, t: float, dt: float, fv: FaceField | None, check: bool, diffusion: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """One Heun step of the congested rate (with the diffusion or not); the mass out per exit."""
        op = self.operator
        iv = op.grid._inv_volume
        result = []
        stage = rho
        outs = []
        for k, tk in enumerate((t, t + dt)):
            s = self.state(stage, tk, fv)
            b = self.bound_of(s, diffusion)
            if check and dt > b * (1 + 1e-12):
                raise self._too_large(dt, b, "monotonicity (ρ <= ρ_max/N)")
            rate, out = self.advective_rate(s, stage)
            if diffusion:
                rate += op._apply(s.diffusion, stage, "xy", np.empty(rho.shape))
            nxt = rate
            nxt *= dt * iv
            nxt += stage
            outs.append(out)
            result.append(nxt)
            if k == 0:
                stage = nxt
        new = result[1]
        new += rho
        new *= 0.5
        return new, 0.5 * dt * (outs[0] + outs[1])


class CongestedExplicitStepper(_CongestedMixin, Stepper):
    """``"explicit"`` with congestion: Heun's method on (C), monotone under the bound (B)."""

    name = "explicit"

    def positivity_bound(self, c: Any) -> float:
        """The bound (B) at the state ``c`` (:meth:`state`): positivity and ``ρ <= ρ_max/N``."""
        return self.bound_of(c, diffusion=True)

    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """One Heun step; the mass through the exits is added to the solver's ``mass_out``."""
        new, out = self._heun(rho, t, dt, face_velocity, check, diffusion=True)
        if len(out):
            self.operator.mass_out += out
        return new


class CongestedSplitStepper(_CongestedMixin, _LineStepper):
    """``"split"`` with congestion: a Heun step of advection and exits, then backward-Euler diffusion sweeps."""

    name = "split"

    def positivity_bound(self, c: Any) -> float:
        """The bound (B) without the diffusion (the implicit sweeps are positive for any ``dt``)."""
        return self.bound_of(c, diffusion=False)

    def automatic_bound(self, c: Any) -> float:
        """The advective bound; without drift or exits four times the explicit diffusion bound (an accuracy step)."""
        b = self.bound_of(c, diffusion=False)
        if math.isfinite(b):
            return b
        return 4.0 * c.diffusion.bound(self.operator.grid, "xy", typical=True)

    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """Heun on the advection and the exits, then the diffusion sweeps (order alternating each step)."""
        op = self.operator
        new, out = self._heun(rho, t, dt, face_velocity, check, diffusion=False)
        c = op._diffusion_coefficients(t + dt)
        key = "diffusion" if (not callable(op.sigma) or not op.time_dependent) else None
        res = self._split_sweeps(c, new, dt, key)
        if len(out):
            op.mass_out += out
        return res


#: The methods that support congestion (``FokkerPlanck(congestion=..., method=...)``).
CONGESTED_STEPPERS: dict[str, type[Stepper]] = {
    CongestedSplitStepper.name: CongestedSplitStepper,
    CongestedExplicitStepper.name: CongestedExplicitStepper,
}
