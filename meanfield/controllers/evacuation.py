"""Step I towards the exits: Hughes' desired field and the controller that tracks it (docs page *Buildings*).

* ``φ``, the potential that leads to the exits, one of ``controller.options.evacuation.potential``
  (:class:`EvacuationOptions`):

  - ``"distance"`` (the default): the geodesic distance to the nearest exit inside Ω, the
    eikonal solution ``|∇φ| = 1`` by fast marching
    (:func:`meanfield.geometry.geodesic.exit_distance`), computed once;
  - ``"balanced"``: the exits balanced by their capacities,
    ``φ = min_k (d_k + v_free τ_k)`` with ``d_k`` the distance to exit ``k`` and the offsets ``τ_k``
    that minimise the time the last person is out, re-solved from the observed density every
    ``rebalance_period`` (:mod:`meanfield.controllers.exit_assignment`, options ``specific_flow``
    and ``rebalance_period``);
  - ``"hughes"``: Hughes' full model (R. L. Hughes, "A continuum theory for the flow of
    pedestrians", Transp. Res. B 36 (2002) 507–535, with his discomfort factor ``g ≡ 1``):
    ``φ`` is the remaining travel time, ``|∇φ| = 1/f̂(ρ)`` with ``φ = 0`` on the exits, solved by
    fast marching (:class:`meanfield.geometry.geodesic.ExitEikonal`, scikit-fmm's
    ``travel_time`` with the speed ``f̂(ρ)`` on the cells) from the observed density at every
    evaluation of the law, so that the field bends round the crowded places.

* :class:`EvacuationController` — the paper's Step II (eq. (8)) tracking the desired field
  of Hughes' model instead of the paper's Step I.  With the walking speed
  ``f(ρ) = v_free (1 − ρ/ρ_max)`` (0 beyond ``ρ_max``; ``ρ`` the toolkit's unit-mass density;
  ``v_free`` the crowd's ``crowd.free_speed``, ``ρ_max`` the option ``rho_max``, ``inf`` by default):

  - ``"distance"`` and ``"balanced"``: ``v_d = −f(ρ) ∇φ − u_W[ρ]``, ``|∇φ| = 1`` (the balanced ``φ`` is
    constant between two solutions, and ``∂_t v_d`` below is the distance's between them);
  - ``"hughes"``: Hughes' ``v_d = −f(ρ) f̂(ρ) ∇φ − u_W[ρ]`` with ``f̂ = max(f, f_min)``, which is his
    ``−f(ρ)² ∇φ`` wherever ``f >= f_min``, so that ``|v_d| = f(ρ)`` there (his conservation law
    is ``∂_t ρ − ∇·(ρ g(ρ) f(ρ)² ∇φ) = 0`` with ``g(ρ) f(ρ) = 1/|∇φ|``; here ``g ≡ 1``).  The floor
    ``f_min = SPEED_FLOOR · v_free`` (5 %) keeps ``φ`` finite behind a jam (with ``f → 0`` the
    travel time through a jammed cell is infinite and ``∇φ`` undefined): crossing a jammed
    cell costs as long as crossing 20 free ones, so the field prefers a detour of up to 20
    cells to a jam, and ``v_d`` still vanishes in the jam itself (its factor ``f = 0``).  A
    larger floor lets the field run into jams; a smaller one makes ``φ`` steep at a jam's edge,
    where ``v_d`` on the face between a jammed and a free cell grows like ``1/f_min``.

  Step II does not care which ``v_d`` it tracks: with the matching ``∂_t v_d`` the law gives
  ``dV₂/dt = S − Σ k_u|b_i|² − Σ k_ω g_i²``, where the Step-I term
  ``S = ⟨∇ρ̃, (v_d + u_W)ρ − ∇(σρ)⟩`` replaces the paper's ``−∫α|∇ρ̃|²`` (reported as
  ``dissipation = −S``).  ``∂_t v_d`` along ``ρ̇`` (``dvd_dt = "model"`` or ``"fokker-planck"``):

  - ``"distance"``: ``−f'(ρ) ρ̇ ∇φ − u_W[ρ̇]``, exact (``φ`` does not depend on ``ρ``);
  - ``"hughes"``: ``−(f' f̂ + f f̂') ρ̇ ∇φ − f f̂ ∇φ̇ − u_W[ρ̇]`` (``f̂' = f'`` above the floor, 0
    on it): the terms in ``f`` are exact, and ``φ̇`` is a forward difference of two fast
    marches, ``(φ(ρ + s ρ̇) − φ(ρ))/s`` with ``s ρ̇`` at most ``RATE_STEP · ρ_max`` on any cell
    (:data:`RATE_STEP`: the speed moves by at most ``10⁻⁶ v_free``; without congestion,
    ``ρ_max = inf``, ``φ̇ = 0`` exactly).  Fast marching is a piecewise smooth function of the
    speed (each node's value comes from the one or two upwind neighbours the march takes), so
    the difference is its derivative to ``O(s)`` where the step keeps every node's upwind
    neighbours, and a one-sided, inexact rate where it changes them (on the ridge between two
    exits, at a tie; docs page *Buildings*, "Routes to the exits", gives its accuracy, checked by
    ``tests/controllers/test_evacuation.py``).  A complex ``ρ = a + i b`` gets
    ``φ(a) + i (φ(a + s b) − φ(a))/s`` with the same step, so that complex-step derivatives of
    the law see the same ``φ̇`` (the identity then holds to round-off).  With
    ``dvd_dt = "finite-difference"`` (the scenarios' default) ``∂_t v_d`` is the backward
    difference of successive ``v_d``, which holds the change of ``φ`` as it is.

  The compiled law (:func:`~meanfield.controllers._law_loops.face_law`) computes the
  ``"distance"`` field; ``"hughes"`` takes the numpy path.  Registered as controller
  ``evacuation``.  It is the backstepping law composed with this Step I, :class:`ExitsStepOne`
  (:mod:`meanfield.controllers.step_one`), plus the exits' events and the balance's schedule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from meanfield.capabilities import ControllerCapabilities
from meanfield.controllers._law_loops import HUGHES_STEP_ONE
from meanfield.controllers.backstepping import BacksteppingController
from meanfield.controllers.exit_assignment import ExitAssignment, distance_to_each_exit
from meanfield.controllers.step_one import Prepared
from meanfield.errors import ParameterError, choice, deprecated, num, options_table
from meanfield.geometry.geodesic import ExitEikonal, exit_distance
from meanfield.geometry.grid import FaceField
from meanfield.interfaces import ControllerParts

__all__ = [
    "exit_distance",
    "EvacuationController",
    "ExitsStepOne",
    "EvacuationOptions",
    "POTENTIALS",
    "REBALANCE_PERIOD",
    "SPEED_FLOOR",
    "RATE_STEP",
    "V_FREE",
]

POTENTIALS = ("distance", "hughes", "balanced")
"""``controller.options.evacuation.potential``: the static distance to the exits, Hughes' travel time at the density,
or the distance to the exits balanced by their capacities (:mod:`meanfield.controllers.exit_assignment`)."""
REBALANCE_PERIOD = 1.0
"""Default ``controller.options.evacuation.rebalance_period``: the balanced potential is solved again this often (s in
SI)."""
V_FREE = 1.34
"""m/s: the walking speed of parts built by hand, which carry no crowd (Weidmann's free speed, the crowd's default
``crowd.free_speed``); from a scenario the law walks at the crowd's own."""
SPEED_FLOOR = 0.05
"""``f_min / v_free``: the floor of the walking speed in Hughes' eikonal equation (module docstring)."""
RATE_STEP = 1e-6
"""The step of the forward difference ``φ̇ = (φ(ρ + s ρ̇) − φ(ρ))/s``: ``s max|ρ̇| = RATE_STEP · ρ_max`` (module
docstring)."""


