"""The registry: every interchangeable part of the closed loop, chosen by name.

A scenario names its parts (``domain.kind``, ``crowd.kind``, ``controller.kind``,
``controller.beta_gamma``); :func:`meanfield.simulation.assembly.assemble` looks each name up here.
Names come from three places, one registration line each:

* this toolkit's own parts, listed in :data:`BUILTIN` as ``"module:attribute"`` references
  (imported only when used, so naming a part costs no import);
* installed packages, by entry point in their distribution's metadata, the way pytest
  plugins extend pytest (``meanfield`` never imports ``analysis`` or ``verification``;
  they register here through ``pyproject.toml``);
* a user's own module, with :func:`register` (e.g. ``register("controller", "parked",
  ParkedRobots.from_parts)``), imported before the scenario is validated: named on the
  command line (``--plugin my_module.py``), imported by the user's script, or listed in the
  scenario's top-level ``plugins = ["my_module"]``.

A scenario *read* from a file, TOML text or a table imports the modules its ``plugins`` lists
only when the user allows it (:func:`allow_scenario_plugins`: ``--allow-plugins`` or
``--plugin`` on the command line, ``allow_plugins=True`` in Python); otherwise it is refused with
a :class:`ParameterError` naming ``plugins`` before anything is imported.  Scenario files are
shared like data (a study's appendix, a colleague's building), and importing a module runs its
code: reading one must not run code the user did not ask for.  Built-in parts and installed
entry points are not affected (installing a package is the user's choice).

A name registered twice is refused, naming both origins.

Every part of a kind that has a capability record (:data:`meanfield.capabilities.RECORDS`: every kind but
``command``) carries one: what it can do, in typed fields that the core reads (:func:`capabilities`).  A part
without it is refused when it is registered, and a built-in or entry-point part when it is first loaded, naming
the part and the record it lacks.

The kinds and what a factory of each kind receives and returns (docs page *Architecture*):

``region`` (entry-point group ``meanfield.regions``)
    ``factory(**table) -> Region``, ``table`` being the scenario's ``[domain]`` table
    without ``kind``.
``crowd`` (``meanfield.crowds``)
    ``factory(context: CrowdContext) -> Crowd`` (:mod:`meanfield.interfaces`).
``controller`` (``meanfield.controllers``)
    ``factory(parts: ControllerParts) -> Controller``.
``guidance`` (``meanfield.guidance``)
    ``factory(context: CrowdContext, positions) -> Guidance | None``: what the agents follow
    (None: the robots' signs; :mod:`meanfield.crowds.guidance`).
``congestion`` (``meanfield.congestion``)
    ``factory(free_speed, rho_max) -> FundamentalDiagram``: the speed–density relation a
    congested crowd walks by (:mod:`meanfield.crowds.congestion`; ``crowd.congestion``).
``beta_gamma`` (``meanfield.beta_gamma``)
    ``factory(scenario) -> BetaGammaStrategy``.
``command`` (``meanfield.commands``)
    ``register(subparsers) -> handler``: adds a sub-command; ``handler(args) -> int``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from meanfield.capabilities import RECORDS, capabilities_of
from meanfield.errors import ParameterError, deprecated

__all__ = [
    "BUILTIN",
    "GROUPS",
    "ALLOW_PLUGINS_HINT",
    "PluginPermission",
    "allow_scenario_plugins",
    "available",
    "capabilities",
    "check_scenario_plugins",
    "current_permission",
    "declared",
    "import_plugin_modules",
    "load",
    "loaders",
    "origin",
    "permitted",
    "register",
    "unregister",
]

GROUPS = {
    "region": "meanfield.regions",
    "crowd": "meanfield.crowds",
    "controller": "meanfield.controllers",
    "guidance": "meanfield.guidance",
    "congestion": "meanfield.congestion",
    "beta_gamma": "meanfield.beta_gamma",
    "command": "meanfield.commands",
}
"""Plugin kinds and their entry-point groups."""

BUILTIN: dict[str, dict[str, str]] = {
    "region": {
        "box": "meanfield.geometry.domain:Domain.box",
        "disk": "meanfield.geometry.domain:Domain.disk",
        "polygon": "meanfield.geometry.domain:Domain.polygon",
        "plan": "meanfield.geometry.plan:plan_from_table",
    },
    "crowd": {
        "point-mass": "meanfield.crowds.agent_crowd:point_mass_crowd",
        "jupedsim": "meanfield.crowds.jupedsim_engine:jupedsim_crowd",
        "fokker-planck": "meanfield.crowds.density_crowd:DensityCrowd.from_context",
    },
    "controller": {
        "backstepping": "meanfield.controllers.backstepping:BacksteppingController.from_parts",
        "evacuation": "meanfield.controllers.evacuation:EvacuationController.from_parts",
        "static-signs": "meanfield.controllers.static_signs:StaticSigns.from_parts",
        "coverage": "meanfield.controllers.coverage:CoverageController.from_parts",
        "guide": "meanfield.controllers.guide:GuideController.from_parts",
    },
    "guidance": {
        "signs": "meanfield.crowds.guidance:signs",
        "geodesic": "meanfield.crowds.guidance:geodesic",
        "hughes": "meanfield.crowds.guidance:hughes",
        "fastest-route": "meanfield.crowds.guidance:fastest_route",
        "random-walk": "meanfield.crowds.guidance:random_walk",
    },
    "congestion": {
        "none": "meanfield.crowds.congestion:NoCongestion.from_scenario",
        "weidmann": "meanfield.crowds.congestion:Weidmann.from_scenario",
        "linear": "meanfield.crowds.congestion:Linear.from_scenario",
    },
    "beta_gamma": {
        "min-norm": "meanfield.controllers.beta_gamma:MinimumNormBetaGamma.from_scenario",
    },
    "command": {
        "run": "meanfield.cli.run:register",
        "compare": "meanfield.cli.compare:register",
        "scenario": "meanfield.cli.scenario:register",
        "sweep": "meanfield.cli.sweep:register",
        "study": "meanfield.cli.study:register",
    },
}
"""This toolkit's own parts: ``{kind: {name: "module:attribute"}}``."""


