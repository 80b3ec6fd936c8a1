"""Coverage and heading: robots spread over where they are needed, signs turned by density feedback.

The paper's law moves each robot along ``b_i``, the gradient of ``½‖ṽ‖²`` in its position
(eq. (8)): a robot far from a straggler has kernel columns that barely see it, so nothing
pulls a robot there and stragglers stay behind (design notes, section 7).  The authors'
follow-up work (Zheng et al., 2023) splits the robots' job, and so does this controller
(registered as ``coverage``):

**Positions: density-weighted coverage** (Lloyd's iteration on the grid), in one of three
metrics (``controller.options.coverage.metric``; ``"routed"`` the default, ``"straight"`` deprecated):

* ``"straight"``: each cell of Ω belongs to the nearest robot that sees it
  (:mod:`meanfield.geometry.sight`; the nearest robot when none does), and robot ``i`` drives
  towards the weighted centroid ``C_i`` of its cells::

      u_i = k_position (C_i − R_i),   C_i = Σ_{c ∈ V_i} w_c x_c |c| / Σ_{c ∈ V_i} w_c |c|;

* ``"routed"``: the straight metric's cells and centroids, but a robot that does not see its
  centroid ``C_i`` walks to it: it heads along the first leg of the walking route
  (:mod:`meanfield.geometry.walking`) to the cell of its own nearest ``C_i``, with the pull
  ``d_i(c) e_i(c)`` (``C_i − R_i`` when it sees ``C_i``, the straight law).  A robot whose centroid
  lies behind a wall (in the next room, where its people are) no longer presses against the wall;
* ``"walking"``: the cells are geodesic Voronoi cells, each cell belonging to the robot
  that walks to it soonest, and each cell pulls its robot along the first leg ``e_i(c)`` of
  the route to it, by the walking distance ``d_i(c)`` (:mod:`meanfield.geometry.walking`)::

      u_i = k_position Σ_{c ∈ V_i} w_c |c| d_i(c) e_i(c) / Σ_{c ∈ V_i} w_c |c|.

  This is the descent direction of Lloyd's cost in the walking metric,
  ``H = Σ_i Σ_{c ∈ V_i} w_c |c| d_i(c)²`` (``∂H/∂R_i = −2 Σ w_c |c| d_i(c) e_i(c)``;
  Bhattacharya, Ghrist & Kumar, *IJRR* 33, 2014), so a robot heads through the door
  towards the people of the next room instead of at the wall between them, and where every
  cell is in sight (``e_i(c) = (x_c − R_i)/|x_c − R_i|``, ``d_i(c) = |x_c − R_i|``) it is the
  straight metric's law exactly.

Which wins where is measured on the shipped plans (docs page *Buildings*, "Coverage's options"): ``"routed"`` is
the same law as ``"straight"`` wherever a robot sees its centroid (so in a convex room exactly), and the default;
it was never slower on the plans before (H5), and with (H5) it is slower on the office's median seed (99.6 % out at
240 s, ``"straight"`` everyone at 227 s); ``"walking"`` stays for where it wins.

with the weight ``w`` (``controller.options.coverage.weight``) the tracking error ``ρ |ṽ|`` (``"tracking-error"``,
the default; ``"density"``, ``ρ``, and ``"excess"``, ``max(ρ − ρ_*, 0)``, are deprecated): people already where the
law wants them (``ṽ ≈ 0``) stop attracting robots, and the robots go where people are not
yet guided.  ``"unswept"`` is the tracking error where no sign has reached lately: the robots
keep, for each cell, when a sign last reached it (some robot sees it and its kernel there is at
least :data:`~meanfield.signs.kernels.REACH_FRACTION` of its peak), and a cell weighs again
``revisit_after`` seconds later (:data:`REVISIT_AFTER`); with nothing unswept left it is the
tracking error everywhere.  It is for people who remember the way once a sign has reached them
(``view.memory``, :mod:`meanfield.crowds.memory`): the robots then sweep the building, going
where nobody has been told, instead of herding those already told.  It needs only what the
robots know of themselves (their positions, kernels and sight), not who was guided.  A robot
whose cells hold no weight holds its position (counted in ``summary.json`` as
``coverage_idle_fraction``).

**Headings: density feedback.**  The ω-part of the law, ``ω_i = −k_heading g_i`` with
``g_i = ∫ ṽᵀ K_θ^i`` (eq. (8)), where ``ṽ = v_r − v_d`` and ``v_d`` is the paper's Step I
(a safe zone) or Hughes' field towards the exits (:mod:`meanfield.controllers.evacuation`) when the
region has exits (``controller.options.coverage.v_d``, deprecated, overrides).  **What is guaranteed.**  For fixed
positions and a frozen ``v_d``, ``V(θ) = ½∫|ṽ|²`` obeys ``dV/dt = Σ_i g_i ω_i = −k_heading Σ_i g_i² <= 0``:
the headings descend the tracking error, and ``V`` stops decreasing only where every
``g_i = 0``.  Nothing is claimed for the density (the positions are not the law's), and the
check of this statement along a PDE-plant run is in the test suite.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from meanfield.capabilities import ControllerCapabilities
from meanfield.controllers._coverage_loops import owners as nearest_owners
from meanfield.controllers.evacuation import EvacuationOptions
from meanfield.errors import ParameterError, choice, deprecated, num, options_table
from meanfield.interfaces import Command, ControllerParts, ControlState, Observation

__all__ = ["CoverageController", "CoverageOptions", "DEPRECATED", "METRICS", "WEIGHTS", "V_D"]

WEIGHTS = ("tracking-error", "density", "excess", "unswept")
"""The coverage weights: ``ρ|ṽ|``, ``ρ``, ``max(ρ − ρ_*, 0)``, or ``ρ|ṽ|`` where no sign has reached lately."""
REVISIT_AFTER = 20.0
"""Default ``controller.options.coverage.revisit_after`` (s in SI): the ``unswept`` weight counts a cell again this long
after a sign last reached it (docs page *Buildings*, "Coverage's options", measures it against 10 s and never)."""
METRICS = ("straight", "routed", "walking")
"""Coverage's metrics: straight lines (``straight``, deprecated), straight cells reached by walking (``routed``, the
default), or walking round walls (``walking``)."""
DEPRECATED = {
    "metric": ({"straight": "routed"}, "the same law wherever a robot sees its centroid (docs: Coverage's options)"),
    "weight": ({"density": "tracking-error", "excess": "tracking-error"}, "never measured to win"),
    "v_d": ({"safe-zone": "auto", "exits": "auto"}, "auto tracks the exits where the plan has them"),
}
"""Option values removed in 0.3.0: each option's old value and its replacement, and why (docs page *Buildings*,
"Coverage's options")."""
HEADING_GAIN_FACTOR = 3.0
"""Default ``k_heading``: this many times the law's ``k_ω`` (chosen on ``paper`` against 1, 2 and 5 times: docs page
*The controller*, "Coverage and heading")."""
V_D = ("auto", "safe-zone", "exits")
"""Which Step I the headings track: the exits' when the region has exits (``auto``)."""
_NOTHING_HIDDEN = np.ones((0, 0), dtype=bool)