@dataclass
class EvacuationOptions:
    """``[controller.options.evacuation]``: what a scenario may set of the evacuation law (module docstring).

    Parameters
    ----------
    potential : {"distance", "hughes", "balanced"}
        ``φ``, the potential that leads to the exits (:data:`POTENTIALS`).
    specific_flow : float, optional
        With ``"balanced"``: each exit's flow per metre of its width, persons/(m·s) (default:
        :data:`~meanfield.controllers.exit_assignment.SPECIFIC_FLOW`).
    rebalance_period : float
        With ``"balanced"``: how often the exits' shares are solved again, > 0 (s in SI).
    rho_max : float
        ``ρ_max`` of the law's walking speed ``f(ρ)`` (module docstring), in the unit-mass density's units (the
        crowd's jam density over ``crowd.n``), > 0; ``inf`` (the default): ``f = v_free``, the law asks for the free
        speed everywhere and the crowd's own diagram slows it.  Measured (docs page *Buildings*, "The evacuation
        law's jam density"): the crowd's jam density here made the coverage slower.
    v_free : float, optional
        Deprecated (removed in 0.3.0): the law walks at the crowd's ``crowd.free_speed``.  Given here, with a
        warning, as before.
    """

    KIND: ClassVar[str] = "evacuation"
    """The controller whose table these are (the errors name ``controller.options.<KIND>.<field>``)."""

    potential: str = "distance"
    specific_flow: float | None = None
    rebalance_period: float = REBALANCE_PERIOD
    rho_max: float = math.inf
    v_free: float | None = None

    def __post_init__(self) -> None:
        name = f"controller.options.{self.KIND}."
        self.potential = choice(name + "potential", self.potential, POTENTIALS)
        if self.specific_flow is not None:
            self.specific_flow = num(name + "specific_flow", self.specific_flow, lo=0.0, lo_open=True,
                                     allowed="a flow > 0, persons/(m·s)")  # fmt: skip
        self.rebalance_period = num(name + "rebalance_period", self.rebalance_period, lo=0.0, lo_open=True)
        if self.v_free is not None:
            self.v_free = num(name + "v_free", self.v_free, lo=0.0, lo_open=True)
            deprecated(name + "v_free", "the controller takes the crowd's crowd.free_speed", stacklevel=3)
        if self.rho_max != math.inf:
            self.rho_max = num(name + "rho_max", self.rho_max, lo=0.0, lo_open=True,
                               allowed="a density > 0 (unit mass), or inf for no congestion in the law")  # fmt: skip


