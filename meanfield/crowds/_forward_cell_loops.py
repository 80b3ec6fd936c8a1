"""The forward-cell door model's loop, compiled: the part of each human's Voronoi cell that lies ahead of it.

:func:`forward_cells` gives every active human ``j`` and every turn ``θ_q`` of its route's direction ``e_j`` the
area (m²) of its forward cell::

    A_jq = | V_j ∩ { y : (y − X_j)·t_q >= 0 } |,   t_q = e_j turned by θ_q                                  (C1)

where ``V_j`` is the part of its Voronoi cell among the active humans (the points nearer ``X_j`` than any other
human, within the square of half-side ``R``, the reach, centred on ``X_j``) that ``X_j`` sees: the cell less the
*shadow* of every wall, the points behind the wall's segment as seen from ``X_j`` (beyond its line, between the
rays through its ends).  The door model reads the density ``1 / (2 A_jq)`` (docs page *Congestion*, "The
forward-cell door model").

The cell is the intersection of half-planes, built by clipping the square by each bisector in turn
(Sutherland–Hodgman); a neighbour farther than twice the cell's farthest vertex cannot cut it, so the compiled loop
reads its neighbours from a cell list ring by ring and stops at the first ring beyond that.  A shadow is the
intersection of three half-planes, so the cell's part ahead within one shadow is convex too; its area is taken
off, and the part within two shadows put back (inclusion–exclusion to pairs: three walls near one human that
hide each other's shadows are none of the plans').  The walls are oriented with Ω on their left, and a wall whose
back faces the human (it is on the wall's outer side) is hidden by others and casts nothing: without this, the
corridor's side wall seen from the room through the corridor's mouth would take a second time what the room's
wall hides.  For a standing human (``e_j = 0``) every turn reads half the cell.

The numpy twin clips by every neighbour within twice the square's half-diagonal, in the order of their index, and
takes the same shadows; the areas agree to round-off.  The loop over humans runs on numba's threads above
:data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans, each writing its own row: the same numbers on any number
of threads.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, inlined, prange

__all__ = ["forward_cells", "forward_densities", "CellWork", "CELL_VERTICES", "NEIGHBOURS"]

CELL_VERTICES = 64
"""The most vertices a cell's polygon holds; a cell with more (none in a crowd: a Voronoi cell has about six)
stops clipping there, keeping the larger polygon it has."""


def _clip_numpy(poly: np.ndarray, nx: float, ny: float, c: float, labels: list | None = None, label: int = -1):
    """``poly`` (m, 2), convex, cut to ``{y : y·(nx, ny) <= c}`` (Sutherland–Hodgman).  With ``labels`` (the
    label of each edge ``i → i + 1``), returns the cut polygon and its edges' labels, the new edge along the line
    labelled ``label``."""
    if len(poly) == 0:
        return poly if labels is None else (poly, [])
    a = poly[:, 0] * nx + poly[:, 1] * ny - c
    out, out_labels = [], []
    m = len(poly)
    for i in range(m):
        k = (i + 1) % m
        if a[i] <= 0.0:
            out.append(poly[i])
            out_labels.append(-2 if labels is None else labels[i])
        if (a[i] < 0.0 < a[k]) or (a[k] < 0.0 < a[i]):
            t = a[i] / (a[i] - a[k])
            out.append(poly[i] + t * (poly[k] - poly[i]))
            out_labels.append(label if a[i] < 0.0 else (-2 if labels is None else labels[i]))
    cut = np.array(out).reshape(-1, 2)
    return cut if labels is None else (cut, out_labels)


def _area_numpy(poly: np.ndarray) -> float:
    """The shoelace area of a polygon (m, 2)."""
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def _shadow_planes(ax: float, ay: float, vx: float, vy: float) -> np.ndarray | None:
    """The shadow of the wall ``a + u v`` (Ω on its left; ``a`` relative to the human) as three half-planes
    ``y·n <= c``, rows ``(nx, ny, c)``: beyond its line, and between the rays through its ends; None if the human
    is on its line or behind it."""
    norm = math.hypot(vx, vy)
    lx, ly = -vy / norm, vx / norm  # the left normal, toward Ω
    side = -(lx * ax + ly * ay)  # the human's distance on Ω's side of the line
    if not side > 0.0:
        return None
    bx, by = ax + vx, ay + vy
    return np.array([[lx, ly, -side], [ay, -ax, 0.0], [-by, bx, 0.0]])


def _cells_numpy(x, e, active, cos, sin, reach, wall_a, wall_v, cells, out, whole, seen):
    """The numpy twin of :func:`forward_cells`'s loop (every neighbour within ``2√2 R``; of ``cells`` only the
    order, for the slots ``whole`` and ``seen`` are written by)."""
    out[:] = np.inf
    whole[:] = 0.0
    seen[:] = -1
    ok = active & np.isfinite(x[:, 0]) & np.isfinite(x[:, 1])
    idx = np.flatnonzero(ok)
    slot = np.full(len(x), -1, np.int64)
    slot[cells[0]] = np.arange(len(cells[0]))
    far2_all = 8.0 * reach * reach
    square = np.array([[-reach, -reach], [reach, -reach], [reach, reach], [-reach, reach]])
    for j in idx:
        poly, labels = square.copy(), [-1, -1, -1, -1]
        d = x[idx] - x[j]
        d2 = np.einsum("ij,ij->i", d, d)
        for k in np.flatnonzero((d2 > 0.0) & (d2 < far2_all)):
            poly, labels = _clip_numpy(poly, d[k, 0], d[k, 1], 0.5 * d2[k], labels, int(idx[k]))
        far2 = float(np.max(np.einsum("ij,ij->i", poly, poly))) if len(poly) else 0.0
        shadows = []
        for w in range(len(wall_a)):
            ax, ay = wall_a[w, 0] - x[j, 0], wall_a[w, 1] - x[j, 1]
            vx, vy = wall_v[w]
            u = min(1.0, max(0.0, -(ax * vx + ay * vy) / (vx * vx + vy * vy)))
            if (ax + u * vx) ** 2 + (ay + u * vy) ** 2 < far2:
                planes = _shadow_planes(ax, ay, vx, vy)
                if planes is not None:
                    shadows.append(planes)
        mine = [k for k in labels if k >= 0 and not any(
            all(p[0] * (x[k, 0] - x[j, 0]) + p[1] * (x[k, 1] - x[j, 1]) <= p[2] for p in planes) for planes in shadows)]
        mine = mine[: seen.shape[1]]
        seen[slot[j], : len(mine)] = slot[mine]
        for q in range(-1, len(cos)):  # q = -1: the whole cell
            tx = 0.0 if q < 0 else cos[q] * e[j, 0] - sin[q] * e[j, 1]
            ty = 0.0 if q < 0 else sin[q] * e[j, 0] + cos[q] * e[j, 1]
            ahead = poly if tx == 0.0 and ty == 0.0 else _clip_numpy(poly, -tx, -ty, 0.0)
            area = _area_numpy(ahead)
            parts = []
            for planes in shadows:
                part = ahead
                for nx, ny, c in planes:
                    part = _clip_numpy(part, nx, ny, c)
                area -= _area_numpy(part)
                parts.append(part)
            for i in range(len(parts)):
                for k in range(i + 1, len(parts)):
                    both = parts[i]
                    for nx, ny, c in shadows[k]:
                        both = _clip_numpy(both, nx, ny, c)
                    area += _area_numpy(both)
            area = max(area, 0.0)
            if q < 0:
                whole[slot[j]] = area
            else:
                out[j, q] = 0.5 * area if tx == 0.0 and ty == 0.0 else area


@inlined
def _clip(px, py, m, nx, ny, c, qx, qy):
    """The polygon ``(px, py)[:m]``, convex, cut to ``{y : y·(nx, ny) <= c}`` into ``(qx, qy)``; returns its
    number of vertices (Sutherland–Hodgman, the twin's arithmetic)."""
    k = 0
    for i in range(m):
        i1 = i + 1 if i + 1 < m else 0
        a = px[i] * nx + py[i] * ny - c
        b = px[i1] * nx + py[i1] * ny - c
        if a <= 0.0:
            qx[k] = px[i]
            qy[k] = py[i]
            k += 1
        if (a < 0.0 and b > 0.0) or (b < 0.0 and a > 0.0):
            t = a / (a - b)
            qx[k] = px[i] + t * (px[i1] - px[i])
            qy[k] = py[i] + t * (py[i1] - py[i])
            k += 1
    return k


@inlined
def _area(px, py, m):
    """The shoelace area of the polygon ``(px, py)[:m]`` (the twin's arithmetic)."""
    if m < 3:
        return 0.0
    s = 0.0
    for i in range(m):
        i1 = i + 1 if i + 1 < m else 0
        s += px[i] * py[i1] - px[i1] * py[i]
    return 0.5 * abs(s)


@inlined
def _shoelace_add(s, k, fx, fy, lx, ly, vx, vy):
    """The ``k``-th vertex ``(vx, vy)`` of a polygon into :func:`_clip_area`'s running shoelace sum ``s``: the first
    is kept as ``(fx, fy)``, each later one adds its term with the last ``(lx, ly)``; returns ``(s, k + 1, fx, fy)``."""
    if k == 0:
        return s, 1, vx, vy
    return s + (lx * vy - vx * ly), k + 1, fx, fy


@inlined
def _clip_area(px, py, m, nx, ny, c):
    """:func:`_area` of :func:`_clip`'s polygon, without writing it: the same vertices, each computed as
    :func:`_clip` computes it, and the shoelace's terms added in :func:`_area`'s order (the first vertex's term with
    the second first, the last's with the first at the end), so the same number to the last bit."""
    if m == 0:
        return 0.0
    a0 = px[0] * nx + py[0] * ny - c
    a = a0
    k = 0
    s = 0.0
    fx = 0.0  # the first vertex
    fy = 0.0
    lx = 0.0  # the last one so far
    ly = 0.0
    for i in range(m):
        i1 = i + 1 if i + 1 < m else 0
        b = px[i1] * nx + py[i1] * ny - c if i + 1 < m else a0
        if a <= 0.0:
            s, k, fx, fy = _shoelace_add(s, k, fx, fy, lx, ly, px[i], py[i])
            lx = px[i]
            ly = py[i]
        if (a < 0.0 and b > 0.0) or (b < 0.0 and a > 0.0):
            t = a / (a - b)
            vx = px[i] + t * (px[i1] - px[i])
            vy = py[i] + t * (py[i1] - py[i])
            s, k, fx, fy = _shoelace_add(s, k, fx, fy, lx, ly, vx, vy)
            lx = vx
            ly = vy
        a = b
    if k < 3:
        return 0.0
    s += lx * fy - fx * ly
    return 0.5 * abs(s)


@inlined
def _beyond(px, py, m, nx, ny, c, da):
    """Each vertex's ``y·(nx, ny) - c`` into ``da`` (the twin's arithmetic); whether some vertex lies beyond the line
    ``y·(nx, ny) = c``.  Else :func:`_cut_labelled` would give the polygon back as it is, to the last bit."""
    cut = False
    for i in range(m):
        a = px[i] * nx + py[i] * ny - c
        da[i] = a
        if a > 0.0:
            cut = True
    return cut


@inlined
def _cut_labelled(px, py, pl, m, da, label, qx, qy, ql):
    """:func:`_clip` of ``(px, py)`` into ``(qx, qy)`` by the line whose vertex values :func:`_beyond` wrote into
    ``da``, keeping each edge's label (``pl[i]``: the slot in the cell list's order of the neighbour whose bisector
    the edge ``i → i + 1`` lies on, −1 for the square's) into ``ql``, the new edge labelled ``label`` (the twin's
    labels); returns the new vertex count, the squared distance of its farthest vertex and its bounding box
    ``(x0, x1, y0, y1)``; the cut polygon is copied back into ``(px, py, pl)``.  The clipping is :func:`_clip`'s,
    each vertex's value computed once (by :func:`_beyond`), written out again so that the loop over the turns, which
    needs no labels, writes none."""
    k = 0
    for i in range(m):
        i1 = i + 1 if i + 1 < m else 0
        a = da[i]
        b = da[i1]
        if a <= 0.0:
            qx[k] = px[i]
            qy[k] = py[i]
            ql[k] = pl[i]
            k += 1
        if (a < 0.0 and b > 0.0) or (b < 0.0 and a > 0.0):
            t = a / (a - b)
            qx[k] = px[i] + t * (px[i1] - px[i])
            qy[k] = py[i] + t * (py[i1] - py[i])
            ql[k] = label if a < 0.0 else pl[i]
            k += 1
    far2 = 0.0
    x0 = math.inf
    x1 = -math.inf
    y0 = math.inf
    y1 = -math.inf
    for i in range(k):
        px[i] = qx[i]
        py[i] = qy[i]
        pl[i] = ql[i]
        r2 = qx[i] * qx[i] + qy[i] * qy[i]  # (max and min as numba's select them, without their overloads)
        far2 = r2 if r2 > far2 else far2
        x0 = qx[i] if qx[i] < x0 else x0
        x1 = qx[i] if qx[i] > x1 else x1
        y0 = qy[i] if qy[i] < y0 else y0
        y1 = qy[i] if qy[i] > y1 else y1
    return k, far2, x0, x1, y0, y1


_SHADOW_MARGIN = 1e-9
"""A shadow is left out of a cell's areas where every vertex of the cell lies beyond one of its three lines by this
share of the line's scale (``(|n_x| + |n_y|) R + |c| + 1``): the parts ahead are the cell clipped, their vertices
within a few ulps of it, so each would clip to nothing and take exactly 0.0 off; the same areas to the last bit."""

SHADOWS = 16
"""The most walls whose shadows one human's cell takes; farther ones beyond that many are left out (a cell reaches
a few metres; no plan has more walls that near)."""


@compiled(fallback=_cells_numpy, parallel_over="x")
def _cells_compiled(x, e, active, cos, sin, reach, wall_a, wall_v, cells, out, whole, seen):
    order, starts, pos, origin, h, nx, ny = cells
    ox = origin[0]
    oy = origin[1]
    for j in prange(x.shape[0]):
        for q in range(cos.shape[0]):
            out[j, q] = math.inf
        whole[j] = 0.0
        for i in range(seen.shape[1]):
            seen[j, i] = -1
    n_walls = wall_a.shape[0]
    m_all = order.shape[0]
    cap = CELL_VERTICES
    for chunk in prange((m_all + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the humans in cell order
        # (empty_array and conditional expressions for min, max and int: no overload of numba's to compile)
        px = empty_array(cap + 2, np.float64)
        py = empty_array(cap + 2, np.float64)
        pl = empty_array(cap + 2, np.int64)
        qx = empty_array(cap + 2, np.float64)
        qy = empty_array(cap + 2, np.float64)
        ql = empty_array(cap + 2, np.int64)
        da = empty_array(cap + 2, np.float64)  # each vertex's side of a bisector
        rx = empty_array(cap + 2, np.float64)
        ry = empty_array(cap + 2, np.float64)
        ax_ = empty_array(cap + 2, np.float64)  # the cell ahead
        ay_ = empty_array(cap + 2, np.float64)
        sx = empty_array((SHADOWS, cap + 2), np.float64)  # its part in each shadow
        sy = empty_array((SHADOWS, cap + 2), np.float64)
        sm = empty_array(SHADOWS, np.int64)
        lv = empty_array(SHADOWS, np.int64)  # the shadows that fall on the cell
        planes = empty_array((SHADOWS, 9), np.float64)
        end = (chunk + 1) * PARALLEL_CHUNK
        for t in range(chunk * PARALLEL_CHUNK, m_all if m_all < end else end):
            j = order[t]
            xj = pos[t, 0]
            yj = pos[t, 1]
            px[0] = -reach
            py[0] = -reach
            px[1] = reach
            py[1] = -reach
            px[2] = reach
            py[2] = reach
            px[3] = -reach
            py[3] = reach
            for i in range(4):
                pl[i] = -1
            m = 4
            far2 = 2.0 * reach * reach
            x0 = -reach  # the cell's bounding box
            x1 = reach
            y0 = -reach
            y1 = reach
            cx = np.int64((xj - ox) // h)
            cx = nx - 1 if nx - 1 < cx else cx
            cy = np.int64((yj - oy) // h)
            cy = ny - 1 if ny - 1 < cy else cy
            rings = cx if cx > nx - 1 - cx else nx - 1 - cx  # the farthest ring with a cell of the list
            rings = cy if cy > rings else rings
            rings = ny - 1 - cy if ny - 1 - cy > rings else rings
            ring = 0
            while True:  # the neighbours ring by ring, until no farther one can cut the cell
                if ring > 0 and (ring - 1) * h * ((ring - 1) * h) >= 4.0 * far2:
                    break
                if ring > rings:
                    break
                for gy in range(0 if cy - ring < 0 else cy - ring, (ny - 1 if ny - 1 < cy + ring else cy + ring) + 1):
                    full = gy == cy - ring or gy == cy + ring  # the ring's top or bottom row: one run of cells
                    for part in range(1 if full else 2):  # else its two cells on this row, left then right
                        if full:
                            lo = starts[gy * nx + (0 if cx - ring < 0 else cx - ring)]
                            hi = starts[gy * nx + (nx - 1 if nx - 1 < cx + ring else cx + ring) + 1]
                        else:
                            gx = cx - ring if part == 0 else cx + ring
                            if gx < 0 or gx >= nx:
                                continue
                            lo = starts[gy * nx + gx]
                            hi = starts[gy * nx + gx + 1]
                        for s in range(lo, hi):
                            dx = pos[s, 0] - xj
                            dy = pos[s, 1] - yj
                            d2 = dx * dx + dy * dy
                            # a bisector can cut only what lies beyond it: within twice the farthest vertex, past
                            # the bounding box's corner along it, past a vertex (each test exact: no cut is missed)
                            if (d2 > 0.0 and 0.25 * d2 < far2 and m < cap
                                    and (x1 * dx if dx > 0.0 else x0 * dx) + (y1 * dy if dy > 0.0 else y0 * dy)
                                    > 0.5 * d2 and _beyond(px, py, m, dx, dy, 0.5 * d2, da)):  # fmt: skip
                                m, far2, x0, x1, y0, y1 = _cut_labelled(px, py, pl, m, da, s, qx, qy, ql)
                ring += 1
            shadows = 0
            for w in range(n_walls):  # the walls near enough to hide part of the cell, facing the human
                wx = wall_a[w, 0] - xj
                wy = wall_a[w, 1] - yj
                vx = wall_v[w, 0]
                vy = wall_v[w, 1]
                u = -(wx * vx + wy * vy) / (vx * vx + vy * vy)  # min(1, max(0, u)), as numba selects
                u = u if u > 0.0 else 0.0
                u = u if u < 1.0 else 1.0
                if (wx + u * vx) * (wx + u * vx) + (wy + u * vy) * (wy + u * vy) >= far2 or shadows == SHADOWS:
                    continue
                norm = math.hypot(vx, vy)
                lx = -vy / norm
                ly = vx / norm
                side = -(lx * wx + ly * wy)
                if not side > 0.0:
                    continue
                planes[shadows, 0] = lx
                planes[shadows, 1] = ly
                planes[shadows, 2] = -side
                planes[shadows, 3] = wy
                planes[shadows, 4] = -wx
                planes[shadows, 5] = 0.0
                planes[shadows, 6] = -(wy + vy)
                planes[shadows, 7] = wx + vx
                planes[shadows, 8] = 0.0
                shadows += 1
            slots = 0
            for i in range(m):  # the neighbours that bound the cell and are in no shadow, in the cell's order
                k2 = pl[i]
                if k2 < 0 or slots == seen.shape[1]:
                    continue
                kx = pos[k2, 0] - xj
                ky = pos[k2, 1] - yj
                hidden = False
                for i2 in range(shadows):
                    if (kx * planes[i2, 0] + ky * planes[i2, 1] <= planes[i2, 2]
                            and kx * planes[i2, 3] + ky * planes[i2, 4] <= planes[i2, 5]
                            and kx * planes[i2, 6] + ky * planes[i2, 7] <= planes[i2, 8]):  # fmt: skip
                        hidden = True
                if not hidden:
                    seen[t, slots] = k2
                    slots += 1
            live = 0  # the shadows that fall on the cell: a shadow whose half-plane holds no vertex of the cell, by a
            for i in range(shadows):  # margin, takes nothing off any part of it (each of its terms below is 0.0)
                dead = False
                for p3 in range(0, 9, 3):
                    pnx = planes[i, p3]
                    pny = planes[i, p3 + 1]
                    pc = planes[i, p3 + 2]
                    tol = _SHADOW_MARGIN * (((pnx if pnx > 0.0 else -pnx) + (pny if pny > 0.0 else -pny)) * reach
                                            + (pc if pc > 0.0 else -pc) + 1.0)  # fmt: skip
                    beyond = True
                    for v in range(m):
                        if not px[v] * pnx + py[v] * pny - pc > tol:
                            beyond = False
                            break
                    if beyond:
                        dead = True
                        break
                if not dead:
                    lv[live] = i
                    live += 1
            ex = e[j, 0]
            ey = e[j, 1]
            for q in range(-1, cos.shape[0]):  # q = -1: the whole cell
                tx = 0.0 if q < 0 else cos[q] * ex - sin[q] * ey
                ty = 0.0 if q < 0 else sin[q] * ex + cos[q] * ey
                standing = tx == 0.0 and ty == 0.0
                if live == 0:  # the common case: the area alone, the polygon ahead never written
                    area = _area(px, py, m) if standing else _clip_area(px, py, m, -tx, -ty, 0.0)
                    area = 0.0 if 0.0 > area else area
                    if q < 0:
                        whole[t] = area
                    else:
                        out[j, q] = 0.5 * area if standing else area
                    continue
                if standing:
                    k = m
                    for i in range(m):
                        ax_[i] = px[i]
                        ay_[i] = py[i]
                else:
                    k = _clip(px, py, m, -tx, -ty, 0.0, ax_, ay_)
                area = _area(ax_, ay_, k)
                for a in range(live):  # less each shadow's part
                    i = lv[a]
                    mi = _clip(ax_, ay_, k, planes[i, 0], planes[i, 1], planes[i, 2], qx, qy)
                    mi = _clip(qx, qy, mi, planes[i, 3], planes[i, 4], planes[i, 5], sx[i], sy[i])
                    mi = _clip(sx[i], sy[i], mi, planes[i, 6], planes[i, 7], planes[i, 8], qx, qy)
                    for v in range(mi):
                        sx[i, v] = qx[v]
                        sy[i, v] = qy[v]
                    sm[i] = mi
                    area -= _area(sx[i], sy[i], mi)
                for a in range(live):  # and each pair's common part put back
                    i = lv[a]
                    for b in range(a + 1, live):
                        i2 = lv[b]
                        mb = _clip(sx[i], sy[i], sm[i], planes[i2, 0], planes[i2, 1], planes[i2, 2], qx, qy)
                        mb = _clip(qx, qy, mb, planes[i2, 3], planes[i2, 4], planes[i2, 5], rx, ry)
                        mb = _clip(rx, ry, mb, planes[i2, 6], planes[i2, 7], planes[i2, 8], qx, qy)
                        area += _area(qx, qy, mb)
                area = 0.0 if 0.0 > area else area
                if q < 0:
                    whole[t] = area
                else:
                    out[j, q] = 0.5 * area if standing else area


def _pool_numpy(x, e, cos, sin, whole, seen, area, order, pos, out):
    """The numpy twin of :func:`forward_densities`' pooling."""
    out[:] = 0.0
    for t, j in enumerate(order):
        for q in range(len(cos)):
            if not np.isfinite(area[j, q]):
                continue
            tx = cos[q] * e[j, 0] - sin[q] * e[j, 1]
            ty = sin[q] * e[j, 0] + cos[q] * e[j, 1]
            count, pool = 0.0, 0.0
            for k in seen[t]:
                if k >= 0 and (pos[k, 0] - pos[t, 0]) * tx + (pos[k, 1] - pos[t, 1]) * ty > 0.0:
                    count += 1.0
                    pool += whole[k]
            out[j, q] = (0.5 + count) / (area[j, q] + pool)


@compiled(fallback=_pool_numpy, parallel_over="x")
def _pool_compiled(x, e, cos, sin, whole, seen, area, order, pos, out):
    for j in prange(x.shape[0]):  # those not in the cell list
        for q in range(cos.shape[0]):
            out[j, q] = 0.0
    m_all = order.shape[0]
    for chunk in prange((m_all + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the rest in cell order, near in memory
        end = (chunk + 1) * PARALLEL_CHUNK
        for t in range(chunk * PARALLEL_CHUNK, m_all if m_all < end else end):
            j = order[t]
            for q in range(cos.shape[0]):
                if not math.isfinite(area[j, q]):
                    continue
                tx = cos[q] * e[j, 0] - sin[q] * e[j, 1]
                ty = sin[q] * e[j, 0] + cos[q] * e[j, 1]
                count = 0.0
                pool = 0.0
                for i in range(seen.shape[1]):
                    k = seen[t, i]
                    if k < 0:
                        break
                    if (pos[k, 0] - pos[t, 0]) * tx + (pos[k, 1] - pos[t, 1]) * ty > 0.0:
                        count += 1.0
                        pool += whole[k]
                out[j, q] = (0.5 + count) / (area[j, q] + pool)


NEIGHBOURS = 24
"""The most neighbours ahead a human's density pools (a Voronoi cell has about six; more are left out)."""


def _walls(wall_starts: np.ndarray, wall_vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (np.ascontiguousarray(wall_starts, dtype=float).reshape(-1, 2),
            np.ascontiguousarray(wall_vectors, dtype=float).reshape(-1, 2))  # fmt: skip


class CellWork:
    """What one pass of the cells writes besides ``A_jq``, for ``n`` humans, kept between steps by the door model:
    ``area`` (N, K), by human; each one's ``whole`` visible cell (N,) and its ``seen`` neighbours (N,
    :data:`NEIGHBOURS`), by its slot in the cell list's order, the neighbours too (the pooling then reads memory
    near the human's own: the cells are near in the order)."""

    __slots__ = ("area", "whole", "seen")

    def __init__(self, n: int, k: int) -> None:
        self.area = np.empty((n, k))
        self.whole = np.empty(n)
        self.seen = np.empty((n, NEIGHBOURS), np.int64)

    def fits(self, n: int, k: int) -> bool:
        """Whether it holds ``n`` humans and ``k`` turns."""
        return self.area.shape == (n, k)


def _cells(x, e, active, cos, sin, reach, wall_starts, wall_vectors, cells, out, work):
    """The loop's three outputs: ``A_jq`` into ``out``, and each one's whole visible cell and seen neighbours
    into ``work``."""
    if not reach > 0.0:
        raise ValueError(f"the forward cells need a reach > 0 m, got {reach!r}")
    a, v = _walls(wall_starts, wall_vectors)
    _cells_compiled(x, e, active, cos, sin, float(reach), a, v, cells.arrays(), out, work.whole, work.seen)
    return out


def forward_cells(
    x: np.ndarray, e: np.ndarray, active: np.ndarray, cos: np.ndarray, sin: np.ndarray, reach: float,
    wall_starts: np.ndarray, wall_vectors: np.ndarray, cells: Any, out: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """(C1)'s cells: each active human's forward cell along each turn of its route's direction, its area in
    ``out`` (module docstring; ``inf`` for those not active).

    Parameters
    ----------
    x, e : ndarray, shape (N, 2)
        Positions (m) and the routes' unit directions (0 for one standing).
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    cos, sin : ndarray, shape (K,)
        The turns' cosines and sines (the route's own direction first).
    reach : float
        ``R``, m: the square of half-side ``R`` round each human that bounds its cell.
    wall_starts, wall_vectors : ndarray, shape (W, 2)
        The walls, the segments ``a_w + u v_w``, ``0 <= u <= 1``, with Ω on their left (exits are not walls here:
        a door does not crowd those in front of it).
    cells : CellList
        The active humans in cells (:func:`~meanfield.crowds._cell_list.cell_list`).
    out : ndarray, shape (N, K)
        Written: ``A_jq``, m².
    """
    return _cells(x, e, active, cos, sin, reach, wall_starts, wall_vectors, cells, out, CellWork(len(x), 0))


def forward_densities(
    x: np.ndarray, e: np.ndarray, active: np.ndarray, cos: np.ndarray, sin: np.ndarray, reach: float,
    wall_starts: np.ndarray, wall_vectors: np.ndarray, cells: Any, out: np.ndarray, work: CellWork | None = None,
) -> np.ndarray:  # fmt: skip
    """(C1): the density ahead of each active human along each turn, persons/m², in ``out`` (0 for those not
    active): its forward cell pooled with the whole cells of the neighbours ahead of it that it sees::

        ρ_jq = (1/2 + n_jq) / (A_jq + Σ_{k ∈ N_jq} |V_k|)

    ``N_jq`` the humans whose bisector with ``j`` bounds ``j``'s cell, ahead of it along ``t_q``
    (``(X_k − X_j)·t_q > 0``) and in no wall's shadow, ``n_jq`` their number, ``|V_k|`` their visible cells'
    areas.  The cells tile the plane, so this is a count over an area, exact in any lattice and in lanes; pooling
    the neighbours' cells takes most of the bias of ``1/A`` out of a disordered crowd (docs page *Congestion*,
    "The forward-cell door model").  One pass builds every human's cell once (its parts ahead, the whole, and its
    neighbours), a second sums each one's neighbours ahead.  Parameters as :func:`forward_cells`, and ``work``,
    the passes' arrays (:class:`CellWork`; None: new ones).
    """
    n, k = out.shape
    work = CellWork(n, k) if work is None or not work.fits(n, k) else work
    _cells(x, e, active, cos, sin, reach, wall_starts, wall_vectors, cells, work.area, work)
    _pool_compiled(x, e, cos, sin, work.whole, work.seen, work.area, cells.order, cells.sorted, out)
    return out
