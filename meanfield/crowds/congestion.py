"""Congestion: how fast people walk at a given density, the fundamental diagram.

A crowd with congestion walks at ``g(ρ) v`` where it would walk at ``v`` alone: ``g`` is the
*speed factor* of a fundamental diagram, the walking speed at the local density ``ρ`` (persons
per m²) divided by the free walking speed ``v₀``; ``g(0) = 1``, ``g`` does not increase, and
``g(ρ_max) = 0``, where people stand.  The flow through a cross-section is ``q(ρ) = ρ v₀ g(ρ)``
(persons per metre and second); its maximum, the *capacity*, bounds what a door of width ``b``
passes, ``J ≤ q_max b``.  The mean-field PDE takes the same factor (docs page *Congestion*):
``∂ₜρ + ∇·(ρ g(ρ) v) = σΔρ``.

Densities here are numbers of persons per m²: the toolkit's densities have unit mass, so a crowd
of ``N`` people with density ``ρ`` has ``N ρ`` persons per m² (:func:`persons_per_m2`).

The diagrams (registry kind ``congestion``, :mod:`meanfield.plugins`; ``crowd.congestion``):

``"none"``
    ``g ≡ 1``: the paper's crowd, which no density slows (:class:`NoCongestion`).
``"weidmann"``
    U. Weidmann, *Transporttechnik der Fussgänger*, Schriftenreihe des IVT 90, ETH Zürich
    (1993): ``v(ρ) = v₀ (1 − exp(−γ (1/ρ − 1/ρ_max)))`` with ``v₀ = 1.34 m/s``,
    ``γ = 1.913 persons/m²`` and ``ρ_max = 5.4 persons/m²`` (:class:`Weidmann`); its capacity is
    about 1.22 persons/(m·s) at 1.75 persons/m².
``"linear"``
    Greenshields' linear relation ``v(ρ) = v₀ (1 − ρ/ρ_max)`` (:class:`Linear`); its capacity is
    ``v₀ ρ_max / 4`` at ``ρ_max / 2`` (1.81 persons/(m·s) with the defaults).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from meanfield.capabilities import CongestionCapabilities
from meanfield.errors import ParameterError, num

__all__ = [
    "FundamentalDiagram",
    "NoCongestion",
    "Weidmann",
    "Linear",
    "persons_per_m2",
    "GodunovTwin",
    "WEIDMANN_GAMMA",
    "WEIDMANN_RHO_MAX",
    "FREE_SPEED",
]

FREE_SPEED = 1.34
"""Weidmann's mean free walking speed, m/s."""
WEIDMANN_GAMMA = 1.913
"""Weidmann's fitted constant γ, persons/m²."""
WEIDMANN_RHO_MAX = 5.4
"""Weidmann's jam density, persons/m²."""


@runtime_checkable
class FundamentalDiagram(Protocol):
    """A speed–density relation: what a crowd model asks of ``crowd.congestion``."""

    free_speed: float
    rho_max: float
    slows: bool
    """Whether any density slows the crowd (False for ``"none"``: a crowd model then computes nothing)."""

    def speed_factor(self, rho: np.ndarray) -> np.ndarray:
        """``g(ρ) ∈ [0, 1]`` at densities ``ρ`` (persons/m²; an array of any shape, ``ρ >= 0``)."""
        ...

    def capacity(self) -> tuple[float, float]:
        """``(q_max, ρ_c)``: the largest flow ``ρ v₀ g(ρ)`` (persons/(m·s)) and the density where it is reached."""
        ...


def _check(free_speed: float, rho_max: float) -> tuple[float, float]:
    free_speed = num("crowd.free_speed", free_speed, lo=0.0, lo_open=True)
    rho_max = num("crowd.rho_max", rho_max, lo=0.0, lo_open=True)
    if not (math.isfinite(free_speed) and math.isfinite(rho_max)):
        raise ParameterError("crowd.rho_max", rho_max, "a finite density > 0 (persons/m²)")
    return free_speed, rho_max


