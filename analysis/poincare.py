"""The Poincaré constant of the workspace: the first non-zero Neumann eigenvalue μ₂ of Ω.

Theorem 1 of the paper bounds the decay of the density-tracking Lyapunov function through
the Poincaré–Wirtinger inequality on Ω,

    ∫_Ω |f − f̄|² ≤ (1/μ₂) ∫_Ω |∇f|²,   hence   dV₁/dt ≤ −2 α_inf μ₂ V₁,

where μ₂ is the first non-zero eigenvalue of the Neumann Laplacian
(``-Δu = μ u`` in Ω, ``∂u/∂n = 0`` on ∂Ω) and the paper's Poincaré constant is
``c₂ = √μ₂``.  The inequality holds on every bounded connected Lipschitz domain, convex or
not, so this module computes μ₂ for every region: the shapes of
:class:`~meanfield.geometry.domain.Domain` and floor plans (:class:`~meanfield.geometry.plan.Plan`,
non-convex, with holes):

* :func:`neumann_eigenvalue`: the k-th non-zero eigenvalue of the cell-centred
  finite-volume Neumann Laplacian of :class:`~meanfield.geometry.grid.Grid` (cut cells for disks,
  polygons and plans), by sparse shift-invert Lanczos.  Second-order accurate on boxes,
  disks and convex polygons (measured; see ``docs/poincare.md``), slower at re-entrant
  corners.
* :func:`payne_weinberger_bound`: the certified lower bound ``π²/diam(Ω)²``, for convex Ω
  only (``None`` otherwise: see :func:`is_convex`).
* :func:`exact_neumann_eigenvalue`: closed forms (rectangle, disk, equilateral and
  right isosceles triangle), ``None`` otherwise.
* :func:`poincare_report`: all of the above in one :class:`PoincareReport`.

:mod:`analysis.plan_constants` adds what floor plans need: whether the grid keeps Ω in one
piece, and the decay rate with exits.

Examples
--------
>>> from meanfield import Domain
>>> mu2 = neumann_eigenvalue(Domain.disk(1.0), cells=(128, 128))
>>> round(mu2, 3)
3.39
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.sparse.csgraph import connected_components

from meanfield.errors import ParameterError
from meanfield.geometry.domain import Domain
from meanfield.geometry.grid import Grid
from meanfield.geometry.region import Region, convex_polygon

__all__ = [
    "PoincareReport",
    "exact_neumann_eigenvalue",
    "is_convex",
    "neumann_eigenvalue",
    "payne_weinberger_bound",
    "poincare_report",
]

DEFAULT_CELLS = (128, 128)
_MIN_CELLS = 4
_DENSE_LIMIT = 100  # up to this many unknowns, a dense generalized eigensolve
_SHAPE_RTOL = 1e-9  # relative tolerance of the closed-form shape detection
_MAX_ITERATIONS = 300  # subspace iterations before falling back to ARPACK
_RESIDUAL_TOL = 1e-10  # relative residual of the shift-inverted Ritz pairs
NOT_CONVEX = "not applicable (Ω not convex)"
"""How reports print the Payne–Weinberger bound of a non-convex Ω."""


# ---------------------------------------------------------------------- validation
def _check_domain(domain: Any) -> Domain:
    if isinstance(domain, Grid):
        return domain.domain
    if not isinstance(domain, Region):
        raise ParameterError(
            "domain", type(domain).__name__, "a region (a meanfield.Domain or Plan) or a meanfield.Grid"
        )
    return domain


def _check_cells(cells: Any) -> tuple[int, int]:
    allowed = "a pair of integers, each >= 4"
    if isinstance(cells, (str, bytes)):
        raise ParameterError("cells", cells, allowed)
    try:
        pair = tuple(cells)
    except TypeError:
        raise ParameterError("cells", cells, allowed) from None
    if len(pair) != 2 or any(isinstance(c, (bool, np.bool_)) for c in pair):
        raise ParameterError("cells", cells, allowed)
    try:
        nx, ny = (operator.index(c) for c in pair)
    except TypeError:
        raise ParameterError("cells", cells, allowed) from None
    if nx < _MIN_CELLS or ny < _MIN_CELLS:
        raise ParameterError("cells", cells, allowed)
    return nx, ny


def _check_k(k: Any) -> int:
    if isinstance(k, (bool, np.bool_)):
        raise ParameterError("k", k, "an integer >= 1 (k = 1 gives μ₂)")
    try:
        k = operator.index(k)
    except TypeError:
        raise ParameterError("k", k, "an integer >= 1 (k = 1 gives μ₂)") from None
    if k < 1:
        raise ParameterError("k", k, "an integer >= 1 (k = 1 gives μ₂)")
    return k


def _check_flag(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(name, value, "True or False")
    return bool(value)


# ---------------------------------------------------------------------- operator
def _face_graph(grid: Grid) -> tuple[sp.csr_matrix, np.ndarray]:
    """Weighted adjacency of the active cells through the open faces, and those cells' mask.

    The weight of a face is aperture × face length / cell distance, so that the stiffness
    ``diag(row sums) − adjacency`` is ``Gᵀ W G`` of :func:`_assemble`.
    """
    nx, ny = grid.shape
    active = grid.volume > 0
    index = np.full((nx, ny), -1)
    index[active] = np.arange(int(active.sum()))
    rows, cols, vals = [], [], []
    for coef, left, right in (
        (grid.aperture_x * (grid.dy / grid.dx), index[:-1, :], index[1:, :]),
        (grid.aperture_y * (grid.dx / grid.dy), index[:, :-1], index[:, 1:]),
    ):
        open_ = (coef > 0) & (left >= 0) & (right >= 0)
        rows.append(left[open_])
        cols.append(right[open_])
        vals.append(coef[open_])
    n = int(active.sum())
    r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    return sp.coo_matrix((np.r_[w, w], (np.r_[r, c], np.r_[c, r])), shape=(n, n)).tocsr(), active


def _assemble(grid: Grid) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    """Stiffness ``L = Gᵀ W G``, lumped mass ``M`` (cell volumes) and the unknown cells.

    ``G`` takes differences across the open faces, ``W`` is the face weight of
    :class:`Grid` divided by the squared cell distance, i.e. aperture × face length /
    distance, so that ``uᵀ L u = grid.face_inner(grid.gradient(u), grid.gradient(u))``
    and ``L = -diag(V) · grid.divergence ∘ grid.gradient``.  Only cells in the largest
    connected group of active cells are unknowns: a cell reached by no open face (a
    sliver cut at a vertex) would add a spurious zero eigenvalue.
    """
    nx, ny = grid.shape
    volume = grid.volume
    adjacency, active = _face_graph(grid)
    n = adjacency.shape[0]
    ncomp, labels = connected_components(adjacency, directed=False)
    keep = np.ones(n, bool)
    if ncomp > 1:
        mass = np.bincount(labels, weights=volume[active])
        keep = labels == int(np.argmax(mass))
        adjacency = adjacency[keep][:, keep]
    stiffness = sp.diags(np.asarray(adjacency.sum(axis=1)).ravel()) - adjacency
    unknown = np.zeros(nx * ny, bool)
    unknown[np.flatnonzero(active)[keep]] = True
    unknown = unknown.reshape(nx, ny)
    return stiffness.tocsc(), volume[unknown], unknown


def _smallest_eigenpairs(
    stiffness: sp.csc_matrix, mass: np.ndarray, count: int, shift: float
) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` smallest eigenpairs of ``L u = μ M u`` orthogonal to the constants.

    ``L`` is the stiffness of a connected graph, so its null space is exactly the
    constants: they are projected out (in the ``M`` inner product) and the returned
    eigenvalues are μ₂, μ₃, … (ascending), with ``M``-orthonormal eigenvectors.

    Small problems use a dense solver.  Otherwise a block shift-invert subspace
    iteration with Rayleigh–Ritz: one sparse LU of ``L - σM`` (σ < 0, so it is positive
    definite), block size ``count + 4`` (multiple eigenvalues are resolved), stopped when
    every wanted Ritz pair has a relative residual below 1e-10 (eigenvalues then exact to
    round-off).  It uses no multithreaded BLAS on long vectors: ARPACK does, and on a
    busy machine its threads make a 0.05 s solve take a second.  ARPACK (``eigsh``) is
    the fallback should the iteration stall.
    """
    n = stiffness.shape[0]
    total = float(mass.sum())

    def project(x: np.ndarray) -> np.ndarray:
        return x - np.einsum("i,ij->j", mass, x) / total

    if n <= _DENSE_LIMIT or count + 4 > n // 4:
        vals, vecs = scipy.linalg.eigh(stiffness.toarray(), np.diag(mass))
        return vals[1 : count + 1], vecs[:, 1 : count + 1]
    mass_matrix = sp.diags(mass).tocsc()
    lu = sla.splu((stiffness - shift * mass_matrix).tocsc(), permc_spec="MMD_AT_PLUS_A")
    block = count + 4
    x = project(np.random.default_rng(0).standard_normal((n, block)))
    theta = nu = np.zeros(block)
    for it in range(_MAX_ITERATIONS):
        y = project(lu.solve(mass[:, None] * x))
        if it > 0:
            r = y[:, :count] - x[:, :count] * nu[:count]
            residual = np.sqrt(np.einsum("i,ij,ij->j", mass, r, r)) / nu[:count]
            if np.all(residual <= _RESIDUAL_TOL):
                return theta[:count], x[:, :count]
        gram = np.einsum("i,ij,ik->jk", mass, y, y)
        energy = np.einsum("ij,ik->jk", y, stiffness @ y)
        theta, v = scipy.linalg.eigh(0.5 * (energy + energy.T), 0.5 * (gram + gram.T))
        x = np.einsum("ij,jk->ik", y, v)
        nu = 1.0 / (theta - shift)
    # did not converge (a cluster just beyond the block): ARPACK on the same LU
    opinv = sla.LinearOperator((n, n), matvec=lu.solve, dtype=float)
    vals, vecs = sla.eigsh(stiffness, k=min(count + 2, n - 1), M=mass_matrix, sigma=shift, OPinv=opinv)
    order = np.argsort(vals)[1 : count + 1]
    return vals[order], vecs[:, order]


