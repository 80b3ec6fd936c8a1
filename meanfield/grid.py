"""Finite-volume grid on Ω with adjoint discrete gradient and divergence.

Cells tile the bounding box of Ω; fields are arrays of ``grid.shape == (nx, ny)``
indexed ``[i, j]`` with ``x`` along the first axis (``numpy.meshgrid(..., indexing="ij")``).
For a disk or a polygon, cells are *cut* by the wall: each cell carries its volume
fraction inside Ω and each face its aperture (the fraction of its length inside Ω),
computed exactly: in closed form for a disk (the true circle), and for a polygon by
clipping with shapely the cells the wall crosses (the others are whole or empty).
``cut_cells=False`` gives the staircase mask instead (a cell is in Ω when its centre is).

Vector fields (velocities, fluxes, gradients) live on the *interior faces*
(a staggered, MAC-type layout): the x-component on the ``(nx-1, ny)`` faces between
cells ``[i, j]`` and ``[i+1, j]``, the y-component on the ``(nx, ny-1)`` faces between
``[i, j]`` and ``[i, j+1]``.  Wall faces carry no flux (zero-flux boundary condition of
the Fokker–Planck equation, eq. (4) of the paper).

Inner products:

* cells: ``<f, g> = Σ_c V_c f_c g_c``, ``V_c`` the cell volume inside Ω;
* faces: ``<F, G> = Σ_x-faces w F_x G_x + Σ_y-faces w F_y G_y``, ``w`` = aperture ×
  face length × distance between the two cell centres.

With these, ``divergence = -gradientᵀ`` exactly (summation by parts,
``<f, div F> = -<grad f, F>``), which makes the discrete Lyapunov identities of the
paper (Theorems 1–3) hold to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from meanfield.domain import Domain
from meanfield.errors import ParameterError

__all__ = ["Grid", "FaceField", "linear_binning"]

FaceField = tuple[np.ndarray, np.ndarray]
"""A vector field on interior faces: ``(Fx, Fy)`` of shapes ``(nx-1, ny)``, ``(nx, ny-1)``."""


def linear_binning(
    points: np.ndarray,
    origin: tuple[float, float],
    spacing: tuple[float, float],
    shape: tuple[int, int],
    weight: float = 1.0,
) -> np.ndarray:
    """Cloud-in-cell (bilinear) binning of ``points`` onto a lattice of centres.

    The lattice has centres ``origin + (i + ½, j + ½) · spacing`` for ``(i, j) < shape``;
    each point spreads ``weight`` over its four nearest centres with bilinear weights
    (points beyond the outer centres go to the nearest edge).  Cost O(N).
    """
    mx, my = shape
    # in-place arithmetic on a few N-sized arrays; np.bincount scatters ~10× faster than np.add.at
    s = points[:, 0] - origin[0]
    s *= 1.0 / spacing[0]
    s -= 0.5
    np.clip(s, 0.0, mx - 1.0, out=s)
    t = points[:, 1] - origin[1]
    t *= 1.0 / spacing[1]
    t -= 0.5
    np.clip(t, 0.0, my - 1.0, out=t)
    i = s.astype(np.intp)
    np.minimum(i, mx - 2, out=i)
    j = t.astype(np.intp)
    np.minimum(j, my - 2, out=j)
    s -= i  # fs
    t -= j  # ft
    base = i
    base *= my
    base += j
    w11 = s * t
    s -= w11  # fs (1 - ft)
    t -= w11  # (1 - fs) ft
    w00 = 1.0 - w11
    w00 -= s
    w00 -= t  # (1 - fs)(1 - ft)
    if weight != 1.0:
        for w in (w00, s, t, w11):
            w *= weight
    n = mx * my
    out = np.bincount(base, w00, n)
    out[my:] += np.bincount(base, s, n)[: n - my]
    out[1:] += np.bincount(base, t, n)[: n - 1]
    out[my + 1 :] += np.bincount(base, w11, n)[: n - my - 1]
    return out.reshape(mx, my)


# ---------------------------------------------------------------------- cut-cell geometry
_SLIVER = 1e-12
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


def _disk_cut_cells(
    domain: Domain, xe: np.ndarray, ye: np.ndarray, dx: float, dy: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Volume fractions and apertures of the true circle, in closed form.

    Cells whose farthest point is in the disk are whole (1), cells whose nearest point
    is not are empty (0); only the cells the circle crosses get the exact area of
    square ∩ disk (:func:`_disk_wedge_area` over their four edges).  Apertures are the
    exact chord lengths.
    """
    cx, cy = domain.center
    r = domain.radius
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


