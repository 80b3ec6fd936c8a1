"""What each registered part can do: one frozen record per part kind, read by the core as typed fields.

A part of the closed loop (docs page *Architecture*, "Capabilities") says what it can do once, in the record of
its kind, and the core reads the record's fields instead of testing the part's name or probing it for
attributes:

* a class whose class method is the factory (``Class.from_parts``) carries the record as the class attribute
  ``capabilities``;
* a plain function factory carries it through :func:`declares` (``@declares(CrowdCapabilities(...))``);
* a user's factory may also be registered with its record: ``plugins.register(kind, name, factory,
  capabilities=record)``.

Every field has its default here, where it is declared, and a field that does not exist is an error
(:class:`AttributeError` when read, :class:`TypeError` when set), never a silent default.
:func:`meanfield.plugins.register` refuses a part of a kind in :data:`RECORDS` that carries no record of that
kind, naming the part and the record.

The hooks a part offers (a controller's stability step, a crowd's cross-field check, a guidance's drift for the
density) are fields of its record holding functions; the record's methods call them, with the behaviour of a
part that offers none.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, TypeVar

__all__ = [
    "BetaGammaCapabilities",
    "CongestionCapabilities",
    "ControllerCapabilities",
    "CrowdCapabilities",
    "GuidanceCapabilities",
    "RECORDS",
    "RegionCapabilities",
    "capabilities_of",
    "declares",
]


def _options_class(owner: str, options: Any) -> None:
    if options is not None and not isinstance(options, type):
        raise TypeError(f"{owner}.options must be a dataclass type (the part's options) or None, not {options!r}")


def _hook(owner: str, name: str, hook: Any) -> None:
    if hook is not None and not callable(hook):
        raise TypeError(f"{owner}.{name} must be a function or None, not {hook!r}")


@dataclass(frozen=True)
class CrowdCapabilities:
    """What a crowd kind (registry kind ``crowd``) can do.

    Attributes
    ----------
    models_individuals : bool
        Each human is an agent of its own: it may wait its pre-movement time and ignore the signs
        (``crowd.premovement``, ``crowd.compliance``, ``view.memory``; docs page *Buildings*, "People are not all
        alike"), and congestion is modelled per person in SI units.
    places_groups : bool
        People may start in groups, each in its region (``crowd.initial = "groups"``).
    group_exits : bool
        A group may walk to an exit of its own (``[[crowd.groups]] exit = k``).
    closes_exits : bool
        An exit may close during a run (``[[events]] close_exit``).
    changes_walls : bool
        A region may become wall during a run (``[[events]] block``).
    door_models : tuple of str
        The door models it takes (``crowd.door_model``), its default first (docs page *Congestion*, "The agents'
        door model").  A crowd whose queues are its own (the density's Godunov flux, JuPedSim's bodies) takes
        only ``"count"``, which it ignores: the default before ``"auto"``, written in older runs' scenarios.
    default_congestion : mapping of str to str
        ``crowd.congestion = "auto"``: the registered diagram for each unit system (``{"SI": "linear"}``); a unit
        system not listed gets ``"none"``.
    options : type or None
        The dataclass that reads ``[crowd.options.<kind>]`` and checks its fields; None: the crowd takes none.
    check_scenario : callable or None
        ``check_scenario(scenario) -> None``: the crowd's own cross-field checks, raising
        :class:`~meanfield.errors.ParameterError`; None: it has none.
    """

    models_individuals: bool = False
    places_groups: bool = False
    group_exits: bool = False
    closes_exits: bool = False
    changes_walls: bool = False
    door_models: tuple[str, ...] = ("count",)
    default_congestion: Mapping[str, str] = field(default_factory=dict)
    options: type | None = None
    check_scenario: Callable[[Any], None] | None = None

    def __post_init__(self) -> None:
        if not self.door_models or not all(isinstance(m, str) and m for m in self.door_models):
            wrong = self.door_models
            raise TypeError(f"CrowdCapabilities.door_models must be a non-empty tuple of names, not {wrong!r}")
        object.__setattr__(self, "door_models", tuple(self.door_models))
        object.__setattr__(self, "default_congestion", MappingProxyType(dict(self.default_congestion)))
        _options_class("CrowdCapabilities", self.options)
        _hook("CrowdCapabilities", "check_scenario", self.check_scenario)

    def check(self, scenario: Any) -> None:
        """Run the crowd's own cross-field checks on ``scenario`` (nothing for a crowd that has none)."""
        if self.check_scenario is not None:
            self.check_scenario(scenario)


@dataclass(frozen=True)
class ControllerCapabilities:
    """What a controller kind (registry kind ``controller``) can do.

    Attributes
    ----------
    accepts_sensing : bool
        It runs on a group's local knowledge (``[sensing]``, :mod:`meanfield.controllers.local_sensing`).
    requires_exits : bool
        It needs a room with exits (a study offers it only there).
    changes_walls : bool
        It keeps working when a region becomes wall during a run (``[[events]] block``).
    options : type or None
        The dataclass that reads ``[controller.options.<kind>]`` and checks its fields; None: the controller
        takes none.
    stability_step : callable or None
        ``stability_step(scenario, grid) -> StabilityStep | None``: the largest stable time step of its scheme
        (:class:`~meanfield.interfaces.StabilityStep`); None: it declares none.
    """

    accepts_sensing: bool = False
    requires_exits: bool = False
    changes_walls: bool = False
    options: type | None = None
    stability_step: Callable[[Any, Any], Any] | None = None

    def __post_init__(self) -> None:
        _options_class("ControllerCapabilities", self.options)
        _hook("ControllerCapabilities", "stability_step", self.stability_step)

    def largest_stable_step(self, scenario: Any, grid: Any) -> Any:
        """The controller's :class:`~meanfield.interfaces.StabilityStep` on ``scenario`` and ``grid`` (None: none)."""
        return self.stability_step(scenario, grid) if self.stability_step is not None else None


@dataclass(frozen=True)
class RegionCapabilities:
    """What a region kind (registry kind ``region``, the scenario's ``[domain]``) declares beyond
    :class:`~meanfield.geometry.region.Region`: nothing yet.

    A region answers the core's questions through the protocol itself (its boundary's parts and exits, its walls,
    its outline), and the keys of its ``[domain]`` table are its factory's keyword arguments
    (:func:`~meanfield.geometry.region.region_from_table`).  The record is still required, so that a capability
    added here later is declared by every region kind, never probed.
    """


@dataclass(frozen=True)
class GuidanceCapabilities:
    """What a guidance (registry kind ``guidance``, ``crowd.guidance``) can do.

    Attributes
    ----------
    for_density : callable or None
        ``for_density(context) -> DensityGuidance``: what it gives the density (docs page *Congestion*, "The
        PDE"); None: it guides agents only, and the density refuses it.
    """

    for_density: Callable[[Any], Any] | None = None

    def __post_init__(self) -> None:
        _hook("GuidanceCapabilities", "for_density", self.for_density)


@dataclass(frozen=True)
class CongestionCapabilities:
    """What a fundamental diagram (registry kind ``congestion``, ``crowd.congestion``) does.

    Attributes
    ----------
    slows : bool
        It slows a crowd with its density (False: the paper's crowd, ``"none"``).
    """

    slows: bool = True


@dataclass(frozen=True)
class BetaGammaCapabilities:
    """What a β/γ rule (registry kind ``beta_gamma``, ``controller.beta_gamma``) can do.

    Attributes
    ----------
    accepts_kernel_scaling : bool
        It works in the kernel's units (``controller.scaling = "kernel"``): it has no limits in the scenario's
        units that the scaling would change.
    """

    accepts_kernel_scaling: bool = False


RECORDS: dict[str, type] = {
    "region": RegionCapabilities,
    "crowd": CrowdCapabilities,
    "controller": ControllerCapabilities,
    "guidance": GuidanceCapabilities,
    "congestion": CongestionCapabilities,
    "beta_gamma": BetaGammaCapabilities,
}
"""The record each registry kind's parts carry (a command, kind ``command``, carries none)."""


F = TypeVar("F", bound=Callable[..., Any])


def declares(record: Any) -> Callable[[F], F]:
    """Attach ``record`` to a factory function as its ``capabilities`` (a class carries its own as a class attribute).

    Parameters
    ----------
    record : one of the records of :data:`RECORDS`

    Returns
    -------
    A decorator that returns the function itself, with ``capabilities = record``.
    """
    if type(record) not in RECORDS.values():
        raise TypeError(f"declares() takes a capability record ({', '.join(r.__name__ for r in RECORDS.values())})")

    def attach(factory: F) -> F:
        factory.capabilities = record  # type: ignore[attr-defined]  # the one typed record of the part
        return factory

    return attach


def capabilities_of(factory: Any) -> Any:
    """The record a factory carries: its own ``capabilities``, or its class's for a bound class method (None: none)."""
    record = getattr(factory, "capabilities", None)
    if record is None:
        record = getattr(getattr(factory, "__self__", None), "capabilities", None)
    return record