@dataclass(frozen=True)
class _Entry:
    name: str
    origin: str  # where the name was registered, for messages
    target: Any  # a "module:attribute" reference, an entry point, or the object itself
    record: Any = None  # the capability record given to register(); None: the factory's own

    def load(self) -> Any:
        t = self.target
        if isinstance(t, str):
            module, _, attr = t.partition(":")
            obj: Any = importlib.import_module(module)
            for part in attr.split("."):
                obj = getattr(obj, part)
            return obj
        if hasattr(t, "load") and hasattr(t, "group"):  # an importlib.metadata.EntryPoint
            return t.load()
        return t


_registered: dict[str, dict[str, _Entry]] = {kind: {} for kind in GROUPS}


_INSTALLED: dict[tuple[Any, str], tuple[Any, ...]] = {}


def _installed(group: str) -> tuple[Any, ...]:
    """The installed packages' entry points of ``group``, read once per process (a scan of every
    distribution's metadata costs about 5 ms, and a scenario asks the registry a dozen times).
    Keyed by the reader as well, so that a test that replaces :func:`entry_points` reads afresh."""
    key = (entry_points, group)
    if key not in _INSTALLED:
        _INSTALLED[key] = tuple(entry_points(group=group))
    return _INSTALLED[key]


def _check_kind(kind: str) -> None:
    if kind not in GROUPS:
        raise ParameterError("kind", kind, " or ".join(map(repr, GROUPS)))


def _describe(obj: Any) -> str:
    module = getattr(obj, "__module__", None) or "?"
    return f"{module}:{getattr(obj, '__qualname__', type(obj).__name__)}"


def _entries(kind: str) -> dict[str, _Entry]:
    """Every registered name of one kind; a name that two origins claim is refused."""
    _check_kind(kind)
    out: dict[str, _Entry] = {}

    def add(entry: _Entry) -> None:
        if entry.name in out:
            first = out[entry.name]
            raise ParameterError(
                f"{kind} plugin {entry.name!r}",
                f"registered twice: by {first.origin} and by {entry.origin}",
                "one registration per name (rename or uninstall one of them)",
            )
        out[entry.name] = entry

    for name, ref in BUILTIN[kind].items():
        add(_Entry(name, f"meanfield (built-in {ref})", ref))
    for ep in _installed(GROUPS[kind]):
        dist = getattr(getattr(ep, "dist", None), "name", None) or "an installed package"
        add(_Entry(ep.name, f"entry point {ep.value} of {dist}", ep))
    for entry in _registered[kind].values():
        add(entry)
    return out


