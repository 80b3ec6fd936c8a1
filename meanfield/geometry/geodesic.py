"""Geodesic routes to the exits: the distance ``φ`` and the way each cell goes (docs page *Buildings*).

* :class:`ExitEikonal` — the eikonal equation ``|∇φ| = 1/F`` in Ω with ``φ = 0`` on the exits,
  solved by fast marching (scikit-fmm's ``travel_time``, second order) on the grid's
  *half-cell lattice*: the cells' centres, the centres of their faces and their corners, a node
  every ``h/2`` (``_open_nodes``).  A centre is open when its cell is active
  (:mod:`meanfield.geometry.grid`), a face when it is open or is a wall's face on Ω's closure,
  a corner when Ω's closure holds it; a face closed between two active cells (a thin wall) and
  a corner where only two diagonal cells touch stay closed.  So the front runs along the walls'
  surfaces and grazes their corners as a geodesic does, goes round pillars, and joins exactly
  the cells the grid's open faces join (through a door one cell wide, never through a wall).
  ``F = 1`` gives the geodesic distance (:func:`exit_distance`), ``F = f(ρ)`` Hughes'
  potential (:mod:`meanfield.controllers.evacuation`).

  *The exits' front.*  Exits lie on Ω's walls, and a front started on a segment sees its two
  ends as point sources, fast marching's worst case.  So it starts at a known time ``τ₀``
  from the exits instead: the nodes within ``F τ₀`` of an exit (``τ₀ = r / max F``, ``r`` =
  :data:`FRONT_CELLS` cells) take ``φ = d/F``, ``d`` the exact Euclidean distance to the
  nearest exit, and the march starts from the curve ``d/F = τ₀`` (a stadium round each exit
  for a constant ``F``), the others taking ``φ = τ₀ + T``.  A node of that tube is a seed only
  if the lattice joins it to the exit inside the tube and no wall hides the exit from it;
  nodes just beyond an exit (outside Ω) are opened as ghosts, so that a slow exit, whose curve
  falls between the exit and the first node, still has a front.  The march runs in units of
  the fastest speed, so a constant ``F = c`` gives exactly ``φ/c`` of ``F = 1``.

  Its accuracy (exact for a whole wall as the exit, within a fraction of a cell of the Euclidean distance to
  a small door and round a corner) is tested in ``tests/geometry/test_fast_marching.py`` and stated, with the
  Dijkstra distance it replaced, on the docs page *Buildings*, "Routes to the exits".

* :func:`exit_distance` — ``φ`` on the cells for ``F = 1``: the geodesic distance to the
  nearest exit inside Ω (``inf`` on inactive cells).

* :class:`ExitRoutes` — the route an informed walker takes from each cell.  Each cell's next
  cell is the 8-neighbour (joined through open faces; a diagonal only when a path along two
  faces is open) that minimises ``φ(m) + |c − m|`` among those lower than it — the step down
  ``−∇φ`` on the cells — or, for a cell an exit crosses, the exit itself when its centre's
  distance to it is no longer; the walker heads for
  the farthest of the next cells (up to :data:`LOOK_AHEAD`) that its centre sees in a
  straight line (:mod:`meanfield.geometry.sight`), or for the exit itself when it is in sight
  ("string pulling").  A point's distance to the exit (:meth:`ExitRoutes.distance`, what the
  evacuation lower bound uses) is the straight leg to its cell's waypoint plus ``φ`` there:
  the length of a path inside Ω, within ``φ``'s error of the geodesic when the waypoint is on
  it (docs page *Buildings*, "Routes to the exits").

  *Why a tree down φ, string-pulled, and not the stream lines of* ``−∇φ``.  A walker steered
  by ``−∇φ`` itself takes the cell-centred difference of ``φ`` at the wall, where it is one
  sided or undefined (cut cells, the cell at a re-entrant corner) and points into the wall,
  and its length to the exit needs the stream line integrated; a string-pulled leg is in sight
  by construction, so a walker never heads into a wall.  What the 8-neighbour Dijkstra tree
  (the route before fast marching) got wrong was its direction: its shortest paths run along
  the axes and the diagonals, so a waypoint 16 cells ahead could sit up to ``tan 22.5°`` of
  that distance off the straight line, and near the ridge between two exits it chose the exit
  nearer in its metric, up to 8 % off; the tree down ``φ`` alternates between the two
  neighbours that bracket ``−∇φ`` and chooses the exit nearer in Ω.  A cell that no
  lower neighbour joins (none has been seen: fast marching gives every node a lower upwind
  neighbour) would take its Dijkstra predecessor, and the routes would fall back to the
  Dijkstra tree altogether if that closed a loop (:attr:`ExitRoutes.tree` says which).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield.errors import ParameterError
from meanfield.geometry.grid import Grid
from meanfield.geometry.sight import SightLines

__all__ = ["ExitEikonal", "exit_distance", "ExitRoutes", "AssignedRoutes", "routes_for", "LOOK_AHEAD", "FRONT_CELLS"]

LOOK_AHEAD = 16
"""How many cells ahead along its route a cell looks for the farthest one in sight."""
FRONT_CELLS = 2.0
"""The fast-marching front starts this many cells (``r = FRONT_CELLS · max(dx, dy)``) from the exits."""


def _no_exit(grid: Grid, cut: int) -> ParameterError:
    return ParameterError(
        "grid.cells",
        grid.cells,
        f"a grid on which every cell of Ω reaches an exit ({cut} cells do not: a passage is narrower than a cell)",
    )


class ExitEikonal:
    """The eikonal equation ``|∇φ| = 1/F`` in Ω, ``φ = 0`` on the exits, by fast marching (module docstring).

    The lattice, its open nodes and the exits' front are built once; each :meth:`travel_time`
    is one march (scikit-fmm, second order) for the speed it is given.

    Parameters
    ----------
    grid : Grid
        The cells (their region is Ω).
    segs : ndarray, shape (E, 2, 2)
        The exits (:func:`meanfield.geometry.exits.exit_segments`), on Ω's walls.
    sight : SightLines, optional
        The walls that block a straight line (built from ``grid.domain`` when omitted).

    Attributes
    ----------
    distance : ndarray, shape (nx, ny)
        ``φ`` for ``F = 1``: the geodesic distance to the nearest exit (``inf`` on inactive cells).

    Raises
    ------
    ParameterError
        Named ``domain.exits`` without exits, or ``grid.cells`` when some cell of Ω reaches
        no exit on this grid although cells of its piece do (a passage narrower than a cell: refine
        the grid).  In a plan in pieces (a region blocked during a run,
        :mod:`meanfield.geometry.blocking`) the cells of a piece none of these exits is in keep
        ``φ = inf``.
    """

    def __init__(self, grid: Grid, segs: np.ndarray, sight: SightLines | None = None):
        from scipy import ndimage

        from meanfield.geometry.exits import distance_to_segments

        segs = np.asarray(segs, float).reshape(-1, 2, 2)
        if not len(segs):
            raise ParameterError("domain.exits", "none", "at least one exit (the geodesic Step I leads to them)")
        self.grid = grid
        self.segs, self.sight = segs, sight  # (to solve again with fewer exits)
        nx, ny = grid.shape
        x0, _, y0, _ = grid.domain.bounds
        self.spacing = (0.5 * grid.dx, 0.5 * grid.dy)
        X, Y = np.meshgrid(x0 + self.spacing[0] * np.arange(2 * nx + 1), y0 + self.spacing[1] * np.arange(2 * ny + 1),
                           indexing="ij")  # fmt: skip
        points = np.column_stack([X.ravel(), Y.ravel()])
        inside = np.asarray(grid.domain.contains(points[:, 0], points[:, 1]), bool).reshape(X.shape)
        opened = _open_nodes(grid, inside)
        d = distance_to_segments(points, segs)  # (nodes, E)
        a, ab = segs[:, 0], segs[:, 1] - segs[:, 0]
        along = ((points[:, None, :] - a[None]) * ab[None]).sum(-1) / (ab * ab).sum(-1)[None]
        band = (1 + 1e-9) * math.hypot(*self.spacing)  # a node beside the exit is within half a cell's diagonal
        facing = ((along >= -1e-9) & (along <= 1 + 1e-9) & (d <= band)).any(axis=1)
        d = d.min(axis=1)
        on_exit = d <= 1e-9 * max(grid.dx, grid.dy)
        beyond = facing & (on_exit | ~inside.ravel())
        beyond = beyond.reshape(X.shape)
        self.opened = opened | beyond  # the ghosts: the nodes just beyond an exit
        self.signed = np.where(beyond, -d.reshape(X.shape), d.reshape(X.shape))  # < 0 beyond an exit
        self.front = FRONT_CELLS * max(grid.dx, grid.dy)
        # the front starts from the tube round the exits; a node of it that the lattice does not join to an exit
        # inside the tube, or that a wall hides from its nearest exit point, is marched instead
        near = self.opened & (self.signed <= self.front)
        labels, _ = ndimage.label(near)
        self.seeds = beyond | (near & np.isin(labels, np.unique(labels[beyond])))
        tube = np.flatnonzero((self.seeds & (self.signed > 0)).ravel())
        sight = SightLines(grid.domain) if sight is None else sight
        if len(tube) and not sight.trivial:
            p = points[tube]
            k = distance_to_segments(p, segs).argmin(axis=1)
            u = np.clip(along[tube, k], 0.0, 1.0)
            q = a[k] + u[:, None] * ab[k]
            q += 1e-6 * (p - q)  # (off the wall the exit is on)
            self.seeds.ravel()[tube] = sight.visible(p, q)
        # inactive cells take the speed of the nearest active one (the ghosts beyond an exit, the walls' nodes)
        _, self._nearest = ndimage.distance_transform_edt(~grid.active, return_indices=True)
        self.distance = self._march(np.ones(opened.shape))
        reached = np.isfinite(self.distance[grid.active])
        if not reached.all():
            cut = cut_off(grid, reached, segs)
            if cut:
                raise _no_exit(grid, cut)

    def lattice_speed(self, speed: np.ndarray) -> np.ndarray:
        """A cell field on the half-cell lattice: the cell's value at its centre, the mean of the cells that
        share a face or a corner there (an inactive cell counts as its nearest active one)."""
        s = np.asarray(speed, float)[self._nearest[0], self._nearest[1]]
        p = np.pad(s, 1, mode="edge")
        nx, ny = s.shape
        out = np.empty((2 * nx + 1, 2 * ny + 1))
        out[1::2, 1::2] = s
        out[0::2, 1::2] = 0.5 * (p[:-1, 1:-1] + p[1:, 1:-1])
        out[1::2, 0::2] = 0.5 * (p[1:-1, :-1] + p[1:-1, 1:])
        out[0::2, 0::2] = 0.5 * (0.5 * (p[:-1, :-1] + p[1:, :-1]) + 0.5 * (p[:-1, 1:] + p[1:, 1:]))  # (a constant stays
        return out  # exactly itself)

    def travel_time(self, speed: np.ndarray) -> np.ndarray:
        """``φ`` with ``|∇φ| = 1/F``, ``F = speed`` on the cells (> 0 and finite on every active cell).

        The speed is taken at the lattice's nodes as :meth:`lattice_speed` says; ``inf`` on inactive cells.

        Raises
        ------
        ParameterError
            Named ``speed`` when it is not positive and finite on every cell of Ω.
        """
        speed = np.asarray(speed, float)
        if speed.shape != self.grid.shape:
            raise ParameterError("speed", speed.shape, f"an array of grid.shape {self.grid.shape}")
        live = speed[self.grid.active]
        if not (np.isfinite(live).all() and (live > 0).all()):
            raise ParameterError("speed", f"min {live.min()}", "a finite speed > 0 on every cell of Ω")
        return self._march(self.lattice_speed(speed))

    def _march(self, speed: np.ndarray) -> np.ndarray:
        """One fast march for the speed on the lattice; ``φ`` on the cells."""
        import skfmm

        grid = self.grid
        scale = float(speed[self.opened].max())
        speed = speed / scale  # the march in units of the fastest speed: a constant speed marches as F = 1
        near = self.signed / speed
        phi = near - self.front  # < 0 within the time τ₀ of the exits (in the tube, or beyond an exit)
        phi = np.where(self.seeds, phi, np.maximum(phi, 1e-9 * min(self.spacing)))  # no front elsewhere
        out = np.abs(near)
        ahead = self.opened & (phi >= 0)
        if ahead.any():
            try:
                t = skfmm.travel_time(np.ma.MaskedArray(phi, ~self.opened), speed, dx=list(self.spacing), order=2)
            except ValueError:  # no front at all: the exits touch no open node
                raise _no_exit(grid, int(grid.active.sum())) from None
            out = np.where(ahead, self.front + np.ma.filled(t, np.inf), out)
        cells = out[1::2, 1::2]
        return np.where(grid.active, cells, np.inf) / scale


def _open_nodes(grid: Grid, inside: np.ndarray) -> np.ndarray:
    """The open nodes of the half-cell lattice (``inside``: which nodes the closed region holds).

    A cell's centre is open when the cell is active.  A face's centre is open when the face is
    (both cells active, aperture > 0), or when it is a wall's face, between an active cell and an
    inactive one or the grid's edge, and on Ω's closure; a face with an active cell on each side
    and aperture 0 is a thin wall and stays closed.  A corner is open when Ω's closure holds it,
    a cell beside it is active, no thin wall ends at it, and it joins no two cells that only
    touch there (two active cells diagonally across it with the other two inactive).  So the
    walls' surfaces are open, a route may graze a wall's corner as the geodesic does, and the
    lattice joins exactly the cells the grid's open faces join.
    """
    nx, ny = grid.shape
    act = np.pad(grid.active, 1)  # the grid's edge: inactive cells beyond it
    ax, ay = grid.aperture_x > 0, grid.aperture_y > 0
    opened = np.zeros((2 * nx + 1, 2 * ny + 1), dtype=bool)
    opened[1::2, 1::2] = grid.active
    # x-faces (the lattice's even rows, odd columns): cells act[i, j+1] and act[i+1, j+1] in the padded array
    left, right = act[:-1, 1:-1], act[1:, 1:-1]
    wall = left ^ right
    thin_x = np.zeros((nx + 1, ny), dtype=bool)
    thin_x[1:-1] = left[1:-1] & right[1:-1] & ~ax
    face = wall & inside[0::2, 1::2]
    face[1:-1] |= ax
    opened[0::2, 1::2] = face
    below, above = act[1:-1, :-1], act[1:-1, 1:]
    wall = below ^ above
    thin_y = np.zeros((nx, ny + 1), dtype=bool)
    thin_y[:, 1:-1] = below[:, 1:-1] & above[:, 1:-1] & ~ay
    face = wall & inside[1::2, 0::2]
    face[:, 1:-1] |= ay
    opened[1::2, 0::2] = face
    # corners: cells act[i, j], act[i+1, j], act[i, j+1], act[i+1, j+1] round the corner (i, j) of the padded array
    c00, c10, c01, c11 = act[:-1, :-1], act[1:, :-1], act[:-1, 1:], act[1:, 1:]
    thin = np.zeros((nx + 1, ny + 1), dtype=bool)
    thin[:, :-1] |= thin_x
    thin[:, 1:] |= thin_x
    thin[:-1, :] |= thin_y
    thin[1:, :] |= thin_y
    pinch = (c00 & c11 & ~c10 & ~c01) | (c10 & c01 & ~c00 & ~c11)
    opened[0::2, 0::2] = inside[0::2, 0::2] & (c00 | c10 | c01 | c11) & ~thin & ~pinch
    return opened


def exit_distance(grid: Grid, segs: np.ndarray) -> np.ndarray:
    """``φ`` on the cells: the geodesic distance inside Ω to the nearest exit (``inf`` on inactive cells).

    The eikonal solution ``|∇φ| = 1``, ``φ = 0`` on the exits, by fast marching
    (:class:`ExitEikonal`; docs page *Buildings*, "Routes to the exits").

    Raises
    ------
    ParameterError
        Named ``domain.exits`` without exits, or ``grid.cells`` when some cell of Ω reaches
        no exit on this grid (a passage narrower than a cell: refine the grid).
    """
    return ExitEikonal(grid, segs).distance.copy()


def cut_off(grid: Grid, reached: np.ndarray, segs: np.ndarray) -> int:
    """How many of the active cells ``~reached`` lie in a piece of Ω that one of the exits ``segs`` is on: cells a
    route should reach and does not (a passage narrower than a cell).  In a plan in pieces (a region blocked during
    a run cut it) the cells of a piece none of these exits is on count none; a cell belongs to the piece nearest its
    centre."""
    import shapely

    from meanfield.geometry.exits import exits_on
    from meanfield.geometry.plan import polygon_pieces

    omega = grid.domain.to_shapely() if hasattr(grid.domain, "to_shapely") else None
    pieces = [omega] if omega is None else polygon_pieces(omega)
    if len(pieces) == 1:
        return int((~reached).sum())
    X, Y = grid.centers
    centres = shapely.points(X[grid.active], Y[grid.active])
    piece = np.argmin(np.stack([shapely.distance(p, centres) for p in pieces]), axis=0)
    served = np.array([bool(exits_on(p, segs, 1e-9 * grid.domain.diameter)) for p in pieces])
    return int((~reached & served[piece]).sum())


OPEN_APERTURE = 1e-9
"""A face whose aperture is at most this is shut for the routes: the round-off of a face inside a wall
(a face between two cells cut by a wall that lies on their centres measured 2e-15)."""


def cell_links(grid: Grid, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cells' 8-neighbour links ``(a, b, length)``: through an open face, or diagonally when a path
    along two faces is open."""
    ox = grid.aperture_x > OPEN_APERTURE  # open x-faces between (i, j) and (i+1, j)
    oy = grid.aperture_y > OPEN_APERTURE  # open y-faces between (i, j) and (i, j+1)
    a, b, w = [], [], []

    def link(p: np.ndarray, q: np.ndarray, length: float) -> None:
        a.append(p)
        b.append(q)
        w.append(np.full(len(p), length))

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
    return np.concatenate(a), np.concatenate(b), np.concatenate(w)