@dataclass
class _HughesPrepared(Prepared):
    """:class:`~meanfield.controllers.step_one.Prepared` and Hughes' potential at that density."""

    phi: np.ndarray | None = None
    grad_phi: FaceField | None = None


def _face_gradient(grid: Any, phi: np.ndarray) -> FaceField:
    """``∇φ`` on the faces of ``grid`` (0 where ``φ`` is not finite)."""
    return grid.gradient(np.where(np.isfinite(phi), phi, 0.0))


class ExitsStepOne:
    """Step I towards the exits (module docstring): ``v_d = −f(ρ) ∇φ − u_W[ρ]``, or Hughes' ``−f(ρ) f̂(ρ) ∇φ``;
    a :class:`~meanfield.controllers.step_one.StepOne` of the law.

    Parameters
    ----------
    potential : {"distance", "hughes", "balanced"}
        ``φ`` (:data:`POTENTIALS`).
    v_free, rho_max, speed_floor : float
        ``f(ρ) = v_free (1 − ρ/ρ_max)`` and ``f_min = speed_floor · v_free``.
    eikonal : ExitEikonal or None
        The exits' fast-marching solver (Hughes' potential needs it).
    grad_phi : FaceField or None
        ``∇φ`` of the static or balanced potential on the faces (set again as the exits or walls change).
    """

    def __init__(self, potential: str, v_free: float, rho_max: float, eikonal: ExitEikonal | None,
                 speed_floor: float, grad_phi: FaceField | None = None) -> None:  # fmt: skip
        self.potential, self.v_free, self.rho_max = potential, float(v_free), float(rho_max)
        self.eikonal, self.speed_floor, self.grad_phi = eikonal, float(speed_floor), grad_phi

    # ------------------------------------------------------------------ the walking speed
    def speed(self, rf: Any) -> tuple[Any, Any]:
        """``f(ρ)`` and ``f'(ρ)`` on the faces (0 beyond ``ρ_max``; complex ρ allowed for derivative checks)."""
        if math.isinf(self.rho_max):
            return self.v_free + 0 * rf, 0 * rf
        moving = np.real(rf) < self.rho_max
        f = np.where(moving, self.v_free * (1 - rf / self.rho_max), 0 * rf)
        return f, np.where(moving, -self.v_free / self.rho_max + 0 * rf, 0 * rf)

    def floored(self, rf: Any) -> tuple[Any, Any, Any, Any]:
        """``f``, ``f'``, ``f̂ = max(f, f_min)`` and ``f̂'`` (``f'`` above the floor, 0 on it)."""
        f, df = self.speed(rf)
        floor = self.speed_floor * self.v_free
        above = np.real(f) > floor
        return f, df, np.where(above, f, floor + 0 * f), np.where(above, df, 0 * df)

    # ------------------------------------------------------------------ Hughes' potential
    def hughes_potential(self, grid: Any, rho: np.ndarray) -> np.ndarray:
        """Hughes' ``φ`` on the cells of ``grid`` for the density ``rho``: ``|∇φ| = 1/f̂(ρ)``, ``φ = 0`` on the exits.

        One fast march (:meth:`~meanfield.geometry.geodesic.ExitEikonal.travel_time`) with the speed
        ``f̂(ρ)`` on the cells; ``inf`` on inactive cells.  A complex ``ρ = a + i b`` gives
        ``φ(a) + i (φ(a + s b) − φ(a))/s`` (module docstring, :data:`RATE_STEP`).
        """
        if self.eikonal is None:
            raise ParameterError("eikonal", None, "the exits' ExitEikonal on this grid, for Hughes' potential")
        rho = np.asarray(rho)
        if np.iscomplexobj(rho):
            a = np.ascontiguousarray(rho.real)
            phi = self._march(grid, a)
            return phi + 1j * self._potential_rate(grid, a, phi, np.ascontiguousarray(rho.imag))
        return self._march(grid, rho)

    def _march(self, grid: Any, rho: np.ndarray) -> np.ndarray:
        if math.isinf(self.rho_max):  # f = v_free everywhere: the march of a constant speed, distance / v_free exactly
            return self.eikonal.distance / self.v_free
        speed = np.real(self.floored(np.asarray(rho, float))[2])
        return self.eikonal.travel_time(np.where(grid.active, speed, self.v_free))

    def _potential_rate(self, grid: Any, rho: np.ndarray, phi: np.ndarray, rho_dot: np.ndarray) -> np.ndarray:
        """``φ̇ = (φ(ρ + s ρ̇) − φ(ρ))/s`` on the cells (0 on inactive ones), ``s ρ̇`` at most :data:`RATE_STEP`
        ``· ρ_max`` on any cell (the speed moves by at most ``RATE_STEP · v_free``): one more fast march."""
        act = grid.active
        top = float(np.abs(rho_dot[act]).max()) if act.any() else 0.0
        if top == 0.0 or math.isinf(self.rho_max):  # (no congestion: φ = distance / v_free whatever ρ)
            return np.zeros(grid.shape)
        s = RATE_STEP * self.rho_max / top
        out = np.zeros(grid.shape)
        out[act] = (self._march(grid, rho + s * rho_dot)[act] - phi[act]) / s
        return out

    # ------------------------------------------------------------------ Step I (StepOne)
    def prepare(self, law: Any, p: Prepared) -> Prepared:
        """``p``, with Hughes' potential at the density for ``potential = "hughes"``."""
        if self.potential != "hughes":
            return p
        phi = self.hughes_potential(law.grid, p.rho)
        shared = {f.name: getattr(p, f.name) for f in fields(p)}
        return _HughesPrepared(**shared, phi=phi, grad_phi=_face_gradient(law.grid, phi))

    def compiled(self, law: Any) -> tuple[int, float, float, Any] | None:
        """Hughes' Step I for :func:`~meanfield.controllers._law_loops.face_law` with the static or balanced
        distance; Hughes' potential takes the numpy path."""
        if self.potential == "hughes":
            return None
        return HUGHES_STEP_ONE, self.v_free, self.rho_max, self.grad_phi

    def virtual_velocity(self, law: Any, p: Prepared) -> FaceField:
        if isinstance(p, _HughesPrepared):
            out = []
            for k in range(2):
                f, _, fh, _ = self.floored(p.rf[k])
                out.append(-f * fh * p.grad_phi[k])
        else:
            out = [-self.speed(p.rf[k])[0] * self.grad_phi[k] for k in range(2)]
        if p.uw is not None:
            out = [out[k] - p.uw[k] for k in range(2)]
        return out[0], out[1]

    def virtual_velocity_rate(self, law: Any, p: Prepared, rho_dot: np.ndarray) -> FaceField:
        df = law.grid.face_average(rho_dot)
        if isinstance(p, _HughesPrepared):
            if np.iscomplexobj(p.rho) or np.iscomplexobj(rho_dot):
                raise TypeError("∂_t v_d of Hughes' potential needs a real density and rate (fast marching is real)")
            dphi = _face_gradient(law.grid, self._potential_rate(law.grid, p.rho, p.phi, rho_dot))
            out = []
            for k in range(2):
                f, fd, fh, fhd = self.floored(p.rf[k])
                out.append(-(fd * fh + f * fhd) * df[k] * p.grad_phi[k] - f * fh * dphi[k])
        else:
            out = [-self.speed(p.rf[k])[1] * df[k] * self.grad_phi[k] for k in range(2)]
        uw = law.interaction_on_faces(rho_dot)
        if uw is not None:
            out = [out[0] - uw[0], out[1] - uw[1]]
        return out[0], out[1]

    def dissipation(self, law: Any, p: Prepared) -> float:
        """``−S = ⟨∇ρ̃, ∇(σρ) − (v_d + u_W)ρ⟩``: what Step I's own flux does to ``½∫ρ̃²``, negated."""
        v = self.virtual_velocity(law, p)
        if p.uw is not None:
            v = (v[0] + p.uw[0], v[1] + p.uw[1])
        return law.grid.face_inner(p.grt, (p.gs[0] - v[0] * p.rf[0], p.gs[1] - v[1] * p.rf[1]))


