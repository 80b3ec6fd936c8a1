"""Package namespaces: names imported on first use (PEP 562), and the modules that moved.

``import meanfield`` (and ``analysis``, ``verification``) costs milliseconds instead of
SciPy's, xarray's and the solvers' import time, and ``meanfield --help`` stays quick; a name
such as ``meanfield.run`` is imported the first time it is read, then kept
(:func:`lazy_namespace`).

Modules that moved into the subpackages keep working at their old paths for one release
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
            _warn(f"{package}.{name} is deprecated: use {module}.{new_name}")
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


def _new_place(old: str, name: str) -> tuple[str, str] | None:
    """The module and the name that ``meanfield.<old>.<name>`` became (None: it has no such name)."""
    entry = MOVED[old]
    if isinstance(entry, str):
        return f"meanfield.{entry}", name
    if isinstance(entry, tuple):
        module, renamed = entry
        new = renamed.get(name, name)
        if ":" in new:
            module, _, new = new.partition(":")
        return f"meanfield.{module}", new
    module = entry.get(name)
    return None if module is None else (f"meanfield.{module}", name)


def _warn(message: str) -> None:
    """Warn, attributed to the first frame outside the import machinery and this module (the user's line)."""
    from meanfield.errors import MeanfieldDeprecationWarning

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

    def __getattr__(self, name: str) -> Any:
        old = self.__name__.removeprefix("meanfield.")
        place = None if name.startswith("__") else _new_place(old, name)
        if place is None:
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        module, new_name = place
        value = getattr(importlib.import_module(module), new_name)
        _warn(f"{self.__name__}.{name} is deprecated: use {module}.{new_name}")
        return value

    def __dir__(self) -> list[str]:
        entry = MOVED[self.__name__.removeprefix("meanfield.")]
        if isinstance(entry, dict):
            return sorted(entry)
        module = entry if isinstance(entry, str) else entry[0]
        return sorted(getattr(importlib.import_module(f"meanfield.{module}"), "__all__", ()))


class _MovedFinder:
    """Finds ``meanfield.<old>`` for every old module in :data:`MOVED` (and nothing else): a meta-path
    finder and its loader (the protocols of :mod:`importlib.abc`, without importing it at start-up)."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if not fullname.startswith("meanfield.") or fullname.removeprefix("meanfield.") not in MOVED:
            return None
        from importlib.machinery import ModuleSpec

        return ModuleSpec(fullname, self)

    def create_module(self, spec: Any) -> types.ModuleType:
        return _MovedModule(spec.name)

    def exec_module(self, module: types.ModuleType) -> None:
        old = module.__name__.removeprefix("meanfield.")
        entry = MOVED[old]
        if isinstance(entry, dict):
            where = " and ".join(sorted({f"meanfield.{m}" for m in entry.values()}))
        else:
            where = f"meanfield.{entry if isinstance(entry, str) else entry[0]}"
        module.__doc__ = f"Deprecated: moved to {where}."
        _warn(f"the module {module.__name__} is deprecated: its names moved to {where}")


_FINDER = _MovedFinder()


def install_moved_modules() -> None:
    """Let the old module paths of :data:`MOVED` be imported (once per process; ``meanfield`` calls it)."""
    if _FINDER not in sys.meta_path:
        sys.meta_path.append(_FINDER)
