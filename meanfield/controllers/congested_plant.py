"""The law on a congested plant: the crowd walks at ``g(Nρ) v_r`` and Step II tracks ``v_d / ĝ`` (docs page
*Verification*, "Steps I and II on the congested plant").

On a congested plant (``crowd.congestion``; docs page *Congestion*) ``∂_t ρ = −∇·(ρ g(Nρ) v_r + ρ u_W) + Δ(σρ)``.
With a :class:`CongestedPlant` (``controller.congestion = "compensate"``) the backstepping law
(:class:`~meanfield.controllers.backstepping.BacksteppingController`) keeps Step I and tracks ``v_d / ĝ``,
``ĝ = max(g(Nρ_f), g_min)``; this module holds the plant's speed factor on the faces (:class:`CongestionFaces`),
the plant (:class:`CongestedPlant`), what the law reports of it (:class:`CongestionReport`) and the plant from a
scenario's parts (:func:`congested_plant`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from meanfield.errors import ParameterError, positive_number
from meanfield.geometry.grid import FaceField
from meanfield.interfaces import ControllerParts

__all__ = ["G_MIN", "CongestionFaces", "CongestedPlant", "CongestionReport", "congested_plant"]

G_MIN = 0.1
"""The default floor ``g_min`` of the speed factor the law divides by: at most 10× the walking velocity
asked of the robots' field; the linear diagram reaches it at 0.9 ρ_max (4.86 persons/m²), Weidmann's at
4.16 persons/m² (docs page *Verification*, "Steps I and II on the congested plant")."""
_SLOPE_STEP = 6e-6
"""Central-difference step of ``g'``, as a fraction of the diagram's ``ρ_max`` (about ε^(1/3))."""


@dataclass(frozen=True)
class CongestionFaces:
    """The speed factor of a congested plant on the faces, as the law uses it (:meth:`CongestedPlant.on_faces`).

    Attributes
    ----------
    g : FaceField
        ``g(Nρ_f)``: the plant's speed factor at the face densities.
    gain : FaceField
        ``1/ĝ``, ``ĝ = max(g, g_min)``: the tracked field is ``v_d · gain``.
    gain_slope : FaceField
        ``d(1/ĝ)/dρ_f = -N g'(Nρ_f)/g²`` where ``g >= g_min``, 0 where capped (``1/ĝ`` is constant there).
    capped : tuple of bool arrays
        The faces where ``g < g_min``: the law cannot ask the robots for ``v_d/g`` there.
    excess : FaceField
        ``g/ĝ - 1``: 0 where ``g >= g_min`` (exactly), ``g/g_min - 1 ∈ [-1, 0)`` where capped.
    """

    g: FaceField
    gain: FaceField
    gain_slope: FaceField
    capped: tuple[np.ndarray, np.ndarray]
    excess: FaceField


@dataclass(frozen=True)
class CongestedPlant:
    """What the law knows of a congested crowd: its fundamental diagram and its number of people.

    The plant (docs page *Congestion*) is ``∂_t ρ = -∇·(ρ g(Nρ) v_r + ρ u_W) + Δ(σρ)``, ``ρ`` of unit
    mass, ``Nρ`` persons/m².  The law tracks ``v_d/ĝ`` with ``ĝ = max(g(Nρ_f), g_min)`` (the module
    docstring; docs page *Verification*, "Steps I and II on the congested plant").

    Parameters
    ----------
    diagram : FundamentalDiagram
        Duck-typed (:mod:`meanfield.crowds.congestion`): ``speed_factor(persons/m²)`` in ``[0, 1]``, a
        finite ``rho_max`` (persons/m²) and ``slows`` true.  ``g'`` is a central difference of
        ``speed_factor`` with step ``h = 6e-6 ρ_max`` (:meth:`slope`): exact but for round-off of about
        1e-11 relative for the linear diagram, whose ``g`` is linear; a truncation error of order
        ``h² g‴/6`` otherwise.
    people : float
        ``N`` (> 0), the number of people.
    g_min : float
        The floor of the speed factor the law divides by, in ``(0, 1]`` (:data:`G_MIN`).
    """

    diagram: Any
    people: float
    g_min: float = G_MIN

    def __post_init__(self) -> None:
        for attr in ("speed_factor", "rho_max"):
            if not hasattr(self.diagram, attr):
                raise ParameterError(
                    "crowd.congestion", type(self.diagram).__name__, "a fundamental diagram (speed_factor, rho_max)"
                )
        if not getattr(self.diagram, "slows", True):
            raise ParameterError("crowd.congestion", "none", "a diagram that slows the crowd")
        rho_max = float(self.diagram.rho_max)
        if not (math.isfinite(rho_max) and rho_max > 0):
            raise ParameterError("crowd.rho_max", rho_max, "a finite jam density > 0 (persons/m²)")
        object.__setattr__(self, "people", positive_number("crowd.n", self.people))
        g_min = float(self.g_min)
        if not (0.0 < g_min <= 1.0):
            raise ParameterError("g_min", self.g_min, "a speed factor in (0, 1]")
        object.__setattr__(self, "g_min", g_min)

    def speed_factor(self, rho_f: np.ndarray) -> np.ndarray:
        """``g(Nρ)`` at unit-mass densities ``rho_f``."""
        return np.asarray(self.diagram.speed_factor(self.people * np.asarray(rho_f, float)), float)

    def slope(self, rho_f: np.ndarray) -> np.ndarray:
        """``g'(r)`` at ``r = Nρ_f`` persons/m²: ``(g(r + h) - g(max(r - h, 0))) / (their distance)``."""
        r = self.people * np.asarray(rho_f, float)
        h = _SLOPE_STEP * float(self.diagram.rho_max)
        lo = np.maximum(r - h, 0.0)
        hi = r + h
        f = self.diagram.speed_factor
        return (np.asarray(f(hi), float) - np.asarray(f(lo), float)) / (hi - lo)

    def on_faces(self, rf: FaceField) -> CongestionFaces:
        """:class:`CongestionFaces` at the face densities ``rf``."""
        out: dict[str, list[np.ndarray]] = {"g": [], "gain": [], "slope": [], "capped": [], "excess": []}
        for r in rf:
            g = self.speed_factor(r)
            capped = g < self.g_min
            gain = 1.0 / np.where(capped, self.g_min, g)
            out["g"].append(g)
            out["gain"].append(gain)
            out["slope"].append(np.where(capped, 0.0, -self.people * self.slope(r) * gain * gain))
            out["capped"].append(capped)
            out["excess"].append(np.where(capped, g / self.g_min - 1.0, 0.0))
        pair = {k: (v[0], v[1]) for k, v in out.items()}
        return CongestionFaces(pair["g"], pair["gain"], pair["slope"], pair["capped"], pair["excess"])


@dataclass(frozen=True)
class CongestionReport:
    """What one evaluation of the congestion-aware law found (``BacksteppingController.congestion_report``).

    Attributes
    ----------
    capped_mass : float
        The share of the crowd's mass on the faces where ``g < g_min`` (``ρ_f`` weighted as in the face
        inner product, over both families of faces): where the guarantee does not hold.
    capped_faces : float
        The share of the open faces where ``g < g_min``.
    residual : float
        ``J = ⟨∇ρ̃, ρ_f (g/ĝ - 1) v_d⟩``: what the capped faces add to ``dV₂/dt`` (0 when none is capped).
    g_least : float
        The smallest ``g(Nρ_f)`` over the open faces.
    """

    capped_mass: float
    capped_faces: float
    residual: float
    g_least: float


def congested_plant(parts: ControllerParts, g_min: float = G_MIN) -> CongestedPlant | None:
    """The plant's congestion from the assembled parts (``parts.congestion``, ``parts.people``), or None
    when there is none to compensate (no diagram, or one that does not slow: ``"none"``)."""
    diagram = parts.congestion
    if diagram is None or not getattr(diagram, "slows", False):
        return None
    return CongestedPlant(diagram, parts.people, g_min)