@dataclasses.dataclass
class CoverageOptions(EvacuationOptions):
    """``[controller.options.coverage]``: the coverage's own options, and those of the evacuation law it runs when
    its headings track the exits (:class:`~meanfield.controllers.evacuation.EvacuationOptions`: ``potential``,
    ``specific_flow``, ``rebalance_period``, ``rho_max``; the deprecated ``v_free``).

    A value of :data:`DEPRECATED` is read with a warning naming its replacement; it is removed in 0.3.0.

    Parameters
    ----------
    k_position : float
        Gain of the drive to the centroid, 1/s, > 0.
    k_heading : float, optional
        Gain of the heading feedback, > 0 (default: :data:`HEADING_GAIN_FACTOR` × ``controller.k_omega``).
    weight : {"tracking-error", "density", "excess", "unswept"}
        The coverage weight (:data:`WEIGHTS`).
    revisit_after : float
        With ``weight = "unswept"``: how long after a sign last reached a cell it weighs again, > 0 (s in SI).
    metric : {"routed", "walking"}
        The distance of the coverage (:data:`METRICS`; ``"straight"`` deprecated).
    v_d : {"auto"}
        Which Step I the headings track (:data:`V_D`; ``"safe-zone"`` and ``"exits"`` deprecated).
    """

    KIND: ClassVar[str] = "coverage"

    k_position: float = 1.0
    k_heading: float | None = None
    weight: str = "tracking-error"
    revisit_after: float = REVISIT_AFTER
    metric: str = "routed"
    v_d: str = "auto"

    def __post_init__(self) -> None:
        super().__post_init__()
        name = f"controller.options.{self.KIND}."
        self.k_position = num(name + "k_position", self.k_position, lo=0.0, lo_open=True)
        if self.k_heading is not None:
            self.k_heading = num(name + "k_heading", self.k_heading, lo=0.0, lo_open=True)
        self.weight = choice(name + "weight", self.weight, WEIGHTS)
        self.revisit_after = num(name + "revisit_after", self.revisit_after, lo=0.0, lo_open=True,
                                 allowed="a time > 0 (s in SI)")  # fmt: skip
        self.metric = choice(name + "metric", self.metric, METRICS)
        self.v_d = choice(name + "v_d", self.v_d, V_D)
        for option, (old, why) in DEPRECATED.items():
            value = getattr(self, option)
            if value in old:
                deprecated(f"{name}{option} = {value!r}", f"use {old[value]!r} ({why})", stacklevel=3)


