"""Finite-volume solver of the crowd's Fokker–Planck equation with zero-flux walls.

The mean-field limit of the human SDE (paper, eq. (1)) is the Fokker–Planck equation
(paper, eq. (4), with the interaction sign derived from the SDE, see
:mod:`meanfield.signs.interaction`)::

    ∂_t ρ = -∇·( (u_W[ρ] + v_r + v_a) ρ ) + Δ(σρ)     in Ω,
    n · ( (u_W[ρ] + v_r + v_a) ρ - ∇(σρ) ) = 0       on ∂Ω.

Written as a conservation law ``∂_t ρ + ∇·J = 0`` with the flux
``J = -σ∇ρ + (v - ∇σ) ρ`` (``v`` the total drift), it is discretised with cell-centred
finite volumes on a :class:`~meanfield.geometry.grid.Grid` (boxes, or disks and convex polygons
through cut cells).  The flux through each interior face is the Scharfetter–Gummel
(exponential-fitting) flux

    ``J = (σ_f / h) [ B(-P) ρ_L - B(P) ρ_R ]``,  ``P = a h / σ_f``,  ``B(z) = z / (e^z - 1)``,

with ``a`` the normal drift ``v - ∇σ`` on the face and ``σ_f`` the diffusion on the face.
It is second-order accurate where the grid Péclet number ``|P|`` is small, becomes the
upwind flux as ``|P| → ∞`` (and exactly the upwind flux when ``σ = 0``), and keeps the
discrete Gibbs state ``ρ ∝ exp(-U/σ)`` of a gradient drift ``v = -∇U`` exactly
stationary.  Wall faces carry no flux, so the total mass is conserved to round-off.

This module is that spatial operator (docs/fokker_planck.md, "The scheme", and
docs/discretisation.md, "The grid"): the face fluxes (:func:`scharfetter_gummel`), the
drift and the diffusion ``σ`` on the faces, the right-hand side ``-∇·J`` of eq. (4)
(:meth:`FokkerPlanck.rhs`) and the sparse matrix of a backward-Euler step.  The time
integrators (``method``: ``"adi"``, ``"split"``, ``"explicit"``, ``"implicit"``; order,
positivity and step bounds) are the steppers of :mod:`meanfield.fokker_planck.stepping`,
chosen by name (:data:`~meanfield.fokker_planck.stepping.STEPPERS`): :class:`FokkerPlanck`,
the solver, holds the one its ``method`` names and hands it each step, around which it
checks the arguments, chooses the automatic step and drives :meth:`FokkerPlanck.solve`
(docs/fokker_planck.md, "Time stepping").

Exits (docs/fokker_planck.md, "Exits and congestion"): on a region with exits the solver
absorbs by default, ``ρ = 0`` on them through the sink of
:class:`~meanfield.geometry.exits.ExitSink` applied after every step, and counts the mass out
per exit (:attr:`FokkerPlanck.mass_out`).  Congestion (``congestion=diagram, people=N``)
replaces the advective part of the flux by Godunov's flux of the LWR model,
``∂_t ρ + ∇·(ρ g(Nρ) v) = Δ(σρ)`` (:mod:`meanfield.fokker_planck.congested`), with the
methods ``"split"`` and ``"explicit"`` only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from scipy import sparse

from meanfield.errors import ParameterError, SigmaLike, check_sigma, positive_number
from meanfield.fokker_planck.congested import CONGESTED_STEPPERS, CongestedFlux, door_lengths, exit_normals
from meanfield.fokker_planck.stepping import STEPPERS, Stepper, _check_face_field, _Coefficients, _StepTooLarge
from meanfield.fokker_planck.stepping import (
    FaceVelocity as FaceVelocity,  # re-exported: the type of solve's face_velocity
)
from meanfield.geometry.exits import ExitSink, exit_segments
from meanfield.geometry.grid import FaceField, Grid
from meanfield.signs.interaction import InteractionField, InteractionPotential

__all__ = ["FokkerPlanck", "scharfetter_gummel", "METHODS"]

#: The names of the time-stepping methods (:data:`~meanfield.fokker_planck.stepping.STEPPERS`).
METHODS = tuple(STEPPERS)

Method = Literal["adi", "split", "explicit", "implicit"]
PointVelocity = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]


def scharfetter_gummel(
    drift: np.ndarray, diffusion: np.ndarray | float, spacing: float
) -> tuple[np.ndarray, np.ndarray]:
    """Scharfetter–Gummel face coefficients: the flux is ``c_left ρ_L - c_right ρ_R``.

    Parameters
    ----------
    drift : ndarray
        Normal drift ``a`` on each face, positive from the left cell to the right one.
    diffusion : ndarray or float
        ``σ_f >= 0`` on each face.
    spacing : float
        Distance ``h`` between the two cell centres.

    Returns
    -------
    c_left, c_right : ndarray
        ``(σ_f/h) B(-P)`` and ``(σ_f/h) B(P)`` with ``P = a h / σ_f`` and
        ``B(z) = z / (e^z - 1)``; both are ``>= 0`` and ``c_left - c_right = a``.  Where
        ``σ_f = 0`` they are the upwind coefficients ``max(a, 0)`` and ``max(-a, 0)``.

    Notes
    -----
    With ``s = |P|`` the smaller coefficient is ``(σ_f/h) B(s) = (σ_f/h) s / (e^s - 1)``,
    evaluated with ``expm1`` (no overflow, full relative accuracy for every ``s``), and the
    larger one is the smaller plus ``|a|`` (``B(-s) = B(s) + s``).  So their ratio is
    ``e^{|P|}`` to round-off, which keeps the discrete Gibbs state exact.
    """
    a = np.asarray(drift, dtype=float)
    out_l, out_r = np.empty_like(a), np.empty_like(a)
    _scharfetter_gummel_into(a, diffusion, spacing, 1.0, out_l, out_r, np.empty_like(a), np.empty_like(a))
    return out_l, out_r


def _scharfetter_gummel_into(a, diffusion, spacing, length, out_l, out_r, t1, t2) -> None:
    """:func:`scharfetter_gummel` times ``length``, written into ``out_l``, ``out_r``.

    No temporaries (``t1``, ``t2`` are work arrays of ``a``'s shape): a fresh half-megabyte
    array per operation costs more in page faults than the arithmetic.
    """
    np.maximum(a, 0.0, out=out_l)
    np.subtract(out_l, a, out=out_r)  # max(-a, 0), exactly
    if np.ndim(diffusion) == 0:
        d = float(diffusion)
        if d > 0.0:
            np.abs(a, out=t1)
            t1 *= spacing
            with np.errstate(over="ignore"):  # s = inf for a subnormal σ_f: clipped below; e^s = inf: B(s) = 0
                t1 /= d
                np.clip(t1, 1e-300, 1e300, out=t1)  # B(0) = 1 as s -> 0; B(1e300) = 0
                np.expm1(t1, out=t2)
            np.divide(t1, t2, out=t1)
            t1 *= d / spacing
            out_l += t1
            out_r += t1
    else:
        d = np.broadcast_to(np.asarray(diffusion, dtype=float), a.shape)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            s = np.clip(np.abs(a) * spacing / d, 1e-300, 1e300)
            small = np.where(d > 0, (d / spacing) * (s / np.expm1(s)), 0.0)
        out_l += small
        out_r += small
    if np.ndim(length) or length != 1.0:
        out_l *= length
        out_r *= length


def _check_point_velocity(name: str, value, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    try:
        vx, vy = value
    except (TypeError, ValueError):
        raise ParameterError(name, type(value).__name__, "a callable returning a pair (vx, vy)") from None
    vx = np.broadcast_to(np.asarray(vx, dtype=float), shape) if np.ndim(vx) == 0 else np.asarray(vx, dtype=float)
    vy = np.broadcast_to(np.asarray(vy, dtype=float), shape) if np.ndim(vy) == 0 else np.asarray(vy, dtype=float)
    if vx.shape != shape or vy.shape != shape:
        raise ParameterError(
            name, f"components of shapes {vx.shape}, {vy.shape}", f"arrays shaped like the inputs x, y: {shape}"
        )
    if not (np.all(np.isfinite(vx)) and np.all(np.isfinite(vy))):
        raise ParameterError(name, "non-finite values (NaN or inf)", "finite velocities")
    return vx, vy


def _stepper_class(method, congestion: CongestedFlux | None = None) -> type[Stepper]:
    """The stepper registered as ``method`` in :data:`~meanfield.fokker_planck.stepping.STEPPERS`
    (with congestion, in :data:`~meanfield.fokker_planck.congested.CONGESTED_STEPPERS`)."""
    if congestion is not None:
        if method not in CONGESTED_STEPPERS:
            raise ParameterError("method", method, f"one of {', '.join(map(repr, CONGESTED_STEPPERS))} with congestion")
        return CONGESTED_STEPPERS[method]
    if method not in STEPPERS:
        raise ParameterError("method", method, f"one of {', '.join(map(repr, STEPPERS))}")
    return STEPPERS[method]


def _congested_flux(congestion: Any, people: float | None) -> CongestedFlux | None:
    """The LWR flux of a fundamental diagram, or None for none (no diagram, or an infinite jam density)."""
    if congestion is None:
        return None
    rho_max = getattr(congestion, "rho_max", None)
    if rho_max is not None and not math.isfinite(float(rho_max)) and hasattr(congestion, "speed_factor"):
        return None  # NoCongestion: g ≡ 1, the uncongested code path
    if people is None:
        raise ParameterError("people", people, "the number of people N (> 0) with congestion: Nρ is persons/m²")
    return CongestedFlux(congestion, people)


def _check_courant(stepper: type[Stepper], courant) -> None:
    """Refuse an accuracy step ``courant`` for a method it does not apply to."""
    if courant is not None and not stepper.accepts_courant:
        raise ParameterError("courant", courant, "None unless method='adi' (the only method it applies to)")


class FokkerPlanck:
    """Finite-volume Fokker–Planck solver of the crowd density (paper, eq. (4)).

    The spatial operator (Scharfetter–Gummel fluxes, :meth:`rhs`) is defined here; each
    time step (:meth:`step`, :meth:`solve`, :meth:`automatic_dt`, :meth:`positivity_bound`)
    is taken by :attr:`stepper`, the :class:`~meanfield.fokker_planck.stepping.Stepper` of
    ``method``, from :mod:`meanfield.fokker_planck.stepping`.  See docs/fokker_planck.md.

    Parameters
    ----------
    grid : Grid
        Cells of Ω (box, or disk/polygon through cut cells).
    sigma : float or callable, default 0
        Diffusion ``σ >= 0``, or ``σ(x, y, t)`` returning an array shaped like ``x``;
        the SDE noise is ``sqrt(2σ) dB`` and the diffusion term ``Δ(σρ)``.
    velocity : callable, optional
        ``velocity(x, y, t) -> (vx, vy)``, a prescribed drift (e.g. the robots' ``v_r``),
        evaluated at the face midpoints.
    potential : callable, optional
        ``U(x, y)``: adds the gradient drift ``-∇U``, taken as differences of ``U`` between
        cell centres, so that ``exp(-U/σ)`` is an exact discrete steady state.
    interaction : InteractionPotential or InteractionField, optional
        ``W``; adds ``u_W[ρ](x) = ∫ ∇W(y - x) ρ(y) dy`` (the SDE's sign).
    disturbance : callable, optional
        ``v_a(x, y, t) -> (vx, vy)``, the unmodelled drift of the paper.
    method : {"adi", "split", "explicit", "implicit"}, optional
        Time integrator (see :mod:`meanfield.fokker_planck.stepping` for order and positivity).  Default:
        ``"adi"`` on a box; ``"split"`` on cut-cell grids (disks, polygons), whose small
        cells would bound the ADI and explicit steps.
    time_dependent : bool, default True
        Whether ``sigma``, ``velocity`` or ``disturbance`` depend on ``t``.  When False
        they are evaluated once and the face coefficients (and factorisations) reused.
    cfl : float, default 0.9
        Fraction of the positivity bound used by the automatic step (0 < cfl <= 1).
    courant : float, optional
        ``"adi"`` only: choose the automatic step for accuracy instead of positivity,
        ``dt = courant · min_faces(h / |a|)`` (the drift crosses at most ``courant`` cells
        per step), so that the O(dt²) time error of Peaceman–Rachford scales like the
        O(h²) space error.  The step is stable whatever its size; each step's result is
        still checked to be ``>= 0`` and the step shortened when it is not.  Without any
        drift it falls back to the positivity step.  Default None: ``cfl`` × the
        positivity bound, O(h²) steps.

    Examples
    --------
    >>> from meanfield import Domain, Grid, FokkerPlanck
    >>> grid = Grid(Domain.box(1.0, 1.0), cells=(32, 32))
    >>> fp = FokkerPlanck(grid, sigma=0.01, velocity=lambda x, y, t: (0.1 + 0 * x, 0 * y))
    >>> rho = fp.solve(grid.normalize(np.ones(grid.shape)), t_final=1.0)
    >>> bool(abs(grid.integrate(rho) - 1.0) < 1e-12)
    True
    """

    def __init__(
        self,
        grid: Grid,
        sigma: SigmaLike = 0.0,
        velocity: PointVelocity | None = None,
        *,
        potential: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
        interaction: InteractionPotential | InteractionField | None = None,
        disturbance: PointVelocity | None = None,
        method: Method | None = None,
        time_dependent: bool = True,
        cfl: float = 0.9,
        courant: float | None = None,
        exits: bool = True,
        congestion: Any = None,
        people: float | None = None,
    ):
        if not isinstance(grid, Grid):
            raise ParameterError("grid", type(grid).__name__, "a meanfield.Grid")
        self.grid = grid
        self.sigma: SigmaLike = check_sigma("sigma", sigma)
        for name, f in (("velocity", velocity), ("potential", potential), ("disturbance", disturbance)):
            if f is not None and not callable(f):
                raise ParameterError(name, type(f).__name__, "a callable of (x, y, t) (potential: of (x, y)), or None")
        self.velocity = velocity
        self.disturbance = disturbance
        self.potential = potential
        if interaction is None or isinstance(interaction, InteractionField):
            self.interaction = interaction
        elif hasattr(interaction, "gradient"):
            self.interaction = InteractionField(grid, interaction)
        else:
            raise ParameterError(
                "interaction", type(interaction).__name__, "an InteractionPotential, InteractionField or None"
            )
        self.congestion: CongestedFlux | None = _congested_flux(congestion, people)
        if method is None:
            method = "split" if self.congestion is not None or not grid.is_box else "adi"
        stepper = _stepper_class(method, self.congestion)
        self.time_dependent = bool(time_dependent)
        cfl_v = positive_number("cfl", cfl)
        if cfl_v > 1:
            raise ParameterError("cfl", cfl, "a number in (0, 1]")
        self.cfl = cfl_v
        _check_courant(stepper, courant)
        self.courant = None if courant is None else positive_number("courant", courant)
        self._static: tuple[FaceField, FaceField] | None = None  # (drift, diffusion) when cacheable
        self._potential_drift: FaceField | None = None
        self._coeff_cache: _Coefficients | None = None
        self._dynamic: _Coefficients | None = None
        self._work: dict[str, np.ndarray] = {}
        self._diffusion_cache: _Coefficients | None = None
        segs = exit_segments(grid.domain)
        #: The region's exits as a sink (:class:`~meanfield.geometry.exits.ExitSink`), None without exits.
        self.sink: ExitSink | None = (
            ExitSink(grid, segs, 0.0 if callable(self.sigma) else float(self.sigma)) if len(segs) else None
        )
        #: Whether the exits absorb in :meth:`step` and :meth:`solve` (the constructor's ``exits``).
        self.absorbing: bool = bool(exits)
        #: The mass that has left through each exit since construction (or :meth:`reset_mass_out`).
        self.mass_out: np.ndarray = np.zeros(0 if self.sink is None else self.sink.n_exits)
        self._exit_normals = exit_normals(grid, segs) if len(segs) else np.zeros((0, 2))
        self._door_lengths = door_lengths(self.sink) if self.sink is not None else None
        self._all_exits = self.sink  # (exits_closed closes some of these)
        self._sink_seen: tuple[Any, Any] | None = None  # the sink (and its rates) _exit_sink last split by axis
        self._sink_axes: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        self._sink_mass_rate: np.ndarray | None = None  # s per exit and cell, (E, nx, ny)
        #: A counter of the exits' rates the steppers integrate: their factors are kept per version.
        self._sink_version = 0
        #: The time-stepping method (docs/fokker_planck.md, "Time stepping"), built on this operator.
        self.stepper: Stepper = stepper(self)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """From now on only the exits with ``open_exits[k]`` take mass (a scenario's ``[[events]]``): the others are
        walls, for the sink and for the congested doors (:meth:`~meanfield.geometry.exits.ExitSink.closed`)."""
        if self._all_exits is None:
            return
        self.sink = self._all_exits.closed(open_exits)
        self._door_lengths = door_lengths(self.sink)

    @property
    def method(self) -> str:
        """The name of the time-stepping method, a key of :data:`~meanfield.fokker_planck.stepping.STEPPERS`.

        Setting it swaps :attr:`stepper` for a new one of that method (checked like the
        constructor's ``method``, with ``courant``).
        """
        return self.stepper.name

    @method.setter
    def method(self, method: Method) -> None:
        stepper = _stepper_class(method, self.congestion)
        _check_courant(stepper, self.courant)
        self.stepper = stepper(self)

    @property
    def mass_out_total(self) -> float:
        """The mass that has left through all the exits (``Σ mass_out``)."""
        return float(self.mass_out.sum())

    def reset_mass_out(self) -> None:
        """Set the count of the mass out through each exit back to zero."""
        self.mass_out[...] = 0.0

    # ------------------------------------------------------------------ validation
    def check_density(self, rho, name: str = "rho") -> np.ndarray:
        """Validate a density on ``grid.shape``: finite, ``>= 0``, positive mass.

        Returns a float copy with the cells outside Ω set to zero.
        """
        g = self.grid
        try:
            arr = np.array(rho, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(name, type(rho).__name__, f"a real array of grid.shape {g.shape}") from None
        if arr.shape != g.shape:
            raise ParameterError(name, f"shape {arr.shape}", f"an array of grid.shape {g.shape}")
        if not np.all(np.isfinite(arr)):
            raise ParameterError(name, "non-finite values (NaN or inf)", "a finite density")
        if np.any(arr < 0):
            raise ParameterError(name, f"minimum {arr.min():.3g}", "a density >= 0 everywhere")
        arr = np.where(g.active, arr, 0.0)
        mass = g.integrate(arr)
        if not mass > 0:
            raise ParameterError(name, "zero mass", "a density of positive mass (∫ρ dx > 0)")
        return arr

    # ------------------------------------------------------------------ drift and diffusion
    def _sigma_fields(self, t: float) -> tuple[FaceField, FaceField | None]:
        """``σ`` on the faces and ``∇σ`` on the faces (None if σ is constant)."""
        g = self.grid
        if not callable(self.sigma):
            return (self.sigma, self.sigma), None
        out = []
        for X, Y in (g.face_points_x, g.face_points_y, g.centers):
            s = np.asarray(self.sigma(X, Y, t), dtype=float)
            if s.shape != X.shape:
                s = np.broadcast_to(s, X.shape) if s.ndim == 0 else s
            if s.shape != X.shape:
                raise ParameterError("sigma", f"σ(x, y, t) of shape {s.shape}", f"an array shaped like x: {X.shape}")
            if not np.all(np.isfinite(s)) or np.any(s < 0):
                raise ParameterError("sigma", "σ(x, y, t) negative or non-finite", "σ(x, y, t) >= 0 and finite")
            out.append(s)
        return (out[0], out[1]), g.gradient(out[2])

    def _point_drift(self, f: PointVelocity, name: str, t: float) -> FaceField:
        g = self.grid
        Xx, Yx = g.face_points_x
        Xy, Yy = g.face_points_y
        vx = _check_point_velocity(name, f(Xx, Yx, t), Xx.shape)[0]
        vy = _check_point_velocity(name, f(Xy, Yy, t), Xy.shape)[1]
        return vx, vy

    def _base_drift(self, t: float) -> tuple[FaceField, FaceField]:
        """Drift ``v + v_a - ∇U - ∇σ`` on faces and ``σ`` on faces (no ρ-dependent part)."""
        if self._static is not None:
            return self._static
        g = self.grid
        ax = np.zeros((g.shape[0] - 1, g.shape[1]))
        ay = np.zeros((g.shape[0], g.shape[1] - 1))
        if self.velocity is not None:
            vx, vy = self._point_drift(self.velocity, "velocity", t)
            ax += vx
            ay += vy
        if self.disturbance is not None:
            vx, vy = self._point_drift(self.disturbance, "disturbance", t)
            ax += vx
            ay += vy
        if self.potential is not None:
            if self._potential_drift is None:
                X, Y = g.centers
                U = np.asarray(self.potential(X, Y), dtype=float)
                if U.shape != g.shape or not np.all(np.isfinite(U[g.active])):
                    raise ParameterError(
                        "potential", "U(x, y) of wrong shape or non-finite", f"finite, shape {g.shape}"
                    )
                gx, gy = g.gradient(np.where(g.active, U, 0.0))
                self._potential_drift = (-gx, -gy)
            ax += self._potential_drift[0]
            ay += self._potential_drift[1]
        diff, grad_sigma = self._sigma_fields(t)
        if grad_sigma is not None:
            ax -= grad_sigma[0]
            ay -= grad_sigma[1]
        result = ((ax, ay), diff)
        if not self.time_dependent:
            self._static = result
        return result

    def drift(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> FaceField:
        """Total normal drift ``u_W[ρ] + v + v_a - ∇U - ∇σ`` on the interior faces."""
        (ax, ay), _ = self._base_drift(t)
        if self.interaction is not None:
            ux, uy = self.interaction.on_faces(rho)
            ax, ay = ax + ux, ay + uy
        if face_velocity is not None:
            ax, ay = ax + face_velocity[0], ay + face_velocity[1]
        return ax, ay

    def _buffer(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """A work array reused from step to step (see :func:`_scharfetter_gummel_into`)."""
        b = self._work.get(name)
        if b is None or b.shape != shape:
            b = self._work[name] = np.empty(shape)
        return b

    def _coefficients(self, rho: np.ndarray, t: float, face_velocity: FaceField | None) -> _Coefficients:
        """Face coefficients at ``(ρ, t)``; cached when nothing depends on time or ``ρ``.

        The dynamic set is written into the same arrays every call: a caller must be done
        with the previous set before asking for the next.
        """
        cacheable = not self.time_dependent and self.interaction is None and face_velocity is None
        if cacheable and self._coeff_cache is not None:
            return self._with_exit_sink(self._coeff_cache)
        g = self.grid
        nx, ny = g.shape
        (bx, by), (dxf, dyf) = self._base_drift(t)
        uw = self.interaction.on_faces(rho) if self.interaction is not None else None
        if cacheable:
            arrays = [np.empty((nx - 1, ny)), np.empty((nx - 1, ny)), np.empty((nx, ny - 1)), np.empty((nx, ny - 1))]
        else:
            arrays = [
                self._buffer(k, sh)
                for k, sh in (("lx", (nx - 1, ny)), ("rx", (nx - 1, ny)), ("ly", (nx, ny - 1)), ("ry", (nx, ny - 1)))
            ]
        for k, (base, d, h, length) in enumerate(((bx, dxf, g.dx, g._len_x), (by, dyf, g.dy, g._len_y))):
            shape = base.shape
            a = base
            if uw is not None or face_velocity is not None:
                a = self._buffer(f"a{k}", shape)
                np.copyto(a, base)
                if uw is not None:
                    a += uw[k]
                if face_velocity is not None:
                    a += face_velocity[k]
            length = g.dy if (g.is_box and k == 0) else g.dx if g.is_box else length
            _scharfetter_gummel_into(
                a,
                d,
                h,
                length,
                arrays[2 * k],
                arrays[2 * k + 1],
                self._buffer(f"t1{k}", shape),
                self._buffer(f"t2{k}", shape),
            )
        if cacheable:
            self._coeff_cache = _Coefficients(*arrays)
            return self._with_exit_sink(self._coeff_cache)
        c = self._dynamic
        if c is None:
            c = self._dynamic = _Coefficients(*arrays)
        else:
            c.reset()
        return self._with_exit_sink(c)

    def _exit_sink(self) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The exits' outflow coefficients ``(s_x, s_y)`` the steppers integrate (mass rate ``s ρ`` per cell).

        ``s = k V`` from the current :attr:`sink` (``σ ℓ / d``, the Dirichlet face, plus a drift's outflow where the
        crowd set one), each exit's counted along the axis closest to its normal.  ``(None, None)`` where the exits
        are not the solver's to integrate: none, ``exits=False``, or congestion (its doors are faces of the
        congested flux).  Recomputed when :attr:`sink` or its rates change.
        """
        sink = self.sink
        if sink is None or not self.absorbing or self.congestion is not None:
            return None, None
        if self._sink_seen is None or self._sink_seen[0] is not sink or self._sink_seen[1] is not sink.rates:
            mass_rate = np.where(sink.rates > 0, sink.rates * self.grid.volume[None], 0.0)  # (E, nx, ny)
            normals = exit_normals(self.grid, sink.segments)
            along_x = np.abs(normals[:, 0]) >= np.abs(normals[:, 1])
            self._sink_axes = (mass_rate[along_x].sum(axis=0), mass_rate[~along_x].sum(axis=0))
            self._sink_mass_rate = mass_rate
            self._sink_seen = (sink, sink.rates)
            self._sink_version += 1
        return self._sink_axes

    def _with_exit_sink(self, c: _Coefficients) -> _Coefficients:
        """``c`` carrying the exits' outflow coefficients (:meth:`_exit_sink`); its bounds forgotten if they changed."""
        sx, sy = self._exit_sink()
        if c.sink_version != self._sink_version or c.sink_x is not sx:
            c.sink_x, c.sink_y, c.sink_version = sx, sy, self._sink_version
            c.reset()  # (its bounds counted the exits it had)
        return c

    def _diffusion_coefficients(self, t: float) -> _Coefficients:
        """Scharfetter–Gummel coefficients of the diffusion ``Δ(σρ)`` alone (drift ``−∇σ``), for congestion.

        For a constant σ they are ``σ_f ℓ / h`` on both sides (central differences); kept while
        σ does not depend on time.
        """
        if self._diffusion_cache is not None:
            return self._diffusion_cache
        g = self.grid
        (dxf, dyf), grad = self._sigma_fields(t)
        arrays = []
        for k, (d, h, length) in enumerate(((dxf, g.dx, g._len_x), (dyf, g.dy, g._len_y))):
            shape = (g.shape[0] - 1, g.shape[1]) if k == 0 else (g.shape[0], g.shape[1] - 1)
            a = -grad[k] if grad is not None else np.zeros(shape)
            length = g.dy if (g.is_box and k == 0) else g.dx if g.is_box else length
            lo, hi = np.empty(shape), np.empty(shape)
            _scharfetter_gummel_into(a, d, h, length, lo, hi, np.empty(shape), np.empty(shape))
            arrays += [lo, hi]
        c = _Coefficients(*arrays)
        if not callable(self.sigma) or not self.time_dependent:
            self._diffusion_cache = c
        return c

    def _state(self, rho: np.ndarray, t: float, face_velocity: FaceField | None) -> Any:
        """What the stepper's bounds read: the face coefficients, or with congestion the congested state."""
        if self.congestion is not None:
            return self.stepper.state(rho, t, face_velocity)
        return self._coefficients(rho, t, face_velocity)

    def _advance(self, rho: np.ndarray, t: float, dt: float, fv: FaceField | None) -> np.ndarray:
        """One step of the stepper, then (without congestion) the exits' outflow over it.

        Without congestion the exits are the Dirichlet sink of
        :class:`~meanfield.geometry.exits.ExitSink`, applied exactly after the step (Lie
        splitting, ``ρ ← ρ e^{−k dt}``); with congestion they are faces of the congested flux
        (the stepper counts their outflow).  Either way ``mass_out`` counts the mass that left.
        """
        new = self.stepper.step(rho, t, dt, fv, check=True)
        if self._exit_sink()[0] is not None:  # the exits were integrated with the step: count what left
            self.mass_out += self._out_per_exit(rho, new)
        return new

    def _out_per_exit(self, before: np.ndarray, after: np.ndarray) -> np.ndarray:
        """The mass that left over a step, ``∫ρ − ∫ρ'`` (the operator conserves mass otherwise), shared among the
        exits by their outflow ``s_j (ρ + ρ') / 2`` over the step (``s_j`` as :meth:`_exit_sink` keeps it)."""
        g = self.grid
        lost = g.integrate(before) - g.integrate(after)
        flow = (self._sink_mass_rate * (before + after)[None]).sum(axis=(1, 2))
        total = flow.sum()
        return lost * flow / total if total > 0 else np.zeros(len(flow))

    # ------------------------------------------------------------------ right-hand side
    def flux(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> FaceField:
        """Scharfetter–Gummel flux ``J·n`` on the interior faces (per unit face length)."""
        g = self.grid
        ax, ay = self.drift(rho, t, face_velocity)
        _, (dxf, dyf) = self._base_drift(t)
        lx, rx = scharfetter_gummel(ax, dxf, g.dx)
        ly, ry = scharfetter_gummel(ay, dyf, g.dy)
        return lx * rho[:-1, :] - rx * rho[1:, :], ly * rho[:, :-1] - ry * rho[:, 1:]

    def rhs(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> np.ndarray:
        """``∂_t ρ = -∇·J`` (paper, eq. (4); with congestion eq. (C) of
        :mod:`~meanfield.fokker_planck.congested`) on the cells, zero flux through the walls and
        the exits (their outflow is not included: see :attr:`sink`)."""
        if self.congestion is not None:
            st = self.stepper.state(rho, t, face_velocity)
            st.exit_speed = None
            rate, _ = self.stepper.advective_rate(st, rho)
            rate += self._apply(st.diffusion, rho, "xy", np.empty(rho.shape))
            return rate * self.grid._inv_volume
        c = self._coefficients(rho, t, face_velocity)
        return self._apply(c, rho, "xy", np.empty(rho.shape)) * self.grid._inv_volume

    def _apply(self, c: _Coefficients, rho: np.ndarray, axes: str, out: np.ndarray) -> np.ndarray:
        """Mass rate ``A ρ`` (per cell, not divided by volume) along ``axes``, into ``out``."""
        out[...] = 0.0
        nx, ny = rho.shape
        if "x" in axes:
            G = self._buffer("Gx", (nx - 1, ny))
            T = self._buffer("Tx", (nx - 1, ny))
            np.multiply(c.lx, rho[:-1, :], out=G)
            np.multiply(c.rx, rho[1:, :], out=T)
            G -= T
            out[:-1, :] -= G
            out[1:, :] += G
        if "y" in axes:
            G = self._buffer("Gy", (nx, ny - 1))
            T = self._buffer("Ty", (nx, ny - 1))
            np.multiply(c.ly, rho[:, :-1], out=G)
            np.multiply(c.ry, rho[:, 1:], out=T)
            G -= T
            out[:, :-1] -= G
            out[:, 1:] += G
        return out

    def _matrix(self, c: _Coefficients, dt: float) -> sparse.csc_matrix:
        """The backward-Euler matrix ``V - dt A`` of eq. (4) (an M-matrix; identity rows outside Ω)."""
        g = self.grid
        nx, ny = g.shape
        idx = np.arange(nx * ny).reshape(nx, ny)
        V = g.volume
        diag = V.copy()
        diag[:-1, :] += dt * c.lx
        diag[1:, :] += dt * c.rx
        diag[:, :-1] += dt * c.ly
        diag[:, 1:] += dt * c.ry
        if c.sink_x is not None:  # the exits' outflow (Dirichlet faces)
            diag += dt * (c.sink_x + c.sink_y)
        diag[V <= 0] = 1.0
        rows = [idx.ravel(), idx[:-1, :].ravel(), idx[1:, :].ravel(), idx[:, :-1].ravel(), idx[:, 1:].ravel()]
        cols = [idx.ravel(), idx[1:, :].ravel(), idx[:-1, :].ravel(), idx[:, 1:].ravel(), idx[:, :-1].ravel()]
        vals = [diag.ravel(), -dt * c.rx.ravel(), -dt * c.lx.ravel(), -dt * c.ry.ravel(), -dt * c.ly.ravel()]
        return sparse.csc_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nx * ny, nx * ny)
        )

    # ------------------------------------------------------------------ time stepping (the stepper's)
    def positivity_bound(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> float:
        """Largest ``dt`` for which the chosen method keeps ``ρ >= 0`` (inf if unconditional).

        ``"explicit"``: ``min_c V_c / Σ_out(c)`` (forward-Euler bound, also the stability
        bound); ``"adi"``: ``2 min(V_c / Σ_out^x(c), V_c / Σ_out^y(c))``;
        ``"split"`` and ``"implicit"``: inf (M-matrices).  See
        :meth:`Stepper.positivity_bound <meanfield.fokker_planck.stepping.Stepper.positivity_bound>`
        and docs/fokker_planck.md, "Time stepping".
        """
        return self.stepper.positivity_bound(self._state(rho, t, face_velocity))

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

        Returns
        -------
        ndarray
            ``ρ(t + dt)``; on a region with exits (and ``exits=True``) after their outflow over
            the step, whose mass is added to :attr:`mass_out`.
        """
        rho = self.check_density(rho)
        dt = positive_number("dt", dt)
        if face_velocity is not None:
            face_velocity = _check_face_field("face_velocity", face_velocity, self.grid)
        return self._advance(rho, float(t), dt, face_velocity)

    def automatic_dt(self, rho: np.ndarray, t: float = 0.0, face_velocity: FaceField | None = None) -> float:
        """The step ``solve`` takes when ``dt`` is None.

        ``cfl`` × the positivity bound for ``"explicit"`` and ``"adi"`` (on cut-cell
        grids the smallest cell sets it: prefer ``"split"`` there, or pass ``dt``); for
        the unconditionally positive ``"split"`` and ``"implicit"``, ``cfl`` × four times
        the explicit bound of the cells at least half inside Ω (their error is first
        order in ``dt``; pass a ``dt`` to go further).  With ``courant`` set (``"adi"``):
        ``courant · min_faces(h / |a|)``, an accuracy step (:meth:`solve` then divides
        the time left into equal steps of at most that size).  See
        :meth:`Stepper.automatic_bound <meanfield.fokker_planck.stepping.Stepper.automatic_bound>`
        and docs/fokker_planck.md, "Time stepping".
        """
        c = self._state(rho, t, face_velocity)
        if self.courant is not None:  # accuracy: the drift crosses `courant` cells per step
            step = self.courant * c.crossing_time(self.grid)
            if math.isfinite(step):
                return step
        b = self.stepper.automatic_bound(c)
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
                        new = self._advance(rho, t, h, fv)
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