# ---------------------------------------------------------------------- public API
def neumann_eigenvalue(
    domain: Domain | Grid,
    cells: tuple[int, int] | None = None,
    *,
    cut_cells: bool | None = None,
    k: int = 1,
    return_mode: bool = False,
) -> float | tuple[float, np.ndarray]:
    """The k-th non-zero eigenvalue of the Neumann Laplacian on Ω (k = 1: μ₂).

    Solves ``-Δu = μ u`` in Ω, ``∂u/∂n = 0`` on ∂Ω, with the cell-centred finite volumes
    of :class:`~meanfield.geometry.grid.Grid`: the generalized eigenproblem ``L u = μ M u`` with
    ``L = Gᵀ W G`` (``G`` the differences across the open faces, ``W`` aperture × face
    length / cell distance) and ``M`` the cell volumes inside Ω.  ``L`` is exactly
    ``-M`` times ``grid.divergence ∘ grid.gradient`` (the Fokker–Planck solver's
    operator for constant σ and no drift, divided by σ), so μ₂ is also the discrete
    decay rate of that operator.

    μ₂ is the constant of the Poincaré–Wirtinger inequality used in Theorem 1 of the
    paper (``dV₁/dt ≤ -2 α_inf μ₂ V₁``); the paper's Poincaré constant is ``c₂ = √μ₂``.

    Accuracy: exact discrete eigenvalue ``(4/h²) sin²(πh/2L)`` on a box (relative error
    ``π²h²/12L²``); second order on disks and convex polygons through cut cells
    (relative error ≈ 6e-5 on the unit disk at 128², see ``docs/poincare.md``).  The
    discrete value converges from below.  On a floor plan (non-convex, holes) the same
    operator with the plan's cut cells: exact on the L of three squares for the modes the
    grid aligns with, slower (below second order) for the modes a re-entrant corner bends.

    Parameters
    ----------
    domain : Domain, Plan or Grid
        The workspace Ω: any region (:class:`~meanfield.geometry.region.Region`), convex or not.  A
        :class:`~meanfield.geometry.grid.Grid` is used as it is (its own cut cells); for a region
        the grid ``Grid(domain, cells, cut_cells)`` is built (exact cut cells: a disk is
        the true circle, a plan is clipped with shapely).
    cells : (int, int), default (128, 128)
        Cells ``(nx, ny)`` over the bounding box, each >= 4.  With a ``Grid``, leave it
        out or give the grid's own.
    cut_cells : bool, default True
        Cut cells on curved or slanted walls; ``False``: the staircase mask (first
        order).  With a ``Grid``, leave it out or give the grid's own.
    k : int, default 1
        Which non-zero eigenvalue (counted with multiplicity): ``k = 1`` gives μ₂.
    return_mode : bool, default False
        Also return the eigenfunction.

    Returns
    -------
    float or (float, ndarray)
        The eigenvalue, and with ``return_mode`` the eigenfunction on ``grid.shape``,
        normalised to ``∫ u² = 1`` (its largest value positive), NaN outside Ω.  For a
        multiple eigenvalue (the disk's μ₂) it is one function of the eigenspace.

    Raises
    ------
    ParameterError
        A ``domain`` that is not a Domain or Grid, ``cells`` not a pair of integers
        >= 4, ``k`` not an integer >= 1 (or beyond the grid's unknowns), or a non-bool
        flag.

    Examples
    --------
    >>> from meanfield import Domain
    >>> mu = neumann_eigenvalue(Domain.box(1.0, 1.0), cells=(64, 64))
    >>> abs(mu - 4 * 64**2 * math.sin(math.pi / 128) ** 2) < 1e-9
    True
    """
    dom = _check_domain(domain)
    k = _check_k(k)
    return_mode = _check_flag("return_mode", return_mode)
    if isinstance(domain, Grid):
        if cells is not None and _check_cells(cells) != domain.cells:
            raise ParameterError("cells", cells, f"left out or the grid's own cells {domain.cells}")
        if cut_cells is not None and _check_flag("cut_cells", cut_cells) != domain.cut_cells:
            raise ParameterError("cut_cells", cut_cells, f"left out or the grid's own {domain.cut_cells}")
        shape = _check_cells(domain.cells)
        grid = domain
    else:
        shape = _check_cells(DEFAULT_CELLS if cells is None else cells)
        cut = True if cut_cells is None else _check_flag("cut_cells", cut_cells)
        grid = Grid(dom, shape, cut_cells=cut)
    stiffness, mass, unknown = _assemble(grid)
    n = stiffness.shape[0]
    if k > n - 1:
        raise ParameterError("k", k, f"an integer between 1 and {n - 1} for this grid ({n} cells in Ω)")
    shift = -1e-3 * math.pi**2 / dom.diameter**2  # any σ < 0 keeps L − σM definite; this one is μ₂'s scale
    vals, vecs = _smallest_eigenpairs(stiffness, mass, k, shift)
    mu = float(vals[k - 1])
    if not return_mode:
        return mu
    u = vecs[:, k - 1] / math.sqrt(float(np.sum(mass * vecs[:, k - 1] ** 2)))
    if u[np.argmax(np.abs(u))] < 0:
        u = -u
    mode = np.full(shape, np.nan)
    mode[unknown] = u
    return mu, mode


