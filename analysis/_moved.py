"""The modules of ``analysis`` that moved into its subpackages, kept at their old paths for one release.

The NMPC baseline now lives in :mod:`analysis.nmpc` and the pedestrian measurements in
:mod:`analysis.pedestrians`.  ``from analysis.nmpc_qp import InputQP`` still gives the class,
with a :class:`~meanfield.errors.MeanfieldDeprecationWarning` naming its new place
(``analysis.nmpc.qp``), as :mod:`meanfield._namespace` does for meanfield's old modules
(:data:`MOVED`, :func:`install_moved_modules`; ``analysis`` calls it).

The old module ``analysis.nmpc`` is now the package of the same name, whose namespace gives
its names without a warning.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from typing import Any

__all__ = ["MOVED", "install_moved_modules"]

PACKAGE = "analysis"

MOVED: dict[str, str] = {
    "nmpc_condensed": "nmpc.condensed",
    "nmpc_ipopt": "nmpc.ipopt",
    "nmpc_model": "nmpc.prediction_model",
    "nmpc_options": "nmpc.options",
    "nmpc_plan": "nmpc.plan",
    "nmpc_qp": "nmpc.qp",
    "nmpc_sqp": "nmpc.sqp",
    "pedestrian_cli": "pedestrians.cli",
    "pedestrian_figures": "pedestrians.figures",
    "pedestrian_flow": "pedestrians.flow",
    "pedestrian_metrics": "pedestrians.metrics",
}
"""Old module (under ``analysis.``) -> its new module (relative to ``analysis``); the names are unchanged."""


def _new_module(old_fullname: str) -> str:
    """``analysis.nmpc_qp`` -> ``analysis.nmpc.qp``."""
    return f"{PACKAGE}.{MOVED[old_fullname.removeprefix(PACKAGE + '.')]}"


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
    """An old module path: each name read from it is read from its new module, with a warning."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        new = _new_module(self.__name__)
        module = importlib.import_module(new)
        if not hasattr(module, name):
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        value = getattr(module, name)
        _warn(f"{self.__name__}.{name} is deprecated: use {new}.{name}")
        return value

    def __dir__(self) -> list[str]:
        return sorted(getattr(importlib.import_module(_new_module(self.__name__)), "__all__", ()))


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``analysis.<old>`` for every old module in :data:`MOVED` (and nothing else)."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if not fullname.startswith(PACKAGE + ".") or fullname.removeprefix(PACKAGE + ".") not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: Any) -> types.ModuleType:
        return _MovedModule(spec.name)

    def exec_module(self, module: types.ModuleType) -> None:
        new = _new_module(module.__name__)
        module.__doc__ = f"Deprecated: moved to {new}."
        _warn(f"the module {module.__name__} is deprecated: its names moved to {new}")


_FINDER = _MovedFinder()


def install_moved_modules() -> None:
    """Let the old module paths of :data:`MOVED` be imported (once per process; ``analysis`` calls it)."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_FINDER)
