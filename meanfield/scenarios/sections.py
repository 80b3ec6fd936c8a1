"""The sections of a scenario: one small validated dataclass per TOML table.

Each class checks its fields on construction and raises
:class:`~meanfield.errors.ParameterError` naming the dotted field (``"crowd.sigma"``).
Names of interchangeable parts (``crowd.kind``, ``controller.kind``, ``controller.beta_gamma``)
are checked against the registry (:mod:`meanfield.plugins`), so a
plugin registered before the section is built is accepted.  :class:`meanfield.scenarios.scenario.Scenario`
assembles the sections and runs the cross-field checks; import the classes from
:mod:`meanfield.scenarios.scenario`, which re-exports them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from meanfield import plugins
from meanfield.controllers.backstepping import CONGESTION_OPTIONS, DVD_DT_OPTIONS
from meanfield.crowds.groups import crowd_groups
from meanfield.crowds.local_density import DENSITY_RADIUS
from meanfield.crowds.memory import MEMORIES
from meanfield.errors import (
    REMOVED_IN,
    ParameterError,
    all_numbers,
    choice,
    deprecated,
    integer,
    num,
    optional_limit,
    options_table,
    point,
)
from meanfield.geometry.region import region_keywords, wkt_polygon

__all__ = [
    "field_hint",
    "region_keys",
    "settable",
    "SECTIONS",
    "GridSpec",
    "CrowdSpec",
    "RobotSpec",
    "KernelSpec",
    "InteractionSpec",
    "DisturbanceSpec",
    "TargetSpec",
    "DensitySpec",
    "ControllerSpec",
    "controller_options",
    "ViewSpec",
    "SensingSpec",
    "EventSpec",
    "EVENT_ACTIONS",
]


@dataclass
class GridSpec:
    """Finite-volume grid: ``cells = (nx, ny)``, each >= 2."""

    cells: tuple[int, int] = (30, 30)

    def __post_init__(self) -> None:
        try:
            nx, ny = self.cells
        except (TypeError, ValueError):
            raise ParameterError("grid.cells", self.cells, "a pair of integers >= 2") from None
        self.cells = (integer("grid.cells[0]", nx, 2), integer("grid.cells[1]", ny, 2))


@dataclass
class CrowdSpec:
    """Humans: which crowd moves them, count ``n >= 1``, initial distribution, diffusion ``σ >= 0``.

    ``kind`` is a registered crowd (:mod:`meanfield.plugins`, kind ``crowd``): ``"point-mass"``
    (the SDE of eq. (1), :mod:`meanfield.crowds.point_mass`), ``"jupedsim"`` (bodies moved by
    JuPedSim, :mod:`meanfield.crowds.jupedsim_engine`), ``"fokker-planck"`` (the density itself,
    eq. (4)) or a plugin's.  ``options`` holds one table per crowd kind, ``[crowd.options.<kind>]``,
    which that crowd checks itself (its record's ``options``, :func:`meanfield.plugins.capabilities`);
    a table is kept whatever ``kind`` is, so that switching kind (``--crowd``) finds it.

    ``field_evaluation`` is how ``v_r`` reaches the humans: ``"exact"`` (eq. (3) at each
    human, O(N n)), ``"sampled"`` (on a lattice twice as fine as the grid, interpolated
    bilinearly, O(N + n M): :mod:`meanfield.signs.sampled_field`) or ``"auto"`` (sampled when
    ``N n > 2·10⁶``).  ``guidance`` is what the humans follow: the robots' ``"signs"``
    (the paper), or a baseline, ``"geodesic"`` (the informed crowd, walking the shortest
    route to an exit at ``free_speed``), ``"fastest-route"`` (the informed crowd on the route of
    least travel time through the crowd to the exit nearest where each started), ``"hughes"``
    (to the exit of least travel time, Hughes' model) or ``"random-walk"`` (the uninformed crowd;
    registry kind ``guidance``, :mod:`meanfield.crowds.guidance`).  ``free_speed`` is the free walking speed
    (1.34 m/s, Weidmann), also used by the evacuation lower bound.  ``congestion`` is the
    speed–density relation the humans walk by (registry kind ``congestion``,
    :mod:`meanfield.crowds.congestion`): ``"none"`` (the paper's crowd), ``"weidmann"`` or
    ``"linear"``, with the jam density ``rho_max`` (persons/m², 5.4), or ``"auto"`` (the default):
    the crowd kind's own default for the scenario's units
    (:attr:`~meanfield.scenarios.scenario.Scenario.congestion_model`; docs page *Congestion*).
    A congested agent's density is the others within ``congestion_radius`` (m, 0.5) over the
    disk's area inside Ω (:mod:`meanfield.crowds.local_density`).  ``door_model`` is
    how a congested agent turns the density round it into a speed (docs page *Congestion*, "The
    agents' door model"): ``"auto"`` (the default: the crowd kind's own, the first it declares in
    ``door_models``; :attr:`~meanfield.scenarios.scenario.Scenario.door_model`), ``"count"`` (``g`` of
    the count in the whole disk),
    ``"godunov-twin"`` (the density's Godunov flux between the half disks behind and ahead of it,
    with the excluded volume's push, :class:`~meanfield.crowds.congestion.GodunovTwin`) or
    ``"headway"`` (the diagram's speed at the spacing to the person ahead in one's lane, and a walk
    that approaches nobody it touches, :class:`~meanfield.crowds.headway.Headway`) or ``"forward-cell"``
    (the diagram's speed at the density of the part of one's Voronoi cell ahead of one,
    :class:`~meanfield.crowds.forward_cell.ForwardCell`); a crowd kind
    takes the models it declares (``door_models``: the point masses all four, the forward cell first; the
    density's flux is Godunov's and JuPedSim's bodies queue by their own model, so they take ``"auto"``,
    and ``"count"``, the default before ``"auto"``, which they ignore).

    People are not all alike (docs pages *Scenarios*, "People who wait, people who do not
    follow", and *Buildings*; :class:`~meanfield.crowds.agent_crowd.Individuals`).
    ``premovement`` is each human's pre-movement time, in the scenario's time unit (s in SI):
    ``"none"`` (the default: everyone walks from the start), ``{law = "uniform", low = L, high = H}``
    (``0 <= L <= H``; RiMEA's test 5 takes 10 to 100 s) or ``{law = "lognormal", median = M,
    sigma = S}`` (``M > 0``, ``S >= 0``; :data:`~meanfield.crowds.agent_crowd.PREMOVEMENT_LAWS`).
    Until its time a human stands: its velocity is 0 and no noise moves it.  ``compliance`` in
    [0, 1] (default 1: everyone follows the signs) is the share of the humans who follow the
    robots' signs; the others, drawn once, walk the random walk of ``[view]`` as if they saw no
    robot.  A compliance below 1 needs ``guidance = "signs"`` (a baseline has no sign to ignore:
    refused when the crowd is built).  Both need a crowd kind that declares
    ``models_individuals`` (the point masses and JuPedSim's bodies, not the density).

    ``initial = "groups"`` places the people group by group, ``[[crowd.groups]]`` tables with a
    ``region`` (a WKT polygon in the plan), a size ``n`` and optionally the ``exit`` its people
    walk to (:mod:`meanfield.crowds.groups`; RiMEA's test 10); ``n`` is the groups' sum.
    """

    kind: str = "point-mass"
    n: int = 200
    initial: str = "uniform"
    initial_center: tuple[float, float] = (0.5, 0.5)
    initial_std: float = 0.1
    sigma: float = 0.015
    field_evaluation: str = "auto"
    guidance: str = "signs"
    free_speed: float = 1.34
    congestion: str = "auto"
    rho_max: float = 5.4
    congestion_radius: float = DENSITY_RADIUS
    door_model: str = "auto"
    premovement: str | dict[str, Any] = "none"
    compliance: float = 1.0
    groups: list[dict[str, Any]] = field(default_factory=list)
    options: dict[str, dict[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.kind = choice("crowd.kind", self.kind, plugins.available("crowd"))
        self.n = integer("crowd.n", self.n, 1)
        self.initial = choice("crowd.initial", self.initial, ("uniform", "gaussian", "groups"))
        self.groups = crowd_groups(self.groups, self.initial, self.n)
        self.initial_center = point("crowd.initial_center", self.initial_center)
        self.initial_std = num("crowd.initial_std", self.initial_std, lo=0.0, lo_open=True)
        self.sigma = num("crowd.sigma", self.sigma, lo=0.0)
        self.field_evaluation = choice("crowd.field_evaluation", self.field_evaluation, ("auto", "exact", "sampled"))
        self.guidance = choice("crowd.guidance", self.guidance, plugins.available("guidance"))
        self.free_speed = num("crowd.free_speed", self.free_speed, lo=0.0, lo_open=True)
        self.congestion = choice("crowd.congestion", self.congestion, ("auto", *plugins.available("congestion")))
        self.rho_max = num(
            "crowd.rho_max", self.rho_max, lo=RHO_MAX_RANGE[0], hi=RHO_MAX_RANGE[1],
            allowed=f"a jam density in [{RHO_MAX_RANGE[0]:g}, {RHO_MAX_RANGE[1]:g}] persons/m² (Weidmann's is 5.4; "
            "below it nobody could stand, above it people would overlap)",
        )  # fmt: skip
        self.congestion_radius = num(
            "crowd.congestion_radius", self.congestion_radius, lo=MIN_CONGESTION_RADIUS,
            allowed=f"a radius >= {MIN_CONGESTION_RADIUS:g} m (a few centimetres: a smaller disk holds nobody) "
            "and at most the plan's size",
        )  # fmt: skip
        self.door_model = choice("crowd.door_model", self.door_model, DOOR_MODELS)
        from meanfield.crowds.agent_crowd import premovement_law  # (loaded with the crowds anyway)

        law = premovement_law(self.premovement, "crowd.premovement")
        self.premovement = "none" if law is None else law
        self.compliance = num("crowd.compliance", self.compliance, lo=0.0, hi=1.0)
        if not isinstance(self.options, dict):
            raise ParameterError("crowd.options", self.options, "a table of tables, one per crowd kind")
        kinds = plugins.available("crowd")
        for kind, table in self.options.items():
            if kind not in kinds:
                raise ParameterError(f"crowd.options.{kind}", table, f"a table named after a registered crowd {kinds}")
            # the crowd checks its own options, naming crowd.options.<kind>.<field>
            options_table(f"crowd.options.{kind}", plugins.capabilities("crowd", kind).options, table)
        self.options = {k: dict(v) for k, v in self.options.items()}


MIN_CONGESTION_RADIUS = 0.05
"""m: the smallest ``crowd.congestion_radius`` (a disk of 5 cm holds nobody but its own human)."""
RHO_MAX_RANGE = (1.0, 20.0)
"""persons/m²: the ``crowd.rho_max`` a fundamental diagram takes (a jam below 1 person/m² freezes everyone; above
20 persons/m² people would overlap: bodies of 0.2 m radius cannot stand closer than about 8 per m²)."""
DOOR_MODELS = ("auto", "count", "godunov-twin", "headway", "forward-cell")
"""``crowd.door_model``: how a congested agent's speed follows the density round it (docs page *Congestion*)."""


@dataclass
class RobotSpec:
    """Robots: count, initial layout and headings, speed limits, wall margin.

    ``layout = "grid"`` puts the robots on a regular lattice (the paper's 4×4),
    ``"random"`` draws them uniformly, ``"explicit"`` takes ``positions``.
    ``headings`` is ``"random"`` (uniform on [0, 2π), as in the paper) or a list.
    ``u_max`` and ``omega_max`` are the paper's limits by default (0.2 and 3 in its units); ``None`` (``"none"`` in
    TOML): no limit.
    ``margin`` keeps robots at least that far inside the bounding walls of a box
    (a robot is a body; it cannot stand in a wall).
    """

    n: int = 16
    layout: str = "grid"
    positions: list[list[float]] | None = None
    headings: str | list[float] = "random"
    u_max: float | None = 0.2
    omega_max: float | None = 3.0
    margin: float = 0.0

    def __post_init__(self) -> None:
        self.n = integer("robots.n", self.n, 1)
        self.layout = choice("robots.layout", self.layout, ("grid", "random", "explicit"))
        if self.layout == "explicit":
            if self.positions is None:
                raise ParameterError("robots.positions", None, "a list of n [x, y] pairs when layout = 'explicit'")
            pos = np.asarray(self.positions, dtype=float) if all_numbers(self.positions) else None
            if pos is None or pos.shape != (self.n, 2) or not np.all(np.isfinite(pos)):
                raise ParameterError("robots.positions", self.positions, f"{self.n} finite [x, y] pairs")
            self.positions = pos.tolist()
        elif self.positions is not None:
            raise ParameterError("robots.positions", "given", "no positions unless layout = 'explicit'")
        if isinstance(self.headings, str):
            choice("robots.headings", self.headings, ("random",))
        else:
            h = np.asarray(self.headings, dtype=float) if all_numbers(self.headings) else None
            if h is None or h.shape != (self.n,) or not np.all(np.isfinite(h)):
                raise ParameterError("robots.headings", self.headings, f"'random' or {self.n} finite angles")
            self.headings = h.tolist()
        self.u_max = optional_limit("robots.u_max", self.u_max)
        self.omega_max = optional_limit("robots.omega_max", self.omega_max)
        self.margin = num("robots.margin", self.margin, lo=0.0)


@dataclass
class KernelSpec:
    """Navigation kernel ``K̄(ξ) = c exp(-|ξ|²/η)``: ``c > 0``, ``η > 0``."""

    c: float = 0.2
    eta: float = 0.05

    def __post_init__(self) -> None:
        self.c = num("kernel.c", self.c, lo=0.0, lo_open=True)
        self.eta = num("kernel.eta", self.eta, lo=0.0, lo_open=True)


@dataclass
class InteractionSpec:
    """Interaction potential W: ``"none"`` or ``"gaussian"`` (``s exp(-|z|²/ℓ²)``, ``s > 0`` repels)."""

    kind: str = "none"
    strength: float = 0.0
    length: float = 0.1

    def __post_init__(self) -> None:
        self.kind = choice("interaction.kind", self.kind, ("none", "gaussian"))
        self.strength = num("interaction.strength", self.strength)
        self.length = num("interaction.length", self.length, lo=0.0, lo_open=True)
        if self.kind == "gaussian" and self.strength == 0:
            raise ParameterError("interaction.strength", 0.0, "a non-zero number when kind = 'gaussian'")


@dataclass
class DisturbanceSpec:
    """Bounded disturbance v_a: ``"none"``, ``"constant"`` (``velocity``) or ``"swirl"``
    (rotation about the domain centre with speed ``strength`` at unit distance)."""

    kind: str = "none"
    velocity: tuple[float, float] = (0.0, 0.0)
    strength: float = 0.0

    def __post_init__(self) -> None:
        self.kind = choice("disturbance.kind", self.kind, ("none", "constant", "swirl"))
        self.velocity = point("disturbance.velocity", self.velocity)
        self.strength = num("disturbance.strength", self.strength)


@dataclass
class TargetSpec:
    """Target density: Gaussian with ``center`` and ``std > 0``, restricted to Ω, unit mass."""

    center: tuple[float, float] = (1.0, 1.0)
    std: float = 0.15

    def __post_init__(self) -> None:
        self.center = point("target.center", self.center)
        self.std = num("target.std", self.std, lo=0.0, lo_open=True)


@dataclass
class DensitySpec:
    """KDE: ``bandwidth`` h > 0 or ``"silverman"``; wall ``boundary``; evaluation ``method``."""

    bandwidth: float | str = 0.08
    boundary: str = "reflect"
    method: str = "auto"

    def __post_init__(self) -> None:
        if isinstance(self.bandwidth, str):
            choice("density.bandwidth", self.bandwidth, ("silverman",))
        else:
            self.bandwidth = num(
                "density.bandwidth", self.bandwidth, lo=0.0, lo_open=True, allowed='a number > 0, or "silverman"'
            )
        self.boundary = choice("density.boundary", self.boundary, ("reflect", "renormalize", "none"))
        self.method = choice("density.method", self.method, ("auto", "separable", "binned"))


@dataclass
class ControllerSpec:
    """Controller gains and options (paper, eqs. (6) and (8)).

    ``beta_gamma`` is ``"min-norm"`` (the minimum-norm rule: docs page ``docs/controller.md``,
    section "Choosing β and γ: the minimum-norm rule") or any other registered strategy, such
    as ``"bounded"`` (the speed-limited program of :mod:`analysis.bounded`).  ``kind`` is
    ``"backstepping"`` (the paper's law) or any other registered controller, such as
    ``"nmpc"`` (:mod:`analysis.nmpc`); ``options`` is passed to that plugin, which
    validates it.  ``dvd_dt`` is one of :data:`meanfield.controllers.backstepping.DVD_DT_OPTIONS`.  See
    :mod:`meanfield.plugins`.  ``scaling`` is ``"paper"`` (the paper's law, in the scenario's
    units) or ``"kernel"`` (the same law in the units ``√|Ω|`` and the kernel's ``c``: the
    robots' inputs no longer depend on the unit of length, and the gains are dimensionless).
    ``congestion`` is ``"ignore"`` (the default: the paper's law whatever the crowd) or
    ``"compensate"`` (on a crowd that a fundamental diagram slows, ``crowd.congestion``, the
    backstepping law tracks ``v_d / g``; without congestion it is the paper's law, number for
    number; docs page *Verification*, "Steps I and II on the congested plant").
    """

    alpha: float = 0.2
    alpha_schedule: str = "saturating"
    rho_floor: float = 2.0
    k_u: float = 10.0
    k_omega: float = 10.0
    beta_gamma: str = "min-norm"
    dvd_dt: str = "finite-difference"
    kind: str = "backstepping"
    options: dict[str, Any] = field(default_factory=dict)
    scaling: str = "paper"
    congestion: str = "ignore"

    def __post_init__(self) -> None:
        self.alpha = num("controller.alpha", self.alpha, lo=0.0, lo_open=True)
        self.alpha_schedule = choice("controller.alpha_schedule", self.alpha_schedule, ("constant", "saturating"))
        self.rho_floor = num("controller.rho_floor", self.rho_floor, lo=0.0, lo_open=True)
        self.k_u = num("controller.k_u", self.k_u, lo=0.0)
        self.k_omega = num("controller.k_omega", self.k_omega, lo=0.0)
        self.beta_gamma = choice("controller.beta_gamma", self.beta_gamma, plugins.available("beta_gamma"))
        self.dvd_dt = choice("controller.dvd_dt", self.dvd_dt, DVD_DT_OPTIONS)
        self.scaling = choice("controller.scaling", self.scaling, ("paper", "kernel"))
        self.congestion = choice("controller.congestion", self.congestion, CONGESTION_OPTIONS)
        self.kind = choice("controller.kind", self.kind, plugins.available("controller"))
        self.options = controller_options(self.options, self.kind)


def controller_options(options: Any, kind: str) -> dict[str, dict[str, Any]]:
    """``controller.options``, one table per controller kind, each checked by its controller's options.

    A controller declares its options as a dataclass (``options`` on its factory or class, as a crowd does; None:
    it takes none); a table ``[controller.options.<kind>]`` is read by it, naming ``controller.options.<kind>.<field>``
    in errors.  A plugin that declares nothing is given its table as it is, to check when it is built.
    Keys directly under ``[controller.options]`` (before 2026-12-05 the options of ``controller.kind``) are read as
    that kind's, with a warning: they are removed in 0.3.0 (:data:`FLAT_CONTROLLER_OPTIONS_REMOVED_IN`).

    Parameters
    ----------
    options : dict
        The scenario's ``controller.options``.
    kind : str
        ``controller.kind``: the kind whose table the flat keys are.

    Returns
    -------
    dict
        ``{kind: table}``, every table a copy.
    """
    if not isinstance(options, dict):
        raise ParameterError("controller.options", options, "a table of tables, one per controller kind")
    kinds = plugins.available("controller")
    nested = {k: dict(v) for k, v in options.items() if k in kinds and isinstance(v, dict)}
    flat = {k: v for k, v in options.items() if not (k in kinds and isinstance(v, dict))}
    if flat:
        table = nested.setdefault(kind, {})
        for key, value in flat.items():
            if key in table:
                raise ParameterError(f"controller.options.{key}", value,
                                     f"one of controller.options.{key} (deprecated) and "
                                     f"controller.options.{kind}.{key}, not both")  # fmt: skip
            table[key] = value
        old = ", ".join(f"controller.options.{k}" for k in sorted(flat))
        new = ", ".join(f"controller.options.{kind}.{k}" for k in sorted(flat))
        deprecated(old, f"use {new} (the table [controller.options.{kind}])", stacklevel=3)
    for k, table in nested.items():
        options_table(f"controller.options.{k}", plugins.capabilities("controller", k).options, table,
                      f"no options: the {k!r} controller takes none (the law's gains are fields of [controller]: "
                      "alpha, k_u, k_omega, ...)")  # fmt: skip
    return nested


FLAT_CONTROLLER_OPTIONS_REMOVED_IN = REMOVED_IN
"""The release that no longer reads options directly under ``[controller.options]`` (they go under the kind's table)."""


@dataclass
class ViewSpec:
    """The humans' local view (the paper's Unity study, Section V-B).

    A human follows the navigation field ``v_r`` (eq. (3)) only while some robot is within
    ``radius`` of it; otherwise it walks a persistent random walk at ``walk_speed`` whose
    heading diffuses with ``turning_rate`` (rad²/s, so the heading decorrelates as
    ``exp(-turning_rate t)``; see :mod:`meanfield.crowds.local_view`).  ``radius = "none"`` (the
    default) is the paper's model (eq. (1)): every human feels every robot.  ``memory = "route"``:
    a person a sign has reached knows the way out from then on (:mod:`meanfield.crowds.memory`);
    ``"sign"``: the way to the exit the latest sign that reached the person showed; ``"none"``: the paper's
    humans, who follow a sign only while they feel it.  ``"auto"`` (the default) is ``"sign"`` for people in a plan
    with exits in SI units (a "THIS WAY" sign is followed: 95 % of 112 subjects followed the robot out in Nayyar et
    al., SSRR 2023) and ``"none"`` otherwise, the paper's dimensionless room among them
    (:attr:`meanfield.scenarios.scenario.Scenario.memory`).
    """

    radius: float | None = None
    walk_speed: float = 0.0
    turning_rate: float = 0.0
    memory: str = "auto"

    def __post_init__(self) -> None:
        self.radius = optional_limit("view.radius", self.radius, what='a view radius > 0, or "none" (no gating)')
        self.walk_speed = num("view.walk_speed", self.walk_speed, lo=0.0)
        self.turning_rate = num("view.turning_rate", self.turning_rate, lo=0.0)
        self.memory = choice("view.memory", self.memory, ("auto", *MEMORIES))


@dataclass
class SensingSpec:
    """What each robot knows (:mod:`meanfield.controllers.local_sensing`).

    ``radius``: a robot sees the crowd's density only within this distance of itself;
    ``comm_radius``: robots within this distance of each other share what they see (a
    connected group shares everything, the limit of consensus on their estimates).  Either
    ``"none"`` (the default): no limit, the paper's centralized robots.
    """

    radius: float | None = None
    comm_radius: float | None = None

    def __post_init__(self) -> None:
        self.radius = optional_limit("sensing.radius", self.radius, what='a radius > 0, or "none" (no limit)')
        self.comm_radius = optional_limit(
            "sensing.comm_radius", self.comm_radius, what='a radius > 0, or "none" (no limit)'
        )

    @property
    def local(self) -> bool:
        """True when some robot knows less than everything."""
        return self.radius is not None or self.comm_radius is not None


EVENT_ACTIONS = ("close_exit", "block")
"""What an event does (one of them per event): close an exit, or make a region a wall."""


@dataclass
class EventSpec:
    """Something that happens during a run: one ``[[events]]`` table (docs page *Buildings*, "Events").

    ``time`` (in the scenario's time unit) and one action: ``close_exit = k``, the index into
    ``domain.exits`` of an exit nobody leaves through from then on, or ``block = "POLYGON (...)"``, a
    region (WKT) that becomes a wall (:mod:`meanfield.geometry.blocking`; checked against the plan by the
    scenario).  ``name`` is how errors name the event (``events[i]``, set by the scenario).
    """

    time: float = 0.0
    close_exit: int | None = None
    block: str | None = None
    name: str = field(default="events[0]", compare=False, repr=False)

    def __post_init__(self) -> None:
        self.time = num(f"{self.name}.time", self.time)
        if (self.close_exit is None) == (self.block is None):
            got = "no action" if self.close_exit is None else "both close_exit and block"
            raise ParameterError(
                self.name, got, 'one action: close_exit = k (an index into domain.exits) or block = "POLYGON ((...))"'
            )
        if self.close_exit is not None:
            self.close_exit = integer(f"{self.name}.close_exit", self.close_exit, 0)
        else:
            wkt_polygon(self.block, f"{self.name}.block")

    @property
    def action(self) -> str:
        """``"close_exit"`` or ``"block"``."""
        return "close_exit" if self.close_exit is not None else "block"

    def to_dict(self) -> dict[str, Any]:
        """The ``[[events]]`` table (TOML-ready)."""
        return {"time": self.time, self.action: getattr(self, self.action)}


SECTIONS: dict[str, type] = {
    "grid": GridSpec,
    "crowd": CrowdSpec,
    "robots": RobotSpec,
    "kernel": KernelSpec,
    "interaction": InteractionSpec,
    "disturbance": DisturbanceSpec,
    "target": TargetSpec,
    "density": DensitySpec,
    "controller": ControllerSpec,
    "view": ViewSpec,
    "sensing": SensingSpec,
}
"""The scenario's tables in TOML order: ``{table name: section class}``."""


# ---------------------------------------------------------------------- keys that --set may name
def region_keys(kind: Any) -> set[str] | None:
    """The keys of the ``[domain]`` table of a registered region kind (None: unknown, or any)."""
    return region_keywords(kind)


def field_hint(parts: list[str], node: dict[str, Any], top_level: tuple[str, ...] = ()) -> str:
    """What is allowed instead of an unknown dotted key: the shape's keys, or the closest field names."""
    import difflib

    if parts[0] == "domain" and len(parts) == 2:
        kind = node.get("kind", "box")
        keys = sorted(region_keys(kind) or ())
        return f"a key of the {kind!r} region ({', '.join(keys)}); set domain.kind first to change the shape"
    names = [f"{sec}.{f.name}" for sec, cls in SECTIONS.items() for f in fields(cls)]
    names += [*top_level, *(f"domain.{k}" for k in sorted(region_keys(node.get("kind", "box")) or ()))]
    close = difflib.get_close_matches(".".join(parts), names, n=3, cutoff=0.75)
    return "an existing scenario field" + (f" (did you mean {' or '.join(close)}?)" if close else "")


def settable(parts: list[str], node: dict[str, Any]) -> bool:
    """Whether a dotted key absent from the scenario's table names a field that may be set.

    A field left empty today (``view.radius = "none"`` is omitted, so is ``robots.positions``
    until a layout uses it), a key of the region's kind (``domain.radius`` after
    ``domain.kind = "disk"``), a controller's or a crowd's option (``controller.options.<kind>.<field>``,
    ``crowd.options.<kind>.<field>``; ``controller.options.<field>``, deprecated, is the kind's).
    """
    if parts[:-1] == ["controller", "options"] or (parts[:2] in (["crowd", "options"], ["controller", "options"])
                                                   and len(parts) == 4):  # fmt: skip
        return True
    if len(parts) != 2:
        return False
    section, name = parts
    if section == "domain":
        keys = region_keys(node.get("kind", "box"))
        return keys is None or name in keys
    cls = SECTIONS.get(section)
    return cls is not None and name in {f.name for f in fields(cls)}
