"""Those a human touches, compiled: the contact cone, its relative form, and the noise among contacts.

:func:`contact_cone` projects each active human's velocity onto the velocities that do not approach anyone
it touches (closer than the jam spacing ``d``)::

    v_j ← argmin{ |u − v_j| : u·n_jk <= 0 for every k with |X_k − X_j| < d },  n_jk = (X_k − X_j)/|X_k − X_j|

(docs page *Congestion*, "The headway door model", (H2)).  The set is a convex cone of the plane, so the
nearest point is ``v_j`` itself, or its projection on one of the violated contacts' lines that satisfies
every other contact (the one that removes least), or 0: exact, in any order of the contacts.  Then each
steps away from those it touches, the more the deeper the overlap (a soft core, (H3))::

    v_j ← v_j − u Σ_{k : 0 < |X_k − X_j| < d} (1 − |X_k − X_j|/d) n_jk

:func:`following_cone` is (H2) made relative, for the forward-cell door model: a walk that approaches nobody it
touches faster than that one walks away, then (H3).

:func:`contact_noise` gives each the share ``φ_j = Π_k (|X_k − X_j|/d)^m`` of the noise it keeps among those it
touches, and its gradient (H5).

The arithmetic of (H2) and (H3) is one function, :func:`_cone`, and that of (H5) another, :func:`_noise_share`,
which these loops and the headway's fused pass (:func:`meanfield.crowds._headway_loops.headway_step`) share.  The
compiled loops read each human's contacts from the cell list (:func:`meanfield.crowds._cell_list.cell_list`,
cells at least ``d`` wide); the numpy twins list every pair closer than ``d``.  The velocities agree to round-off
(the separation is a sum, added in another order).  The loops over humans run on numba's threads above
:data:`~meanfield._compiled.core.PARALLEL_CHUNK` humans, each human writing its own row: the same numbers on any
number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from meanfield._compiled.core import PARALLEL_CHUNK, compiled, empty_array, inlined, inner, prange
from meanfield.crowds._cell_list import CellList, _pairs

__all__ = ["contact_cone", "following_cone", "contact_noise", "CONTACT_NOISE_POWER", "CONTACTS"]


def _cone_numpy(v, x, active, jam, separation, cells):
    """The numpy twin of :func:`contact_cone` (every pair closer than ``d``; ``cells`` unused): the contacts of
    each human padded to the most any has, then (H2) for all at once, then (H3)."""
    j, k, r2 = _pairs(x, active, jam)
    keep = r2 > 0.0
    j, k, r2 = j[keep], k[keep], r2[keep]
    if not len(j):
        return
    r = np.sqrt(r2)
    nxs, nys = (x[k, 0] - x[j, 0]) / r, (x[k, 1] - x[j, 1]) / r
    srt = np.argsort(j, kind="stable")
    j, nxs, nys, r = j[srt], nxs[srt], nys[srt], r[srt]
    w = separation * (jam - r) / jam
    sep_x, sep_y = np.zeros(len(v)), np.zeros(len(v))
    np.add.at(sep_x, j, -w * nxs)
    np.add.at(sep_y, j, -w * nys)
    who, first, count = np.unique(j, return_index=True, return_counts=True)
    m = int(count.max())
    slot = np.arange(len(j)) - np.repeat(first, count)
    row = np.repeat(np.arange(len(who)), count)
    nx_, ny_ = np.zeros((len(who), m)), np.zeros((len(who), m))
    nx_[row, slot], ny_[row, slot] = nxs, nys
    vx, vy = v[who, 0].copy(), v[who, 1].copy()
    a = vx[:, None] * nx_ + vy[:, None] * ny_  # v·n (0 in the padding)
    bad = (a > 0.0).any(axis=1)
    tol = 1e-12 * np.hypot(vx, vy)
    best = np.full(len(who), np.inf)  # the least removal among the feasible faces
    bx, by = np.zeros(len(who)), np.zeros(len(who))
    for f in range(m):
        af = a[:, f]
        px, py = vx - af * nx_[:, f], vy - af * ny_[:, f]
        ok = (af > 0.0) & ((px[:, None] * nx_ + py[:, None] * ny_) <= tol[:, None]).all(axis=1) & (af < best)
        best = np.where(ok, af, best)
        bx, by = np.where(ok, px, bx), np.where(ok, py, by)
    v[who[bad], 0] = bx[bad]
    v[who[bad], 1] = by[bad]
    v[:, 0] += sep_x
    v[:, 1] += sep_y


@inlined
def _cone(cdx, cdy, cr2, contacts, vx, vy, jam, separation):
    """(H2) and (H3) for one human walking ``(vx, vy)`` whose contacts (those closer than ``jam``, not at its own
    point) are at the offsets ``(cdx, cdy)``, squared distances ``cr2``, the first ``contacts`` of them in the
    order of the cells: its walk projected on the cone of those that approach nobody it touches, plus the soft
    core's separation (module docstring).  Returns the new ``(vx, vy)``."""
    sx = 0.0  # (H3), and whether the walk approaches a contact
    sy = 0.0
    bad = False
    for c in range(contacts):
        dx = cdx[c]
        dy = cdy[c]
        r = math.sqrt(cr2[c])
        w = separation * (jam - r) / jam
        sx -= w * (dx / r)
        sy -= w * (dy / r)
        if vx * (dx / r) + vy * (dy / r) > 0.0:
            bad = True
    if bad:  # (H2): the violated contact whose line's projection satisfies all, removing least; else 0
        tol = 1e-12 * math.hypot(vx, vy)
        best = math.inf
        bx = 0.0
        by = 0.0
        for c in range(contacts):
            r = math.sqrt(cr2[c])
            fx = cdx[c] / r
            fy = cdy[c] / r
            af = vx * fx + vy * fy
            if af <= 0.0 or af >= best:
                continue
            px = vx - af * fx
            py = vy - af * fy
            worst = -math.inf  # the largest u·n over the contacts: u approaches none of them iff it is <= 0
            for c2 in range(contacts):
                r2 = math.sqrt(cr2[c2])
                worst = max(worst, px * (cdx[c2] / r2) + py * (cdy[c2] / r2))
            if worst <= tol:
                best = af
                bx = px
                by = py
        vx = bx
        vy = by
    return vx + sx, vy + sy


