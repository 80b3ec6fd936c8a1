"""Scenarios: every parameter of a closed-loop run, validated, round-tripping to TOML.

A :class:`Scenario` is a tree of small dataclasses, one per TOML table
(:mod:`meanfield.scenarios.sections`, re-exported here)::

    name, seed, dt, t_final, record_every, record_humans
    plugins       modules that register parts (imported first, when the user allows it)
    [domain]      kind (a registered region: "box" | "disk" | "polygon" | ...) and its sizes
    [grid]        cells = [nx, ny]
    [crowd]       kind (a registered crowd: "point-mass" | "jupedsim" | "fokker-planck" | ...), n, initial
                  ("uniform" | "gaussian"), initial_center, initial_std, sigma, guidance, ...
    [crowd.options.<kind>]  a crowd's own options, checked by it (e.g. JuPedSim's body radius)
    [robots]      n, layout ("grid" | "random" | "explicit"), positions, headings, u_max, omega_max, margin
    [kernel]      c, eta                       (K̄(ξ) = c exp(-|ξ|²/η))
    [interaction] kind ("none" | "gaussian"), strength, length
    [disturbance] kind ("none" | "constant" | "swirl"), velocity, strength
    [target]      center, std                  (Gaussian ρ_* restricted to Ω)
    [density]     bandwidth, boundary, method
    [controller]  alpha, alpha_schedule, rho_floor, k_u, k_omega, beta_gamma, dvd_dt, kind
    [controller.options.<kind>]  the options of each controller kind (e.g. the NMPC horizon)
    [view]        radius ("none" | > 0), walk_speed, turning_rate   (local view, Unity study)

Every field is checked when the scenario is built (or read); a bad value raises
:class:`~meanfield.errors.ParameterError` naming the field and the allowed range
(:mod:`meanfield.geometry.region`), and an unknown TOML key is refused.  Names of parts
(``domain.kind``, ``crowd.kind``, ``controller.kind``, ``controller.beta_gamma``) must be
registered in :mod:`meanfield.plugins`; a part checks its own options and its own cross-field
conditions (a crowd's capability record holds ``options`` and ``check_scenario``:
:class:`~meanfield.capabilities.CrowdCapabilities`).

The ``[pedestrians]`` table of earlier releases is still read, with a
:class:`~meanfield.errors.MeanfieldDeprecationWarning` naming the new fields
(``pedestrians.backend`` is ``crowd.kind``, its other fields ``crowd.options.jupedsim.*``);
a scenario that uses both the old and the new field is refused, naming both.

The built-in scenarios are TOML files shipped with the package (``meanfield/scenarios/``),
each with a header saying its units and where its values come from.  ``paper``
(:func:`paper_scenario`) reproduces the paper's MATLAB study; the values the paper does
not give are chosen and justified in ``docs/scenarios.md``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from meanfield import plugins as registry
from meanfield.capabilities import CrowdCapabilities
from meanfield.errors import ParameterError, ScenarioWarning, choice, deprecated, integer, module_list, num
from meanfield.geometry.domain import Domain
from meanfield.geometry.region import Region, region_from_table
from meanfield.scenarios.sections import (
    EVENT_ACTIONS,
    ControllerSpec,
    CrowdSpec,
    DensitySpec,
    DisturbanceSpec,
    EventSpec,
    GridSpec,
    InteractionSpec,
    KernelSpec,
    RobotSpec,
    SensingSpec,
    TargetSpec,
    ViewSpec,
    field_hint,
    region_keys,
    settable,
)
from meanfield.scenarios.sections import SECTIONS as _SECTIONS

__all__ = [
    "Scenario",
    "GridSpec",
    "CrowdSpec",
    "RobotSpec",
    "KernelSpec",
    "InteractionSpec",
    "DisturbanceSpec",
    "TargetSpec",
    "DensitySpec",
    "ControllerSpec",
    "ViewSpec",
    "paper_scenario",
    "paper_unity_scenario",
    "stadium_scenario",
    "builtin_scenarios",
    "load_scenario",
    "resolve_key",
]

_TOP_LEVEL = ("name", "seed", "dt", "t_final", "record_every", "record_humans", "units", "plugins", "events")

UNIT_SYSTEMS = ("SI", "dimensionless")
"""``units``: ``"SI"`` (lengths in metres, times in seconds: floor plans, the Unity study) or
``"dimensionless"`` (the paper's MATLAB study: lengths in room widths, its own time unit)."""


# ---------------------------------------------------------------------- fields of earlier releases
_OLD_PEDESTRIAN_KIND = "jupedsim"
"""The crowd whose options the deprecated ``[pedestrians]`` table held."""

OLD_FIELDS: dict[str, str] = {
    "pedestrians.backend": "crowd.kind",
    **{f"pedestrians.{k}": f"crowd.options.{_OLD_PEDESTRIAN_KIND}.{k}" for k in ("model", "radius", "max_speed")},
    "pedestrians.time_step": f"crowd.options.{_OLD_PEDESTRIAN_KIND}.time_step",
}
"""Deprecated dotted fields and the fields that replaced them (read until 0.3.0, :data:`meanfield.errors.REMOVED_IN`,
with a warning)."""


def _get(d: dict[str, Any], key: str) -> Any:
    node: Any = d
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return _MISSING
        node = node[part]
    return node


def _put(d: dict[str, Any], key: str, value: Any) -> None:
    *path, last = key.split(".")
    node = d
    for part in path:
        node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise ParameterError(part, node, "a table")
    node[last] = value


_MISSING = object()


def _upgrade_old_fields(d: dict[str, Any]) -> dict[str, Any]:
    """``d`` with the deprecated ``[pedestrians]`` table moved to its new fields (:data:`OLD_FIELDS`),
    with a warning naming them; a field given both ways is refused, naming both."""
    if "pedestrians" not in d:
        return d
    old = d["pedestrians"]
    if not isinstance(old, dict):
        raise ParameterError("pedestrians", old, "a table (deprecated: use crowd.kind and [crowd.options.jupedsim])")
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in d.items() if k != "pedestrians"}
    if isinstance(d.get("crowd"), dict) and isinstance(d["crowd"].get("options"), dict):
        d["crowd"]["options"] = {k: dict(v) if isinstance(v, dict) else v for k, v in d["crowd"]["options"].items()}
    moved = []
    for key, value in old.items():
        new = OLD_FIELDS.get(f"pedestrians.{key}")
        if new is None:
            raise ParameterError(f"pedestrians.{key}", value, f"a key of the old [pedestrians]: {sorted(OLD_FIELDS)}")
        if _get(d, new) is not _MISSING:
            raise ParameterError(
                f"pedestrians.{key}", value, f"one of pedestrians.{key} (deprecated) and {new}, not both"
            )
        _put(d, new, value)
        moved.append(f"pedestrians.{key} -> {new}")
    instead = f"its new fields ({', '.join(moved)})" if moved else "crowd.kind"
    deprecated("the [pedestrians] table", f"use {instead}")
    return d


