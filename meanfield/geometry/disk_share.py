"""The share of a disk that lies inside Ω, tabulated over the plan.

A congested human's local density counts its neighbours within ``r`` and divides by the area
of the disk they can stand in, ``|B(x, r) ∩ Ω|`` (docs page *Congestion*, "The local density"):
a human against a wall has about half a disk, in a corner a quarter, in a doorway about half.
:func:`disk_share` tabulates ``s(x) = |B(x, r) ∩ Ω| / (π r²)`` once per run on a lattice over
Ω's bounding box, and :class:`DiskShare` reads it back by bilinear interpolation.

The table is a convolution.  Each lattice cell's share of Ω, ``a_c ∈ [0, 1]``, is measured
(the cells whose four corners agree are whole or empty; the others are sampled on an 8 × 8
sub-lattice), and each cell of the disk's footprint gets the area of the disk inside it,
``w_d`` (sampled on a 16 × 16 sub-lattice).  Then ``s(x_c) = Σ_d a_{c+d} w_d / Σ_d w_d``
(``scipy.signal.fftconvolve``; 1 exactly where the disk is whole): exact for a region made of
whole cells, and within a few thousandths of the closed form beside a straight wall (tests/geometry/test_disk_share.py).

The agents' door model also needs each half of the disk, ahead of and behind a walking direction:
:func:`half_disk_share` tabulates those shares for 16 directions the same way (:class:`HalfDiskShare`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = [
    "DiskShare",
    "disk_share",
    "HalfDiskShare",
    "half_disk_share",
    "CELLS_PER_RADIUS",
    "MAX_TABLE_CELLS",
    "HALF_DISK_DIRECTIONS",
    "segment_share",
]

CELLS_PER_RADIUS = 8
"""The table's spacing is ``r / 8`` (coarser only when the plan would need more than
:data:`MAX_TABLE_CELLS` cells)."""

MAX_TABLE_CELLS = 4_000_000
"""At most this many cells (32 MB): a 707 m square room at ``r = 0.6 m`` is tabulated at 0.35 m."""

HALF_DISK_DIRECTIONS = 16
"""The half disks' shares are tabulated for this many directions, ``2πk/16`` (read linearly between them)."""

_CELL_SAMPLES = 8  # a cut cell's share of Ω: 8 × 8 points
_KERNEL_SAMPLES = 16  # each footprint cell's share of the disk: 16 × 16 points


@dataclass(frozen=True)
class DiskShare:
    """``s(x) = |B(x, r) ∩ Ω| / (π r²)`` on a lattice, read back bilinearly.

    Attributes
    ----------
    radius : float
        ``r``, the disk's radius.
    origin : tuple of float
        The centre of the lattice's cell ``(0, 0)``.
    spacing : float
        The lattice's spacing (both directions).
    table : ndarray, shape (nx, ny)
        ``s`` at the cells' centres, in [0, 1].
    """

    radius: float
    origin: tuple[float, float]
    spacing: float
    table: np.ndarray

    def at(self, points: np.ndarray) -> np.ndarray:
        """``s`` at ``points`` (shape (M, 2)), bilinear between the cells' centres (clamped at the edges).

        The same arithmetic as the compiled local density
        (:func:`meanfield.crowds._congestion_loops.neighbour_density`), so the two agree to the last bit.
        """
        p = np.asarray(points, float).reshape(-1, 2)
        return bilinear(self.table, self.origin[0], self.origin[1], self.spacing, p[:, 0], p[:, 1])


