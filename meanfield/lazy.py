"""Package namespaces whose names are imported on first use (PEP 562).

``import meanfield`` (and ``analysis``, ``verification``) then costs milliseconds instead of
SciPy's, xarray's and the solvers' import time, and ``meanfield --help`` stays quick; a name
such as ``meanfield.run`` is imported the first time it is read, then kept.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

__all__ = ["lazy_namespace"]


def lazy_namespace(
    package: str, namespace: dict[str, Any], names: dict[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for a package whose ``names`` map to the modules defining them.

    Usage, in a package's ``__init__.py``::

        __getattr__, __dir__ = lazy_namespace(__name__, globals(), {"run": "meanfield.loop", ...})
    """

    def __getattr__(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value  # once imported, a plain attribute
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *names})

    return __getattr__, __dir__
