"""Step I towards the exits: the geodesic distance to the nearest exit and the controller that follows it.

* :func:`exit_distance` — ``φ``, the length of the shortest path from each cell to an exit
  inside Ω (around walls and pillars): Dijkstra's algorithm on the grid's cells, each joined
  to its 8 neighbours through open faces (a diagonal only when a path along the two faces is
  open), an exit cell starting at its centre's distance to the exit.  The 8-neighbour metric
  is exact along the axes and the diagonals and overestimates other directions by at most
  8.2 % (``1/cos 22.5°``).
* :class:`EvacuationController` — the paper's Step II (eq. (8)) tracking the desired field
  of Hughes' continuum model, ``v_d = −f(ρ) ∇φ − u_W[ρ]`` with ``f(ρ) = v_free (1 − ρ/ρ_max)``
  (walking speed falls with the density), instead of the paper's Step I.  Step II does not
  care which ``v_d`` it tracks: with the matching ``∂_t v_d = −f'(ρ) ρ̇ ∇φ − u_W[ρ̇]`` the law
  gives ``dV₂/dt = S − Σ k_u|b_i|² − Σ k_ω g_i²``, where the Step-I term
  ``S = ⟨∇ρ̃, (v_d + u_W)ρ − ∇(σρ)⟩`` replaces the paper's ``−∫α|∇ρ̃|²`` (reported as
  ``dissipation = −S``).  Registered as controller ``evacuation``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.control import BacksteppingController, _Prepared
from meanfield.errors import ParameterError
from meanfield.grid import FaceField, Grid
from meanfield.interfaces import ControllerParts

__all__ = ["exit_distance", "EvacuationController"]


def exit_distance(grid: Grid, segs: np.ndarray) -> np.ndarray:
    """``φ`` on the cells: the shortest path inside Ω to the nearest exit (``inf`` on inactive cells).

    Raises
    ------
    ParameterError
        Named ``domain.exits`` without exits, or ``grid.cells`` when some cell of Ω reaches
        no exit on this grid (a passage narrower than a cell: refine the grid).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    from meanfield.exits import ExitSink, distance_to_segments

    if not len(segs):
        raise ParameterError("domain.exits", "none", "at least one exit (the geodesic Step I leads to them)")
    nx, ny = grid.shape
    active = grid.active
    index = -np.ones(grid.shape, dtype=np.int64)
    index[active] = np.arange(int(active.sum()))
    n = int(active.sum())
    ox = grid.aperture_x > 0  # open x-faces between (i, j) and (i+1, j)
    oy = grid.aperture_y > 0  # open y-faces between (i, j) and (i, j+1)
    rows, cols, w = [], [], []

    def link(a: np.ndarray, b: np.ndarray, length: float) -> None:
        rows.append(a)
        cols.append(b)
        w.append(np.full(len(a), length))

    i, j = np.nonzero(ox)
    link(index[i, j], index[i + 1, j], grid.dx)
    i, j = np.nonzero(oy)
    link(index[i, j], index[i, j + 1], grid.dy)
    diag = math.hypot(grid.dx, grid.dy)
    # (i, j) -> (i+1, j+1): along x then y, or y then x
    up = (ox[:, :-1] & oy[1:, :]) | (oy[:-1, :] & ox[:, 1:])
    i, j = np.nonzero(up)
    link(index[i, j], index[i + 1, j + 1], diag)
    # (i, j+1) -> (i+1, j): along x then down, or down then x
    down = (ox[:, 1:] & oy[1:, :]) | (oy[:-1, :] & ox[:, :-1])
    i, j = np.nonzero(down)
    link(index[i, j + 1], index[i + 1, j], diag)
    # the exits: a source node joined to each exit cell by the centre's distance to its exit
    sink = ExitSink(grid, segs, 1.0)
    exit_cells = (sink.total_rate > 0) & active
    X, Y = grid.centers
    rows.append(np.full(int(exit_cells.sum()), n))
    cols.append(index[exit_cells])
    w.append(distance_to_segments(np.column_stack([X[exit_cells], Y[exit_cells]]), segs).min(axis=1))
    a, b, length = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    graph = coo_matrix((np.r_[length, length], (np.r_[a, b], np.r_[b, a])), shape=(n + 1, n + 1)).tocsr()
    dist = dijkstra(graph, directed=False, indices=n)[:n]
    if not np.isfinite(dist).all():
        cut = int((~np.isfinite(dist)).sum())
        raise ParameterError(
            "grid.cells",
            grid.cells,
            f"a grid on which every cell of Ω reaches an exit ({cut} cells do not: a passage is narrower than a cell)",
        )
    phi = np.full(grid.shape, np.inf)
    phi[active] = dist
    return phi


