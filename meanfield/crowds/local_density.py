"""Each congested human's local density: the others within ``r``, over the part of the disk in Ω.

    ρ_j = #{k ≠ j still here : |X_k − X_j| < r} / (π r² max(s(X_j), s_min)),
    s(x) = |B(x, r) ∩ Ω| / (π r²)

(docs page *Congestion*, "The local density").  The share ``s`` corrects the count beside walls:
a human against a wall has half a disk to stand in, in a corner a quarter, in a doorway about
half, and without the correction it would see half the density there is, and walk faster than
its density allows (it let rimea-9's doors pass 2.9–3.6 persons/(m·s)).  ``s`` is tabulated once
per run (:func:`meanfield.geometry.disk_share.disk_share`); the count is one compiled pass over
a cell list (:func:`meanfield.crowds._congestion_loops.neighbour_density`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.crowds._congestion_loops import MAX_HUMANS, DensityWork, neighbour_density
from meanfield.errors import ParameterError

__all__ = ["LocalDensity", "local_density", "DENSITY_RADIUS", "SHARE_FLOOR"]

DENSITY_RADIUS = 0.5
"""m: the local density of a congested human counts its neighbours within this radius (docs page
*Congestion*, "Results": with the walls' cut the radius that puts the linear diagram's bottleneck
flows in the measured band at every width, 0.8 to 2.5 m; small enough to resolve a 0.8 m door,
large enough to hold 2.1 people at the diagram's capacity density, 2.7 persons/m²)."""


SHARE_FLOOR = 0.1
"""``s_min``: the disk's share in Ω is taken as at least this.  A human in a right-angled corner
has a quarter; only an acute corner, or a point that a step put a hair outside a wall, has less."""


class LocalDensity:
    """The local density of a crowd of ``n`` in ``region``: ``ρ_j`` for every human, one call per step.

    Parameters
    ----------
    n : int
        The crowd's size (the work arrays, and the order of the last call, are kept).
    radius : float
        ``r > 0``, m.
    region : Region, optional
        Ω: the disk is cut by its walls and exits.  None: the whole disk (a crowd with no walls).
    """

    def __init__(self, n: int, radius: float = DENSITY_RADIUS, region: Any = None) -> None:
        if not (isinstance(radius, (int, float)) and math.isfinite(radius) and radius > 0):
            raise ParameterError("radius", radius, "a radius > 0 (m)")
        if n > MAX_HUMANS:
            raise ParameterError("crowd.n", n, f"at most {MAX_HUMANS:.0e} humans with congestion")
        self.n = int(n)
        self.radius = float(radius)
        self.inv_area = 1.0 / (math.pi * self.radius * self.radius)
        self.share = None
        self._region = region
        self._half_share: Any = None  # the halves' shares, tabulated at the first directed call
        if region is not None:
            from meanfield.geometry.disk_share import disk_share

            self.share = disk_share(region, self.radius)
        self._work = DensityWork(self.n)
        self._everyone = np.ones(self.n, dtype=bool)

    def __call__(self, positions: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        """``ρ_j`` (persons/m²) of every human; 0 for those not active.

        Parameters
        ----------
        positions : ndarray, shape (n, 2)
            The humans (rows of those not active are ignored).
        active : ndarray of bool, shape (n,), optional
            Who is still here (None: everyone).
        """
        return self._count(positions, active, None)[0]

    def here_and_ahead(
        self, positions: np.ndarray, directions: np.ndarray, active: np.ndarray | None = None, jam_spacing: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(ρ_j, ρ⁻_j, ρ⁺_j, P_j)``: each human's density, the densities in the halves of its disk behind and
        ahead of it (persons/m²), and the push of those closer than ``jam_spacing`` (m, shape (n, 2); module
        :mod:`meanfield.crowds._congestion_loops`).

        ``ρ±_j = #{k ≠ j : |X_k − X_j| < r, ±(X_k − X_j)·e_j > 0} / (½ π r² max(s±(X_j, e_j), s_min))``, the
        densities behind and in front of human ``j`` along its walking direction ``e_j``, each over its own half's
        area in Ω (docs page *Congestion*, "The agents' door model"; ``s±`` of
        :class:`~meanfield.geometry.disk_share.HalfDiskShare`, read only for the humans whose disk a wall cuts):
        a human walking into a wall has a whole half behind it and none ahead, where the whole disk's share, a
        half, would double the density behind it.  ``ρ⁺ = 0`` where ``e_j = 0`` (one who does not walk: its
        speed factor multiplies nothing).  One pass over the pairs gives the counts and the push.

        Parameters
        ----------
        positions : ndarray, shape (n, 2)
        directions : ndarray, shape (n, 2)
            Each human's walking direction (its velocity will do: only the sign along a neighbour's offset counts).
        active : ndarray of bool, shape (n,), optional
        jam_spacing : float
            ``d``, m (``0 <= d <= r``; 0: no push).
        """
        e = np.ascontiguousarray(directions, dtype=float)
        if e.shape != (self.n, 2):
            raise ParameterError("directions", e.shape, f"shape ({self.n}, 2)")
        if not 0.0 <= jam_spacing <= self.radius:
            raise ParameterError("jam_spacing", jam_spacing, f"a distance in [0, {self.radius:g}] m (the radius)")
        rho, ahead, push = self._count(positions, active, e, float(jam_spacing))
        assert ahead is not None and push is not None
        behind = 2.0 * rho - ahead  # both over half the whole disk's area in Ω, as the compiled pass counts them
        np.maximum(behind, 0.0, out=behind)
        if self.share is not None:
            self._halves(positions, e, active, ahead, behind)
        return rho, behind, ahead, push

    def _halves(
        self, positions: np.ndarray, e: np.ndarray, active: np.ndarray | None, ahead: np.ndarray, behind: np.ndarray
    ) -> None:
        """Put ``ρ±`` over their own halves' areas, in place, for the humans whose disk a wall cuts (``s < 1``)."""
        x = np.asarray(positions, float)
        here = np.isfinite(x[:, 0]) & np.isfinite(x[:, 1])
        if active is not None:
            here &= np.asarray(active, dtype=bool)
        assert self.share is not None
        cut = np.flatnonzero(here)
        cut = cut[self.share.at(x[cut]) < 1.0]
        cut = cut[(e[cut] != 0.0).any(axis=1)]
        if not len(cut):
            return
        if self._half_share is None:
            from meanfield.geometry.disk_share import half_disk_share

            self._half_share = half_disk_share(self._region, self.radius, disk=self.share)
        whole, front, back = self._half_share.at(x[cut], e[cut])
        whole = np.maximum(whole, SHARE_FLOOR)
        ahead[cut] *= whole / np.maximum(front, SHARE_FLOOR)
        behind[cut] *= whole / np.maximum(back, SHARE_FLOOR)

    def _count(
        self, positions: np.ndarray, active: np.ndarray | None, directions: np.ndarray | None, jam_spacing: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        x = np.ascontiguousarray(positions, dtype=float)
        if x.shape != (self.n, 2):
            raise ParameterError("positions", x.shape, f"shape ({self.n}, 2)")
        here = self._everyone if active is None else np.ascontiguousarray(active, dtype=bool)
        out = np.empty(self.n)
        directed = directions is not None
        ahead = np.empty(self.n) if directed else _NO_AHEAD
        push = np.empty((self.n, 2)) if directed else _NO_PUSH
        s = self.share
        if s is None:
            table, ox, oy, h = _NO_TABLE, 0.0, 0.0, 1.0
        else:
            table, (ox, oy), h = s.table, s.origin, s.spacing
        neighbour_density(
            x, here, self.radius, self.inv_area, table, ox, oy, h, SHARE_FLOOR, s is not None,
            directions if directed else _NO_DIRECTIONS, directed, jam_spacing, *self._work.arrays(), out, ahead, push,
        )  # fmt: skip
        return (out, ahead, push) if directed else (out, None, None)


_NO_TABLE = np.ones((2, 2))
_NO_DIRECTIONS = np.zeros((1, 2))
_NO_AHEAD = np.empty(1)
_NO_PUSH = np.empty((1, 2))


def local_density(
    positions: np.ndarray, active: np.ndarray | None = None, radius: float = DENSITY_RADIUS, region: Any = None
) -> np.ndarray:
    """Each human's local density, persons/m², in one call (:class:`LocalDensity` for a run).

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        The humans (rows of those not active are ignored).
    active : ndarray of bool, shape (N,), optional
        Who is still here (None: everyone).
    radius : float
        ``r > 0``, metres.
    region : Region, optional
        Ω, whose walls cut the disk; None: the whole disk ``π r²``.

    Returns
    -------
    ndarray, shape (N,)
        ``#{k ≠ j active: |X_k − X_j| < r} / (π r² max(s(X_j), s_min))``; 0 for those not active.
    """
    return LocalDensity(len(positions), radius, region)(positions, active)