def is_convex(domain: Domain | Grid) -> bool:
    """Whether Ω is convex, as the region reports it (``is_convex``: every :class:`Domain` is; a plan
    when it has no holes and its convex hull adds no area beyond round-off, relative ``1e-12``,
    :func:`meanfield.geometry.region.convex_polygon`); a region that does not report it is
    judged by its shapely outline the same way.

    Parameters
    ----------
    domain : Domain, Plan or Grid
        The workspace (a grid's domain is used).
    """
    dom = _check_domain(domain)
    reported = getattr(dom, "is_convex", None)
    if reported is not None:
        return bool(reported)
    return convex_polygon(dom.to_shapely())


def payne_weinberger_bound(domain: Domain | Grid) -> float | None:
    """The Payne–Weinberger lower bound ``μ₂ >= π²/diam(Ω)²`` for convex Ω; ``None`` otherwise.

    Payne & Weinberger, "An optimal Poincaré inequality for convex domains",
    Arch. Rational Mech. Anal. 5 (1960) 286–292; the gap in their proof was closed by
    M. Bebendorf, "A note on the Poincaré inequality for convex domains",
    Z. Anal. Anwend. 22 (2003) 751–756.  The bound is sharp (thin domains approach it)
    and certified for every :class:`Domain`, all of which are convex.  It gives the
    guaranteed rate ``dV₁/dt ≤ -2 α_inf (π/diam Ω)² V₁`` in Theorem 1 of the paper.

    It does not hold without convexity: two rooms joined by a narrow door have μ₂ as small
    as one likes at a fixed diameter.  For a region that is not convex (:func:`is_convex`:
    a plan with a re-entrant corner or a hole) the bound is not applicable and ``None`` is
    returned, never a number (``docs/poincare.md``, *Floor plans*); the computed μ₂ of
    :func:`neumann_eigenvalue` still gives Theorem 1's rate there.

    Parameters
    ----------
    domain : Domain, Plan or Grid
        The workspace (a grid's domain is used).

    Returns
    -------
    float or None
        ``π²/diam(Ω)²``, or ``None`` when Ω is not convex.
    """
    dom = _check_domain(domain)
    if not is_convex(dom):
        return None
    return math.pi**2 / dom.diameter**2