class EvacuationController(BacksteppingController):
    """The paper's Step II tracking Hughes' desired field towards the exits (see the module docstring): the
    backstepping law with :class:`ExitsStepOne` as its Step I (``self.step_one``), whose figures it names
    (``potential``, ``v_free``, ``rho_max``, ``grad_phi``, ``eikonal``).

    Parameters
    ----------
    *args : Any
        The arguments of :class:`~meanfield.controllers.backstepping.BacksteppingController` (grid, target,
        σ, α, gains, strategy, interaction, ``dvd_dt``; α is unused by this Step I).
    phi : ndarray
        The distance to the exits on the cells (:func:`exit_distance`).
    v_free : float
        Walking speed in free flow, > 0 (1.34 m/s, Weidmann, in metres and seconds).
    rho_max : float
        Density (of the toolkit's unit-mass ρ) at which walking stops, > 0; ``inf``: no congestion.
    potential : {"distance", "hughes"}
        ``φ`` of ``v_d``: ``phi`` itself, or Hughes' ``|∇φ| = 1/f̂(ρ)`` at each density (:data:`POTENTIALS`).
    eikonal : ExitEikonal, optional
        The fast-marching solver of the exits on this grid (:class:`~meanfield.geometry.geodesic.ExitEikonal`);
        needed by ``potential = "hughes"``.
    speed_floor : float
        ``f_min / v_free`` in ``(0, 1]`` (:data:`SPEED_FLOOR`).
    assignment : ExitAssignment, optional
        The exits' balance (:mod:`meanfield.controllers.exit_assignment`); needed by ``potential = "balanced"``.
    rebalance_period : float
        How often the balanced potential is solved again, > 0 (:data:`REBALANCE_PERIOD`).
    **kwargs : Any
        Keyword arguments of :class:`~meanfield.controllers.backstepping.BacksteppingController`.
    """


    def __init__(
        self,
        *args: Any,
        phi: np.ndarray,
        v_free: float = V_FREE,
        rho_max: float = math.inf,
        potential: str = "distance",
        eikonal: ExitEikonal | None = None,
        speed_floor: float = SPEED_FLOOR,
        assignment: ExitAssignment | None = None,
        rebalance_period: float = REBALANCE_PERIOD,
        **kwargs: Any,
    ):
        if not (math.isfinite(v_free) and v_free > 0):
            raise ParameterError("controller.options.evacuation.v_free", v_free, "a walking speed > 0")
        if not rho_max > 0:
            raise ParameterError("controller.options.evacuation.rho_max", rho_max,
                                 "a density > 0, or inf for no congestion")  # fmt: skip
        if potential not in POTENTIALS:
            raise ParameterError("controller.options.evacuation.potential", potential,
                                 " or ".join(map(repr, POTENTIALS)))  # fmt: skip
        if not 0 < speed_floor <= 1:
            raise ParameterError("speed_floor", speed_floor, "a share of v_free in (0, 1]")
        if potential == "hughes" and eikonal is None:
            raise ParameterError("eikonal", None, "the exits' ExitEikonal on this grid, for Hughes' potential")
        if potential == "balanced" and assignment is None:
            raise ParameterError("assignment", None, "the exits' ExitAssignment, for the balanced potential")
        if not (math.isfinite(rebalance_period) and rebalance_period > 0):
            raise ParameterError("controller.options.evacuation.rebalance_period", rebalance_period, "a period > 0")
        step_one = ExitsStepOne(potential, v_free, rho_max, eikonal, speed_floor)
        super().__init__(*args, step_one=step_one, **kwargs)
        self.step_one: ExitsStepOne = step_one
        self.assignment = assignment if potential == "balanced" else None
        self.rebalance_period = float(rebalance_period)
        self._next_balance = -math.inf
        self._all_exits = None if eikonal is None else eikonal.segs  # (exits_closed solves to a subset of these)
        self._open: np.ndarray | None = None  # the exits open, by exits_closed (None: all)
        self.grad_phi = _face_gradient(self.grid, phi)

    # ------------------------------------------------------------------ its Step I's figures, by name
    potential = property(lambda self: self.step_one.potential, doc="``φ``: one of :data:`POTENTIALS`.")
    v_free = property(lambda self: self.step_one.v_free, doc="The walking speed in free flow.")
    rho_max = property(lambda self: self.step_one.rho_max, doc="``ρ_max`` of ``f(ρ)`` (unit-mass density).")
    speed_floor = property(lambda self: self.step_one.speed_floor, doc="``f_min / v_free``.")

    @property
    def eikonal(self) -> ExitEikonal | None:
        """The exits' fast-marching solver, to the exits open."""
        return self.step_one.eikonal

    @eikonal.setter
    def eikonal(self, value: ExitEikonal | None) -> None:
        self.step_one.eikonal = value

    @property
    def grad_phi(self) -> FaceField:
        """``∇φ`` of the static or balanced potential on the faces."""
        return self.step_one.grad_phi

    @grad_phi.setter
    def grad_phi(self, value: FaceField) -> None:
        self.step_one.grad_phi = value

    def hughes_potential(self, rho: np.ndarray) -> np.ndarray:
        """Hughes' ``φ`` on the law's cells for the density ``rho`` (:meth:`ExitsStepOne.hughes_potential`)."""
        return self.step_one.hughes_potential(self.grid, rho)

    capabilities: ClassVar[ControllerCapabilities] = ControllerCapabilities(
        accepts_sensing=True,  # as the paper's law: it runs on a group's knowledge
        requires_exits=True,  # it steers towards the region's exits: a region without has nothing to offer it
        changes_walls=True,  # a region can become wall during a run (walls_changed)
        options=EvacuationOptions,  # [controller.options.evacuation]
        stability_step=None,  # Hughes' Step I (v_d = -f(ρ) ∇φ) is not the sampled diffusion the paper's step bounds
    )
    """What it can do (:class:`~meanfield.capabilities.ControllerCapabilities`)."""

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> EvacuationController:
        """Registry factory (kind ``controller``, name ``evacuation``): the options of :class:`EvacuationOptions`
        (``parts.options``, refused naming ``controller.options.evacuation.<field>``)."""
        return cls.with_options(parts, options_table("controller.options.evacuation", EvacuationOptions,
                                                     dict(parts.options)))  # fmt: skip

    @classmethod
    def with_options(cls, parts: ControllerParts, options: EvacuationOptions) -> EvacuationController:
        """The law on ``parts`` with ``options`` (those of another controller's table, for one that runs it): the
        walking speed ``v_free`` is the crowd's (``parts.free_speed``, :data:`V_FREE` for parts built by hand)
        unless the deprecated option gives it."""
        from meanfield.geometry.exits import exit_segments

        o = options
        v_free = o.v_free if o.v_free is not None else V_FREE if parts.free_speed is None else float(parts.free_speed)
        segs = exit_segments(parts.region)
        eikonal = ExitEikonal(parts.grid, segs, parts.sight)
        extra: dict[str, Any] = {}
        if o.potential == "balanced":
            extra["assignment"] = cls.balance(parts, segs, eikonal, v_free, o.specific_flow)
        return cls(*cls.law_arguments(parts), phi=eikonal.distance, scales=parts.scales, potential=o.potential,
                   eikonal=eikonal, v_free=v_free, rho_max=o.rho_max, rebalance_period=o.rebalance_period,
                   **extra)  # fmt: skip

    @staticmethod
    def balance(parts: ControllerParts, segs: np.ndarray, eikonal: ExitEikonal, v_free: float,
                specific_flow: float | None, min_gain: float | None = None) -> ExitAssignment:  # fmt: skip
        """The exits' :class:`ExitAssignment`: one fast march per exit alone, the exits' widths, ``N`` of the crowd
        (``min_gain``: :class:`ExitAssignment`'s, default :data:`~meanfield.controllers.exit_assignment.MIN_GAIN`)."""
        from meanfield.controllers.exit_assignment import MIN_GAIN, SPECIFIC_FLOW

        if parts.people is None:
            raise ParameterError("crowd.n", None, "the crowd's size, for the balanced potential (persons per exit)")
        distances = eikonal.distance[None] if len(segs) == 1 else distance_to_each_exit(parts.grid, segs, parts.sight)
        widths = np.hypot(*(segs[:, 1] - segs[:, 0]).T)
        flow = SPECIFIC_FLOW if specific_flow is None else specific_flow
        gain = MIN_GAIN if min_gain is None else min_gain
        return ExitAssignment(distances, widths, parts.grid.volume, parts.people, v_free, flow, gain)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """The robots learn that only the exits with ``open_exits[k]`` are open (a scenario's ``[[events]]``):
        the potential is solved again to those (with no exit left it stays as it was)."""
        open_exits = np.asarray(open_exits, dtype=bool)
        if self.eikonal is None or not open_exits.any():
            return
        self._open = open_exits.copy()
        if self.assignment is not None:  # balanced again over the open exits at the next evaluation
            self.assignment.open = open_exits.copy()
            self._next_balance = -math.inf
        e = self.eikonal
        self.eikonal = ExitEikonal(e.grid, self._all_exits[open_exits], e.sight)
        self.grad_phi = _face_gradient(self.grid, self.eikonal.distance)

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event): the law moves to the new grid and the potential is solved
        again round the new walls, to the exits open (and with the balanced potential, each exit's distance)."""
        super().walls_changed(change)
        if self.eikonal is None:
            return
        segs = self._all_exits
        open_exits = np.ones(len(segs), dtype=bool) if self._open is None else self._open
        self.eikonal = ExitEikonal(change.grid, segs[open_exits], change.sight)
        if self.assignment is not None:
            self.assignment.walls_changed(distance_to_each_exit(change.grid, segs, change.sight), change.grid.volume)
            self._next_balance = -math.inf
        self.grad_phi = _face_gradient(self.grid, self.eikonal.distance)

    # ------------------------------------------------------------------ the exits' balance
    def robot_inputs(self, rho: np.ndarray, field: Any, t: float = 0.0, dt: float | None = None) -> Any:
        """Step II (:meth:`BacksteppingController.robot_inputs`), the balanced potential solved again first when due."""
        if self.assignment is not None and t >= self._next_balance:
            self.assignment.solve(rho)
            self.grad_phi = _face_gradient(self.grid, self.assignment.potential())
            self._next_balance = t + self.rebalance_period * (1 - 1e-9)
        return super().robot_inputs(rho, field, t, dt)

    def summary(self) -> dict[str, Any]:
        """The law's figures, and with the balanced potential the exits' last offsets ``τ_k`` and makespan."""
        out = dict(super().summary())
        if self.assignment is not None:
            out["exit_offsets"] = [float(x) for x in self.assignment.offsets]
            out["balanced_makespan"] = float(self.assignment.makespan)
        return out

    def reset(self) -> None:
        """Forget the previous ``v_d``, and solve the balanced potential again at the next evaluation."""
        super().reset()
        self._next_balance = -math.inf