def _dijkstra_tree(n: int, a: np.ndarray, b: np.ndarray, w: np.ndarray, exit_cells: np.ndarray,
                   exit_length: np.ndarray) -> np.ndarray:  # fmt: skip
    """The predecessors of Dijkstra's tree from the exits (node ``n``) over the links: ``n`` for a cell joined to the
    exits directly, negative for a cell the links do not join to them."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    a, b = np.r_[a, np.full(len(exit_cells), n)], np.r_[b, exit_cells]
    w = np.r_[w, exit_length]
    graph = coo_matrix((np.r_[w, w], (np.r_[a, b], np.r_[b, a])), shape=(n + 1, n + 1)).tocsr()
    _, pred = dijkstra(graph, directed=False, indices=n, return_predecessors=True)
    return pred[:n]


def _descent_tree(phi: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray, exit_cells: np.ndarray,
                  exit_length: np.ndarray) -> np.ndarray:  # fmt: skip
    """Each cell's next cell down ``φ``: the linked cell ``m`` with ``φ(m) < φ(c)`` minimising ``φ(m) + |c − m|``,
    or the exits (``n``) for a cell an exit crosses when its own distance to the exit is no longer; -1 for none."""
    n = len(phi)
    down_ab, down_ba = phi[b] < phi[a], phi[a] < phi[b]
    cell = np.r_[a[down_ab], b[down_ba], exit_cells]
    via = np.r_[b[down_ab], a[down_ba], np.full(len(exit_cells), n)]
    value = np.r_[phi[b[down_ab]] + w[down_ab], phi[a[down_ba]] + w[down_ba], exit_length]
    last = np.r_[np.ones(len(cell) - len(exit_cells)), np.zeros(len(exit_cells))]  # ties go to the exit
    order = np.lexsort((last, value, cell))
    first = np.unique(cell[order], return_index=True)[1]
    pred = np.full(n, -1, dtype=np.int64)
    pred[cell[order][first]] = via[order][first]
    return pred


def _reaches_exits(pred: np.ndarray) -> bool:
    """Whether every cell's chain of next cells reaches the exits (node ``n``): no loop."""
    n = len(pred)
    nxt = np.r_[pred, n]
    done = nxt == n
    while True:
        fresh = ~done[:n] & done[nxt[:n]]
        if not fresh.any():
            return bool(done[:n].all())
        done[:n] |= fresh


