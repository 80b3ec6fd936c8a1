"""Which hypotheses of Theorems 1–3 the scenario's grid meets: Ω in one piece, zero flux on ∂Ω.

The theorems' proofs use two facts about Ω beyond its size (``docs/verification.md``,
*Floor plans and exits*):

* the **Poincaré–Wirtinger inequality** ``∫|f − f̄|² ≤ ∫|∇f|²/μ₂``.  It holds on every
  bounded *connected* Lipschitz domain, convex or not, so the checks run on floor plans
  (re-entrant corners, pillars) with μ₂ computed on the plan's cut-cell grid; convexity
  only buys the Payne–Weinberger lower bound, which the checks do not use.  What they
  need is the grid's Ω in one piece (:func:`analysis.rates.grid_pieces`);
* **mass conservation**, ``∫ρ̃ = 0`` at all times, which lets the inequality be applied to
  ``ρ̃`` itself: zero flux through all of ∂Ω.  Exits absorb, so with exits it fails, and
  with it the convergence to a target of the initial mass.

:func:`hypotheses` collects both for a grid; the ``*_reason`` functions word the verdicts.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from analysis.poincare import is_convex
from analysis.rates import grid_pieces
from meanfield.geometry.exits import exit_segments
from meanfield.geometry.grid import Grid

__all__ = ["Hypotheses", "hypotheses", "disconnected_reason", "exits_reason"]


@dataclass(frozen=True)
class Hypotheses:
    """What the grid of a scenario offers the theorems.

    Attributes
    ----------
    region : str
        The region's kind (``"box"``, ``"disk"``, ``"polygon"``, ``"plan"``, ...).
    convex : bool
        Whether Ω is convex (:func:`analysis.poincare.is_convex`); reported only: no check
        needs it.
    pieces : int
        Connected pieces of the grid's active cells through open faces (1: one piece).
    detached_share : float
        Share of Ω's area outside the largest piece.
    exits : int
        Exit segments on ∂Ω (0: zero flux everywhere, mass conserved).
    """

    region: str
    convex: bool
    pieces: int
    detached_share: float
    exits: int

    @property
    def connected(self) -> bool:
        return self.pieces == 1

    @property
    def mass_conserved(self) -> bool:
        return self.exits == 0

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "connected": self.connected, "mass_conserved": self.mass_conserved}


def hypotheses(grid: Grid) -> Hypotheses:
    """The hypotheses of the theorems that ``grid`` (and its region) meets."""
    pieces, share = grid_pieces(grid)
    region = grid.domain
    return Hypotheses(
        region=str(getattr(region, "kind", type(region).__name__)),
        convex=is_convex(region),
        pieces=pieces,
        detached_share=share,
        exits=len(exit_segments(region)),
    )


def disconnected_reason(h: Hypotheses, cells: Any) -> str | None:
    """Why the Poincaré–Wirtinger step does not apply on this grid, or ``None`` when it does."""
    if h.connected:
        return None
    return (
        f"the grid {tuple(cells)} splits Ω into {h.pieces} pieces ({h.detached_share:.2%} of the area outside the "
        "largest; a door or passage narrower than the cells closes): the discrete μ₂ is then 0 and the theorem's "
        "Poincaré–Wirtinger step does not apply — refine grid.cells"
    )


def exits_reason(mass_out: float, t_final: float) -> str:
    """Why the claims that need mass conservation do not apply with exits."""
    return (
        f"Ω has exits, so mass is not conserved ({mass_out:.2%} of the crowd left by t = {t_final:.3g}): ∫ρ̃ ≠ 0, "
        "so the theorem's Poincaré–Wirtinger step does not apply to ρ̃, and ρ_* (of the initial mass) can no longer "
        "be reached (‖ρ̃‖ ≥ mass out/√|Ω|)"
    )