def _close(a: float, b: float, scale: float) -> bool:
    return abs(a - b) <= _SHAPE_RTOL * scale


def exact_neumann_eigenvalue(domain: Domain | Grid) -> float | None:
    """μ₂ in closed form where it is known, else ``None``.

    * rectangle ``w × h`` (a box, or a polygon that is a rotated rectangle):
      ``π²/max(w, h)²``;
    * disk of radius ``r``: ``(j′₁₁/r)²``, ``j′₁₁ ≈ 1.8411837813`` the first positive
      zero of ``J₁′`` (unit disk: 3.389957…), a double eigenvalue;
    * equilateral triangle of side ``a``: ``16π²/(9a²)`` (Lamé; B. J. McCartin,
      "Eigenstructure of the equilateral triangle, Part II: The Neumann problem",
      Math. Probl. Eng. 8 (2002) 517–539);
    * right isosceles triangle with legs ``a``: ``π²/a²`` (the square's modes that are
      even about its diagonal, e.g. ``cos(πx/a) − cos(πy/a)`` on ``x + y <= a``).

    The polygon shapes are recognised up to vertex order, rotation and translation
    (relative tolerance 1e-9).  Both triangle values are also confirmed by the
    second-order convergence of :func:`neumann_eigenvalue` (``docs/poincare.md``).

    Parameters
    ----------
    domain : Domain or Grid
        The workspace (a grid's domain is used).
    """
    dom = _check_domain(domain)
    closed_form = dom.neumann_eigenvalue()  # the shape's own: rectangle, disk
    if closed_form is not None:
        return closed_form
    v = getattr(dom, "vertices", None)  # a polygon's vertices (a plan with holes has none)
    if v is None:
        return None
    scale = dom.diameter
    sides = np.hypot(*(np.roll(v, -1, axis=0) - v).T)
    if len(v) == 4:
        # a parallelogram with equal diagonals is a rectangle
        diag1, diag2 = np.hypot(*(v[2] - v[0])), np.hypot(*(v[3] - v[1]))
        parallelogram = np.allclose(v[0] + v[2], v[1] + v[3], rtol=0.0, atol=_SHAPE_RTOL * scale)
        if parallelogram and _close(diag1, diag2, scale):
            return math.pi**2 / float(sides.max()) ** 2
        return None
    if len(v) == 3:
        a, b, c = np.sort(sides)
        if _close(a, c, scale):
            return 16 * math.pi**2 / (9 * float(a) ** 2)
        if _close(a, b, scale) and _close(c, math.sqrt(2) * a, scale):
            return math.pi**2 / float(a) ** 2
    return None