def _capacity(diagram: FundamentalDiagram, points: int = 20001) -> tuple[float, float]:
    """The flow's maximum on a fine lattice of ``[0, ρ_max]`` (the flow is unimodal for every diagram here)."""
    rho = np.linspace(0.0, diagram.rho_max, points)
    q = rho * diagram.free_speed * diagram.speed_factor(rho)
    k = int(np.argmax(q))
    return float(q[k]), float(rho[k])


@dataclass(frozen=True)
class NoCongestion:
    """No congestion: ``g ≡ 1`` (the paper's crowd); its capacity is unbounded."""

    free_speed: float = FREE_SPEED
    rho_max: float = math.inf
    capabilities: ClassVar[CongestionCapabilities] = CongestionCapabilities(slows=False)
    """No density slows the crowd (:class:`~meanfield.capabilities.CongestionCapabilities`)."""

    @property
    def slows(self) -> bool:
        """False: a crowd model then computes nothing (the record's ``slows``)."""
        return self.capabilities.slows

    def speed_factor(self, rho: np.ndarray) -> np.ndarray:
        """``g ≡ 1``."""
        return np.ones_like(np.asarray(rho, float))

    def capacity(self) -> tuple[float, float]:
        """``(inf, inf)``: point masses without congestion pass a door at any rate."""
        return math.inf, math.inf

    @classmethod
    def from_scenario(cls, free_speed: float, rho_max: float) -> NoCongestion:
        """Registry factory (kind ``congestion``, name ``none``)."""
        return cls(num("crowd.free_speed", free_speed, lo=0.0, lo_open=True))


@dataclass(frozen=True)
class Weidmann:
    """Weidmann's relation (1993): ``g(ρ) = 1 − exp(−γ (1/ρ − 1/ρ_max))`` for ``0 < ρ < ρ_max``.

    ``g(0) = 1``; ``g = 0`` at and above ``ρ_max``.

    Parameters
    ----------
    free_speed : float
        ``v₀``, m/s (> 0).
    rho_max : float
        The jam density, persons/m² (> 0).
    gamma : float
        Weidmann's constant, persons/m².
    """

    free_speed: float = FREE_SPEED
    rho_max: float = WEIDMANN_RHO_MAX
    gamma: float = WEIDMANN_GAMMA
    capabilities: ClassVar[CongestionCapabilities] = CongestionCapabilities(slows=True)
    """It slows the crowd with its density (:class:`~meanfield.capabilities.CongestionCapabilities`)."""

    @property
    def slows(self) -> bool:
        """True: the crowd walks ``v₀ g(ρ)`` (the record's ``slows``)."""
        return self.capabilities.slows

    def speed_factor(self, rho: np.ndarray) -> np.ndarray:
        """``1 − exp(−γ (1/ρ − 1/ρ_max))``, 1 at ``ρ = 0`` and 0 from ``ρ_max`` on."""
        rho = np.asarray(rho, float)
        with np.errstate(divide="ignore"):
            inv = np.where(rho > 0, 1.0 / np.maximum(rho, 1e-300), np.inf)
        g = -np.expm1(-self.gamma * (inv - 1.0 / self.rho_max))
        return np.clip(g, 0.0, 1.0)

    def capacity(self) -> tuple[float, float]:
        """``(q_max, ρ_c)`` found on a fine lattice (about 1.22 persons/(m·s) at 1.75 persons/m²)."""
        return _capacity(self)

    @classmethod
    def from_scenario(cls, free_speed: float, rho_max: float) -> Weidmann:
        """Registry factory (kind ``congestion``, name ``weidmann``)."""
        v0, rmax = _check(free_speed, rho_max)
        return cls(v0, rmax)