def bilinear(table: np.ndarray, ox: float, oy: float, h: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``table`` (centres ``(ox + i h, oy + k h)``), clamped to its edges."""
    nx, ny = table.shape
    fx = (x - ox) / h
    fy = (y - oy) / h
    i = np.clip(np.floor(fx), 0, nx - 2).astype(np.int64)
    k = np.clip(np.floor(fy), 0, ny - 2).astype(np.int64)
    wx = np.clip(fx - i, 0.0, 1.0)
    wy = np.clip(fy - k, 0.0, 1.0)
    lo = table[i, k] + wy * (table[i, k + 1] - table[i, k])  # a + w (b − a): exactly a where a = b
    hi = table[i + 1, k] + wy * (table[i + 1, k + 1] - table[i + 1, k])
    return lo + wx * (hi - lo)


def _cell_shares(region: Any, xe: np.ndarray, ye: np.ndarray) -> np.ndarray:
    """Each lattice cell's share of Ω: 0 or 1 where its four corners agree, else sampled 8 × 8."""
    cx, cy = np.meshgrid(xe, ye, indexing="ij")
    corner = np.asarray(region.contains(cx, cy), dtype=np.int8)
    corners = corner[:-1, :-1] + corner[1:, :-1] + corner[:-1, 1:] + corner[1:, 1:]
    share = (corners == 4).astype(float)
    ci, ck = np.nonzero((corners > 0) & (corners < 4))
    if len(ci):
        h = xe[1] - xe[0]
        u = (np.arange(_CELL_SAMPLES) + 0.5) / _CELL_SAMPLES * h
        sx = (xe[ci][:, None, None] + u[None, :, None]) + 0.0 * u[None, None, :]
        sy = (ye[ck][:, None, None] + u[None, None, :]) + 0.0 * u[None, :, None]
        share[ci, ck] = np.asarray(region.contains(sx, sy), float).mean(axis=(1, 2))
    return share


def _footprint(radius: float, h: float, direction: float | None = None) -> np.ndarray:
    """The disk's area in each cell of its footprint (cells of width ``h`` centred on the disk's centre); with
    a ``direction`` (an angle), the area of the half disk ahead along it."""
    half = int(math.ceil(radius / h - 0.5))
    offsets = np.arange(-half, half + 1) * h
    u = ((np.arange(_KERNEL_SAMPLES) + 0.5) / _KERNEL_SAMPLES - 0.5) * h
    px = offsets[:, None, None, None] + u[None, None, :, None]
    py = offsets[None, :, None, None] + u[None, None, None, :]
    inside = px * px + py * py < radius * radius
    if direction is not None:
        inside &= px * math.cos(direction) + py * math.sin(direction) > 0.0
    return inside.mean(axis=(2, 3)) * h * h


def disk_share(region: Any, radius: float, spacing: float | None = None) -> DiskShare:
    """Tabulate ``s(x) = |B(x, r) ∩ Ω| / (π r²)`` over ``region`` (docs page *Congestion*).

    Parameters
    ----------
    region : Region
        Ω (:class:`meanfield.geometry.region.Region`); its exits are openings, beyond which
        nobody stands, so a disk over an exit is cut there as by a wall.
    radius : float
        ``r > 0``, the disk's radius (m).
    spacing : float, optional
        The lattice's spacing; default ``r / 8`` (:data:`CELLS_PER_RADIUS`), coarser when the
        bounding box would need more than :data:`MAX_TABLE_CELLS` cells.

    Returns
    -------
    DiskShare
        The table over the bounding box grown by one cell on every side.
    """
    if not (isinstance(radius, (int, float)) and math.isfinite(radius) and radius > 0):
        raise ParameterError("radius", radius, "a radius > 0 (m)")
    x0, x1, y0, y1 = region.bounds
    if spacing is None:
        spacing = max(radius / CELLS_PER_RADIUS, math.sqrt((x1 - x0) * (y1 - y0) / MAX_TABLE_CELLS))
    elif not (math.isfinite(spacing) and spacing > 0):
        raise ParameterError("spacing", spacing, "a spacing > 0 (m)")
    h = float(spacing)
    nx = int(math.ceil((x1 - x0) / h)) + 2  # one cell beyond the box on each side, so that a point on the
    ny = int(math.ceil((y1 - y0) / h)) + 2  # wall lies between two cells' centres
    xe = x0 - h + h * np.arange(nx + 1)
    ye = y0 - h + h * np.arange(ny + 1)
    weights = _footprint(float(radius), h)
    if not weights.sum() > 0.0:  # a disk that misses every sample of its cell (r far below the spacing):
        weights = np.ones((1, 1))  # its share is its cell's
    table = _convolved(_cell_shares(region, xe, ye), weights, weights.sum())
    return DiskShare(float(radius), (float(xe[0] + h / 2), float(ye[0] + h / 2)), h, table)


def _convolved(cells: np.ndarray, weights: np.ndarray, area: float) -> np.ndarray:
    """``Σ_d a_{c+d} w_d / area`` in [0, 1] (a correlation: ``w`` is flipped for the transform's convolution)."""
    from scipy.signal import fftconvolve

    table = fftconvolve(cells, weights[::-1, ::-1], mode="same") / area
    np.clip(table, 0.0, 1.0, out=table)  # the transform's round-off: whole disks are 1 exactly,
    table[table > 1.0 - 1e-9] = 1.0  # so that a crowd away from the walls counts as without them
    return table


@dataclass(frozen=True)
class HalfDiskShare:
    """The shares in Ω of the two halves of each disk, ahead of and behind a direction ``e``::

        s±(x, e) = |{y ∈ B(x, r) ∩ Ω : ±(y − x)·e > 0}| / (½ π r²),     s⁺ + s⁻ = 2 s(x)

    (docs page *Congestion*, "The agents' door model"), tabulated as :class:`DiskShare` for the
    :data:`HALF_DISK_DIRECTIONS` directions ``θ_k = 2πk/K``, read bilinearly in space and linearly in the
    angle.  Only half of them are stored: the half disk ahead along ``θ_k + π`` is the one behind ``θ_k``.

    Attributes
    ----------
    disk : DiskShare
        ``s``, the whole disk's share, on the same lattice.
    ahead : ndarray, shape (K/2, nx, ny)
        ``s⁺(·, θ_k)`` for ``k < K/2``.
    """

    disk: DiskShare
    ahead: np.ndarray

    def at(self, points: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(s, s⁺, s⁻)`` at ``points`` (shape (M, 2)) for the ``directions`` (shape (M, 2), any length > 0)."""
        p = np.asarray(points, float).reshape(-1, 2)
        e = np.asarray(directions, float).reshape(-1, 2)
        d = self.disk
        whole = d.at(p)
        half = len(self.ahead)
        read = np.stack([bilinear(t, d.origin[0], d.origin[1], d.spacing, p[:, 0], p[:, 1]) for t in self.ahead])
        # s⁺ for all K directions: the stored half, then the other half as 2s − s⁺ of the opposite direction
        every = np.concatenate([read, 2.0 * whole[None, :] - read])
        step = np.arctan2(e[:, 1], e[:, 0]) % (2.0 * math.pi) / (math.pi / half)
        k0 = np.floor(step).astype(np.int64) % (2 * half)
        w = step - np.floor(step)
        rows = np.arange(len(p))
        ahead = np.clip((1.0 - w) * every[k0, rows] + w * every[(k0 + 1) % (2 * half), rows], 0.0, 1.0)
        return whole, ahead, np.clip(2.0 * whole - ahead, 0.0, 1.0)


def half_disk_share(
    region: Any, radius: float, directions: int = HALF_DISK_DIRECTIONS, disk: DiskShare | None = None
) -> HalfDiskShare:
    """Tabulate the half disks' shares ``s±(x, e)`` over ``region`` (:class:`HalfDiskShare`).

    The lattice and the cells' shares of Ω are :func:`disk_share`'s; each direction's table is the
    correlation of the cells' shares with the half disk's footprint.  ``directions`` (even, >= 4) of them:
    ``s⁺`` is continuous in the angle, and reading it linearly between 16 directions is within 0.02 of a
    polar quadrature at 95 % of the points, and within 1/16 where a wall along the direction puts a kink
    between two of them (tests/geometry/test_disk_share.py).  ``disk``: the whole disk's table of
    ``region`` and ``radius`` when the caller has it (:func:`disk_share`'s, not built again).
    """
    if not (isinstance(directions, int) and directions >= 4 and directions % 2 == 0):
        raise ParameterError("directions", directions, "an even number of directions >= 4")
    if disk is None:
        disk = disk_share(region, radius)
    elif disk.radius != radius:
        raise ParameterError("disk", disk.radius, f"the table of the radius {radius:g} m")
    h = disk.spacing
    nx, ny = disk.table.shape
    xe = disk.origin[0] - h / 2 + h * np.arange(nx + 1)
    ye = disk.origin[1] - h / 2 + h * np.arange(ny + 1)
    cells = _cell_shares(region, xe, ye)
    area = 0.5 * _footprint(float(radius), h).sum()
    if not area > 0.0:  # a disk that misses every sample of its cell: both halves have their cell's share
        return HalfDiskShare(disk, np.repeat(disk.table[None], directions // 2, axis=0))
    angles = 2.0 * math.pi * np.arange(directions // 2) / directions
    return HalfDiskShare(disk, np.stack([_convolved(cells, _footprint(float(radius), h, a), area) for a in angles]))


def segment_share(distance: np.ndarray | float, radius: float) -> np.ndarray:
    """The closed form beside one straight wall: the share of ``B(x, r)`` on the wall's open side.

    ``1 − (r² acos(d/r) − d √(r² − d²)) / (π r²)`` at distance ``d ∈ [0, r]`` from the wall
    (the circular segment beyond it), 1 beyond ``r``.  The reference of the tests.
    """
    d = np.clip(np.asarray(distance, float) / radius, 0.0, 1.0)
    return 1.0 - (np.arccos(d) - d * np.sqrt(1.0 - d * d)) / math.pi