@dataclass(frozen=True)
class PoincareReport:
    """μ₂ of a domain with its Poincaré constant, lower bound and closed form.

    Attributes
    ----------
    mu2 : float
        Computed first non-zero Neumann eigenvalue.
    c2 : float
        The paper's Poincaré constant ``√μ₂``.
    payne_weinberger : float or None
        The certified lower bound ``π²/diam(Ω)²``; ``None`` when Ω is not convex (the bound
        is not applicable: :func:`payne_weinberger_bound`).
    exact : float or None
        The closed form, where known.
    relative_error : float or None
        ``|mu2 - exact| / exact``, where the closed form is known.
    cells : (int, int)
        The grid used.
    """

    mu2: float
    c2: float
    payne_weinberger: float | None
    exact: float | None
    relative_error: float | None
    cells: tuple[int, int]

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (JSON/TOML friendly)."""
        return {
            "mu2": self.mu2,
            "c2": self.c2,
            "payne_weinberger": self.payne_weinberger,
            "exact": self.exact,
            "relative_error": self.relative_error,
            "cells": list(self.cells),
        }


def poincare_report(
    domain: Domain | Grid, cells: tuple[int, int] | None = None, *, cut_cells: bool | None = None
) -> PoincareReport:
    """Compute μ₂ and collect it with ``c₂ = √μ₂``, the Payne–Weinberger bound and the closed form.

    Arguments as in :func:`neumann_eigenvalue`.  On a region that is not convex the
    Payne–Weinberger entry is ``None`` (not applicable), never a number.
    """
    mu2 = neumann_eigenvalue(domain, cells, cut_cells=cut_cells)
    exact = exact_neumann_eigenvalue(domain)
    used = domain.cells if isinstance(domain, Grid) else _check_cells(DEFAULT_CELLS if cells is None else cells)
    return PoincareReport(
        mu2=mu2,
        c2=math.sqrt(mu2),
        payne_weinberger=payne_weinberger_bound(domain),
        exact=exact,
        relative_error=None if exact is None else abs(mu2 - exact) / exact,
        cells=tuple(used),
    )