class EvacuationController(BacksteppingController):
    """The paper's Step II tracking Hughes' desired field towards the exits (see the module docstring).

    Parameters
    ----------
    *args : Any
        The arguments of :class:`~meanfield.control.BacksteppingController` (grid, target,
        σ, α, gains, strategy, interaction, ``dvd_dt``; α is unused by this Step I).
    phi : ndarray
        The distance to the exits on the cells (:func:`exit_distance`).
    v_free : float
        Walking speed in free flow, > 0 (1.34 m/s, Weidmann, in metres and seconds).
    rho_max : float
        Density (of the toolkit's unit-mass ρ) at which walking stops, > 0; ``inf``: no congestion.
    **kwargs : Any
        Keyword arguments of :class:`~meanfield.control.BacksteppingController`.
    """

    def __init__(self, *args: Any, phi: np.ndarray, v_free: float = 1.34, rho_max: float = math.inf, **kwargs: Any):
        super().__init__(*args, **kwargs)
        if not (math.isfinite(v_free) and v_free > 0):
            raise ParameterError("controller.options.v_free", v_free, "a walking speed > 0")
        if not rho_max > 0:
            raise ParameterError("controller.options.rho_max", rho_max, "a density > 0, or inf for no congestion")
        self.v_free, self.rho_max = float(v_free), float(rho_max)
        finite = np.where(np.isfinite(phi), phi, 0.0)
        self.grad_phi = self.grid.gradient(finite)

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> EvacuationController:
        """Registry factory (kind ``controller``, name ``evacuation``): options ``v_free``, ``rho_max``."""
        from meanfield.exits import exit_segments

        allowed = {"v_free", "rho_max"}
        unknown = sorted(set(parts.options) - allowed)
        if unknown:
            raise ParameterError("controller.options", unknown, f"options among {sorted(allowed)}")
        phi = exit_distance(parts.grid, exit_segments(parts.region))
        opts = {k: float(v) for k, v in parts.options.items()}
        return cls(*cls.law_arguments(parts), phi=phi, **opts)

    def _speed(self, rf: Any) -> tuple[Any, Any]:
        """``f(ρ)`` and ``f'(ρ)`` on the faces (0 beyond ``ρ_max``; complex ρ allowed for derivative checks)."""
        if math.isinf(self.rho_max):
            return self.v_free + 0 * rf, 0 * rf
        moving = np.real(rf) < self.rho_max
        f = np.where(moving, self.v_free * (1 - rf / self.rho_max), 0 * rf)
        return f, np.where(moving, -self.v_free / self.rho_max + 0 * rf, 0 * rf)

    def _virtual_velocity(self, p: _Prepared) -> FaceField:
        out = [-self._speed(p.rf[k])[0] * self.grad_phi[k] for k in range(2)]
        if p.uw is not None:
            out = [out[k] - p.uw[k] for k in range(2)]
        return out[0], out[1]

    def _virtual_velocity_rate(self, p: _Prepared, rho_dot: np.ndarray) -> FaceField:
        df = self.grid.face_average(rho_dot)
        out = [-self._speed(p.rf[k])[1] * df[k] * self.grad_phi[k] for k in range(2)]
        uw = self.interaction_on_faces(rho_dot)
        if uw is not None:
            out = [out[0] - uw[0], out[1] - uw[1]]
        return out[0], out[1]

    def _dissipation(self, p: _Prepared) -> float:
        """``−S = ⟨∇ρ̃, ∇(σρ) − (v_d + u_W)ρ⟩``: what Step I's own flux does to ``½∫ρ̃²``, negated."""
        v = self._virtual_velocity(p)
        if p.uw is not None:
            v = (v[0] + p.uw[0], v[1] + p.uw[1])
        return self.grid.face_inner(p.grt, (p.gs[0] - v[0] * p.rf[0], p.gs[1] - v[1] * p.rf[1]))