def resolve_key(key: str, value: Any = None) -> str:
    """The dotted scenario key a short name stands for (``--set`` accepts either).

    A dotted key or a top-level field is returned as it is; a section with a count
    (``robots``, ``crowd``) stands for its ``n``; a field name found in exactly one section
    (``eta``, ``sigma``, ``u_max``) stands for that section's field.

    ``value`` is only quoted in the error.

    Raises
    ------
    ParameterError
        For a name in no section, or in several (the message lists the dotted keys).
    """
    if not isinstance(key, str) or not key:
        raise ParameterError("key", key, "a scenario field name")
    shown = key if value is None else value
    if "." in key or key in _TOP_LEVEL or key == "domain":
        return key
    if key in _SECTIONS and "n" in {f.name for f in fields(_SECTIONS[key])}:
        return f"{key}.n"
    found = [f"{sec}.{key}" for sec, cls in _SECTIONS.items() if key in {f.name for f in fields(cls)}]
    if len(found) == 1:
        return found[0]
    if found:
        raise ParameterError(key, shown, f"a dotted key, one of {', '.join(found)}")
    raise ParameterError(key, shown, "an existing scenario field (a dotted key such as robots.n or kernel.eta)")


@dataclass
class Scenario:
    """All parameters of one closed-loop run (see the module docstring for the layout).

    Every field's default is the paper's: a bare ``Scenario()`` is the paper's room (the built-in ``paper``
    scenario but for its name), in the paper's dimensionless units, so that no congestion and no memory are on
    unless a scenario in ``"SI"`` units asks for them.

    Cross-field checks run on construction: explicit robot positions and the initial
    crowd centre must lie in Ω, the target must put mass in Ω, ``dt < t_final``, and a crowd
    with congestion (a :attr:`congestion_model` other than ``"none"``) needs ``units = "SI"``.

    ``plugins`` lists modules (dotted names or paths to ``.py`` files) that register parts
    in :mod:`meanfield.plugins`; :meth:`from_dict` imports them before it validates any
    section, so the scenario may name the parts they register.

    Who may import them: a scenario that is *read* (:func:`load_scenario`, :meth:`from_toml`,
    :meth:`from_dict`, and :meth:`with_values` for modules the scenario did not list) imports
    its plugins only when the user allows it, with ``allow_plugins=True`` or within
    :func:`meanfield.plugins.allow_scenario_plugins` (the command line's ``--allow-plugins``
    and ``--plugin``); otherwise a :class:`~meanfield.errors.ParameterError` naming ``plugins``
    is raised before anything is imported (a scenario file is shared like data; importing a
    module runs its code).  The loaders check this before they build the dataclass, so the
    permission does not need to reach ``__post_init__``: building ``Scenario(plugins=[...])``
    (or :meth:`replace`) in Python imports the modules, since the caller is Python code that
    asked for them by name.
    """

    name: str = "custom"
    seed: int = 0
    dt: float = 0.01
    t_final: float = 40.0
    record_every: int = 10
    record_humans: int | str = 10_000
    units: str = "dimensionless"
    domain: Region = field(default_factory=lambda: Domain.box(1.0, 1.0))
    grid: GridSpec = field(default_factory=GridSpec)
    crowd: CrowdSpec = field(default_factory=CrowdSpec)
    robots: RobotSpec = field(default_factory=RobotSpec)
    kernel: KernelSpec = field(default_factory=KernelSpec)
    interaction: InteractionSpec = field(default_factory=InteractionSpec)
    disturbance: DisturbanceSpec = field(default_factory=DisturbanceSpec)
    target: TargetSpec = field(default_factory=TargetSpec)
    density: DensitySpec = field(default_factory=DensitySpec)
    controller: ControllerSpec = field(default_factory=ControllerSpec)
    view: ViewSpec = field(default_factory=ViewSpec)
    sensing: SensingSpec = field(default_factory=SensingSpec)
    plugins: tuple[str, ...] = ()
    events: tuple[EventSpec, ...] = ()

    def __post_init__(self) -> None:
        self.plugins = module_list("plugins", self.plugins)
        registry.import_plugin_modules(self.plugins, field="plugins")
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError("name", self.name, "a non-empty string")
        self.seed = integer("seed", self.seed, 0, 2**63 - 1)  # (stored as a 64-bit integer in the run's files)
        self.dt = num("dt", self.dt, lo=0.0, lo_open=True)
        self.t_final = num("t_final", self.t_final, lo=0.0, lo_open=True)
        if self.dt > self.t_final:
            raise ParameterError("dt", self.dt, f"a step <= t_final = {self.t_final}")
        self.record_every = integer("record_every", self.record_every, 1)
        if self.record_humans != "all":
            if isinstance(self.record_humans, str):
                raise ParameterError("record_humans", self.record_humans, 'an integer >= 0, or "all"')
            self.record_humans = integer("record_humans", self.record_humans, 0)
        self.units = choice("units", self.units, UNIT_SYSTEMS)
        if not isinstance(self.domain, Region):
            raise ParameterError("domain", self.domain, "a Region (e.g. a meanfield.Domain)")
        for key, cls in _SECTIONS.items():
            if not isinstance(getattr(self, key), cls):
                raise ParameterError(key, getattr(self, key), f"a {cls.__name__}")
        dom = self.domain
        if self.robots.layout == "explicit":
            pos = np.asarray(self.robots.positions)
            inside = dom.contains(pos[:, 0], pos[:, 1], tol=1e-12)
            if not inside.all():
                k = int(np.flatnonzero(~inside)[0])
                raise ParameterError(f"robots.positions[{k}]", pos[k].tolist(), "a point inside the domain")
        if self.crowd.initial == "gaussian":
            c = self.crowd.initial_center
            if not dom.contains(c[0], c[1]):
                raise ParameterError("crowd.initial_center", list(c), "a point inside the domain")
        if self.target_mass_in_domain() < 1e-6:
            raise ParameterError(
                "target.center",
                list(self.target.center),
                "a target Gaussian with mass in the domain (centre inside Ω or within a few std)",
            )
        self._check_crowd()
        self._check_groups()
        self._check_door_model()
        c = self.crowd  # individuals' traits (docs page Buildings, "People are not all alike")
        for key, value, default in (
            ("crowd.premovement", c.premovement, "none"),
            ("crowd.compliance", c.compliance, 1.0),
            ("view.memory", self.memory, "none"),
        ):
            if value != default and not self.crowd_capabilities.models_individuals:
                raise ParameterError(
                    key,
                    value,
                    f"{default!r} with the {c.kind!r} crowd, which does not model individuals (it declares no "
                    "models_individuals): use a crowd of agents, such as point masses or JuPedSim's bodies",
                )
        if c.compliance < 1.0 and c.guidance != CrowdSpec.guidance:  # here, so that a sweep refuses the combination
            raise ParameterError(
                "crowd.compliance", c.compliance,
                f"1 with crowd.guidance = {c.guidance!r} (compliance is the share who follow the robots' signs: "
                f'a crowd that follows no sign has none to ignore; use crowd.guidance = "{CrowdSpec.guidance}")',
            )  # fmt: skip
        if self._congestion().slows and self.units != "SI":
            raise ParameterError(
                "crowd.congestion",
                self.congestion_model,
                f'"none" in a scenario in {self.units} units: a fundamental diagram takes densities in '
                'persons/m² and speeds in m/s (units = "SI")',
            )
        if self._congestion().slows and c.congestion_radius > dom.diameter:
            raise ParameterError(
                "crowd.congestion_radius", c.congestion_radius,
                f"a radius of at most the plan's size, {dom.diameter:.3g} m (the local density's disk)",
            )  # fmt: skip
        self.events = self._checked_events(self.events)
        if self.robots.margin > 0:
            x0, x1, y0, y1 = dom.bounds
            if 2 * self.robots.margin >= min(x1 - x0, y1 - y0):
                raise ParameterError(
                    "robots.margin", self.robots.margin, "less than half the domain's width and height"
                )

    def _check_door_model(self) -> None:
        """``crowd.door_model`` against the crowd kind (the models it declares in ``door_models``; ``"auto"``, the
        default, is taken by every kind: its own).  A kind that declares none also takes ``"count"``, which it
        ignores: the default before ``"auto"``, written in the scenarios that runs of that time recorded."""
        c = self.crowd
        if c.door_model == "auto":
            return
        takes = self.crowd_capabilities.door_models
        if c.door_model not in takes:
            raise ParameterError(
                "crowd.door_model", c.door_model,
                f"{' or '.join(map(repr, ('auto', *takes)))} with the {c.kind!r} crowd (it declares the door models "
                "it takes, door_models): the density's flux is Godunov's already, JuPedSim's bodies queue by their own",
            )  # fmt: skip

    def _check_groups(self) -> None:
        """``crowd.groups`` against the plan (each region inside it, each exit one it has) and the crowd kind."""
        c = self.crowd
        if c.initial != "groups":
            return
        import shapely

        from meanfield.crowds.groups import group_region
        from meanfield.geometry.exits import exit_segments

        if not self.crowd_capabilities.places_groups:
            raise ParameterError(
                "crowd.initial", c.initial, f"'uniform' or 'gaussian' with the {c.kind!r} crowd (it declares no "
                "places_groups): use point masses or the density"
            )  # fmt: skip
        n_exits = len(exit_segments(self.domain))
        plan = self.domain.to_shapely()
        for i, g in enumerate(c.groups):
            region = group_region(g["region"], f"crowd.groups[{i}].region")
            if plan is not None and shapely.intersection(region, plan).area < 0.5 * region.area:
                raise ParameterError(f"crowd.groups[{i}].region", g["region"], "a region inside the plan (domain)")
            if g.get("exit") is not None and g["exit"] >= n_exits:
                allowed = f"an index into domain.exits, 0 to {n_exits - 1}" if n_exits else "none (no exits)"
                raise ParameterError(f"crowd.groups[{i}].exit", g["exit"], allowed)
            if g.get("exit") is not None and not self.crowd_capabilities.group_exits:
                raise ParameterError(
                    f"crowd.groups[{i}].exit", g["exit"],
                    f"no exit of the group's own with the {c.kind!r} crowd (it declares no group_exits: its people "
                    "walk as the crowd's guidance says); leave exit out, or use point masses",
                )  # fmt: skip

    def _checked_events(self, events: Any) -> tuple[EventSpec, ...]:
        """``events`` as :class:`EventSpec` in time order, each checked against the plan and the parts.

        Refused, naming ``events[i]...``: an exit index that ``domain.exits`` does not have; a ``block``
        that :func:`~meanfield.geometry.blocking.blocked_region` refuses (outside the plan, meeting an exit,
        cutting people off from every exit, ...), checked in time order on the plan the earlier blocks
        left; any event with a crowd kind that does not declare ``closes_exits``, a block with a crowd or
        controller kind that does not declare ``changes_walls``, or with the pairwise interaction (which
        lives on the grid the block cuts).  A warning: an event before 0 or after ``t_final`` (it happens
        at the first step, or never).
        """
        import warnings

        from meanfield.geometry.exits import exit_segments

        if events is None or (isinstance(events, (list, tuple)) and not events):
            return ()
        if not isinstance(events, (list, tuple)):
            raise ParameterError("events", events, "an array of tables [[events]] with time and close_exit or block")
        out = []
        n_exits = len(exit_segments(self.domain))
        for i, e in enumerate(events):
            name = f"events[{i}]"
            if isinstance(e, EventSpec):
                e = e.to_dict()
            if not isinstance(e, dict):
                raise ParameterError(name, e, "a table with time and close_exit or block")
            unknown = sorted(set(e) - {"time", *EVENT_ACTIONS})
            if unknown:
                raise ParameterError(f"{name}.{unknown[0]}", e[unknown[0]], "time, and close_exit or block")
            if "time" not in e:
                raise ParameterError(f"{name}.time", None, "the time the event happens")
            ev = EventSpec(**e, name=name)
            if ev.close_exit is not None and ev.close_exit >= n_exits:
                allowed = f"an index into domain.exits, 0 to {n_exits - 1}" if n_exits else "none (no exits)"
                raise ParameterError(f"{name}.close_exit", ev.close_exit, allowed)
            if not 0.0 <= ev.time < self.t_final:  # the last step ends at t_final: an event then has nothing to act on
                warnings.warn(
                    f"{name}.time = {ev.time:g} is outside the run [0, {self.t_final:g}): "
                    + ("it happens at the first step" if ev.time < 0 else "it never happens"),
                    ScenarioWarning,
                    stacklevel=4,
                )
            out.append(ev)
        out.sort(key=lambda ev: ev.time)
        if not self.crowd_capabilities.closes_exits:
            raise ParameterError(
                "events",
                f"{len(out)} event(s)",
                f"no events with the {self.crowd.kind!r} crowd, which cannot close an exit during a run "
                "(it declares no closes_exits): use point masses, JuPedSim's bodies or the density",
            )
        blocks = [ev for ev in out if ev.block is not None]
        if blocks:
            first = blocks[0].name + ".block"
            for kind, part in (("crowd", self.crowd.kind), ("controller", self.controller.kind)):
                if not registry.capabilities(kind, part).changes_walls:
                    fits = [k for k in registry.available(kind) if registry.capabilities(kind, k).changes_walls]
                    raise ParameterError(first, f"a block with the {part!r} {kind}", f"{kind}.kind among {fits}")
            if self.interaction.kind != "none":
                why = 'interaction.kind = "none" (the interaction lives on the grid the block cuts)'
                raise ParameterError(first, f"a block with interaction.kind = {self.interaction.kind!r}", why)
        self._check_event_geometry(out)
        return tuple(out)

    def _check_event_geometry(self, events: list[EventSpec]) -> None:
        """Play the events in time order on the plan: each ``block`` is refused by
        :func:`~meanfield.geometry.blocking.blocked_region` or when it leaves the robots' region in pieces; once a block
        has cut the plan, an event that leaves a piece without an open exit while another piece has one is refused
        (its people would be shut in; closing the last exit of all is allowed: "no exit left")."""
        from meanfield.geometry.blocking import blocked_region, exit_pieces
        from meanfield.geometry.exits import exit_segments

        if not any(ev.block is not None for ev in events):
            return
        region, open_exits = self.domain, np.ones(len(exit_segments(self.domain)), dtype=bool)
        for k, ev in enumerate(events):
            if ev.block is None:
                open_exits[ev.close_exit] = False
                field = f"{ev.name}.close_exit"
            else:
                field = f"{ev.name}.block"
                region = blocked_region(region, ev.block, field)
                try:  # where the robots may stand must keep the plan's pieces, as before the block
                    region.robot_region(self.robots.margin)
                except ParameterError:
                    raise ParameterError(
                        field, "a block that leaves the robots' region in pieces",
                        f"a region that leaves one piece at robots.margin = {self.robots.margin} from the walls",
                    ) from None  # fmt: skip
            simultaneous = k + 1 < len(events) and events[k + 1].time == ev.time  # (judged once all have happened)
            if region is not self.domain and open_exits.any() and not simultaneous:
                shut = [exits for exits in exit_pieces(region) if not open_exits[exits].any()]
                if shut:
                    raise ParameterError(
                        field, f"an event that leaves the people by exits {shut[0]} (all closed) shut in",
                        "events that leave every piece of the plan an open exit (or close the last one of all)",
                    )  # fmt: skip

    @property
    def congestion_model(self) -> str:
        """The speed–density relation the crowd walks by: ``crowd.congestion``, or for ``"auto"``
        the crowd kind's default for the scenario's units.

        A crowd declares ``default_congestion``, a table from units to a registered diagram
        (:attr:`crowd_capabilities`): the point masses and the density walk by the
        ``"linear"`` diagram in SI units, the one that puts the bottleneck's measured flows in
        range (docs page *Congestion*), and by none in the paper's dimensionless units (its
        study, unchanged); JuPedSim's bodies declare none (they queue by their own model).  A
        kind that declares nothing walks by ``"none"``.
        """
        if self.crowd.congestion != "auto":
            return self.crowd.congestion
        return self.crowd_capabilities.default_congestion.get(self.units, "none")

    @property
    def memory(self) -> str:
        """What people remember of a sign: ``view.memory``, or for ``"auto"`` ``"sign"`` for agents (a crowd kind
        that declares ``models_individuals``) in a plan with exits in SI units, and ``"none"`` otherwise (the paper's
        dimensionless room, the density)."""
        if self.view.memory != "auto":
            return self.view.memory
        from meanfield.geometry.exits import exit_segments

        if self.units != "SI" or not self.crowd_capabilities.models_individuals:
            return "none"
        return "sign" if len(exit_segments(self.domain)) else "none"

    @property
    def door_model(self) -> str:
        """How a congested agent's speed follows the crowd round it: ``crowd.door_model``, or for ``"auto"`` the
        crowd kind's own, the first of the models it declares in ``door_models`` (the point masses: ``"forward-cell"``,
        docs page *Congestion*, "The forward-cell door model").  A kind that declares none (the density, whose flux is
        Godunov's; JuPedSim's bodies, which queue by their own model) reads ``"count"``, which it ignores.
        """
        if self.crowd.door_model != "auto":
            return self.crowd.door_model
        return self.crowd_capabilities.door_models[0]

    def _congestion(self) -> Any:
        """The crowd's fundamental diagram (:mod:`meanfield.crowds.congestion`), from the registry."""
        c = self.crowd
        return registry.load("congestion", self.congestion_model)(free_speed=c.free_speed, rho_max=c.rho_max)

    def _check_crowd(self) -> None:
        """The chosen crowd's own cross-field checks (its record's ``check_scenario``)."""
        self.crowd_capabilities.check(self)

    @property
    def crowd_capabilities(self) -> CrowdCapabilities:
        """What the chosen crowd kind can do (:class:`~meanfield.capabilities.CrowdCapabilities`, from the registry)."""
        return registry.capabilities("crowd", self.crowd.kind)

    @property
    def pedestrians(self) -> Any:
        """Deprecated: the ``[pedestrians]`` table of earlier releases, read from ``crowd.kind`` and
        ``crowd.options.jupedsim`` (with a warning naming them)."""
        from types import SimpleNamespace

        deprecated("Scenario.pedestrians", "use Scenario.crowd.kind and Scenario.crowd.options")
        options = registry.capabilities("crowd", _OLD_PEDESTRIAN_KIND).options
        table = dataclasses.asdict(options(**self.crowd.options.get(_OLD_PEDESTRIAN_KIND, {})))
        return SimpleNamespace(backend=self.crowd.kind, **table)

    # ------------------------------------------------------------------ derived
    @property
    def steps(self) -> int:
        """Number of time steps ``round(t_final / dt)``."""
        return int(round(self.t_final / self.dt))

    def target_mass_in_domain(self, samples: int = 200) -> float:
        """Fraction of the (untruncated) target Gaussian's mass that lies in Ω."""
        x0, x1, y0, y1 = self.domain.bounds
        xs = np.linspace(x0, x1, samples)
        ys = np.linspace(y0, y1, samples)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        cx, cy = self.target.center
        s = self.target.std
        dens = np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) / (2 * math.pi * s * s)
        dens = np.where(self.domain.contains(X, Y), dens, 0.0)
        return float(dens.sum() * (xs[1] - xs[0]) * (ys[1] - ys[0]))

    def replace(self, **changes: Any) -> Scenario:
        """A copy with top-level fields replaced (validated again)."""
        return dataclasses.replace(self, **changes)

    def with_values(self, assignments: dict[str, Any]) -> Scenario:
        """A copy with dotted fields set, e.g. ``{"kernel.eta": 0.02, "robots.n": 9}``.

        Short names are read by :func:`resolve_key` (``{"eta": 0.02, "robots": 9}`` is the
        same).  Keys under ``controller.options.<kind>.`` and ``crowd.options.<kind>.`` may be new
        (the kind's declared options check them).
        """
        d = self.to_dict()
        d.setdefault("plugins", [])  # omitted from to_dict when empty, settable all the same
        d.setdefault("events", [])
        listed = self.plugins
        renamed = {}
        for short, value in assignments.items():
            if short in OLD_FIELDS:
                new = OLD_FIELDS[short]
                if new in assignments:
                    raise ParameterError(short, value, f"one of {short} (deprecated) and {new}, not both")
                deprecated(short, f"use {new}")
                short = new
            renamed[short] = value
        for short, value in renamed.items():
            key = resolve_key(short, value)
            parts = key.split(".")
            node = d
            for depth, p in enumerate(parts[:-1]):
                if parts[: depth + 1] in (["controller", "options"], ["crowd", "options"]) or (
                    parts[:2] in (["crowd", "options"], ["controller", "options"]) and depth == 2
                ):
                    node = node.setdefault(p, {})  # free-form: the part checks its own options
                    continue
                if p not in node or not isinstance(node[p], dict):
                    raise ParameterError(key, value, field_hint(parts, {}, _TOP_LEVEL))
                node = node[p]
            if parts[-1] not in node and not settable(parts, node):
                raise ParameterError(key, value, field_hint(parts, node, _TOP_LEVEL))
            if parts == ["domain", "kind"] and value != node.get("kind", "box"):
                # another shape: keep only the keys the new one takes (exits survive the switch)
                keep = region_keys(value)
                for k in [k for k in node if k != "kind" and keep is not None and k not in keep]:
                    del node[k]
            node[parts[-1]] = copy.deepcopy(value)  # (a later key under it must not write into the caller's table)
        # this scenario's own modules are imported already; a module it did not list needs the permission
        mods = d.get("plugins")
        kept = isinstance(mods, list | tuple) and all(m in listed for m in mods)
        return Scenario.from_dict(d, allow_plugins=kept)

    # ------------------------------------------------------------------ TOML
    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (TOML-ready: no None values, tuples as lists; no ``plugins`` when empty)."""
        out: dict[str, Any] = {
            "name": self.name,
            "seed": self.seed,
            "dt": self.dt,
            "t_final": self.t_final,
            "record_every": self.record_every,
            "record_humans": self.record_humans,
            "units": self.units,
        }
        if self.plugins:
            out["plugins"] = list(self.plugins)
        if self.events:
            out["events"] = [e.to_dict() for e in self.events]
        out["domain"] = self.domain.to_dict()
        for key in _SECTIONS:
            sec = {}
            for f in fields(getattr(self, key)):
                v = getattr(getattr(self, key), f.name)
                if v is None:
                    if key == "robots" and f.name in ("u_max", "omega_max"):
                        sec[f.name] = "none"
                    continue
                if isinstance(v, dict):
                    if not v:
                        continue
                    v = copy.deepcopy(v)  # crowd.options holds tables: a copy must not share them
                sec[f.name] = list(v) if isinstance(v, tuple) else v
            out[key] = sec
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any], *, allow_plugins: bool = False) -> Scenario:
        """Build and validate from a nested dict; unknown keys raise :class:`ParameterError`.

        The modules listed in ``plugins`` are imported first, when allowed (``allow_plugins``,
        or :func:`meanfield.plugins.allow_scenario_plugins`), and refused otherwise, before any
        import (see the class docstring); the ``[domain]`` table is read by
        :func:`meanfield.geometry.region.region_from_table`.
        """
        if not isinstance(d, dict):
            raise ParameterError("scenario", type(d).__name__, "a table of fields")
        d = _upgrade_old_fields(d)
        top = {*_TOP_LEVEL, "domain", *_SECTIONS}
        unknown = set(d) - top
        if unknown:
            raise ParameterError(sorted(unknown)[0], d[sorted(unknown)[0]], f"a known key: one of {sorted(top)}")
        # first the user's modules, so that the sections may name the parts they register
        modules = module_list("plugins", d.get("plugins"))
        registry.check_scenario_plugins(modules, allow=allow_plugins)  # nothing is imported before this
        registry.import_plugin_modules(modules, field="plugins")
        kwargs: dict[str, Any] = {k: d[k] for k in _TOP_LEVEL if k in d}
        if "domain" in d:
            kwargs["domain"] = region_from_table(d["domain"])
        for key, sec_cls in _SECTIONS.items():
            if key not in d:
                continue
            sec = d[key]
            if not isinstance(sec, dict):
                raise ParameterError(key, sec, "a table")
            names = {f.name for f in fields(sec_cls)}
            bad = set(sec) - names
            if bad:
                b = sorted(bad)[0]
                raise ParameterError(f"{key}.{b}", sec[b], f"a known key of [{key}]: one of {sorted(names)}")
            values = dict(sec)
            for k, v in values.items():
                if isinstance(v, list) and k in ("cells", "initial_center", "velocity", "center"):
                    values[k] = tuple(v)
            kwargs[key] = sec_cls(**values)
        return cls(**kwargs)

    def to_toml(self) -> str:
        """The scenario as TOML text."""
        import tomli_w

        return tomli_w.dumps(self.to_dict())

    @classmethod
    def from_toml(cls, text: str, *, allow_plugins: bool = False) -> Scenario:
        """Parse TOML text (see :meth:`from_dict`; ``allow_plugins`` lets its ``plugins`` be imported)."""
        try:
            d = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ParameterError("scenario file", str(exc), "valid TOML") from None
        return cls.from_dict(d, allow_plugins=allow_plugins)

    def save(self, path: str | Path) -> None:
        """Write the scenario to a TOML file (atomically)."""
        from meanfield.io.atomic import atomic_write_text

        atomic_write_text(Path(path), self.to_toml())


# ---------------------------------------------------------------------- built-ins
def _builtin(name: str, seed: int = 0) -> Scenario:
    """The built-in scenario ``meanfield/scenarios/<name>.toml``, with ``seed``."""
    text = (resources.files("meanfield") / "scenarios" / f"{name}.toml").read_text(encoding="utf-8")
    d = tomllib.loads(text)
    d["seed"] = seed
    return Scenario.from_dict(d)


def paper_scenario(seed: int = 0) -> Scenario:
    """The paper's MATLAB study (Section V): 200 humans, 16 robots, unit square, 30×30 grid.

    Read from ``meanfield/scenarios/paper.toml``.  Values the paper leaves open (c, η, σ,
    α, gains, h, speed limits, T, target width) are chosen in ``docs/scenarios.md``, where
    the reasons and the measured outcome are.
    """
    return _builtin("paper", seed)


# the Unity study's room (metres) and the time unit that makes the kernel's peak speed a
# walking speed: paper-unity is the paper scenario under x -> L x, t -> T t (docs/scenarios.md)
UNITY_LENGTH = 150.0
UNITY_TIME = 25.0


def paper_unity_scenario(seed: int = 0) -> Scenario:
    """The paper's Unity study (Section V-B): 150 × 150 m, 200 humans, 16 robots, 30 m view.

    Read from ``meanfield/scenarios/paper-unity.toml``.  Every parameter of
    :func:`paper_scenario` is carried over by the similarity ``x -> L x``, ``t -> T t``
    with ``L = 150 m`` and ``T = 25 s`` (:data:`UNITY_LENGTH`, :data:`UNITY_TIME`; so the
    kernel's peak speed ``c`` becomes 1.2 m/s): lengths scale by ``L``, speeds by ``L/T``,
    diffusions and ``α`` by ``L²/T``, rates by ``1/T``, densities by ``1/L²``, with one
    exception: the crowd's diffusion is a pedestrian's ``σ = 0.5 m²/s``, not the similar
    13.5 m²/s (a random displacement of 5 m per second is not walking; JuPedSim bodies
    have no such noise, and a controller that assumes it concentrates them).  The crowd,
    the density estimate and the Step-I law (``v_d``, ``ṽ``) are then exactly similar to
    the paper scenario's; the robot law is not, because ``V₂`` adds ``∫ρ̃²`` (scaling as
    ``1/L²``) to ``∫|ṽ|²`` (scaling as ``L⁴/T²``), so its inputs depend on the unit of
    length.  The Unity study's own assumptions are added on top: a human follows the
    signs only within 30 m of a robot and otherwise walks randomly (1.0 m/s, heading
    persistence ``1/D_r`` = 20 s), and the crowd may be run as JuPedSim bodies
    (``pedestrians.backend = "jupedsim"``).  The reasons for each value, and how the
    outcome depends on them, are in ``docs/scenarios.md``.
    """
    return _builtin("paper-unity", seed)


STADIUM_CROWD = 1_000_000
"""Humans in the built-in ``stadium`` scenario."""


def stadium_scenario(seed: int = 0) -> Scenario:
    """The ``paper`` scenario with a stadium's crowd: 10⁶ humans, 64 robots, 128×128 grid.

    Read from ``meanfield/scenarios/stadium.toml``.  Everything else is ``paper``'s,
    except the KDE bandwidth (0.03: about four cells of the finer grid, where ``paper``'s
    0.08 is 2.4 of its cells) and that the positions of 10 000 evenly spaced humans are
    recorded rather than all (``record_humans``).  The navigation field is sampled on a
    lattice (``crowd.field_evaluation = "auto"`` chooses it above 2·10⁶ human-robot pairs)
    and the KDE bins the crowd: a closed-loop step costs O(N + G log G) (docs/scale.md).
    """
    return _builtin("stadium", seed)


_FACTORIES: dict[str, Callable[..., Scenario]] = {
    "paper": paper_scenario,
    "paper-unity": paper_unity_scenario,
    "stadium": stadium_scenario,
}


def builtin_scenarios() -> dict[str, Any]:
    """Names of the built-in scenarios (the TOML files in ``meanfield/scenarios/``) and their
    factories ``factory(seed=0) -> Scenario``."""
    folder = resources.files("meanfield") / "scenarios"
    names = sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml"))
    return {name: _FACTORIES.get(name) or functools.partial(_builtin, name) for name in names}


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("scenario file", f"{path}: {exc}", "valid TOML") from None


def _plugins_beside(d: dict[str, Any], folder: Path) -> dict[str, Any]:
    """A scenario file's ``plugins`` with relative ``.py`` paths read from the file's folder."""
    mods = d.get("plugins")
    if isinstance(mods, list):
        d["plugins"] = [
            str((folder / m).resolve()) if isinstance(m, str) and m.endswith(".py") and not Path(m).is_absolute() else m
            for m in mods
        ]
    return d


def load_scenario(spec: str | Path, seed: int | None = None, *, allow_plugins: bool = False) -> Scenario:
    """A built-in scenario by name, a TOML file by path, or a JuPedSim web-app export (a ZIP, a folder
    or a JSON file: :mod:`meanfield.scenarios.webapp`); ``seed`` overrides the file's.

    In a file, ``plugins`` paths to ``.py`` files are relative to the file's folder; they are
    imported only with ``allow_plugins=True`` (or within
    :func:`meanfield.plugins.allow_scenario_plugins`), and otherwise refused with a
    :class:`ParameterError` naming ``plugins``, before anything is imported.
    """
    from meanfield.io.webapp import looks_like_export, read_export

    spec = str(spec)
    table = builtin_scenarios()
    if spec in table:
        sc = table[spec]()
    elif looks_like_export(spec):
        from meanfield.scenarios.webapp import scenario_table

        sc = Scenario.from_dict(scenario_table(read_export(spec)))
    else:
        path = Path(spec)
        if not path.is_file():
            allowed = f"a built-in name ({', '.join(table)}), an existing .toml file or a JuPedSim web-app export"
            raise ParameterError("scenario", spec, allowed)
        sc = Scenario.from_dict(_plugins_beside(_read_toml(path), path.parent), allow_plugins=allow_plugins)
    if seed is not None:
        sc = sc.replace(seed=seed)
    return sc
