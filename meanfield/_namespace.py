"""Package namespaces: names imported on first use (PEP 562), and the modules that moved.

``import meanfield`` (and ``analysis``, ``verification``) costs milliseconds instead of
SciPy's, xarray's and the solvers' import time, and ``meanfield --help`` stays quick; a name
such as ``meanfield.run`` is imported the first time it is read, then kept
(:func:`lazy_namespace`).

Modules that moved into the subpackages keep working at their old paths until 0.3.0
(:data:`MOVED`, :func:`install_moved_modules`): ``from meanfield.crowd import Crowd`` still
gives the point-mass engine, with a :class:`~meanfield.errors.MeanfieldDeprecationWarning`
that names its new place (``meanfield.crowds.point_mass.PointMassEngine``).
"""

from __future__ import annotations

import importlib
import sys
import types
import warnings
from collections.abc import Callable
from typing import Any

__all__ = ["lazy_namespace", "MOVED", "install_moved_modules"]


def lazy_namespace(
    package: str,
    namespace: dict[str, Any],
    names: dict[str, str],
    deprecated: dict[str, tuple[str, str]] | None = None,
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for a package whose ``names`` map to the modules defining them.

    Usage, in a package's ``__init__.py``::

        __getattr__, __dir__ = lazy_namespace(__name__, globals(), {"run": "meanfield.simulation.loop", ...})

    ``deprecated`` maps an old name to ``(module, new name)``: reading it gives the new name's
    value with a :class:`~meanfield.errors.MeanfieldDeprecationWarning` naming it (never cached,
    so that every use is told).
    """
    deprecated = deprecated or {}

    def __getattr__(name: str) -> Any:
        if name in deprecated:
            module, new_name = deprecated[name]
            _warn(f"{package}.{name}", f"use {module}.{new_name}")
            return getattr(importlib.import_module(module), new_name)
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value  # once imported, a plain attribute
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *names})

    return __getattr__, __dir__


# ---------------------------------------------------------------------- modules that moved
MOVED: dict[str, Any] = {
    "agent_crowd": "crowds.agent_crowd",
    "assembly": "simulation.assembly",
    "blas": "_compiled.blas",
    "budget": "simulation.preflight",
    "cluster": "workflows.dask_cluster",
    "compare": "workflows.mean_field_limit",
    "compiled": (
        "_compiled.core",
        {"CompiledKernel": "CompiledLoop", "kernels": "compiled_loops"},
    ),
    "control": "controllers.backstepping",
    "controller_study": "workflows.controller_study",
    "coverage": "controllers.coverage",
    "crowd": (
        "crowds.point_mass",
        {"Crowd": "PointMassEngine"},
    ),
    "crowd_loops": {
        "gaussian_field_at": "crowds._field_loops",
        "bilinear_at": "crowds._field_loops",
        "euler_maruyama": "crowds._point_mass_loops",
        "input_report": "signs._robot_loops",
        "limit_inputs": "signs._robot_loops",
        "robot_euler": "signs._robot_loops",
        "NO_BOX": "_compiled.core",
        "count_in_disk": "geometry._target_loops",
    },
    "cut_cells": "geometry.cut_cells",
    "density": "crowds.kde",
    "density_crowd": "crowds.density_crowd",
    "domain": "geometry.domain",
    "evacuation": "controllers.evacuation",
    "evacuation_measures": "simulation.evacuation_measures",
    "exit_loops": "geometry._exit_loops",
    "exits": "geometry.exits",
    "fp_compiled": "fokker_planck._sweeps",
    "fp_stepping": "fokker_planck.stepping",
    "geodesic": "geometry.geodesic",
    "grid": "geometry.grid",
    "guidance": "crowds.guidance",
    "interaction": "signs.interaction",
    "jupedsim_api": "crowds._jupedsim_api",
    "kde_loops": "crowds._kde_loops",
    "kernels": "signs.kernels",
    "law_loops": "controllers._law_loops",
    "lazy": "_namespace",
    "local_sensing": "controllers.local_sensing",
    "local_view": "crowds.local_view",
    "loop": "simulation.loop",
    "metrics": {
        "gaussian_target": "geometry.target",
        "target_region_radius": "geometry.target",
        "fraction_in_disk": "geometry.target",
        "wasserstein2_to_grid_density": "simulation.wasserstein",
        "w2_block_size": "simulation.wasserstein",
        "max_body_overlap": "crowds.jupedsim_engine",
        "fit_slope": "workflows.mean_field_limit",
    },
    "observers": "simulation.observers",
    "pedestrian_crowd": (
        "crowds.jupedsim_engine",
        {"PedestrianCrowd": "JuPedSimEngine"},
    ),
    "plan": "geometry.plan",
    "plan_dxf": "geometry.dxf",
    "plan_loops": {
        "SIGHT_EPS": "geometry._sight_loops",
        "segments_clear": "geometry._sight_loops",
        "sight_row": "geometry._sight_loops",
        "cell_index": "geometry._sight_loops",
        "masked_face_kernels": "signs._masked_loops",
        "face_moments": "signs._masked_loops",
        "owners": "controllers._coverage_loops",
        "in_view": "crowds._view_loops",
        "turn_walkers": "crowds._view_loops",
    },
    "region": "geometry.region",
    "result": "simulation.result",
    "robots": "signs.robots",
    "sampled_field": "signs.sampled_field",
    "scenario": (
        "scenarios.scenario",
        {
            "PedestrianSpec": "crowds.jupedsim_engine:JuPedSimOptions",
            "PEDESTRIAN_MODELS": "crowds.jupedsim_engine:PEDESTRIAN_MODELS",
        },
    ),
    "scenario_sections": (
        "scenarios.sections",
        {
            "PedestrianSpec": "crowds.jupedsim_engine:JuPedSimOptions",
            "PEDESTRIAN_MODELS": "crowds.jupedsim_engine:PEDESTRIAN_MODELS",
        },
    ),
    "sight": "geometry.sight",
    "static_signs": "controllers.static_signs",
    "stragglers": "simulation.stragglers",
    "summary": "simulation.summary",
    "sweep": "workflows.sweep",
    "sweep_plan": "workflows.sweep_plan",
    "trajectories": "io.trajectories",
    "validation": {
        "region_keywords": "geometry.region",
        "region_from_table": "geometry.region",
        "num": "errors",
        "range_text": "errors",
        "integer": "errors",
        "choice": "errors",
        "point": "errors",
        "optional_limit": "errors",
        "all_numbers": "errors",
        "module_list": "errors",
    },
    "vector_exp": "_compiled.vector_exp",
    "wall_index": "geometry.walls",
    "wall_loops": "geometry._wall_loops",
    "warmup": "_compiled.warmup",
}
"""Old module (under ``meanfield.``) -> where its names live now: a module path (relative to
``meanfield``), a pair (module path, {old name: new name}) for renamed names (a new name
``"module:name"`` lives in another module), or, for a module split in several,
``{name: module path}``.  The old modules ``cli``, ``io``, ``plotting`` and ``fokker_planck``
are now packages of the same name, whose namespaces give the old names."""


def _new_place(package: str, table: dict[str, Any], old: str, name: str) -> tuple[str, str] | None:
    """The module and the name that ``<package>.<old>.<name>`` became (None: it has no such name);
    ``table`` is a table of moved modules shaped as :data:`MOVED`."""
    entry = table[old]
    if isinstance(entry, str):
        return f"{package}.{entry}", name
    if isinstance(entry, tuple):
        module, renamed = entry
        new = renamed.get(name, name)
        if ":" in new:
            module, _, new = new.partition(":")
        return f"{package}.{module}", new
    module = entry.get(name)
    return None if module is None else (f"{package}.{module}", name)


def _where(package: str, entry: Any) -> str:
    """The new module(s) of an old one, for messages."""
    if isinstance(entry, dict):
        return " and ".join(sorted({f"{package}.{m}" for m in entry.values()}))
    return f"{package}.{entry if isinstance(entry, str) else entry[0]}"


def _warn(what: str, instead: str) -> None:
    """Warn that ``what`` is deprecated (and removed in :data:`meanfield.errors.REMOVED_IN`), attributed to the first
    frame outside the import machinery and this module (the user's line)."""
    from meanfield.errors import MeanfieldDeprecationWarning, deprecation_message

    message = deprecation_message(what, instead)

    def skipped(f: Any) -> bool:
        return f.f_code.co_filename == __file__ or "importlib" in f.f_code.co_filename

    def internal(f: Any) -> bool:  # frames that warnings.warn itself skips without counting them
        return "importlib" in f.f_code.co_filename and "_bootstrap" in f.f_code.co_filename

    frame, level = sys._getframe(1), 2  # level 2: the caller of _warn
    while frame is not None and skipped(frame):
        frame = frame.f_back
        if frame is not None and not internal(frame):
            level += 1
    warnings.warn(message, MeanfieldDeprecationWarning, stacklevel=level)


class _MovedModule(types.ModuleType):
    """An old module path: each name read from it is looked up at its new place, with a warning."""

    def __init__(self, name: str, finder: _MovedFinder):
        super().__init__(name)
        self._finder = finder

    def _entry(self) -> Any:
        return self._finder.table[self.__name__.removeprefix(self._finder.package + ".")]

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name == "_finder":
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        f = self._finder
        place = _new_place(f.package, f.table, self.__name__.removeprefix(f.package + "."), name)
        module = None if place is None else importlib.import_module(place[0])
        if place is None or not hasattr(module, place[1]):
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        _warn(f"{self.__name__}.{name}", f"use {place[0]}.{place[1]}")
        return getattr(module, place[1])

    def __dir__(self) -> list[str]:
        entry = self._entry()
        if isinstance(entry, dict):
            return sorted(entry)
        module = entry if isinstance(entry, str) else entry[0]
        return sorted(getattr(importlib.import_module(f"{self._finder.package}.{module}"), "__all__", ()))


class _MovedFinder:
    """Finds ``<package>.<old>`` for every old module of its table (and nothing else): a meta-path
    finder and its loader (the protocols of :mod:`importlib.abc`, without importing it at start-up)."""

    def __init__(self, package: str, table: dict[str, Any]):
        self.package, self.table = package, table

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        prefix = self.package + "."
        if not fullname.startswith(prefix) or fullname[len(prefix) :] not in self.table:
            return None
        from importlib.machinery import ModuleSpec

        return ModuleSpec(fullname, self)

    def create_module(self, spec: Any) -> types.ModuleType:
        return _MovedModule(spec.name, self)

    def exec_module(self, module: types.ModuleType) -> None:
        where = _where(self.package, self.table[module.__name__.removeprefix(self.package + ".")])
        module.__doc__ = f"Deprecated: moved to {where}."
        _warn(f"the module {module.__name__}", f"its names moved to {where}")


def install_moved_modules(package: str = "meanfield", table: dict[str, Any] | None = None) -> None:
    """Let the old module paths of ``package`` be imported, once per process (``meanfield`` calls it
    with :data:`MOVED`; ``analysis`` with its own table, :mod:`analysis._moved`).

    ``table`` maps each old module (under ``package``) to its new place, shaped as :data:`MOVED`.
    """
    if any(isinstance(f, _MovedFinder) and f.package == package for f in sys.meta_path):
        return
    sys.meta_path.append(_MovedFinder(package, MOVED if table is None else table))