def register(kind: str, name: str, factory: Any, origin: str | None = None, capabilities: Any = None) -> Any:
    """Register ``factory`` under ``name`` (one line in the module that defines it).

    Parameters
    ----------
    kind : {"region", "crowd", "controller", "guidance", "congestion", "beta_gamma", "command"}
    name : str
        The name a scenario uses (``controller.kind = name``, ...).
    factory : callable
        See the module docstring for each kind's signature.
    origin : str, optional
        Where the registration comes from (default: the factory's module and name).
    capabilities : capability record, optional
        What the part can do, the record of its kind (:data:`meanfield.capabilities.RECORDS`, e.g.
        :class:`~meanfield.capabilities.ControllerCapabilities`); default: the factory's own (a class's
        ``capabilities`` attribute, or a function's from :func:`~meanfield.capabilities.declares`).

    Returns
    -------
    factory, so that ``register`` can be used in an assignment or a decorator helper.

    Raises
    ------
    ParameterError
        If the name is taken (built in, by an entry point, or registered before), naming both origins; if the
        part carries no capability record of its kind, naming the part and the record.
    """
    _check_kind(kind)
    if not isinstance(name, str) or not name:
        raise ParameterError("name", name, "a non-empty string")
    entry = _Entry(name, origin or _describe(factory), factory, capabilities)
    _record(kind, entry, factory)  # refused here, before the name is taken
    existing = _entries(kind).get(name)
    if existing is not None:
        raise ParameterError(
            f"{kind} plugin {name!r}",
            f"registered twice: by {existing.origin} and by {entry.origin}",
            "one registration per name (rename or unregister one of them)",
        )
    _registered[kind][name] = entry
    return factory


def _record(kind: str, entry: _Entry, factory: Any) -> Any:
    """The capability record of ``entry`` (its own, else the factory's); refused if it has none of its kind."""
    wanted = RECORDS.get(kind)
    record = entry.record if entry.record is not None else capabilities_of(factory)
    if wanted is None:
        if entry.record is not None:
            why = f"no capability record (a {kind} has none)"
            raise ParameterError(f"{kind} plugin {entry.name!r}", entry.record, why)
        return None
    if not isinstance(record, wanted):
        how = (
            f"a {wanted.__name__} (meanfield.capabilities): a class attribute capabilities = {wanted.__name__}(...), "
            f"@declares({wanted.__name__}(...)) on a function, or register(..., capabilities={wanted.__name__}(...))"
        )
        lacks = "no capability record" if record is None else f"a record of another kind ({type(record).__name__})"
        raise ParameterError(f"{kind} plugin {entry.name!r} ({entry.origin})", lacks, how)
    return record


def capabilities(kind: str, name: str) -> Any:
    """What the part ``name`` of ``kind`` can do: its capability record (:mod:`meanfield.capabilities`).

    The core reads the record's fields (``capabilities("controller", name).accepts_sensing``) instead of testing a
    part's name; a field that does not exist raises :class:`AttributeError`.

    Raises
    ------
    ParameterError
        If no part of that kind has this name, or the part carries no record of its kind (naming the part and
        the record it lacks).
    """
    if kind not in RECORDS:
        raise ParameterError("kind", kind, " or ".join(map(repr, RECORDS)) + " (the kinds with a capability record)")
    entry = _get(kind, name)
    return _record(kind, entry, entry.load())


def unregister(kind: str, name: str) -> None:
    """Remove a name added by :func:`register` (built-ins and entry points stay)."""
    _check_kind(kind)
    _registered[kind].pop(name, None)


def available(kind: str) -> tuple[str, ...]:
    """Names registered for one kind (``"region"``, ``"crowd"``, ``"controller"``, ...), sorted."""
    return tuple(sorted(_entries(kind)))


