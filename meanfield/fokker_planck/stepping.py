"""Time stepping of the crowd's Fokker–Planck equation (paper, eq. (4)).

The finite-volume operator of :mod:`meanfield.fokker_planck.solver` turns eq. (4) into the
semi-discrete system ``V dρ/dt = A(ρ, t) ρ`` (cell volumes ``V``, Scharfetter–Gummel
face coefficients in ``A``; see docs/fokker_planck.md, "The scheme").  This module
advances that system in time; it is mixed into
:class:`~meanfield.fokker_planck.solver.FokkerPlanck`, the public solver, and is not used on its
own.  Time stepping (``method``; docs/fokker_planck.md, "Time stepping", and
docs/discretisation.md, "Time stepping"):

``"explicit"``
    Heun's method (SSP Runge–Kutta 2), second order.  Positive when
    ``dt <= min_c V_c / Σ_out(c)``, the forward-Euler positivity bound, which is also its
    stability bound; the step is chosen automatically, and a user ``dt`` above the bound
    is refused.
``"split"`` (the default on cut-cell grids)
    Directional splitting: backward-Euler sweeps along x then y (the order alternates
    each step), each a batch of tridiagonal solves, O(cells) per step
    whatever the drift does.  Every sweep matrix is an M-matrix, so ``ρ >= 0`` for any
    ``dt``.  First order in time.
``"adi"`` (the default on a box)
    Peaceman–Rachford alternating-direction implicit scheme (Crank–Nicolson halves),
    second order in time, two tridiagonal sweeps per step, stable for any ``dt``.
    Guaranteed positive when ``dt <= 2 min(V_c / Σ_out^x(c), V_c / Σ_out^y(c))`` (about
    four times the explicit bound), which the automatic step uses; a larger user ``dt``
    is accepted while the result stays ``>= 0`` and refused, with the bound, when it
    does not.  With ``courant`` set, the automatic step is chosen for accuracy instead:
    ``courant · min_faces(h / |a|)``, whose O(dt²) time error scales like the O(h²)
    space error (the positivity bound scales like h²).
``"implicit"``
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
from collections.abc import Callable

import numpy as np
from scipy.linalg import lapack
from scipy.sparse import linalg as splinalg

from meanfield.errors import ParameterError, positive_number
from meanfield.fokker_planck import _sweeps as fp_compiled
from meanfield.geometry.grid import FaceField, Grid

__all__ = ["FaceVelocity"]

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
    """Scharfetter–Gummel face coefficients times face length, and derived bounds."""

    __slots__ = ("lx", "rx", "ly", "ry", "_out_x", "_out_y", "bounds")

    def __init__(self, lx, rx, ly, ry):
        self.lx, self.rx, self.ly, self.ry = lx, rx, ly, ry
        self._out_x = None
        self._out_y = None
        self.bounds: dict[str, float] = {}

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
            self._out_x, self._out_y = ox, oy
        return self._out_x, self._out_y


#: factorisations kept for a fixed drift (one per step size and axis): the latest few
_CACHED_FACTORS = 8


class _StepTooLarge(ParameterError):
    """A step above the method's bound; ``bound`` is the bound at the offending stage."""

    def __init__(self, bound: float, *args):
        super().__init__(*args)
        self.bound = bound