@inlined
def _contacts(pos, starts, ox, oy, h, nx, ny, t, jam2, cdx, cdy, cr2):
    """The contacts of the human in slot ``t`` (``0 < r² < jam2``, in the 3 × 3 cells round it: cells at least
    ``√jam2`` wide), in the order of the cells, into ``cdx``, ``cdy``, ``cr2`` while they hold them; returns how
    many there are."""
    xj = pos[t, 0]
    yj = pos[t, 1]
    cx = min(int((xj - ox) // h), nx - 1)
    cy = min(int((yj - oy) // h), ny - 1)
    cap = cdx.shape[0]
    contacts = 0
    for gy in range(max(cy - 1, 0), min(cy + 2, ny)):  # each row's three cells: one run of the cell order
        for u in range(starts[gy * nx + max(cx - 1, 0)], starts[gy * nx + min(cx + 2, nx)]):
            dx = pos[u, 0] - xj
            dy = pos[u, 1] - yj
            r2 = dx * dx + dy * dy
            if 0.0 < r2 < jam2:
                if contacts < cap:
                    cdx[contacts] = dx
                    cdy[contacts] = dy
                    cr2[contacts] = r2
                contacts += 1
    return contacts


@inner
def _read_contacts(pos, starts, ox, oy, h, nx, ny, t, jam2, cdx, cdy, cr2):
    """:func:`_contacts` of the human in slot ``t`` into ``cdx``, ``cdy``, ``cr2``, or, if they hold too few, into
    new buffers; returns ``(contacts, cdx, cdy, cr2)``."""
    contacts = _contacts(pos, starts, ox, oy, h, nx, ny, t, jam2, cdx, cdy, cr2)
    if contacts > cdx.shape[0]:
        cdx = np.empty(contacts)
        cdy = np.empty(contacts)
        cr2 = np.empty(contacts)
        _contacts(pos, starts, ox, oy, h, nx, ny, t, jam2, cdx, cdy, cr2)
    return contacts, cdx, cdy, cr2


@inner
def _contact_cone_one(pos, starts, ox, oy, h, nx, ny, t, vx, vy, jam, separation, cdx, cdy, cr2):
    """:func:`_cone` for the human in slot ``t``, its contacts read from the cells (buffers grown as needed)."""
    contacts, cdx, cdy, cr2 = _read_contacts(pos, starts, ox, oy, h, nx, ny, t, jam * jam, cdx, cdy, cr2)
    return _cone(cdx, cdy, cr2, contacts, vx, vy, jam, separation)


@inlined
def _noise_share(cdx, cdy, cr2, contacts, jam, power):
    """(H5) for one human whose contacts are at the offsets ``(cdx, cdy)``, squared distances ``cr2`` (the first
    ``contacts``, in the order of the cells): ``(φ_j, ∂φ_j/∂x, ∂φ_j/∂y)`` of :func:`contact_noise`, ``(1, 0, 0)``
    for one who touches nobody."""
    if contacts == 0:
        return 1.0, 0.0, 0.0
    log_phi = 0.0
    gx = 0.0
    gy = 0.0
    for c in range(contacts):
        r2 = cr2[c]
        log_phi += power * math.log(math.sqrt(r2) / jam)
        gx -= power * cdx[c] / r2
        gy -= power * cdy[c] / r2
    f = math.exp(log_phi)
    return f, f * gx, f * gy


CONTACTS = 32
"""Contacts a human's buffers hold before the compiled cone reads them again into larger ones."""

CONTACT_NOISE_POWER = 4.0
"""``m`` of :func:`contact_noise`: each contact at ``r < d`` scales a human's diffusion by ``(r/d)^m``."""


@compiled(fallback=_cone_numpy, parallel_over="v")
def _cone_compiled(v, x, active, jam, separation, cells):
    order, starts, pos, origin, h, nx, ny = cells
    ox = origin[0]
    oy = origin[1]
    m = order.shape[0]
    for chunk in prange((m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the humans in cell order
        cdx = np.empty(CONTACTS)
        cdy = np.empty(CONTACTS)
        cr2 = np.empty(CONTACTS)
        for t in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m)):
            j = order[t]
            vx, vy = _contact_cone_one(pos, starts, ox, oy, h, nx, ny, t, v[j, 0], v[j, 1], jam, separation, cdx,
                                       cdy, cr2)  # fmt: skip
            v[j, 0] = vx
            v[j, 1] = vy


def contact_cone(
    v: np.ndarray, x: np.ndarray, active: np.ndarray, jam: float, separation: float, cells: CellList
) -> np.ndarray:
    """Each active human's velocity projected on the cone of those that approach nobody it touches, then the
    soft core's separation added, in place (module docstring, (H2) and (H3)).

    Parameters
    ----------
    v : ndarray, shape (N, 2)
        Velocities, changed in place.
    x : ndarray, shape (N, 2)
        Positions.
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    jam : float
        ``d``: those closer than this touch (m).
    separation : float
        ``u``, m/s: the speed at which two people at the same point step apart ((H3); 0: none).
    cells : CellList
        The active humans in cells of width at least ``d`` (:func:`cell_list`).
    """
    if cells.h < jam:
        raise ValueError(f"contact_cone needs cells at least {jam} m wide, got {cells.h}")
    _cone_compiled(v, x, active, jam, separation, cells.arrays())
    return v


def _nearest_feasible_numpy(vx, vy, n, b):
    """The point nearest ``(vx, vy)`` of ``{u : u·n_c <= b_c}`` (``n`` (c, 2) unit, ``b >= 0``): the point itself,
    a projection on one line or a meeting of two, whichever is feasible and nearest (the origin always is)."""
    tol = 1e-12 * (math.hypot(vx, vy) + float(b.max()))
    cands = [(vx, vy)]
    for c in range(len(b)):
        a = vx * n[c, 0] + vy * n[c, 1] - b[c]
        cands.append((vx - a * n[c, 0], vy - a * n[c, 1]))
    for c1 in range(len(b)):
        for c2 in range(c1 + 1, len(b)):
            det = n[c1, 0] * n[c2, 1] - n[c1, 1] * n[c2, 0]
            if abs(det) > 1e-12:
                cands.append(((b[c1] * n[c2, 1] - b[c2] * n[c1, 1]) / det, (n[c1, 0] * b[c2] - n[c2, 0] * b[c1]) / det))
    cands.append((0.0, 0.0))
    best, out = math.inf, (0.0, 0.0)
    for ux, uy in cands:
        if np.all(ux * n[:, 0] + uy * n[:, 1] - b <= tol):
            d = (ux - vx) ** 2 + (uy - vy) ** 2
            if d < best:
                best, out = d, (ux, uy)
    return out


def _following_numpy(v, walk, x, active, jam, separation, cells, power, phi, grad):
    """The numpy twin of :func:`following_cone` (every pair closer than ``d``; ``cells`` unused)."""
    if len(phi):
        _contact_noise_numpy(x, active, jam, power, phi, grad, cells)
    v[:] = walk
    j, k, r2 = _pairs(x, active, jam)
    keep = r2 > 0.0
    j, k, r2 = j[keep], k[keep], r2[keep]
    r = np.sqrt(r2)
    n = (x[k] - x[j]) / r[:, None]
    w = separation * (jam - r) / jam
    b = np.maximum(0.0, np.einsum("ij,ij->i", walk[k], n))
    for who in np.unique(j):
        mine = j == who
        v[who] = _nearest_feasible_numpy(walk[who, 0], walk[who, 1], n[mine], b[mine])
        v[who, 0] -= float(np.sum(w[mine] * n[mine, 0]))
        v[who, 1] -= float(np.sum(w[mine] * n[mine, 1]))


@inlined
def _feasible(ux, uy, cnx, cny, cb, contacts, tol):
    """Whether ``u`` approaches none of the contacts faster than it may: ``u·n_c <= b_c`` (within ``tol``)."""
    for c in range(contacts):
        if ux * cnx[c] + uy * cny[c] - cb[c] > tol:
            return False
    return True


@inlined
def _nearest_feasible(vx, vy, cnx, cny, cb, contacts):
    """:func:`_nearest_feasible_numpy`'s point, its candidates in the same order."""
    bmax = 0.0
    for c in range(contacts):
        bmax = cb[c] if cb[c] > bmax else bmax  # (max(bmax, cb[c]) as numba selects, no overload)
    tol = 1e-12 * (math.hypot(vx, vy) + bmax)
    if _feasible(vx, vy, cnx, cny, cb, contacts, tol):
        return vx, vy
    best = math.inf
    bx = 0.0
    by = 0.0
    for c in range(contacts):
        a = vx * cnx[c] + vy * cny[c] - cb[c]
        ux = vx - a * cnx[c]
        uy = vy - a * cny[c]
        if _feasible(ux, uy, cnx, cny, cb, contacts, tol):
            d = (ux - vx) * (ux - vx) + (uy - vy) * (uy - vy)
            if d < best:
                best = d
                bx = ux
                by = uy
    for c1 in range(contacts):
        for c2 in range(c1 + 1, contacts):
            det = cnx[c1] * cny[c2] - cny[c1] * cnx[c2]
            if abs(det) > 1e-12:
                ux = (cb[c1] * cny[c2] - cb[c2] * cny[c1]) / det
                uy = (cnx[c1] * cb[c2] - cnx[c2] * cb[c1]) / det
                if _feasible(ux, uy, cnx, cny, cb, contacts, tol):
                    d = (ux - vx) * (ux - vx) + (uy - vy) * (uy - vy)
                    if d < best:
                        best = d
                        bx = ux
                        by = uy
    if vx * vx + vy * vy < best:  # the origin, always feasible
        bx = 0.0
        by = 0.0
    return bx, by


@inner
def _grown(values, cap):
    """A buffer of ``cap`` entries that begins with ``values`` (element by element: a slice assignment would have
    numba compile its shape-mismatch message, about 2 s of string formatting, in every process)."""
    out = empty_array(cap, np.float64)
    for i in range(values.shape[0]):
        out[i] = values[i]
    return out


@compiled(fallback=_following_numpy, parallel_over="v")
def _following_compiled(v, walk, x, active, jam, separation, cells, power, phi, grad):
    order, starts, pos, origin, h, nx, ny = cells
    ox = origin[0]
    oy = origin[1]
    jam2 = jam * jam
    m = order.shape[0]
    noise = phi.shape[0] > 0
    for j in prange(v.shape[0]):
        v[j, 0] = walk[j, 0]
        v[j, 1] = walk[j, 1]
        if noise:
            phi[j] = 1.0
            grad[j, 0] = 0.0
            grad[j, 1] = 0.0
    for chunk in prange((m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the humans in cell order
        cap = CONTACTS  # (empty_array and conditional expressions: no overload of numba's to compile, _grown)
        cnx = empty_array(cap, np.float64)
        cny = empty_array(cap, np.float64)
        cb = empty_array(cap, np.float64)
        cw = empty_array(cap, np.float64)
        cdx = empty_array(cap, np.float64)
        cdy = empty_array(cap, np.float64)
        cr2 = empty_array(cap, np.float64)
        end = (chunk + 1) * PARALLEL_CHUNK
        for t in range(chunk * PARALLEL_CHUNK, m if m < end else end):
            j = order[t]
            xj = pos[t, 0]
            yj = pos[t, 1]
            cx = np.int64((xj - ox) // h)
            cx = nx - 1 if nx - 1 < cx else cx
            cy = np.int64((yj - oy) // h)
            cy = ny - 1 if ny - 1 < cy else cy
            contacts = 0
            x0 = 0 if 0 > cx - 1 else cx - 1
            x1 = nx if nx < cx + 2 else cx + 2
            for gy in range(0 if 0 > cy - 1 else cy - 1, ny if ny < cy + 2 else cy + 2):
                for u in range(starts[gy * nx + x0], starts[gy * nx + x1]):
                    dx = pos[u, 0] - xj
                    dy = pos[u, 1] - yj
                    r2 = dx * dx + dy * dy
                    if 0.0 < r2 < jam2:
                        if contacts == cap:  # more contacts than the buffers hold: grow them
                            cap *= 2
                            cnx = _grown(cnx, cap)
                            cny = _grown(cny, cap)
                            cb = _grown(cb, cap)
                            cw = _grown(cw, cap)
                            cdx = _grown(cdx, cap)
                            cdy = _grown(cdy, cap)
                            cr2 = _grown(cr2, cap)
                        r = math.sqrt(r2)
                        k = order[u]
                        cnx[contacts] = dx / r
                        cny[contacts] = dy / r
                        ahead = walk[k, 0] * (dx / r) + walk[k, 1] * (dy / r)
                        cb[contacts] = ahead if ahead > 0.0 else 0.0
                        cw[contacts] = separation * (jam - r) / jam
                        cdx[contacts] = dx
                        cdy[contacts] = dy
                        cr2[contacts] = r2
                        contacts += 1
            if contacts == 0:
                continue
            if noise:
                phi[j], grad[j, 0], grad[j, 1] = _noise_share(cdx, cdy, cr2, contacts, jam, power)
            vx, vy = _nearest_feasible(walk[j, 0], walk[j, 1], cnx, cny, cb, contacts)
            for c in range(contacts):
                vx -= cw[c] * cnx[c]
                vy -= cw[c] * cny[c]
            v[j, 0] = vx
            v[j, 1] = vy


def following_cone(
    v: np.ndarray, walk: np.ndarray, x: np.ndarray, active: np.ndarray, jam: float, separation: float,
    cells: CellList, noise: tuple[np.ndarray, np.ndarray] | None = None, power: float = CONTACT_NOISE_POWER,
) -> np.ndarray:  # fmt: skip
    """(H2') and (H3): each active human's walk, the nearest velocity that approaches nobody it touches faster
    than that one walks away, then the soft core's separation, into ``v`` (docs page *Congestion*, "The
    forward-cell door model")::

        v_j = argmin{ |u − w_j| : u·n_jk <= max(0, w_k·n_jk) for every k with |X_k − X_j| < d }
              − u Σ_k (1 − |X_k − X_j|/d) n_jk,        n_jk = (X_k − X_j)/|X_k − X_j|

    ``w`` the walks before contacts (every human's is read, none is changed, so the order does not matter).  The
    set is a convex polygon holding the origin; its nearest point is ``w_j``, a projection on one of its lines or
    a meeting of two.  With ``w_k = 0`` it is (H2)'s cone; a human whose leader walks away is not stopped by it.

    Parameters
    ----------
    v : ndarray, shape (N, 2)
        Written: the velocities (those not active keep their walk).
    walk : ndarray, shape (N, 2)
        The walks before contacts, m/s.
    x : ndarray, shape (N, 2)
        Positions.
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    jam : float
        ``d``: those closer than this touch (m).
    separation : float
        ``u``, m/s: the speed at which two people at the same point step apart.
    cells : CellList
        The active humans in cells of width at least ``d`` (:func:`cell_list`).
    noise : tuple of ndarray, optional
        ``(φ, ∇φ)``, shapes (N,) and (N, 2): written, (H5)'s share of the noise among the same contacts and its
        gradient, :func:`contact_noise`'s numbers to the last bit in one search of the cells instead of two
        (None: not computed).
    power : float
        ``m`` of (H5) (:data:`CONTACT_NOISE_POWER`), with ``noise``.
    """
    if cells.h < jam:
        raise ValueError(f"following_cone needs cells at least {jam} m wide, got {cells.h}")
    phi, grad = (np.empty(0), _NO_GRADIENT) if noise is None else noise
    _following_compiled(v, walk, x, active, float(jam), float(separation), cells.arrays(), float(power), phi, grad)
    return v


_NO_GRADIENT = np.zeros((1, 2))
"""What :func:`headway_step` passes for ``∇φ`` without (H5) (not written)."""


def _contact_noise_numpy(x, active, jam, power, phi, grad, cells):
    """The numpy twin of :func:`contact_noise`'s loop (every pair closer than ``d``; ``cells`` unused)."""
    phi[:] = 1.0
    grad[:] = 0.0
    j, k, r2 = _pairs(x, active, jam)
    keep = r2 > 0.0
    j, k, r2 = j[keep], k[keep], r2[keep]
    if not len(j):
        return
    r = np.sqrt(r2)
    log_phi = np.zeros(len(x))
    np.add.at(log_phi, j, power * np.log(r / jam))
    np.add.at(grad[:, 0], j, -power * (x[k, 0] - x[j, 0]) / r2)
    np.add.at(grad[:, 1], j, -power * (x[k, 1] - x[j, 1]) / r2)
    touched = np.unique(j)
    phi[touched] = np.exp(log_phi[touched])
    grad[touched] *= phi[touched, None]


@compiled(fallback=_contact_noise_numpy, parallel_over="x")
def _contact_noise_compiled(x, active, jam, power, phi, grad, cells):
    order, starts, pos, origin, h, nx, ny = cells
    ox = origin[0]
    oy = origin[1]
    jam2 = jam * jam
    for j in prange(x.shape[0]):
        phi[j] = 1.0
        grad[j, 0] = 0.0
        grad[j, 1] = 0.0
    m = order.shape[0]
    for chunk in prange((m + PARALLEL_CHUNK - 1) // PARALLEL_CHUNK):  # the humans in cell order
        cdx = np.empty(CONTACTS)
        cdy = np.empty(CONTACTS)
        cr2 = np.empty(CONTACTS)
        for t in range(chunk * PARALLEL_CHUNK, min((chunk + 1) * PARALLEL_CHUNK, m)):
            j = order[t]
            contacts, bdx, bdy, br2 = _read_contacts(pos, starts, ox, oy, h, nx, ny, t, jam2, cdx, cdy, cr2)
            phi[j], grad[j, 0], grad[j, 1] = _noise_share(bdx, bdy, br2, contacts, jam, power)


def contact_noise(x: np.ndarray, active: np.ndarray, jam: float, cells: CellList, phi: np.ndarray, grad: np.ndarray,
                  power: float = CONTACT_NOISE_POWER) -> np.ndarray:  # fmt: skip
    """The noise's share ``φ_j`` that each active human keeps among those it touches, and its gradient, in place
    (docs page *Congestion*, "The headway door model").

    A human's diffusion is ``σ φ_j``, each contact closer than the jam spacing ``d`` scaling it by ``(r/d)^m``::

        φ_j = Π_{k : 0 < |X_k − X_j| < d} (|X_k − X_j|/d)^m,    ∇_j φ_j = −m φ_j Σ_k (X_k − X_j)/|X_k − X_j|²

    (1 and 0 for a human who touches nobody, or is not active).  The crowd's step adds ``σ ∇_j φ_j`` to the drift:
    the noise is then the divergence ``∇·(σ φ ∇p)`` of the density ``p``, not Itô's ``Δ(σ φ p)``, which would
    drift everyone down the gradient of its own noise, into its contacts.  With it, two people who touch and
    only step apart by (H3) at ``u (1 − r/d)`` each keep their separation ``r < d`` at the stationary law::

        p(r) / p(d) = exp(−∫_r^d u (1 − s/d) / (σ (s/d)^m) ds)

    whose overlap shrinks as ``(r/d)^m`` falls, instead of the Ornstein–Uhlenbeck pair's ``√(σ d / u)``; at the
    jam spacing and beyond, nobody's noise changes, so a queue standing at ``d`` keeps its noise and no jam is
    frozen.

    Parameters
    ----------
    x : ndarray, shape (N, 2)
        Positions.
    active : ndarray of bool, shape (N,)
        Who counts and is counted.
    jam : float
        ``d``: those closer than this touch (m).
    cells : CellList
        The active humans in cells of width at least ``d`` (:func:`cell_list`).
    phi : ndarray, shape (N,)
        ``φ``, written.
    grad : ndarray, shape (N, 2)
        ``∇_j φ_j``, 1/m, written.
    power : float
        ``m`` (:data:`CONTACT_NOISE_POWER`).

    Returns
    -------
    phi : ndarray
    """
    if cells.h < jam:
        raise ValueError(f"contact_noise needs cells at least {jam} m wide, got {cells.h}")
    _contact_noise_compiled(x, active, float(jam), float(power), phi, grad, cells.arrays())
    return phi