def loaders(kind: str) -> dict[str, Callable[[], Any]]:
    """Every registered name of one kind, sorted, with a function that loads its factory.

    One look-up for all the names: the ``meanfield`` command builds its parser this way.
    """
    return {name: entry.load for name, entry in sorted(_entries(kind).items())}


def origin(kind: str, name: str) -> str:
    """Where ``name`` of ``kind`` was registered (for messages and ``meanfield`` diagnostics)."""
    return _get(kind, name).origin


def _get(kind: str, name: str) -> _Entry:
    entries = _entries(kind)
    if name not in entries:
        names = ", ".join(map(repr, sorted(entries))) or "none installed"
        raise ParameterError(kind, name, f"a registered {kind} ({names})")
    return entries[name]


def load(kind: str, name: str) -> Any:
    """The factory registered as ``name`` of ``kind``.

    Raises
    ------
    ParameterError
        If no part of that kind has this name (the message lists those that do), or the part carries no
        capability record of its kind (a built-in or an installed entry point is checked here, when first loaded).
    """
    entry = _get(kind, name)
    factory = entry.load()
    _record(kind, entry, factory)
    return factory


def declared(kind: str, name: str, attribute: str, default: Any = None) -> Any:
    """Deprecated: ``capabilities(kind, name).<attribute>`` (:func:`capabilities`), removed in 0.3.0.

    The field ``attribute`` of the part's capability record, ``default`` if the record has no such field (the old
    behaviour; the record itself raises :class:`AttributeError` for a field it does not have).
    """
    deprecated("meanfield.plugins.declared(kind, name, attribute)",
               "use meanfield.plugins.capabilities(kind, name).<field>")  # fmt: skip
    return getattr(capabilities(kind, name), attribute, default)


# ---------------------------------------------------------------------- a scenario's own modules
ALLOW_PLUGINS_HINT = (
    "no modules unless the user allows them: a scenario file is shared like data, and its plugins "
    "would run Python code when it is read. Allow them with --allow-plugins on the command line "
    "(or name each with --plugin FILE_OR_MODULE), or with allow_plugins=True in Python "
    "(load_scenario, Scenario.from_toml, Scenario.from_dict)"
)
"""What a refused scenario ``plugins`` list is told (the ``allowed`` part of the :class:`ParameterError`)."""


@dataclass(frozen=True)
class PluginPermission:
    """Which modules a scenario that is read may import (see :func:`allow_scenario_plugins`).

    Attributes
    ----------
    every : bool
        Whatever a scenario lists (``--allow-plugins``).
    modules : frozenset of str
        These modules (``--plugin``): dotted names, and ``.py`` files by absolute path.
    """

    every: bool = False
    modules: frozenset[str] = frozenset()

    def allows(self, spec: str) -> bool:
        """Whether the module ``spec`` (a dotted name or a path to a ``.py`` file) may be imported."""
        return self.every or _module_key(spec) in self.modules


_NOTHING_ALLOWED = PluginPermission()  # frozen: safe to share as the default
_PERMISSION: ContextVar[PluginPermission] = ContextVar("meanfield_scenario_plugins", default=_NOTHING_ALLOWED)
"""The permission of the code running now (a context variable: it holds within one
:func:`allow_scenario_plugins` block of one thread or task, and never leaks into another call)."""


def _module_key(spec: str) -> str:
    """A module as the permission compares it: a ``.py`` file by its absolute path, else its dotted name."""
    return str(Path(spec).resolve()) if spec.endswith(".py") else spec


@contextmanager
def allow_scenario_plugins(modules: Iterable[str] | None = None) -> Iterator[None]:
    """Within the block, scenarios that are read may import the modules their ``plugins`` lists.

    Parameters
    ----------
    modules : iterable of str, optional
        None (the default) allows every module a scenario lists (the command line's
        ``--allow-plugins``); a list allows those modules only (``--plugin``: the modules the user
        named), each a dotted name or a path to a ``.py`` file (compared by absolute path).

    Notes
    -----
    The permission is a :class:`contextvars.ContextVar`, set for the block and restored after it:
    it does not leak into later calls, other threads or other processes.  A sweep's worker is
    given it with each job (:func:`meanfield.workflows.sweep.run_sweep`).  Loaders take the
    same permission as a keyword, ``allow_plugins=True``.
    """
    current = _PERMISSION.get()
    if modules is None:
        granted = PluginPermission(True, current.modules)
    else:
        named = [modules] if isinstance(modules, str) else list(modules)
        keys = {_module_key(m) for m in named if isinstance(m, str) and m}
        granted = PluginPermission(current.every, current.modules | keys)
    with permitted(granted):
        yield