@dataclass(frozen=True)
class Linear:
    """Greenshields' linear relation: ``g(ρ) = max(0, 1 − ρ/ρ_max)``; capacity ``v₀ ρ_max / 4`` at ``ρ_max / 2``."""

    free_speed: float = FREE_SPEED
    rho_max: float = WEIDMANN_RHO_MAX
    capabilities: ClassVar[CongestionCapabilities] = CongestionCapabilities(slows=True)
    """It slows the crowd with its density (:class:`~meanfield.capabilities.CongestionCapabilities`)."""

    @property
    def slows(self) -> bool:
        """True: the crowd walks ``v₀ g(ρ)`` (the record's ``slows``)."""
        return self.capabilities.slows

    def speed_factor(self, rho: np.ndarray) -> np.ndarray:
        """``max(0, 1 − ρ/ρ_max)`` (clipped to [0, 1]; in place on one new array, a step of 10⁶ humans)."""
        rho = np.asarray(rho, float)
        if rho.ndim == 0:
            return np.clip(1.0 - rho / self.rho_max, 0.0, 1.0)
        g = rho / -self.rho_max  # = −(ρ/ρ_max) exactly: the same numbers as 1 − ρ/ρ_max
        g += 1.0
        np.maximum(g, 0.0, out=g)
        return np.minimum(g, 1.0, out=g)

    def capacity(self) -> tuple[float, float]:
        """``(v₀ ρ_max / 4, ρ_max / 2)``, in closed form."""
        return self.free_speed * self.rho_max / 4.0, self.rho_max / 2.0

    @classmethod
    def from_scenario(cls, free_speed: float, rho_max: float) -> Linear:
        """Registry factory (kind ``congestion``, name ``linear``)."""
        v0, rmax = _check(free_speed, rho_max)
        return cls(v0, rmax)


def persons_per_m2(density: np.ndarray, n: int) -> np.ndarray:
    """A unit-mass density of a crowd of ``n`` people as persons per m² (``n ρ``)."""
    return n * np.asarray(density, float)


