"""Time stepping of the crowd's Fokker–Planck equation (paper, eq. (4)), one class per method.

The finite-volume operator of :mod:`meanfield.fokker_planck.solver` turns eq. (4) into the
semi-discrete system ``V dρ/dt = A(ρ, t) ρ`` (cell volumes ``V``, Scharfetter–Gummel
face coefficients in ``A``; see docs/fokker_planck.md, "The scheme").  This module
advances that system in time.  Each method is a :class:`Stepper`, registered by name in
:data:`STEPPERS`; :class:`~meanfield.fokker_planck.solver.FokkerPlanck`, the public solver,
holds the one its ``method`` names and hands it every step.  Time stepping (``method``;
docs/fokker_planck.md, "Time stepping", and docs/discretisation.md, "Time stepping"):

``"explicit"`` (:class:`ExplicitStepper`)
    Heun's method (SSP Runge–Kutta 2), second order.  Positive when
    ``dt <= min_c V_c / Σ_out(c)``, the forward-Euler positivity bound, which is also its
    stability bound; the step is chosen automatically, and a user ``dt`` above the bound
    is refused.
``"split"`` (:class:`SplitStepper`, the default on cut-cell grids)
    Directional splitting: backward-Euler sweeps along x then y (the order alternates
    each step), each a batch of tridiagonal solves, O(cells) per step
    whatever the drift does.  Every sweep matrix is an M-matrix, so ``ρ >= 0`` for any
    ``dt``.  First order in time.
``"adi"`` (:class:`AdiStepper`, the default on a box)
    Peaceman–Rachford alternating-direction implicit scheme (Crank–Nicolson halves),
    second order in time, two tridiagonal sweeps per step, stable for any ``dt``.
    Guaranteed positive when ``dt <= 2 min(V_c / Σ_out^x(c), V_c / Σ_out^y(c))`` (about
    four times the explicit bound), which the automatic step uses; a larger user ``dt``
    is accepted while the result stays ``>= 0`` and refused, with the bound, when it
    does not.  With ``courant`` set, the automatic step is chosen for accuracy instead:
    ``courant · min_faces(h / |a|)``, whose O(dt²) time error scales like the O(h²)
    space error (the positivity bound scales like h²).
``"implicit"`` (:class:`ImplicitStepper`)
    Backward Euler on the full 2-D M-matrix (sparse LU), positive for any ``dt``, first
    order in time.  The factorisation is reused while the coefficients and ``dt`` stay
    fixed; a drift that moves every step forces a refactorisation, which is why
    ``"split"`` and ``"adi"`` exist (see ``benchmarks/bench_fokker_planck.py``).

The tridiagonal sweeps of ``"split"`` and ``"adi"`` are the compiled loops of
:mod:`meanfield.fokker_planck._sweeps` (the Thomas algorithm; one fused pass down and up the grid
per ADI step), their factors kept for a fixed drift; with ``MEANFIELD_COMPILED=0``
(:mod:`meanfield._compiled.core`) they are LAPACK's ``gtsv`` / ``gttrf`` / ``gttrs`` on all
grid lines at once, the reference the tests compare with.

The interaction drift ``u_W[ρ]`` (FFT convolution on a zero-padded grid) is frozen at the
start of each step (IMEX: nonlinear drift explicit, linear drift–diffusion implicit).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
from scipy.linalg import lapack
from scipy.sparse import linalg as splinalg

from meanfield.errors import ParameterError
from meanfield.fokker_planck import _sweeps as fp_compiled
from meanfield.geometry.grid import FaceField, Grid

if TYPE_CHECKING:
    from scipy import sparse

__all__ = ["FaceVelocity", "Stepper", "AdiStepper", "SplitStepper", "ExplicitStepper", "ImplicitStepper", "STEPPERS"]

#: An extra drift on the faces for :meth:`~meanfield.fokker_planck.solver.FokkerPlanck.solve`:
#: a face field ``(Fx, Fy)``, or a callable ``t -> (Fx, Fy)``.
FaceVelocity = FaceField | Callable[[float], FaceField]


def _check_face_field(name: str, value, grid: Grid) -> FaceField:
    nx, ny = grid.shape
    try:
        fx, fy = (np.asarray(c, dtype=float) for c in value)
    except (TypeError, ValueError):
        raise ParameterError(name, type(value).__name__, "a face field (Fx, Fy)") from None
    if fx.shape != (nx - 1, ny) or fy.shape != (nx, ny - 1):
        raise ParameterError(
            name, f"shapes {fx.shape}, {fy.shape}", f"a face field of shapes {(nx - 1, ny)}, {(nx, ny - 1)}"
        )
    if not (np.all(np.isfinite(fx)) and np.all(np.isfinite(fy))):
        raise ParameterError(name, "non-finite values (NaN or inf)", "finite face velocities")
    return fx, fy


class _Coefficients:
    """Scharfetter–Gummel face coefficients times face length, and derived bounds.

    ``sink_x``, ``sink_y`` (None, or arrays of the grid's shape): the exits' outflow coefficients of each cell, the
    mass rate ``s ρ`` that leaves through an exit face (``s = σ ℓ / d + a_n⁺ ℓ``, the Dirichlet face of
    :class:`~meanfield.geometry.exits.ExitSink`), counted with the sweeps along x or along y (the axis closest to the
    exit's normal), so that the steppers integrate the exits with the rest of the operator.
    """

    __slots__ = ("lx", "rx", "ly", "ry", "_out_x", "_out_y", "bounds", "sink_x", "sink_y", "sink_version")

    def __init__(self, lx, rx, ly, ry):
        self.lx, self.rx, self.ly, self.ry = lx, rx, ly, ry
        self._out_x = None
        self._out_y = None
        self.bounds: dict[str, float] = {}
        self.sink_x = self.sink_y = None
        self.sink_version = -1

    def reset(self) -> None:
        """Forget the derived quantities (the arrays were overwritten)."""
        self._out_x = None
        self._out_y = None
        self.bounds = {}

    def outflow(self, shape) -> tuple[np.ndarray, np.ndarray]:
        """Σ of the outgoing coefficients of each cell, per direction."""
        if self._out_x is None:
            ox = np.zeros(shape)
            ox[:-1, :] += self.lx
            ox[1:, :] += self.rx
            oy = np.zeros(shape)
            oy[:, :-1] += self.ly
            oy[:, 1:] += self.ry
            if self.sink_x is not None:  # an exit face is an outgoing face too
                ox += self.sink_x
                oy += self.sink_y
            self._out_x, self._out_y = ox, oy
        return self._out_x, self._out_y

    def bound(self, grid: Grid, axes: str, typical: bool = False) -> float:
        """``min_c V_c / Σ_out(c)`` over the faces along ``axes`` (cached with the coefficients).

        The forward-Euler positivity bound of the coefficients' ``A`` restricted to ``axes``
        (docs/fokker_planck.md, "Time stepping").  ``typical``: only over the cells at least
        half inside Ω (a step size, not a bound).
        """
        key = axes + ("-typical" if typical else "")
        if key in self.bounds:
            return self.bounds[key]
        ox, oy = self.outflow(grid.shape)
        out = (ox if "x" in axes else 0.0) + (oy if "y" in axes else 0.0)
        mask = (grid.volume_fraction >= 0.5 if typical else grid.active) & (out > 0)
        b = float(np.min(grid.volume[mask] / out[mask])) if np.any(mask) else math.inf
        self.bounds[key] = b
        return b

    def crossing_time(self, grid: Grid) -> float:
        """``min_faces h / |a|``, the time the drift takes to cross a cell (cached with the coefficients).

        ``|a|`` is read off the coefficients: ``c_left - c_right = a`` times the face length.
        """
        if "crossing" not in self.bounds:
            rate = 0.0
            faces = ((self.lx, self.rx, grid._len_x, grid.dx), (self.ly, self.ry, grid._len_y, grid.dy))
            for lo, hi, length, h in faces:
                open_ = length > 0
                if np.any(open_):
                    rate = max(rate, float(np.max(np.abs(lo - hi)[open_] / length[open_])) / h)
            self.bounds["crossing"] = 1.0 / rate if rate > 0 else math.inf
        return self.bounds["crossing"]


#: factorisations kept for a fixed drift (one per step size and axis): the latest few
_CACHED_FACTORS = 8


def _with_sink(V: np.ndarray, c: _Coefficients, axis: str, tau: float) -> np.ndarray:
    """``V + τ s_axis``: the volumes with the exits' outflow along ``axis`` over ``τ`` (``V`` itself without exits)."""
    s = c.sink_x if axis == "x" else c.sink_y
    return V if s is None else V + tau * s


def _with_exits(c: _Coefficients, rho: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """``A ρ − s ρ``, in place in ``rate``: the mass rate with the exits' outflow (``rate`` itself without exits)."""
    if c.sink_x is not None:
        rate -= (c.sink_x + c.sink_y) * rho
    return rate


class _StepTooLarge(ParameterError):
    """A step above the method's bound; ``bound`` is the bound at the offending stage."""

    def __init__(self, bound: float, *args):
        super().__init__(*args)
        self.bound = bound


class _Operator(Protocol):
    """What a :class:`Stepper` asks of the spatial operator (docs/fokker_planck.md, "The scheme").

    :class:`~meanfield.fokker_planck.solver.FokkerPlanck` provides it: the ``grid``, whether
    the coefficients may be kept (``time_dependent``, ``interaction``), the face coefficients
    of ``A(ρ, t)`` (``_coefficients``), the mass rate ``A ρ`` along some axes (``_apply``) and
    the backward-Euler matrix ``V - dt A`` (``_matrix``).
    """

    grid: Grid
    time_dependent: bool
    interaction: Any

    def _coefficients(self, rho: np.ndarray, t: float, face_velocity: FaceField | None) -> _Coefficients: ...

    def _apply(self, c: _Coefficients, rho: np.ndarray, axes: str, out: np.ndarray) -> np.ndarray: ...

    def _matrix(self, c: _Coefficients, dt: float) -> sparse.csc_matrix: ...


class Stepper(ABC):
    """One time-stepping method of eq. (4): its step, its positivity bound and its state.

    A method is chosen by name (:data:`STEPPERS`, ``FokkerPlanck(method=...)``); the solver
    holds one stepper, built on itself (the spatial operator: face coefficients, ``A ρ``,
    the backward-Euler matrix), and asks it for every step and bound
    (docs/fokker_planck.md, "Time stepping").  A stepper keeps what its method reuses from
    step to step: the factorisations for a fixed drift (the latest few) and work arrays.

    Parameters
    ----------
    operator : FokkerPlanck
        The spatial operator it advances (the solver that holds it).

    Attributes
    ----------
    name : str
        The method's name in :data:`STEPPERS` (``FokkerPlanck.method``).
    accepts_courant : bool
        Whether the accuracy step ``courant`` applies (``FokkerPlanck(courant=...)``).
    """

    name: ClassVar[str]
    accepts_courant: ClassVar[bool] = False

    def __init__(self, operator: _Operator) -> None:
        self.operator = operator
        self._lu_cache: dict = {}
        self._work: dict[str, np.ndarray] = {}

    @abstractmethod
    def positivity_bound(self, c: _Coefficients) -> float:
        """Largest ``dt`` for which one step from the coefficients ``c`` keeps ``ρ >= 0`` (inf if unconditional)."""

    def automatic_bound(self, c: _Coefficients) -> float:
        """The step the automatic step is the fraction ``cfl`` of: the positivity bound unless it is infinite."""
        return self.positivity_bound(c)

    @abstractmethod
    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """Advance ``ρ`` from ``t`` to ``t + dt`` (arguments already checked by the solver).

        Parameters
        ----------
        rho : ndarray
            Density on ``grid.shape``.
        t, dt : float
            Current time and step.
        face_velocity : FaceField or None
            Extra face drift, held over the step.
        check : bool
            Refuse a step above the method's bound (:class:`~meanfield.errors.ParameterError`
            naming ``dt``); the solver's automatic step retries below it.
        """

    # ------------------------------------------------------------------ shared machinery
    def _buffer(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """A work array reused from step to step (a fresh one costs more in page faults than the arithmetic)."""
        b = self._work.get(name)
        if b is None or b.shape != shape:
            b = self._work[name] = np.empty(shape)
        return b

    def _cache_key(self, fv):
        op = self.operator
        cacheable = not op.time_dependent and op.interaction is None and fv is None
        return ("static", op._sink_version) if cacheable else None  # (new exits' rates: new factors)

    def _remember(self, key, factors) -> None:
        """Keep a factorisation for a fixed drift; steps of many sizes keep only the latest few."""
        while len(self._lu_cache) >= _CACHED_FACTORS:
            self._lu_cache.pop(next(iter(self._lu_cache)))
        self._lu_cache[key] = factors

    def _too_large(self, dt: float, bound: float, what: str) -> ParameterError:
        return _StepTooLarge(
            bound,
            "dt",
            dt,
            f"dt <= {bound:.6g}, the {what} bound of method={self.name!r} at this state "
            "(or dt=None for an automatic step, or method='split'/'implicit', positive for any dt)",
        )


class ExplicitStepper(Stepper):
    """``"explicit"``: Heun's method (SSP Runge–Kutta 2), second order in time.

    Positive, and stable, for ``dt <= min_c V_c / Σ_out(c)`` (the forward-Euler bound,
    docs/fokker_planck.md, "Time stepping"); with ``check`` a larger step is refused at
    either stage.
    """

    name = "explicit"

    def positivity_bound(self, c: _Coefficients) -> float:
        """``min_c V_c / Σ_out(c)``: the forward-Euler positivity bound, also the stability bound."""
        return c.bound(self.operator.grid, "xy")

    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """One Heun step: two forward-Euler stages (coefficients at ``t`` and ``t + dt``), averaged."""
        op = self.operator
        iv = op.grid._inv_volume
        c1 = op._coefficients(rho, t, face_velocity)
        if check and dt > self.positivity_bound(c1) * (1 + 1e-12):
            raise self._too_large(dt, self.positivity_bound(c1), "stability/positivity")
        r1 = _with_exits(c1, rho, op._apply(c1, rho, "xy", np.empty(rho.shape)))
        r1 *= dt * iv
        r1 += rho
        c2 = op._coefficients(r1, t + dt, face_velocity)
        if check and dt > self.positivity_bound(c2) * (1 + 1e-12):
            raise self._too_large(dt, self.positivity_bound(c2), "stability/positivity")
        out = _with_exits(c2, r1, op._apply(c2, r1, "xy", np.empty(rho.shape)))
        out *= dt * iv
        out += r1
        out += rho
        out *= 0.5
        return out


class ImplicitStepper(Stepper):
    """``"implicit"``: backward Euler on the full 2-D M-matrix ``V - dt A`` (sparse LU), first order.

    Positive for any ``dt``.  The LU factors are kept while the coefficients and ``dt``
    stay fixed; a drift that moves every step refactorises every step
    (docs/fokker_planck.md, "Time stepping").
    """

    name = "implicit"

    def positivity_bound(self, c: _Coefficients) -> float:
        """Infinite: ``V - dt A`` is an M-matrix for any ``dt``."""
        return math.inf

    def automatic_bound(self, c: _Coefficients) -> float:
        """Four times the explicit bound of the cells at least half inside Ω (first order: an accuracy step)."""
        return 4.0 * c.bound(self.operator.grid, "xy", typical=True)

    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """Solve ``(V - dt A(ρ, t + dt)) ρ' = V ρ`` (``check`` is moot: positive for any ``dt``)."""
        op = self.operator
        c = op._coefficients(rho, t + dt, face_velocity)
        key = self._cache_key(face_velocity)
        lu = self._lu_cache.get(("2d", dt, key)) if key is not None else None
        if lu is None:
            lu = splinalg.splu(op._matrix(c, dt))
            if key is not None:
                self._remember(("2d", dt, key), lu)
        return lu.solve((op.grid.volume * rho).ravel()).reshape(rho.shape)


class _LineStepper(Stepper):
    """A method made of implicit sweeps along grid lines: the tridiagonal solves of ``"split"`` and ``"adi"``.

    Each sweep solves ``(V - τ A_axis) ρ' = b`` on every line along one axis
    (:mod:`meanfield.fokker_planck._sweeps`, eq. (S)): compiled Thomas factors, or LAPACK
    on the numpy path, kept for a fixed drift.
    """

    _parity = False
    """Which axis :meth:`_split_sweeps` sweeps first: toggled at each call (an instance's own after the first)."""

    def _sweep(self, c: _Coefficients, rhs_mass: np.ndarray, tau: float, axis: str, cache_key) -> np.ndarray:
        """Solve ``(V - τ A_axis) ρ' = rhs_mass`` by tridiagonal solves along ``axis``.

        The systems of all grid lines form one tridiagonal matrix (zero couplings between
        lines), solved by one LAPACK call; ``rhs_mass`` may be overwritten.
        """
        g = self.operator.grid
        V = _with_sink(g.volume, c, axis, tau)  # (the diagonal: V + τ s along this axis)
        if axis == "x":
            lo, hi, Vt = c.lx.T, c.rx.T, V.T
            b = self._buffer("bx", (V.shape[1], V.shape[0]))
            np.copyto(b, rhs_mass.T)
        else:
            lo, hi, Vt = c.ly, c.ry, V
            b = rhs_mass if rhs_mass.flags.c_contiguous else np.ascontiguousarray(rhs_mass)
        rows, n = Vt.shape
        key = (axis, tau, cache_key) if cache_key is not None else None
        lu = self._lu_cache.get(key) if key is not None else None
        if lu is None:
            du = self._buffer("du" + axis, (rows, n))
            np.multiply(hi, -tau, out=du[:, :-1])
            du[:, -1] = 0.0
            dl = self._buffer("dl" + axis, (rows, n))
            np.multiply(lo, -tau, out=dl[:, :-1])
            dl[:, -1] = 0.0
            d = self._buffer("d" + axis, (rows, n))
            np.copyto(d, Vt)
            d[:, :-1] -= dl[:, :-1]  # column sums of the matrix are the volumes: mass is conserved
            d[:, 1:] -= du[:, :-1]
            if not g.is_box:
                d[Vt <= 0] = 1.0  # cells outside Ω: identity rows
            dl_, d_, du_ = dl.reshape(-1)[:-1], d.reshape(-1), du.reshape(-1)[:-1]
            if key is None:
                _, _, _, x, info = lapack.dgtsv(dl_, d_, du_, b.reshape(-1, 1), 1, 1, 1, 1)
                if info != 0:  # pragma: no cover - M-matrices are non-singular
                    raise FloatingPointError(f"tridiagonal solve failed (info={info})")
                x = x.reshape(rows, n)
                return x.T if axis == "x" else x
            lu = lapack.dgttrf(dl_.copy(), d_.copy(), du_.copy())
            if lu[-1] != 0:  # pragma: no cover
                raise FloatingPointError(f"tridiagonal factorisation failed (info={lu[-1]})")
            self._remember(key, lu)
        dl_, d_, du_, du2, ipiv, _ = lu
        x, info = lapack.dgttrs(dl_, d_, du_, du2, ipiv, b.reshape(-1, 1), overwrite_b=1)
        x = x.reshape(rows, n)
        return x.T if axis == "x" else x

    def _thomas(self, c: _Coefficients, tau: float, axis: str, key) -> tuple[np.ndarray, np.ndarray]:
        """Factors of ``V - τ A_axis`` (:func:`~meanfield.fokker_planck._sweeps.tridiagonal_factor`), kept for a
        fixed drift."""
        ck = ("thomas", axis, tau, key) if key is not None else None
        if ck is not None and ck in self._lu_cache:
            return self._lu_cache[ck]
        grid = self.operator.grid
        shape = grid.shape
        if ck is None:  # a new drift every step: factor into work arrays
            g, rp = self._buffer("g" + axis, shape), self._buffer("rp" + axis, shape)
        else:
            g, rp = np.empty(shape), np.empty(shape)
        lo, hi = (c.lx, c.rx) if axis == "x" else (c.ly, c.ry)
        diagonal = _with_sink(grid.volume, c, axis, tau)  # (V + τ s: the exits' outflow along this axis)
        fp_compiled.tridiagonal_factor(diagonal, lo, hi, tau, 0 if axis == "x" else 1, g, rp)
        if ck is not None:
            self._remember(ck, (g, rp))
        return g, rp


    def _split_sweeps(self, c: _Coefficients, rho: np.ndarray, dt: float, key: Any) -> np.ndarray:
        """Two backward-Euler sweeps of ``V - dt A_axis`` from ``ρ``, the order of the axes alternating
        from one call to the next (``self._parity``): compiled, or by LAPACK's banded solver."""
        V = self.operator.grid.volume
        self._parity = not self._parity
        first, second = ("x", "y") if self._parity else ("y", "x")
        if fp_compiled.enabled():
            out = np.multiply(V, rho)
            for axis in (first, second):
                if axis == second:
                    out *= V
                g, rp = self._thomas(c, dt, axis, key)
                hi = c.rx if axis == "x" else c.ry
                fp_compiled.tridiagonal_solve(out, hi, dt, g, rp, 0 if axis == "x" else 1, out)
            return out
        r = self._sweep(c, V * rho, dt, first, key)
        return np.array(self._sweep(c, V * r, dt, second, key))

class SplitStepper(_LineStepper):
    """``"split"``: directional splitting, backward-Euler sweeps along x then y, first order in time.

    The order of the two sweeps alternates from step to step (the stepper remembers which
    came first).  Every sweep matrix is an M-matrix, so ``ρ >= 0`` for any ``dt``
    (docs/fokker_planck.md, "Time stepping"); the default on cut-cell grids.
    """

    name = "split"

    def positivity_bound(self, c: _Coefficients) -> float:
        """Infinite: each sweep matrix ``V - dt A_axis`` is an M-matrix for any ``dt``."""
        return math.inf

    def automatic_bound(self, c: _Coefficients) -> float:
        """Four times the explicit bound of the cells at least half inside Ω (first order: an accuracy step)."""
        return 4.0 * c.bound(self.operator.grid, "xy", typical=True)

    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """Two backward-Euler sweeps, coefficients at ``t + dt`` (``check`` is moot: positive for any ``dt``)."""
        c = self.operator._coefficients(rho, t + dt, face_velocity)
        return self._split_sweeps(c, rho, dt, self._cache_key(face_velocity))


class AdiStepper(_LineStepper):
    """``"adi"``: the Peaceman–Rachford alternating-direction implicit scheme, second order in time.

    ``(V - h A_x) r = (V + h A_y) ρ``, ``(V - h A_y) ρ' = (V + h A_x) r`` with ``h = dt/2``
    and the coefficients at ``t + dt/2`` (:mod:`meanfield.fokker_planck._sweeps`): stable for
    any ``dt``, positive for ``dt <= 2 min(V_c / Σ_out^x(c), V_c / Σ_out^y(c))``; beyond it
    each result is checked to be ``>= 0`` (docs/fokker_planck.md, "Time stepping").  The
    default on a box, and the one method with an accuracy step (``courant``).
    """

    name = "adi"
    accepts_courant = True

    def positivity_bound(self, c: _Coefficients) -> float:
        """``2 min(V_c / Σ_out^x(c), V_c / Σ_out^y(c))``: both Crank–Nicolson halves positive (about 4× explicit)."""
        g = self.operator.grid
        return 2.0 * min(c.bound(g, "x"), c.bound(g, "y"))

    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None, check: bool) -> np.ndarray:
        """One Peaceman–Rachford step; with ``check`` a result below zero refuses ``dt`` with the bound."""
        op = self.operator
        c = op._coefficients(rho, t + 0.5 * dt, face_velocity)
        key = self._cache_key(face_velocity)
        V = op.grid.volume
        h = 0.5 * dt
        if fp_compiled.enabled():
            gx, rpx = self._thomas(c, h, "x", key)
            gy, rpy = self._thomas(c, h, "y", key)
            out = np.empty(rho.shape)
            work = self._buffer("r", rho.shape)
            v1, v2 = _with_sink(V, c, "y", -h), _with_sink(V, c, "x", -h)  # the explicit halves: V - h s
            lowest = fp_compiled.adi_step(rho, v1, v2, c.lx, c.rx, c.ly, c.ry, h, gx, rpx, gy, rpy, work, out)
            if check and lowest < 0:  # possible only above the positivity bound
                raise self._too_large(dt, self.positivity_bound(c), "positivity")
            return out
        vr = self._buffer("vr", rho.shape)
        b = op._apply(c, rho, "y", self._buffer("rhs", rho.shape))
        b *= h
        b += np.multiply(_with_sink(V, c, "y", -h), rho, out=vr)
        r = self._sweep(c, b, h, "x", key)
        b = op._apply(c, r, "x", self._buffer("rhs", rho.shape))
        b *= h
        b += np.multiply(_with_sink(V, c, "x", -h), r, out=vr)
        out = np.array(self._sweep(c, b, h, "y", key))
        if check and out.min() < 0:  # possible only above the positivity bound
            raise self._too_large(dt, self.positivity_bound(c), "positivity")
        return out


#: The time-stepping methods by name (``FokkerPlanck(method=...)``), in the order of ``METHODS``.
STEPPERS: dict[str, type[Stepper]] = {
    AdiStepper.name: AdiStepper,
    SplitStepper.name: SplitStepper,
    ExplicitStepper.name: ExplicitStepper,
    ImplicitStepper.name: ImplicitStepper,
}