class _TimeStepping:
    """The time integrators of eq. (4), mixed into :class:`~meanfield.fokker_planck.solver.FokkerPlanck`.

    The host class provides the spatial operator (docs/fokker_planck.md, "The scheme"):
    ``grid``, ``method``, ``cfl``, ``courant``, ``time_dependent``, ``interaction``, the caches
    ``_lu_cache`` and ``_work``, and the methods ``check_density``, ``_coefficients``
    (the face coefficients of ``A(ρ, t)``), ``_apply`` (the mass rate ``A ρ``),
    ``_matrix`` (the backward-Euler matrix ``V - dt A``) and ``_buffer`` (work arrays).
    """

    # ------------------------------------------------------------------ step bounds
    def _bound(self, c: _Coefficients, axes: str, typical: bool = False) -> float:
        """``min_c V_c / Σ_out(c)`` over the faces along ``axes`` (cached per coefficient set).

        ``typical``: only over the cells at least half inside Ω (a step size, not a bound).
        """
        key = axes + ("-typical" if typical else "")
        if key in c.bounds:
            return c.bounds[key]
        g = self.grid
        ox, oy = c.outflow(g.shape)
        out = (ox if "x" in axes else 0.0) + (oy if "y" in axes else 0.0)
        mask = (g.volume_fraction >= 0.5 if typical else g.active) & (out > 0)
        b = float(np.min(g.volume[mask] / out[mask])) if np.any(mask) else math.inf
        c.bounds[key] = b
        return b

    def _crossing_time(self, c: _Coefficients) -> float:
        """``min_faces h / |a|``, the time the drift takes to cross a cell (cached per coefficient set).

        ``|a|`` is read off the coefficients: ``c_left - c_right = a`` times the face length.
        """
        if "crossing" not in c.bounds:
            g = self.grid
            rate = 0.0
            for lo, hi, length, h in ((c.lx, c.rx, g._len_x, g.dx), (c.ly, c.ry, g._len_y, g.dy)):
                open_ = length > 0
                if np.any(open_):
                    rate = max(rate, float(np.max(np.abs(lo - hi)[open_] / length[open_])) / h)
            c.bounds["crossing"] = 1.0 / rate if rate > 0 else math.inf
        return c.bounds["crossing"]

    def positivity_bound(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> float:
        """Largest ``dt`` for which the chosen method keeps ``ρ >= 0`` (inf if unconditional).

        ``"explicit"``: ``min_c V_c / Σ_out(c)`` (forward-Euler bound, also the stability
        bound); ``"adi"``: ``2 min(V_c / Σ_out^x(c), V_c / Σ_out^y(c))``;
        ``"split"`` and ``"implicit"``: inf (M-matrices).
        """
        c = self._coefficients(rho, t, face_velocity)
        if self.method == "explicit":
            return self._bound(c, "xy")
        if self.method == "adi":
            return 2.0 * min(self._bound(c, "x"), self._bound(c, "y"))
        return math.inf

    # ------------------------------------------------------------------ time steps
    def step(self, rho: np.ndarray, t: float, dt: float, face_velocity: FaceField | None = None) -> np.ndarray:
        """Advance ``ρ`` from ``t`` to ``t + dt`` by one step of ``self.method``.

        Parameters
        ----------
        rho : ndarray
            Density on ``grid.shape`` (finite, ``>= 0``, positive mass).
        t, dt : float
            Current time and step (``dt > 0``).  An explicit ``dt`` above the positivity
            and stability bound raises :class:`~meanfield.errors.ParameterError`.
        face_velocity : FaceField, optional
            An extra drift already on the faces (e.g. ``NavigationField.velocity()`` of the
            robots), held constant over the step.
        """
        rho = self.check_density(rho)
        dt = positive_number("dt", dt)
        if face_velocity is not None:
            face_velocity = _check_face_field("face_velocity", face_velocity, self.grid)
        return self._step(rho, float(t), dt, face_velocity, check=True)

    def _step(self, rho, t, dt, fv, check: bool) -> np.ndarray:
        m = self.method
        if m == "explicit":
            return self._heun(rho, t, dt, fv, check)
        if m == "split":
            return self._split(rho, t, dt, fv)
        if m == "adi":
            return self._adi(rho, t, dt, fv, check)
        return self._implicit(rho, t, dt, fv)

    def _too_large(self, dt: float, bound: float, what: str) -> ParameterError:
        return _StepTooLarge(
            bound,
            "dt",
            dt,
            f"dt <= {bound:.6g}, the {what} bound of method={self.method!r} at this state "
            "(or dt=None for an automatic step, or method='split'/'implicit', positive for any dt)",
        )

    def _heun(self, rho, t, dt, fv, check):
        g = self.grid
        iv = g._inv_volume
        c1 = self._coefficients(rho, t, fv)
        if check and dt > self._bound(c1, "xy") * (1 + 1e-12):
            raise self._too_large(dt, self._bound(c1, "xy"), "stability/positivity")
        r1 = self._apply(c1, rho, "xy", np.empty(rho.shape))
        r1 *= dt * iv
        r1 += rho
        c2 = self._coefficients(r1, t + dt, fv)
        if check and dt > self._bound(c2, "xy") * (1 + 1e-12):
            raise self._too_large(dt, self._bound(c2, "xy"), "stability/positivity")
        out = self._apply(c2, r1, "xy", np.empty(rho.shape))
        out *= dt * iv
        out += r1
        out += rho
        out *= 0.5
        return out

    def _sweep(self, c: _Coefficients, rhs_mass: np.ndarray, tau: float, axis: str, cache_key) -> np.ndarray:
        """Solve ``(V - τ A_axis) ρ' = rhs_mass`` by tridiagonal solves along ``axis``.

        The systems of all grid lines form one tridiagonal matrix (zero couplings between
        lines), solved by one LAPACK call; ``rhs_mass`` may be overwritten.
        """
        g = self.grid
        V = g.volume
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

    def _cache_key(self, fv):
        cacheable = not self.time_dependent and self.interaction is None and fv is None
        return "static" if cacheable else None

    def _thomas(self, c: _Coefficients, tau: float, axis: str, key) -> tuple[np.ndarray, np.ndarray]:
        """Factors of ``V - τ A_axis`` (:func:`~meanfield.fokker_planck._sweeps.tridiagonal_factor`), kept for a fixed drift."""
        ck = ("thomas", axis, tau, key) if key is not None else None
        if ck is not None and ck in self._lu_cache:
            return self._lu_cache[ck]
        shape = self.grid.shape
        if ck is None:  # a new drift every step: factor into work arrays
            g, rp = self._buffer("g" + axis, shape), self._buffer("rp" + axis, shape)
        else:
            g, rp = np.empty(shape), np.empty(shape)
        lo, hi = (c.lx, c.rx) if axis == "x" else (c.ly, c.ry)
        fp_compiled.tridiagonal_factor(self.grid.volume, lo, hi, tau, 0 if axis == "x" else 1, g, rp)
        if ck is not None:
            self._remember(ck, (g, rp))
        return g, rp

    def _remember(self, key, factors) -> None:
        """Keep a factorisation for a fixed drift; steps of many sizes keep only the latest few."""
        while len(self._lu_cache) >= _CACHED_FACTORS:
            self._lu_cache.pop(next(iter(self._lu_cache)))
        self._lu_cache[key] = factors

    def _split(self, rho, t, dt, fv):
        c = self._coefficients(rho, t + dt, fv)
        key = self._cache_key(fv)
        V = self.grid.volume
        self._parity = not getattr(self, "_parity", False)
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

    def _adi(self, rho, t, dt, fv, check):
        c = self._coefficients(rho, t + 0.5 * dt, fv)
        key = self._cache_key(fv)
        V = self.grid.volume
        h = 0.5 * dt
        if fp_compiled.enabled():
            gx, rpx = self._thomas(c, h, "x", key)
            gy, rpy = self._thomas(c, h, "y", key)
            out = np.empty(rho.shape)
            work = self._buffer("r", rho.shape)
            lowest = fp_compiled.adi_step(rho, V, c.lx, c.rx, c.ly, c.ry, h, gx, rpx, gy, rpy, work, out)
            if check and lowest < 0:  # possible only above the positivity bound
                raise self._too_large(dt, 2.0 * min(self._bound(c, "x"), self._bound(c, "y")), "positivity")
            return out
        vr = self._buffer("vr", rho.shape)
        b = self._apply(c, rho, "y", self._buffer("rhs", rho.shape))
        b *= h
        b += np.multiply(V, rho, out=vr)
        r = self._sweep(c, b, h, "x", key)
        b = self._apply(c, r, "x", self._buffer("rhs", rho.shape))
        b *= h
        b += np.multiply(V, r, out=vr)
        out = np.array(self._sweep(c, b, h, "y", key))
        if check and out.min() < 0:  # possible only above the positivity bound
            bound = 2.0 * min(self._bound(c, "x"), self._bound(c, "y"))
            raise self._too_large(dt, bound, "positivity")
        return out

    def _implicit(self, rho, t, dt, fv):
        c = self._coefficients(rho, t + dt, fv)
        key = self._cache_key(fv)
        lu = self._lu_cache.get(("2d", dt, key)) if key is not None else None
        if lu is None:
            lu = splinalg.splu(self._matrix(c, dt))
            if key is not None:
                self._remember(("2d", dt, key), lu)
        return lu.solve((self.grid.volume * rho).ravel()).reshape(rho.shape)

    # ------------------------------------------------------------------ driver
    def automatic_dt(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> float:
        """The step ``solve`` takes when ``dt`` is None.

        ``cfl`` × the positivity bound for ``"explicit"`` and ``"adi"`` (on cut-cell
        grids the smallest cell sets it: prefer ``"split"`` there, or pass ``dt``); for
        the unconditionally positive ``"split"`` and ``"implicit"``, ``cfl`` × four times
        the explicit bound of the cells at least half inside Ω (their error is first
        order in ``dt``; pass a ``dt`` to go further).  With ``courant`` set (``"adi"``):
        ``courant · min_faces(h / |a|)``, an accuracy step (:meth:`solve` then divides
        the time left into equal steps of at most that size).
        """
        c = self._coefficients(rho, t, face_velocity)
        if self.courant is not None:  # accuracy: the drift crosses `courant` cells per step
            step = self.courant * self._crossing_time(c)
            if math.isfinite(step):
                return step
        if self.method == "explicit":
            b = self._bound(c, "xy")
        elif self.method == "adi":
            b = 2.0 * min(self._bound(c, "x"), self._bound(c, "y"))
        else:
            b = 4.0 * self._bound(c, "xy", typical=True)
        if not math.isfinite(b):  # no drift and no diffusion: nothing moves
            return math.inf
        return self.cfl * b

    def solve(
        self,
        rho0: np.ndarray,
        t_final: float,
        t0: float = 0.0,
        dt: float | None = None,
        *,
        face_velocity: FaceVelocity | None = None,
        callback: Callable[[float, np.ndarray], None] | None = None,
        progress: bool = False,
    ) -> np.ndarray:
        """Integrate from ``t0`` to ``t_final`` and return ``ρ(t_final)``.

        Parameters
        ----------
        rho0 : ndarray
            Initial density on ``grid.shape`` (finite, ``>= 0``, positive mass).
        t_final, t0 : float
            End and start times (``t_final >= t0``).
        dt : float, optional
            Fixed step (the last step is shortened to land on ``t_final``).  None: the
            automatic step of :meth:`automatic_dt`, re-evaluated every step when the
            drift changes.
        face_velocity : FaceField or callable, optional
            Extra drift on the faces, constant or ``t -> FaceField``.
        callback : callable, optional
            ``callback(t, rho)`` after every step.
        progress : bool
            Show a progress bar (tqdm) over simulated time.
        """
        rho = self.check_density(rho0, "rho0")
        try:
            t0 = float(t0)
            t_final = float(t_final)
        except (TypeError, ValueError):
            raise ParameterError("t_final", t_final, "finite times with t_final >= t0") from None
        if not (math.isfinite(t0) and math.isfinite(t_final)) or t_final < t0:
            raise ParameterError("t_final", t_final, f"a finite time >= t0 = {t0}")
        if dt is not None:
            dt = positive_number("dt", dt)
        fv_fn = None
        fv_const = None
        if callable(face_velocity):
            fv_fn = face_velocity
        elif face_velocity is not None:
            fv_const = _check_face_field("face_velocity", face_velocity, self.grid)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=t_final - t0, unit="t", desc=f"Fokker–Planck ({self.method})")
        t = t0
        span = max(abs(t_final), abs(t0), 1.0)
        try:
            while t_final - t > 1e-13 * span:
                fv = fv_const if fv_fn is None else _check_face_field("face_velocity", fv_fn(t), self.grid)
                h = dt if dt is not None else self.automatic_dt(rho, t, fv)
                if dt is None and self.courant is not None and math.isfinite(h):  # equal steps to t_final
                    h = (t_final - t) / max(1, math.ceil((t_final - t) / h - 1e-9))
                h = min(h, t_final - t)
                for attempt in range(60):
                    try:
                        new = self._step(rho, t, h, fv, check=True)
                        break
                    except _StepTooLarge as exc:
                        # automatic step: the drift grew within the step; retry below its bound
                        if dt is not None or attempt == 59:
                            raise
                        h = min(0.5 * h, self.cfl * exc.bound)
                rho = new
                t = t + h if t_final - (t + h) > 1e-13 * span else t_final
                if callback is not None:
                    callback(t, rho)
                if bar is not None:
                    bar.update(h)
        finally:
            if bar is not None:
                bar.close()
        return rho