def _polygon_cut_cells(
    domain: Domain, xe: np.ndarray, ye: np.ndarray, dx: float, dy: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Volume fractions and apertures of a convex polygon: shapely on the crossed cells only.

    A cell (or face) whose corners are all inside every edge line is whole (1); one whose
    corners are all beyond one edge line is empty (0).  Only the others, those the wall
    crosses, are clipped with shapely, exactly as a clip of every cell would do.
    """
    import shapely

    _, normal, offset = domain._edges()
    poly = domain.to_shapely()

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


@dataclass(eq=False)
class Grid:
    """Uniform Cartesian grid over the bounding box of ``domain``.

    Parameters
    ----------
    domain : Domain
        The workspace Ω.
    cells : (int, int)
        Number of cells ``(nx, ny)`` along x and y, each >= 2.
    cut_cells : bool, default True
        Use volume fractions and face apertures for curved or slanted walls
        (ignored for a box, whose cells are all whole).  ``False``: staircase mask.

    Examples
    --------
    >>> grid = Grid(Domain.box(1.0, 1.0), cells=(30, 30))
    >>> X, Y = grid.centers
    >>> float(grid.integrate(np.ones(grid.shape)))
    1.0
    """

    domain: Domain
    cells: tuple[int, int] = (30, 30)
    cut_cells: bool = True
    x: np.ndarray = field(init=False, repr=False)
    y: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        try:
            nx, ny = (int(c) for c in self.cells)
        except (TypeError, ValueError):
            raise ParameterError("cells", self.cells, "a pair of integers (nx, ny)") from None
        if nx < 2 or ny < 2 or (nx, ny) != tuple(self.cells):
            raise ParameterError("cells", self.cells, "a pair of integers, each >= 2")
        self.cells = (nx, ny)
        x0, x1, y0, y1 = self.domain.bounds
        self.dx = (x1 - x0) / nx
        self.dy = (y1 - y0) / ny
        self.x = x0 + (np.arange(nx) + 0.5) * self.dx
        self.y = y0 + (np.arange(ny) + 0.5) * self.dy
        self.x_faces = x0 + np.arange(1, nx) * self.dx  # interior x-face abscissae
        self.y_faces = y0 + np.arange(1, ny) * self.dy
        frac, ax, ay = self._fractions()
        self.volume_fraction = frac
        self.aperture_x = ax
        self.aperture_y = ay
        self.volume = frac * self.dx * self.dy
        self.active = frac > 0
        self.weight_x = ax * self.dy * self.dx
        self.weight_y = ay * self.dx * self.dy
        self.is_box = self.domain.kind == "box"
        # face-flux factors used by the divergence: aperture * face length / volume
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_v = np.where(self.active, 1.0 / np.where(self.active, self.volume, 1.0), 0.0)
        self._inv_volume = inv_v
        self._len_x = ax * self.dy
        self._len_y = ay * self.dx

    # ------------------------------------------------------------------ geometry
    def _fractions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nx, ny = self.cells
        if self.domain.kind == "box":
            return np.ones((nx, ny)), np.ones((nx - 1, ny)), np.ones((nx, ny - 1))
        if not self.cut_cells:
            X, Y = np.meshgrid(self.x, self.y, indexing="ij")
            inside = self.domain.contains(X, Y)
            frac = inside.astype(float)
            ax = (inside[1:, :] & inside[:-1, :]).astype(float)
            ay = (inside[:, 1:] & inside[:, :-1]).astype(float)
            return frac, ax, ay
        x0, _, y0, _ = self.domain.bounds
        xe = x0 + np.arange(nx + 1) * self.dx  # cell edges; xe[1:-1] == self.x_faces
        ye = y0 + np.arange(ny + 1) * self.dy
        if self.domain.kind == "disk":
            frac, ax, ay = _disk_cut_cells(self.domain, xe, ye, self.dx, self.dy)
        else:
            frac, ax, ay = _polygon_cut_cells(self.domain, xe, ye, self.dx, self.dy)
        frac[frac < _SLIVER] = 0.0  # clipping slivers (a vertex grazing a cell): round-off, not volume
        # a face is open only if both neighbours hold volume
        act = frac > 0
        ax = np.where(act[1:, :] & act[:-1, :], ax, 0.0)
        ay = np.where(act[:, 1:] & act[:, :-1], ay, 0.0)
        return frac, ax, ay

    @property
    def shape(self) -> tuple[int, int]:
        """``(nx, ny)``: the shape of every cell field."""
        return self.cells

    @property
    def centers(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates ``(X, Y)``, each of shape ``grid.shape``."""
        return np.meshgrid(self.x, self.y, indexing="ij")

    @property
    def face_points_x(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates of the interior x-faces, each of shape ``(nx-1, ny)``."""
        return np.meshgrid(self.x_faces, self.y, indexing="ij")

    @property
    def face_points_y(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates of the interior y-faces, each of shape ``(nx, ny-1)``."""
        return np.meshgrid(self.x, self.y_faces, indexing="ij")

    @property
    def area(self) -> float:
        """Discrete area Σ V_c of Ω."""
        return float(self.volume.sum())

    # ------------------------------------------------------------------ integration
    def integrate(self, f: np.ndarray) -> float:
        """``∫_Ω f dx`` by the midpoint rule on cut cells."""
        return (self.volume * f).sum()

    def inner(self, f: np.ndarray, g: np.ndarray) -> float:
        """Cell inner product ``∫_Ω f g dx``."""
        return (self.volume * f * g).sum()

    def norm(self, f: np.ndarray) -> float:
        """``‖f‖_{L²(Ω)}``."""
        return float(np.sqrt(self.inner(f, f)))

    def face_inner(self, F: FaceField, G: FaceField) -> float:
        """Face inner product ``∫_Ω F·G dx`` of two face fields."""
        return (self.weight_x * F[0] * G[0]).sum() + (self.weight_y * F[1] * G[1]).sum()

    def face_norm(self, F: FaceField) -> float:
        """``‖F‖_{L²(Ω)}`` of a face field."""
        return float(np.sqrt(self.face_inner(F, F)))

    # ------------------------------------------------------------------ operators
    def gradient(self, f: np.ndarray) -> FaceField:
        """Discrete gradient on interior faces: ``(f[i+1,j]-f[i,j])/dx``, ``(f[i,j+1]-f[i,j])/dy``."""
        gx = (f[1:, :] - f[:-1, :]) * (1.0 / self.dx)
        gy = (f[:, 1:] - f[:, :-1]) * (1.0 / self.dy)
        if not self.is_box:
            gx = gx * (self.aperture_x > 0)
            gy = gy * (self.aperture_y > 0)
        return gx, gy

    def divergence(self, F: FaceField) -> np.ndarray:
        """Discrete divergence of a face field with zero flux through every wall face.

        ``div F = -gradientᵀ F`` in the cell and face inner products, so
        ``grid.inner(f, grid.divergence(F)) == -grid.face_inner(grid.gradient(f), F)``
        to round-off.
        """
        fx = self._len_x * F[0]
        fy = self._len_y * F[1]
        nx, ny = self.cells
        out = np.zeros((nx, ny), dtype=np.result_type(fx, fy))
        out[:-1, :] += fx
        out[1:, :] -= fx
        out[:, :-1] += fy
        out[:, 1:] -= fy
        return out * self._inv_volume

    def face_average(self, f: np.ndarray) -> FaceField:
        """Arithmetic mean of the two cells on each side of every interior face."""
        return 0.5 * (f[1:, :] + f[:-1, :]), 0.5 * (f[:, 1:] + f[:, :-1])

    def to_cells(self, F: FaceField) -> tuple[np.ndarray, np.ndarray]:
        """Average a face field to cell centres (for plots); wall faces count as zero."""
        nx, ny = self.cells
        u = np.zeros((nx + 1, ny))
        v = np.zeros((nx, ny + 1))
        u[1:-1] = F[0]
        v[:, 1:-1] = F[1]
        return 0.5 * (u[1:] + u[:-1]), 0.5 * (v[:, 1:] + v[:, :-1])

    def interpolate(self, f: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Bilinear interpolation of a cell field at ``points`` (N, 2), clamped at the edges."""
        x0, _, y0, _ = self.domain.bounds
        nx, ny = self.cells
        s = (points[:, 0] - x0) / self.dx - 0.5
        t = (points[:, 1] - y0) / self.dy - 0.5
        s = np.clip(s, 0.0, nx - 1.0)
        t = np.clip(t, 0.0, ny - 1.0)
        i = np.minimum(s.astype(np.intp), nx - 2)
        j = np.minimum(t.astype(np.intp), ny - 2)
        fs = s - i
        ft = t - j
        return (
            f[i, j] * (1 - fs) * (1 - ft)
            + f[i + 1, j] * fs * (1 - ft)
            + f[i, j + 1] * (1 - fs) * ft
            + f[i + 1, j + 1] * fs * ft
        )

    def normalize(self, f: np.ndarray) -> np.ndarray:
        """``f`` restricted to Ω and scaled to unit mass."""
        f = np.where(self.active, f, 0.0)
        m = self.integrate(f)
        if not np.isfinite(m) or m <= 0:
            raise ParameterError("density", f"mass {m}", "a non-negative field of positive mass")
        return f / m