class GodunovTwin:
    """The agents' door model, the Godunov twin: each human's speed from the density behind it and ahead of it.

    A human ``j`` with density ``ρ⁻_j`` behind it and ``ρ⁺_j`` in front of it (persons/m², the two halves of its
    disk, :meth:`~meanfield.crowds.local_density.LocalDensity.here_and_ahead`) walks at the flux the density's
    Godunov scheme passes between the two, over the density it leaves, as a fraction of ``v₀``::

        f_j = min(D(ρ⁻_j), S(ρ⁺_j)) / (v₀ ρ⁻_j),
        D(ρ) = q(min(ρ, ρ_c)),   S(ρ) = q(max(ρ, ρ_c)),   q(ρ) = ρ v₀ g(ρ)          (G1)

    (docs page *Congestion*, "The agents' door model"): the demand and the supply of the diagram, as the
    density's face flux takes them (:mod:`meanfield.fokker_planck.congested`).  Where the crowd is even
    (``ρ⁻ = ρ⁺ = ρ``) ``f = g(ρ)``, the diagram itself; the head of a queue with room in front of it
    (``ρ⁻ > ρ_c``, ``ρ⁺ <= ρ_c``) walks at ``q_max / ρ⁻``, so that a door passes its capacity, where the
    isotropic count stopped it (the people behind it counted); nobody walks into room at the jam density
    (``S(ρ_max) = 0``); nobody behind (``ρ⁻ = 0``): ``g(0) = 1``, or 0 in front of a jam.

    The excluded volume: the agents are points, and a count over half a disk of 0.5 m does not stop two of
    them converging on the same spot from the sides.  Each pair closer than the jam spacing
    ``d = sqrt(2 / (√3 ρ_max))``, the spacing of people packed hexagonally at the jam density (0.46 m at
    5.4 persons/m², :attr:`jam_spacing`), is moved apart by half its overlap in the step (one Jacobi sweep of
    the contact constraint of B. Maury and J. Venel, "A discrete contact model for crowd motion", ESAIM:
    M2AN 45 (2011) 145–168) across each one's walk; along it the push only brakes (:meth:`exclude`, (G2)).
    The densities of the halves are each over its own half's area in Ω, so that a human walking into a
    wall's door does not read the density behind it doubled.

    Parameters
    ----------
    diagram : FundamentalDiagram
        A diagram that slows (finite ``rho_max``).
    """

    def __init__(self, diagram: FundamentalDiagram) -> None:
        self.diagram = diagram
        self.q_max, self.rho_c = diagram.capacity()
        self.free_speed = float(diagram.free_speed)
        self.jam_spacing = math.sqrt(2.0 / (math.sqrt(3.0) * float(diagram.rho_max)))

    def q(self, rho: np.ndarray) -> np.ndarray:
        """The flow ``q(ρ) = ρ v₀ g(ρ)``, persons/(m·s)."""
        rho = np.asarray(rho, float)
        return rho * self.free_speed * self.diagram.speed_factor(rho)

    def demand(self, rho: np.ndarray) -> np.ndarray:
        """``D(ρ) = q(min(ρ, ρ_c))``: what the crowd at density ``ρ`` can send (nondecreasing, persons/(m·s))."""
        return self.q(np.minimum(rho, self.rho_c))

    def supply(self, rho: np.ndarray) -> np.ndarray:
        """``S(ρ) = q(max(ρ, ρ_c))``: what room at density ``ρ`` can take (nonincreasing; 0 at ``ρ_max``)."""
        return self.q(np.maximum(rho, self.rho_c))

    def speed_factor(self, behind: np.ndarray, ahead: np.ndarray) -> np.ndarray:
        """``f`` of (G1) in ``[0, 1]`` for the densities ``behind`` and ``ahead`` of each human (persons/m²)."""
        behind = np.asarray(behind, float)
        ahead = np.asarray(ahead, float)
        walk = self.diagram.speed_factor(np.minimum(behind, self.rho_c))  # D(ρ)/(v₀ ρ) below ρ_c ...
        crowded = behind > self.rho_c
        if crowded.any():  # ... and q_max/(v₀ ρ) above it
            walk = np.where(crowded, self.q_max / (self.free_speed * np.maximum(behind, self.rho_c)), walk)
        room = self.supply(ahead)
        with np.errstate(divide="ignore", invalid="ignore"):
            front = np.where(behind > 0.0, room / (self.free_speed * behind), np.where(room > 0.0, np.inf, 0.0))
        return np.clip(np.minimum(walk, front), 0.0, 1.0)

    def slow_down(self, velocity: np.ndarray, positions: np.ndarray, active: np.ndarray | None, dt: float,
                  density: Any) -> np.ndarray:  # fmt: skip
        """(G1) then (G2), in place on ``velocity`` (the walk before congestion, whose directions are the lines of
        walk); returns the local density ρ_j (persons/m²).  ``density`` is the crowd's
        :class:`~meanfield.crowds.local_density.LocalDensity` (its halves ahead and behind, and the push)."""
        e = velocity.copy()  # the walking directions, before the speed rule
        norm = np.hypot(e[:, 0], e[:, 1])
        np.divide(e, norm[:, None], out=e, where=norm[:, None] > 0)
        e[norm == 0] = 0.0
        rho, behind, ahead, push = density.here_and_ahead(
            positions, e, active, min(self.jam_spacing, density.radius)
        )
        velocity *= self.speed_factor(behind, ahead)[:, None]
        self.exclude(velocity, e, push, dt)
        return rho

    def exclude(self, velocity: np.ndarray, directions: np.ndarray, push: np.ndarray, dt: float) -> None:
        """The excluded volume, in place on the ``velocity`` of humans walking along unit ``directions``
        (0: standing, pushed whole) under the ``push`` of the pairs closer than the jam spacing (m, over the step
        ``dt``)::

            P_j = P∥_j e_j + P⊥_j,   v_j ← v_j − min(max(−P∥_j, 0)/Δt, v_j·e_j) e_j + P⊥_j/Δt        (G2)

        The push across the walk moves the human aside; along the walk it only brakes: one too close to
        the human ahead (``P∥ < 0``) cuts its walk by the overlap, down to standing, and is never moved
        back; one too close to the human behind is not moved on.  Nobody is moved along its walk by the
        push, either way (docs page *Congestion*, "The agents' door model": moving those behind back slowed
        the doors as the noise grew, moving those ahead on sent more through them than (G1) lets through).
        """
        along = (push * directions).sum(axis=1)
        push -= along[:, None] * directions
        walk = np.maximum((velocity * directions).sum(axis=1), 0.0)
        brake = np.minimum(np.maximum(-along, 0.0) / dt, walk)
        velocity -= brake[:, None] * directions
        velocity += push / dt
