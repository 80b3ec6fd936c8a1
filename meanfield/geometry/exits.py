"""Exits that absorb: agents leave through them, the density vanishes on them (docs page *Architecture*).

An exit is a segment of ∂Ω (``exits`` of the region).  Its physics, for both crowds:

* **agents** (:func:`leaving`): a human whose step crosses an exit leaves; so does one whose
  step ends near an exit with the probability that the Brownian path between the two ends
  touched it, ``exp(−d₀ d₁ / (σ Δt))`` for distances ``d₀``, ``d₁`` to the exit's line
  (the Brownian-bridge crossing probability of a straight boundary, noise ``sqrt(2σ) dB``),
  which removes the ``O(sqrt(Δt))`` bias of looking at the steps' ends only;
* **the density** (:class:`ExitSink`): the mean-field limit of that is ``ρ = 0`` on the
  exit (Dirichlet), zero flux on the walls.  On the finite-volume grid, a cell an exit
  crosses loses the diffusive flux through it, ``σ ℓ ρ / d`` (``ℓ`` the exit's length in
  the cell, ``d`` the distance from the centre to the exit: a ghost value 0 on the exit),
  applied exactly over each step, ``ρ ← ρ e^{−k Δt}`` with ``k = σ ℓ / (d V)``; the mass it
  removes is counted per exit, so that mass in Ω plus mass out equals the initial mass.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry._exit_loops import bridge_exits, first_exit_crossed
from meanfield.geometry._exit_loops import segment_distances as distance_to_segments

__all__ = [
    "exit_segments",
    "exits_on",
    "distance_to_segments",
    "leaving",
    "tell_exits_closed",
    "ExitSink",
    "ReactsToClosedExits",
]


def exit_segments(region: Any) -> np.ndarray:
    """The region's exits as an array ``(E, 2, 2)`` of end points (``(0, 2, 2)`` for none, or for a
    stand-in region without :meth:`~meanfield.geometry.region.Region.boundary_parts`)."""
    boundary = getattr(region, "boundary_parts", None)
    parts = [p.points for p in (boundary() if boundary else ()) if p.kind == "exit"]
    segs = [np.stack([pts[k], pts[k + 1]]) for pts in parts for k in range(len(pts) - 1)]
    return np.array(segs, float).reshape(-1, 2, 2)


def exits_on(shape: Any, segs: np.ndarray, tol: float) -> list[int]:
    """The exits (indices into ``segs``) within ``tol`` of the shapely ``shape`` (those on a piece of a plan)."""
    import shapely

    return [k for k, seg in enumerate(segs) if shape.distance(shapely.LineString(seg)) < tol]


@runtime_checkable
class ReactsToClosedExits(Protocol):
    """A part told when exits close during a run (a scenario's ``[[events]] close_exit``; docs page *Buildings*,
    "Events"): a crowd, its engine or guidance, a controller."""

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """From now on only the exits with ``open_exits[k]`` are open."""
        ...


def tell_exits_closed(parts: Any, open_exits: np.ndarray) -> None:
    """Tell each of ``parts`` that reacts to closed exits (:class:`ReactsToClosedExits`) which exits are still open
    (a scenario's ``[[events]]``; docs page *Buildings*, "Events"): the parts that plan to the exits plan again."""
    for part in parts:
        if isinstance(part, ReactsToClosedExits):
            part.exits_closed(np.asarray(open_exits, dtype=bool).copy())


def leaving(
    start: np.ndarray, end: np.ndarray, segs: np.ndarray, sigma: float, dt: float, rng: np.random.Generator
) -> np.ndarray:
    """The exit each step leaves through (its index), or ``-1`` for the humans who stay.

    Two compiled passes over the humans (:mod:`meanfield.geometry._exit_loops`): the first exit each
    step crosses, then, for the others, the Brownian-bridge test with one uniform draw each.

    Parameters
    ----------
    start, end : ndarray, shape (N, 2)
        Where each step starts and (before any reflection) ends.
    segs : ndarray, shape (E, 2, 2)
        The exits.
    sigma : float
        The diffusion σ of the noise ``sqrt(2σ) dB`` (0: crossings only).
    dt : float
    rng : numpy.random.Generator
        One uniform draw per human whose step crosses no exit (the Brownian-bridge test).
    """
    n = len(start)
    out = np.full(n, -1, dtype=np.intp)
    if not len(segs) or not n:
        return out
    start, end = np.ascontiguousarray(start, float), np.ascontiguousarray(end, float)
    segs = np.ascontiguousarray(segs, float)
    first_exit_crossed(start, end, segs, out)
    if sigma > 0:
        near = np.flatnonzero(out < 0)
        if len(near):
            bridge_exits(start, end, segs, near, rng.random(len(near)), sigma * dt, out)
    return out


class ExitSink:
    """The density's outflow through the exits (Dirichlet ``ρ = 0`` on them), cell by cell.

    Parameters
    ----------
    grid : Grid
    segs : ndarray, shape (E, 2, 2)
        The exits.
    sigma : float
        The crowd's diffusion σ.

    Attributes
    ----------
    rates : ndarray, shape (E, nx, ny)
        ``k = σ ℓ / (d V)`` per exit and cell.
    segments : ndarray, shape (E, 2, 2)
        The exits.
    lengths : ndarray, shape (E, nx, ny)
        ``ℓ``, the exit's length in each cell inside Ω (the door width a congested flux passes through).
    """

    def __init__(self, grid: Any, segs: np.ndarray, sigma: float):
        import shapely

        self.grid = grid
        self.segments = np.asarray(segs, float).reshape(-1, 2, 2)
        self.n_exits = len(segs)
        nx, ny = grid.shape
        tol = 1e-9 * max(nx * grid.dx, ny * grid.dy)  # an exit on the outer edge of a cell, up to round-off
        boxes = grid.cell_boxes(tol)
        X, Y = grid.centers
        centres = np.column_stack([X.ravel(), Y.ravel()])
        self.rates = np.zeros((self.n_exits, nx, ny))  # k per exit and cell (1/time)
        self.lengths = np.zeros((self.n_exits, nx, ny))  # ℓ: the exit's length in each cell
        volume = np.where(grid.active, grid.volume, np.inf)
        for j, seg in enumerate(segs):
            length = shapely.length(shapely.intersection(boxes, shapely.LineString(seg)))
            self.lengths[j] = np.where(grid.active, length, 0.0)
            dist = distance_to_segments(centres, seg[None])[:, 0].reshape(nx, ny)
            dist = np.maximum(dist, 1e-3 * min(grid.dx, grid.dy))
            self.rates[j] = np.where(length > 0, sigma * length / (dist * volume), 0.0)
        self.total_rate = self.rates.sum(axis=0)

    def closed(self, open_exits: np.ndarray) -> ExitSink:
        """A copy in which only the exits with ``open_exits[k]`` take anyone (a scenario's ``[[events]]``).

        The others' rates and lengths are 0, so the density's face on them is a wall (zero flux) and no
        congested flux passes there; the per-exit arrays keep their ``E`` rows, so the mass out per exit
        goes on being counted in the same places.
        """
        import copy

        keep = np.asarray(open_exits, dtype=bool).reshape(-1, 1, 1)
        if keep.shape[0] != self.n_exits:
            raise ParameterError("open_exits", keep.shape[0], f"one flag per exit ({self.n_exits})")
        out = copy.copy(self)
        out.rates = np.where(keep, self.rates, 0.0)
        out.lengths = np.where(keep, self.lengths, 0.0)
        out.total_rate = out.rates.sum(axis=0)
        return out

    def apply(self, rho: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``ρ e^{−k Δt}`` and the mass that left through each exit over the step."""
        lost = rho * (1.0 - np.exp(-self.total_rate * dt))
        share = np.divide(self.rates, self.total_rate, out=np.zeros_like(self.rates), where=self.total_rate > 0)
        per_exit = (share * (lost * self.grid.volume)[None]).sum(axis=(1, 2))
        return rho - lost, per_exit