def walk_towards(walking: Any, robots: np.ndarray, owner: np.ndarray, centroid: np.ndarray,
                 rows: np.ndarray) -> np.ndarray:  # fmt: skip
    """The pull of each robot of ``rows`` whose centroid a wall hides: the first leg of its walk to the cell, of those
    it owns, nearest its centroid, times that walk's length (``routed``); 0 for a robot that owns no cell it can walk
    to (a block cut the plan).  ``owner``: each covered cell's robot (``-1``: none), in ``walking``'s cell order."""
    pull = np.zeros((len(rows), 2))
    distance, leg = walking.walks_to_nearest(robots[rows], owner, rows, centroid[rows])  # (its own cells alone)
    reached = np.isfinite(distance)  # (not another piece's cells)
    pull[reached] = distance[reached, None] * leg[reached]
    return pull


class CoverageController:
    """Lloyd coverage for the positions, the law's ω-part for the headings (module docstring).

    Parameters
    ----------
    law : BacksteppingController
        Supplies ``v_d``, ``ṽ`` and ``g_i`` (the paper's law, or the evacuation controller).
    grid : Grid
        The cells the coverage is computed on.
    sight : SightLines or None
        The walls that hide a cell from a robot (None: every cell is seen).
    k_position : float
        Gain of the drive to the centroid, 1/s, > 0.
    k_heading : float, optional
        Gain of the heading feedback, > 0; None (the default, here and in a scenario): :data:`HEADING_GAIN_FACTOR`
        × the law's ``k_ω`` (its largest, with one gain per robot).
    weight : {"tracking-error", "density", "excess", "unswept"}
        The coverage weight (module docstring).
    metric : {"routed", "walking", "straight"}
        The distance of the coverage (module docstring).
    revisit_after : float
        With ``weight = "unswept"``: how long after a sign last reached a cell it weighs again, > 0 (s in SI).
    """

    capabilities: ClassVar[ControllerCapabilities] = ControllerCapabilities(
        accepts_sensing=True,  # it runs on a group's knowledge ([sensing], meanfield.controllers.local_sensing)
        changes_walls=True,  # a region can become wall during a run ([[events]] block, walls_changed)
        options=CoverageOptions,  # [controller.options.coverage]
    )
    """What it can do (:class:`~meanfield.capabilities.ControllerCapabilities`)."""

    def __init__(
        self,
        law: Any,
        grid: Any,
        sight: Any = None,
        k_position: float = 1.0,
        k_heading: float | None = None,
        weight: str = "tracking-error",
        metric: str = "routed",
        revisit_after: float = REVISIT_AFTER,
    ):
        if k_heading is None and law is not None:
            k_heading = HEADING_GAIN_FACTOR * float(np.max(law.k_omega))
        for name, k in (("k_position", k_position), ("k_heading", k_heading)):
            if k is None and law is None:  # no law (the cells' geometry alone): no headings to steer
                continue
            if not (isinstance(k, (int, float)) and math.isfinite(k) and k > 0):
                raise ParameterError(f"controller.options.coverage.{name}", k, "a finite number > 0")
        if weight not in WEIGHTS:
            raise ParameterError("controller.options.coverage.weight", weight, " or ".join(map(repr, WEIGHTS)))
        if not (isinstance(revisit_after, (int, float)) and not isinstance(revisit_after, bool) and revisit_after > 0):
            raise ParameterError("controller.options.coverage.revisit_after", revisit_after, "a time > 0 (s in SI)")
        self.revisit_after = float(revisit_after)
        self.last_reached: np.ndarray | None = None  # with "unswept": when a sign last reached each cell
        if metric not in METRICS:
            raise ParameterError("controller.options.coverage.metric", metric, " or ".join(map(repr, METRICS)))
        self.law = law
        self.metric = metric
        self._cover(grid, sight)
        self.k_position = float(k_position)
        self.k_heading = float(k_heading) if k_heading is not None else math.nan
        self.weight = weight
        self.steps = 0
        self.idle_robot_steps = 0
        self.idle = np.zeros(0, dtype=bool)  # robots whose cells held no weight at the last step

    def _cover(self, grid: Any, sight: Any) -> None:
        """The cells to cover on ``grid``, the walls that hide them and the walking distances between them: for the
        walking metric, and for the routed one where a wall hides something (without, it is the straight law)."""
        self.grid = grid
        self.sight = None if sight is None or sight.trivial else sight
        self.walking = None
        if self.metric == "walking" or (self.metric == "routed" and self.sight is not None):
            from meanfield.geometry.walking import WalkingDistances

            self.walking = WalkingDistances(grid, sight)
        X, Y = grid.centers
        self._cells = np.flatnonzero(grid.active.ravel())
        self._xy = np.column_stack([X.ravel()[self._cells], Y.ravel()[self._cells]])
        self._volume = grid.volume.ravel()[self._cells]

    def walls_changed(self, change: Any) -> None:
        """A region became wall (a ``block`` event, :class:`~meanfield.geometry.blocking.WallsChange`): the law plans
        again, and the cells, sight and walking distances are those of the new grid (when a sign last reached each
        cell is kept: the cells are the same)."""
        from meanfield.geometry.blocking import tell_walls_changed

        tell_walls_changed((self.law,), change)
        self._cover(change.grid, change.sight)

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> CoverageController:
        """Registry factory (kind ``controller``, name ``coverage``): the options of :class:`CoverageOptions`
        (``parts.options``, refused naming ``controller.options.coverage.<field>``)."""
        from meanfield.controllers.backstepping import BacksteppingController
        from meanfield.controllers.evacuation import EvacuationController
        from meanfield.geometry.exits import exit_segments
        from meanfield.geometry.sight import SightLines

        o = options_table("controller.options.coverage", CoverageOptions, dict(parts.options))
        exits = len(exit_segments(parts.region)) > 0
        if o.v_d == "exits" or (o.v_d == "auto" and exits):
            law = EvacuationController.with_options(parts, o)
        else:
            law = BacksteppingController.from_parts(dataclasses.replace(parts, options={}))
        sight = parts.sight if parts.sight is not None else SightLines(parts.region)
        return cls(law, parts.grid, sight, k_position=o.k_position, k_heading=o.k_heading, weight=o.weight,
                   metric=o.metric, revisit_after=o.revisit_after)  # fmt: skip

    # ------------------------------------------------------------------ positions
    def owners(self, robots: np.ndarray) -> np.ndarray:
        """For each active cell, the robot it belongs to: the nearest that sees it, else the nearest.

        One compiled pass over the cells (:func:`meanfield.controllers._coverage_loops.owners`) with the cells each
        robot sees (:meth:`meanfield.geometry.sight.SightLines.cell_rows`).
        """
        robots = np.ascontiguousarray(robots, float)
        seen, hidden = _NOTHING_HIDDEN, False
        if self.sight is not None:
            seen, hidden = np.ascontiguousarray(self.sight.cell_rows(self.grid, robots)).reshape(len(robots), -1), True
        return nearest_owners(self._xy, robots, seen, self._cells, hidden, np.empty(len(self._cells), np.intp))

    def centroids(self, robots: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The weighted centroid of each robot's cells, and which robots' cells hold no weight."""
        n = len(robots)
        owner = self.owners(robots)
        w = np.maximum(weight.ravel()[self._cells], 0.0) * self._volume
        mass = np.bincount(owner, weights=w, minlength=n)
        cx = np.bincount(owner, weights=w * self._xy[:, 0], minlength=n)
        cy = np.bincount(owner, weights=w * self._xy[:, 1], minlength=n)
        idle = mass <= 0
        c = robots.copy()
        c[~idle, 0] = cx[~idle] / mass[~idle]
        c[~idle, 1] = cy[~idle] / mass[~idle]
        return c, idle

    def pulls(self, robots: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each robot's pull ``u_i / k_position`` in the coverage's metric (module docstring), and which are idle.

        ``straight``: ``C_i − R_i``; ``routed``: the same where the robot sees ``C_i``, else the first leg of its
        walk there (:meth:`_routed_pulls`); ``walking``: ``Σ w_c |c| d_i(c) e_i(c) / Σ w_c |c|`` over the geodesic
        Voronoi cell.  A robot whose cells hold no weight is idle and pulled nowhere.
        """
        robots = np.real(np.asarray(robots, float)).reshape(-1, 2)
        if self.walking is None:
            c, idle = self.centroids(robots, weight)
            return c - robots, idle
        if self.metric == "routed":
            return self._routed_pulls(robots, weight)
        n = len(robots)
        field = self.walking.from_points(robots)
        owner = field.owners()
        cells = np.arange(len(owner))
        w = np.maximum(weight.ravel()[self._cells], 0.0) * self._volume
        d = field.distance[owner, cells]
        w = np.where(np.isfinite(d), w, 0.0)  # a piece of the plan no robot can walk to (a block cut it off)
        wd = w * np.where(np.isfinite(d), d, 0.0)
        mass = np.bincount(owner, weights=w, minlength=n)
        px = np.bincount(owner, weights=wd * field.leg[owner, cells, 0], minlength=n)
        py = np.bincount(owner, weights=wd * field.leg[owner, cells, 1], minlength=n)
        idle = mass <= 0
        pull = np.zeros((n, 2))
        pull[~idle, 0] = px[~idle] / mass[~idle]
        pull[~idle, 1] = py[~idle] / mass[~idle]
        return pull, idle

    def _routed_pulls(self, robots: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``routed``: ``C_i − R_i`` where the robot sees ``C_i``, else the first leg of its walk to the cell of its
        own nearest ``C_i``, times that walk's length."""
        c, idle = self.centroids(robots, weight)
        pull = c - robots
        hidden = ~idle if self.sight is not None else np.zeros(len(robots), dtype=bool)  # (no wall hides anything)
        if hidden.any():
            hidden[hidden] = ~np.asarray(self.sight.visible(robots[hidden], c[hidden]), bool)
        if hidden.any():
            rows = np.flatnonzero(hidden)
            pull[rows] = walk_towards(self.walking, robots, self.owners(robots), c, rows)
        return pull, idle

    def _weight(self, rho: np.ndarray, state: ControlState, field: Any = None, t: float = 0.0) -> np.ndarray:
        if self.weight == "density":
            return rho
        if self.weight == "excess":
            return np.maximum(state.rho_tilde, 0.0)
        vx, vy = self.grid.to_cells(state.v_tilde)
        tracking = rho * np.hypot(vx, vy)
        if self.weight == "unswept":
            self.sweep(field, t)
            unswept = np.where(t - self.last_reached >= self.revisit_after, tracking, 0.0)
            return unswept if (unswept[self.grid.active] > 0).any() else tracking
        return tracking

    def sweep(self, field: Any, t: float) -> np.ndarray:
        """Mark the cells the signs reach now as reached at ``t`` (a robot sees the cell and its kernel there is at
        least :data:`~meanfield.signs.kernels.REACH_FRACTION` of its peak); returns :attr:`last_reached`."""
        from meanfield.signs.kernels import reached_cells

        if self.last_reached is None:
            self.last_reached = np.full(self.grid.shape, -np.inf)
        self.last_reached[reached_cells(field.kernel, field.positions, self.grid, self.sight).any(axis=0)] = t
        return self.last_reached

    # ------------------------------------------------------------------ the controller
    def act(self, observation: Observation) -> Command:
        """Drive along the coverage's pulls (:meth:`pulls`); turn the signs down ``½‖ṽ‖²`` (``ω = −k g``)."""
        o = observation
        law = self.law.robot_inputs(o.density, o.field, o.t, o.dt)
        robots = np.real(o.field.positions)
        pull, self.idle = self.pulls(robots, self._weight(o.density, law, o.field, o.t))
        u = self.k_position * pull
        omega = law.input_scale[1] * (-self.k_heading * law.g)  # ω̂ = −k ĝ, in the law's units
        self.steps += 1
        self.idle_robot_steps += int(self.idle.sum())
        state = dataclasses.replace(law, u=u, omega=omega, shortfall=float("nan"), k_u=0.0, k_omega=self.k_heading)
        return Command(u, omega, state)

    def exits_closed(self, open_exits: np.ndarray) -> None:
        """Tell the law whose headings the signs follow (its field towards the exits) which exits are open."""
        from meanfield.geometry.exits import tell_exits_closed

        tell_exits_closed((self.law,), open_exits)

    def reset(self) -> None:
        """Forget the law's previous ``v_d``, the idle count and where the signs have reached."""
        self.law.reset()
        self.steps = self.idle_robot_steps = 0
        self.last_reached = None

    def summary(self) -> dict[str, Any]:
        """``coverage_idle_fraction``: the share of robot-steps in which a robot's cells held no weight."""
        n = max(len(self.idle), 1)
        balance = {k: v for k, v in self.law.summary().items() if k in ("exit_offsets", "balanced_makespan")}
        return {"coverage_idle_fraction": self.idle_robot_steps / max(self.steps * n, 1), **balance}
