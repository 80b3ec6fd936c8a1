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

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry.cut_cells import SLIVER
from meanfield.geometry.region import Region

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


@dataclass(eq=False)
class Grid:
    """Uniform Cartesian grid over the bounding box of ``domain``.

    Parameters
    ----------
    domain : Region
        The region Ω.
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

    domain: Region
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
        # Ω fills the bounding box: every cell whole, every face open (the fast paths of a rectangle)
        self.is_box = bool(self.active.all() and (frac == 1).all() and (ax == 1).all() and (ay == 1).all())
        # face-flux factors used by the divergence: aperture * face length / volume
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_v = np.where(self.active, 1.0 / np.where(self.active, self.volume, 1.0), 0.0)
        self._inv_volume = inv_v
        self._len_x = ax * self.dy
        self._len_y = ay * self.dx

    # ------------------------------------------------------------------ geometry
    def _fractions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cells' volume fractions and the faces' apertures (copies of those remembered for the last few
        grids: a study that runs one plan over many seeds clips its cells once per process)."""
        key = exact_key(self.domain)
        if key is None:  # (a region that cannot say exactly what it is: clipped each time)
            return _fractions(self.domain, self.cells, self.cut_cells)
        fractions = remember(_FRACTIONS, (key, self.cells, self.cut_cells),
                             lambda: _fractions(self.domain, self.cells, self.cut_cells))  # fmt: skip
        return tuple(a.copy() for a in fractions)

    @property
    def shape(self) -> tuple[int, int]:
        """``(nx, ny)``: the shape of every cell field."""
        return self.cells

    @property
    def centers(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates ``(X, Y)``, each of shape ``grid.shape`` (read-only: built once, shared)."""
        kept = self.__dict__.get("_centers")
        if kept is None:
            kept = tuple(np.meshgrid(self.x, self.y, indexing="ij"))
            for a in kept:
                a.flags.writeable = False
            self.__dict__["_centers"] = kept
        return kept

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
        return _weighted_dot(self.volume, f, g)

    def norm(self, f: np.ndarray) -> float:
        """``‖f‖_{L²(Ω)}``."""
        return float(np.sqrt(self.inner(f, f)))

    def face_inner(self, F: FaceField, G: FaceField) -> float:
        """Face inner product ``∫_Ω F·G dx`` of two face fields."""
        return _weighted_dot(self.weight_x, F[0], G[0]) + _weighted_dot(self.weight_y, F[1], G[1])

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

    def cell_boxes(self, grow: float = 0.0) -> np.ndarray:
        """Each cell's square as a shapely polygon, ``(nx, ny)``, grown by ``grow`` on every side (whole squares: a
        cut cell's part in Ω is the square's intersection with it)."""
        import shapely

        x0, _, y0, _ = self.domain.bounds
        nx, ny = self.cells
        XL, YL = np.meshgrid(x0 + np.arange(nx) * self.dx, y0 + np.arange(ny) * self.dy, indexing="ij")
        return shapely.box(XL - grow, YL - grow, XL + self.dx + grow, YL + self.dy + grow)

    def cell_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cell ``(i, j)`` each of ``points`` (N, 2) lies in, clamped to the grid's edge cells outside it."""
        x0, _, y0, _ = self.domain.bounds
        i = ((points[:, 0] - x0) / self.dx).astype(np.intp)
        j = ((points[:, 1] - y0) / self.dy).astype(np.intp)
        np.maximum(i, 0, out=i)  # (np.clip's numbers: its checks cost more than the cells of a few points)
        np.minimum(i, self.cells[0] - 1, out=i)
        np.maximum(j, 0, out=j)
        np.minimum(j, self.cells[1] - 1, out=j)
        return i, j

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


def _weighted_dot(w: np.ndarray, f: np.ndarray, g: np.ndarray) -> Any:
    """``Σ w f g``: one product and a dot (half the cost of ``(w * f * g).sum()``), any shapes that broadcast."""
    a, g = w * f, np.asarray(g)
    if a.shape != g.shape:
        return (a * g).sum()
    return np.dot(a.ravel(), g.ravel())  # (dot, not vdot: a complex step must not be conjugated)


def _fractions(domain: Region, cells: tuple[int, int], cut_cells: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The volume fraction of each of the ``cells`` over ``domain``'s bounding box and the aperture of each interior
    face (:meth:`Grid._fractions`): clipped by the region's :meth:`cut_cells`, or the cells whose centre ``domain``
    contains without ``cut_cells``."""
    nx, ny = cells
    x0, x1, y0, y1 = domain.bounds
    dx = (x1 - x0) / nx
    dy = (y1 - y0) / ny
    if not cut_cells:
        X, Y = np.meshgrid(x0 + (np.arange(nx) + 0.5) * dx, y0 + (np.arange(ny) + 0.5) * dy, indexing="ij")
        inside = domain.contains(X, Y)
        frac = inside.astype(float)
        ax = (inside[1:, :] & inside[:-1, :]).astype(float)
        ay = (inside[:, 1:] & inside[:, :-1]).astype(float)
        return frac, ax, ay
    xe = x0 + np.arange(nx + 1) * dx  # cell edges; xe[1:-1] == Grid.x_faces
    ye = y0 + np.arange(ny + 1) * dy
    frac, ax, ay = domain.cut_cells(xe, ye, dx, dy)
    if frac.all() and ax.all() and ay.all():  # Ω fills its bounding box (a rectangle)
        return frac, ax, ay
    frac = np.where(frac < SLIVER, 0.0, frac)  # clipping slivers (a vertex grazing a cell): round-off
    # a face is open only if both neighbours hold volume
    act = frac > 0
    ax = np.where(act[1:, :] & act[:-1, :], ax, 0.0)
    ay = np.where(act[:, 1:] & act[:, :-1], ay, 0.0)
    return frac, ax, ay


REMEMBERED = 16
"""How many regions' set-up a process keeps (:data:`_FRACTIONS`; the target's radius likewise)."""
_FRACTIONS: dict[Any, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
""":func:`_fractions` of the last :data:`REMEMBERED` grids, by :func:`exact_key`, the cells and ``cut_cells``."""


def exact_key(region: Any) -> Any:
    """A key equal for two regions only when they are written the same, vertex for vertex (their class and
    :meth:`to_dict`), so that what is remembered for one is what would be computed for the other to the last bit;
    None for a region without ``to_dict``."""
    to_dict = getattr(region, "to_dict", None)
    if to_dict is None:
        return None
    wkb = getattr(getattr(region, "polygon", None), "wkb", None)  # (a plan's WKT rounds its vertices; its WKB not)
    return f"{type(region).__module__}.{type(region).__qualname__}", repr(to_dict()), wkb


def remember(table: dict[Any, Any], key: Any, compute: Callable[[], Any]) -> Any:
    """``table[key]``, from ``compute()`` the first time; the oldest entry dropped beyond :data:`REMEMBERED`."""
    if key not in table:
        if len(table) >= REMEMBERED:
            del table[next(iter(table))]  # (dicts keep their order of insertion: the oldest first)
        table[key] = compute()
    return table[key]