def current_permission() -> PluginPermission:
    """The permission in force here: what a job sent to another process carries (:func:`permitted`)."""
    return _PERMISSION.get()


@contextmanager
def permitted(permission: PluginPermission) -> Iterator[None]:
    """Within the block, exactly ``permission`` is in force: a worker runs the job of a process that
    allowed it (:func:`meanfield.workflows.dask_cluster.map_jobs` sends :func:`current_permission`)."""
    if not isinstance(permission, PluginPermission):
        raise ParameterError("permission", permission, "a meanfield.plugins.PluginPermission")
    token = _PERMISSION.set(permission)
    try:
        yield
    finally:
        _PERMISSION.reset(token)


def check_scenario_plugins(modules: Sequence[str], allow: bool = False, field: str = "plugins") -> None:
    """Refuse a scenario's ``plugins`` that the user has not allowed, before anything is imported.

    Parameters
    ----------
    modules : sequence of str
        The modules a scenario that is being read lists (checked by :func:`meanfield.errors.module_list`).
    allow : bool
        The loader's own ``allow_plugins``: True allows them all.
    field : str
        The field named in the error.

    Raises
    ------
    ParameterError
        Naming ``field`` and saying how to allow the modules (:data:`ALLOW_PLUGINS_HINT`), when a
        module is neither allowed by ``allow`` nor by the enclosing :func:`allow_scenario_plugins`.
    """
    if allow or not modules:
        return
    permission = _PERMISSION.get()
    if not all(permission.allows(m) for m in modules):
        raise ParameterError(field, list(modules), ALLOW_PLUGINS_HINT)


def _failure(exc: BaseException) -> str:
    """An import's failure in one line: its type, message and where (file and line) it was raised."""
    where = ""
    if isinstance(exc, SyntaxError):
        where = f" at {exc.filename}:{exc.lineno}"
    else:
        tb = exc.__traceback__
        while tb is not None and tb.tb_next is not None:
            tb = tb.tb_next
        if tb is not None:
            where = f" at {tb.tb_frame.f_code.co_filename}:{tb.tb_lineno}"
    return f"{type(exc).__name__}: {exc}{where}"


def import_plugin_modules(modules: list[str] | tuple[str, ...], field: str = "plugins") -> None:
    """Import user modules (dotted names, or paths to ``.py`` files) that call :func:`register`.

    Importing a module twice is harmless: Python keeps the first import.  This imports whatever
    it is given: a scenario that is read asks :func:`check_scenario_plugins` first.
    """
    import importlib.util
    import sys

    for spec in modules:
        if not isinstance(spec, str) or not spec:
            raise ParameterError(field, spec, "module names or paths to .py files")
        if spec.endswith(".py"):
            path = Path(spec).resolve()
            name = f"meanfield_plugin_{path.stem}_{abs(hash(str(path))):x}"
            if name in sys.modules:
                continue
            if not path.is_file():
                raise ParameterError(field, spec, "an existing .py file or an importable module")
            mod_spec = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(mod_spec)
            sys.modules[name] = module
            try:
                mod_spec.loader.exec_module(module)
            except (KeyboardInterrupt, SystemExit, ParameterError):
                del sys.modules[name]
                raise
            except BaseException as exc:  # a syntax error, or anything the plugin's own code raises
                del sys.modules[name]
                raise ParameterError(field, spec, f"a module that imports ({_failure(exc)})") from None
        else:
            try:
                importlib.import_module(spec)
            except ImportError as exc:
                raise ParameterError(field, spec, f"an importable module ({exc})") from None
            except (KeyboardInterrupt, SystemExit, ParameterError):
                raise
            except BaseException as exc:
                raise ParameterError(field, spec, f"a module that imports ({_failure(exc)})") from None
