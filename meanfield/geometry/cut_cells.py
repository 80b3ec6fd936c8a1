"""Cut cells: the part of each grid cell and face inside Ω, computed exactly.

A disk in closed form (the true circle), a convex polygon by clipping with shapely only
the cells its wall crosses (the others are whole or empty).  Used by
:meth:`meanfield.geometry.domain.Domain.cut_cells`; the grid (:mod:`meanfield.geometry.grid`) turns the
fractions into cell volumes and face apertures (docs page *Discretisation*).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["SLIVER", "disk_cut_cells", "convex_polygon_cut_cells"]

SLIVER = 1e-12
"""Volume fractions below this are clipping round-off (a vertex grazing a cell), not volume."""


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _chord_parameters(p: np.ndarray, q: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``0 <= s1 <= s2 <= 1`` of the part of segment ``p→q`` inside the disk ``|x| <= r``."""
    d = q - p
    a = (d * d).sum(-1)
    b = (p * d).sum(-1)
    c = (p * p).sum(-1) - r * r
    disc = b * b - a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    hit = disc > 0
    s1 = np.clip(np.where(hit, (-b - root) / a, 0.0), 0.0, 1.0)
    s2 = np.clip(np.where(hit, (-b + root) / a, 0.0), 0.0, 1.0)
    return s1, s2


def _disk_wedge_area(p: np.ndarray, q: np.ndarray, r: float) -> np.ndarray:
    """Signed area of (triangle 0, p, q) ∩ (disk of radius ``r`` about 0).

    The part of ``p→q`` inside the disk contributes a triangle, the parts outside a
    circular sector; summed over the edges of a counter-clockwise polygon this is the
    exact area of polygon ∩ disk.
    """
    s1, s2 = _chord_parameters(p, q, r)
    d = q - p
    a = p + s1[..., None] * d
    b = p + s2[..., None] * d

    def angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.arctan2(_cross(u, v), (u * v).sum(-1))

    return 0.5 * r * r * (angle(p, a) + angle(b, q)) + 0.5 * _cross(a, b)


def _interval_near_far(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest ``|t|`` over ``t ∈ [lo, hi]``."""
    near = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
    return near, np.maximum(np.abs(lo), np.abs(hi))


def _disk_apertures(c: np.ndarray, lo: np.ndarray, hi: np.ndarray, length: float, r: float) -> np.ndarray:
    """Fraction of the segments ``{c} × [lo, hi]`` (``c`` across, ``t`` along) inside ``c² + t² <= r²``.

    ``c`` broadcasts against ``lo`` and ``hi``.  Whole segments give exactly 1, and
    segments that miss the disk exactly 0, with the same tests as the cells.
    """
    near, far = _interval_near_far(lo, hi)
    half = np.sqrt(np.maximum((r - np.abs(c)) * (r + np.abs(c)), 0.0))  # half-chord at c
    inside = np.clip((np.minimum(hi, half) - np.maximum(lo, -half)) / length, 0.0, 1.0)
    inside = np.where(c * c + far * far <= r * r, 1.0, inside)
    return np.where(c * c + near * near >= r * r, 0.0, inside)


def disk_cut_cells(
    center: tuple[float, float], r: float, xe: np.ndarray, ye: np.ndarray, dx: float, dy: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Volume fractions and apertures of the true circle, in closed form.

    Cells whose farthest point is in the disk are whole (1), cells whose nearest point
    is not are empty (0); only the cells the circle crosses get the exact area of
    square ∩ disk (:func:`_disk_wedge_area` over their four edges).  Apertures are the
    exact chord lengths.
    """
    cx, cy = center
    x = xe - cx  # edges relative to the centre
    y = ye - cy
    near_x, far_x = _interval_near_far(x[:-1], x[1:])
    near_y, far_y = _interval_near_far(y[:-1], y[1:])
    whole = far_x[:, None] ** 2 + far_y[None, :] ** 2 <= r * r
    cut = ~whole & (near_x[:, None] ** 2 + near_y[None, :] ** 2 < r * r)
    frac = whole.astype(float)
    i, j = np.nonzero(cut)
    corners = [np.stack([x[i + a], y[j + b]], -1) for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))]  # CCW
    area = sum(_disk_wedge_area(corners[m], corners[(m + 1) % 4], r) for m in range(4))
    frac[cut] = np.clip(area / (dx * dy), 0.0, 1.0)
    ax = _disk_apertures(x[1:-1, None], y[None, :-1], y[None, 1:], dy, r)  # x-faces: x = const
    ay = _disk_apertures(y[None, 1:-1], x[:-1, None], x[1:, None], dx, r)  # y-faces: y = const
    return frac, ax, ay


def convex_polygon_cut_cells(
    normal: np.ndarray, offset: np.ndarray, poly: Any, xe: np.ndarray, ye: np.ndarray, dx: float, dy: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Volume fractions and apertures of a convex polygon: shapely on the crossed cells only.

    A cell (or face) whose corners are all inside every edge line is whole (1); one whose
    corners are all beyond one edge line is empty (0).  Only the others, those the wall
    crosses, are clipped with shapely, exactly as a clip of every cell would do.
    """
    import shapely


    def classify(points: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
        """(all points inside Ω, all points beyond one edge line) for each element."""
        dist = [normal[:, 0] * px[..., None] + normal[:, 1] * py[..., None] - offset for px, py in points]
        inside = np.logical_and.reduce([np.all(d <= 0, axis=-1) for d in dist])
        outside = np.any(np.logical_and.reduce([d >= 0 for d in dist]), axis=-1)
        return inside, outside

    XL, YL = np.meshgrid(xe[:-1], ye[:-1], indexing="ij")
    XR, YR = XL + dx, YL + dy
    whole, empty = classify([(XL, YL), (XR, YL), (XR, YR), (XL, YR)])
    frac = whole.astype(float)
    cut = ~whole & ~empty
    boxes = shapely.box(XL[cut], YL[cut], XR[cut], YR[cut])
    frac[cut] = np.clip(shapely.area(shapely.intersection(boxes, poly)) / (dx * dy), 0.0, 1.0)

    def aperture(xa: np.ndarray, ya: np.ndarray, xb: np.ndarray, yb: np.ndarray, length: float) -> np.ndarray:
        inside, outside = classify([(xa, ya), (xb, yb)])
        out = inside.astype(float)
        part = ~inside & ~outside
        ends = np.stack([np.stack([xa[part], ya[part]], -1), np.stack([xb[part], yb[part]], -1)], axis=1)
        out[part] = np.clip(shapely.length(shapely.intersection(shapely.linestrings(ends), poly)) / length, 0.0, 1.0)
        return out

    XF, YF = np.meshgrid(xe[1:-1], ye[:-1], indexing="ij")  # x-faces: vertical segments
    ax = aperture(XF, YF, XF, YF + dy, dy)
    XF, YF = np.meshgrid(xe[:-1], ye[1:-1], indexing="ij")  # y-faces: horizontal segments
    ay = aperture(XF, YF, XF + dx, YF, dx)
    return frac, ax, ay