class ExitRoutes:
    """The informed walker's route from every cell of the grid to the nearest exit (module docstring).

    Parameters
    ----------
    grid : Grid
        The cells (their region is Ω).
    segs : ndarray, shape (E, 2, 2)
        The exits (:func:`meanfield.geometry.exits.exit_segments`).
    sight : SightLines, optional
        The walls that block a straight line (built from ``grid.domain`` when omitted).
    eikonal : ExitEikonal, optional
        The fast-marching solver of these exits on this grid (built when omitted).

    Attributes
    ----------
    phi : ndarray, shape (nx, ny)
        The geodesic distance to the nearest exit (:func:`exit_distance`).
    waypoint : ndarray, shape (nx, ny, 2)
        Where a walker in each cell heads (a cell centre down its route, or a point of the exit).
    remaining : ndarray, shape (nx, ny)
        ``φ`` at each cell's waypoint: its geodesic distance to the exit (0 for a point of the exit).
    tree : str
        ``"descent"`` (the routes go down ``φ``) or ``"dijkstra"`` (the fallback, module docstring).
    everywhere : bool
        Whether a route reaches these exits from every cell (false only in a plan a block cut in pieces).
    segs, sight
        The exits and the walls the routes were planned with.
    """

    def __init__(self, grid: Grid, segs: np.ndarray, sight: SightLines | None = None,
                 eikonal: ExitEikonal | None = None):  # fmt: skip
        from scipy import ndimage

        from meanfield.geometry.exits import ExitSink, distance_to_segments

        sight = SightLines(grid.domain) if sight is None else sight
        eikonal = ExitEikonal(grid, segs, sight) if eikonal is None else eikonal
        self.grid = grid
        self.segs, self.sight = np.asarray(segs, float), sight  # (to plan again with fewer exits)
        self.phi = eikonal.distance
        active = grid.active
        n = int(active.sum())
        index = -np.ones(grid.shape, dtype=np.int64)
        index[active] = np.arange(n)
        dist = self.phi[active]
        X, Y = grid.centers
        centre = np.column_stack([X[active], Y[active]])
        la, lb, lw = cell_links(grid, index)
        # the cells an exit crosses, joined to the exits by their centre's distance to it
        crossed = (ExitSink(grid, segs, 1.0).total_rate > 0)[active]
        exit_cells = np.flatnonzero(crossed)
        d = distance_to_segments(centre, segs)
        exit_length = d.min(axis=1)[exit_cells]
        far = ~np.isfinite(dist)  # cells of a piece none of these exits is in (a plan in pieces): no route
        self.everywhere = not far.any()
        pred = _descent_tree(dist, la, lb, lw, exit_cells, exit_length)
        self.tree = "descent"
        stuck = pred < 0
        if stuck.any():  # a cell no lower neighbour joins: its Dijkstra predecessor
            dijkstra = _dijkstra_tree(n, la, lb, lw, exit_cells, exit_length)
            pred[stuck] = np.where(dijkstra[stuck] < 0, n, dijkstra[stuck])
        if not _reaches_exits(pred):  # (a fallback closed a loop) the Dijkstra tree throughout
            pred = _dijkstra_tree(n, la, lb, lw, exit_cells, exit_length)
            pred = np.where(pred < 0, n, pred)
            self.tree = "dijkstra"
        # each exit cell's exit point: the nearest point of its nearest exit, kept off the exit's ends
        k = d.argmin(axis=1)
        a, b = segs[k, 0], segs[k, 1]
        t = np.clip(((centre - a) * (b - a)).sum(1) / ((b - a) ** 2).sum(1), 0.05, 0.95)
        exit_point = a + t[:, None] * (b - a)
        # the chain of next cells, LOOK_AHEAD deep; n is the exits' node
        pred = np.r_[pred, n]
        chain = [np.arange(n)]
        for _ in range(LOOK_AHEAD):
            chain.append(pred[chain[-1]])
        chain = np.stack(chain, axis=1)  # (n, LOOK_AHEAD + 1)
        reached = chain[:, 1:] == n
        last_cell = chain[:, 1:].copy()  # past the exit: the last cell before it
        for k in range(LOOK_AHEAD):
            last_cell[:, k] = np.where(reached[:, k], chain[:, 0] if k == 0 else last_cell[:, k - 1], last_cell[:, k])
        points = np.where(reached[..., None], exit_point[last_cell], np.r_[centre, [[0.0, 0.0]]][chain[:, 1:]])
        seen = sight.visible(np.broadcast_to(centre[:, None, :], points.shape), points)
        seen[:, 0] = True  # the next cell is always reachable (a face or a diagonal is open)
        # the farthest in sight; past the exit every entry repeats the exit point
        pick = LOOK_AHEAD - 1 - np.argmax(seen[:, ::-1], axis=1)
        rows = np.arange(n)
        target = points[rows, pick]
        via = np.where(reached[rows, pick], n, chain[rows, pick + 1])  # the cell the waypoint is, or the exits
        waypoint = np.full((*grid.shape, 2), np.nan)
        waypoint[active] = np.where(far[:, None], np.nan, target)  # no route: nowhere to head (heading 0)
        rest = np.full(grid.shape, np.nan)
        rest[active] = np.where(far, np.inf, np.where(via == n, 0.0, np.r_[dist, 0.0][via]))  # φ at the waypoint
        # a point in a cell without volume (a sliver) takes the nearest cell's route
        _, (ii, jj) = ndimage.distance_transform_edt(~active, return_indices=True)
        self.waypoint = waypoint[ii, jj]
        self.remaining = rest[ii, jj]

    def heading(self, points: np.ndarray) -> np.ndarray:
        """Unit vectors ``(N, 2)`` from each point towards its cell's waypoint (0 on the waypoint, and where no
        route reaches these exits)."""
        i, j = self.grid.cell_of(points)
        d = self.waypoint[i, j] - points
        norm = np.hypot(d[:, 0], d[:, 1])
        return np.divide(d, norm[:, None], out=np.zeros_like(d), where=norm[:, None] > 0)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Each point's distance to the exit: straight to its cell's waypoint (in sight), then ``φ`` from there
        (``inf`` where no route reaches these exits)."""
        i, j = self.grid.cell_of(points)
        d = np.hypot(*(self.waypoint[i, j] - points).T) + self.remaining[i, j]
        return d if self.everywhere else np.where(np.isfinite(self.remaining[i, j]), d, np.inf)

    def reaches(self, points: np.ndarray) -> np.ndarray:
        """Whether a route reaches these exits from each point: ``np.isfinite(self.distance(points))``, without the
        distances where a route reaches them from every cell (then from every point of the plane, its coordinates
        finite: the waypoints and their ``φ`` are finite)."""
        if not self.everywhere:
            return np.isfinite(self.distance(points))
        return np.isfinite(points).all(axis=1)


class AssignedRoutes:
    """Routes to an assigned exit: each walker to its own exit, or to the nearest open one.

    The informed crowd's groups (:mod:`meanfield.crowds.groups`) and people who remember the exit a sign
    showed (:mod:`meanfield.crowds.memory`) walk to one exit; the others, and those whose exit closed, to
    the nearest open exit.  The routes to an exit alone (:class:`ExitRoutes` of that exit) are planned the
    first time someone is assigned to it, and kept.

    Parameters
    ----------
    grid : Grid
    segs : ndarray, shape (E, 2, 2)
        The exits.
    sight : SightLines, optional
        The walls that block a straight line (built from ``grid.domain`` when omitted).
    nearest : ExitRoutes, optional
        The routes to the nearest of these exits, if already planned.
    """

    def __init__(self, grid: Grid, segs: np.ndarray, sight: SightLines | None = None,
                 nearest: ExitRoutes | None = None):  # fmt: skip
        self.grid, self.sight = grid, sight
        self.segs = np.asarray(segs, float).reshape(-1, 2, 2)
        self.nearest = ExitRoutes(grid, self.segs, sight) if nearest is None else nearest
        self.open = np.ones(len(self.segs), dtype=bool)
        self.planned: dict[int, ExitRoutes] = {}  # the routes to each exit alone, once someone is assigned to it
        self._table: np.ndarray | None = None  # the waypoints of each planned exit and of the nearest (_waypoints)
        self._in_table = np.zeros(len(self.segs), dtype=bool)  # the exits the table holds, reached from every cell

    def to(self, k: int) -> ExitRoutes:
        """The routes to exit ``k`` alone (planned at the first call)."""
        k = int(k)
        if k not in self.planned:
            self.planned[k] = ExitRoutes(self.grid, self.segs[k : k + 1], self.sight)
            self._table = None
        return self.planned[k]

    def _waypoints(self, exits: np.ndarray) -> np.ndarray | None:
        """The waypoints ``(E + 1, nx, ny, 2)`` of the routes to each exit alone (NaN for one not planned) and, last, of
        the routes to the nearest open exit, when each of ``exits`` is planned and reached from every cell (None
        otherwise: then each exit's points are taken in turn).  Built again when a route is planned."""
        planned = [self.to(k) for k in exits]
        if not all(r.everywhere and r.grid is self.grid for r in (*planned, self.nearest)):
            return None
        if self._table is None:
            nan = np.full_like(self.nearest.waypoint, np.nan)
            self._table = np.stack([self.planned[k].waypoint if k in self.planned else nan
                                    for k in range(len(self.segs))] + [self.nearest.waypoint])  # fmt: skip
            held = [self.planned.get(k) for k in range(len(self.segs))]
            self._in_table = np.array([r is not None and r.everywhere and r.grid is self.grid for r in held], bool)
        return self._table

    def _lookup(self, exits_of: np.ndarray) -> np.ndarray | None:
        """:meth:`_waypoints` of the exits ``exits_of`` (each ``>= 0``, repeated as they come): the table kept when it
        holds each of them, without sorting them out."""
        if self._table is not None and self._in_table[exits_of].all():
            return self._table
        return self._waypoints(np.unique(exits_of))

    def reaches(self, points: np.ndarray, exit_of: np.ndarray) -> np.ndarray:
        """Whether a route reaches each point's exit ``exit_of[j]`` from it (:meth:`ExitRoutes.reaches` of :meth:`to`;
        False where ``exit_of[j] < 0``): ``(N,)``."""
        out = np.zeros(len(points), dtype=bool)
        assigned = exit_of >= 0
        kept = self._table is not None and self._in_table[exit_of[assigned]].all()  # (each planned, reached anywhere)
        exits = np.zeros(0, np.intp) if kept else np.unique(exit_of[assigned])
        if all(self.to(k).everywhere for k in exits):  # (from every point of the plane: its coordinates finite)
            out[assigned] = np.isfinite(points[assigned]).all(axis=1)
            return out
        for k in exits:
            rows = np.flatnonzero(exit_of == k)
            out[rows] = self.to(int(k)).reaches(points[rows])
        return out

    def heading_to_each(self, points: np.ndarray, exit_of: np.ndarray) -> np.ndarray:
        """Unit vectors ``(N, 2)`` along each point's route to exit ``exit_of[j]`` alone (:meth:`ExitRoutes.heading` of
        :meth:`to`: 0 on the waypoint and where no route reaches that exit; 0 where ``exit_of[j] < 0``)."""
        out = np.zeros((len(points), 2))
        assigned = exit_of >= 0
        table = self._lookup(exit_of[assigned])
        if table is not None:  # one look-up for all: each point's numbers are its exit's
            out[assigned] = _unit(table, self.grid, points[assigned], exit_of[assigned])
            return out
        for k in np.unique(exit_of[assigned]):
            rows = np.flatnonzero(exit_of == k)
            out[rows] = self.to(int(k)).heading(points[rows])
        return out

    def heading(self, points: np.ndarray, exit_of: np.ndarray) -> np.ndarray:
        """Unit vectors ``(N, 2)`` along each point's route to its exit ``exit_of[j]`` (-1: the nearest open; also
        where no route reaches that exit, from a piece of a plan a block cut without it)."""
        assigned = exit_of >= 0
        if not assigned.any():
            return self.nearest.heading(points)
        table = self._lookup(exit_of[assigned])
        if table is not None:  # every route reached from every cell: one look-up for all, the nearest's last
            return _unit(table, self.grid, points, np.where(assigned, exit_of, len(self.segs)))
        exits = np.unique(exit_of[assigned])
        out = np.empty((len(points), 2))
        nearest = np.flatnonzero(~assigned)
        for k in exits:
            rows = np.flatnonzero(exit_of == k)
            routes = self.to(k)
            if not routes.everywhere:  # (a plan in pieces) those whose exit is in another piece: the nearest
                reached = np.isfinite(routes.distance(points[rows]))
                nearest = np.union1d(nearest, rows[~reached])
                rows = rows[reached]
            out[rows] = routes.heading(points[rows])
        if len(nearest):
            out[nearest] = self.nearest.heading(points[nearest])
        return out

    def exits_closed(self, open_exits: np.ndarray, exit_of: np.ndarray) -> None:
        """Only the exits with ``open_exits[k]`` are open: the nearest is planned again, and ``exit_of`` (in place)
        sends those assigned to a closed exit to the nearest open one (none left: unchanged)."""
        open_exits = np.asarray(open_exits, dtype=bool)
        if open_exits.any():
            self.open = open_exits.copy()
            self.nearest = ExitRoutes(self.grid, self.segs[open_exits], self.sight)
            self._table = None
            exit_of[(exit_of >= 0) & ~open_exits[np.maximum(exit_of, 0)]] = -1

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event, :class:`~meanfield.geometry.blocking.WallsChange`): the routes
        to the open exits are planned again on the new grid, those to each exit alone when next needed."""
        self.grid, self.sight = change.grid, change.sight
        self.nearest = ExitRoutes(self.grid, self.segs[self.open], self.sight)
        self.planned = {}
        self._table = None


def _unit(waypoints: np.ndarray, grid: Grid, points: np.ndarray, route: np.ndarray) -> np.ndarray:
    """:meth:`ExitRoutes.heading` of each point on its routes ``route[j]`` (a row of ``waypoints``, ``(R, nx, ny, 2)``):
    the unit vector towards its cell's waypoint, 0 on it and where there is none (NaN)."""
    i, j = grid.cell_of(points)
    d = waypoints[route, i, j] - points
    norm = np.hypot(d[:, 0], d[:, 1])
    return np.divide(d, norm[:, None], out=np.zeros_like(d), where=norm[:, None] > 0)


def routes_for(region: Any, grid: Grid, sight: SightLines | None = None) -> ExitRoutes:
    """:class:`ExitRoutes` to the exits of ``region`` on ``grid`` (refused, naming ``domain.exits``, without)."""
    from meanfield.geometry.exits import exit_segments

    return ExitRoutes(grid, exit_segments(region), sight)
