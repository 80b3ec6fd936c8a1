"""Atomic output: a file is either complete or absent, never half-written.

Each writer writes to a temporary file in the destination's directory, flushes it to
disk and renames it over the destination (``os.replace`` is atomic on POSIX).
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["atomic_write_text", "atomic_write_json", "atomic_write_with", "save_figure"]


def atomic_write_with(path: Path, writer: Callable[[Path], None]) -> Path:
    """Call ``writer(tmp_path)`` then atomically move ``tmp_path`` to ``path``.

    The temporary file keeps ``path``'s suffix (some writers choose the format by it).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".part{path.suffix}", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp_path, 0o666 & ~umask)
    try:
        writer(tmp_path)
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return atomic_write_with(Path(path), lambda p: p.write_text(text))


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def atomic_write_json(path: Path, data: Any) -> Path:
    """Write ``data`` as indented JSON atomically (numpy scalars and arrays allowed)."""
    return atomic_write_text(Path(path), json.dumps(data, indent=2, default=_json_default) + "\n")


def save_figure(fig: Any, path: str | Path, *, dpi: int = 110, close: bool = True, **kwargs: Any) -> Path:
    """Save a matplotlib figure atomically (the one figure writer of the toolkit).

    The format follows ``path``'s suffix (PNG by default); ``kwargs`` go to
    :meth:`matplotlib.figure.Figure.savefig` (e.g. ``bbox_inches="tight"``).  The figure is
    closed afterwards unless ``close=False``, so that scripts and sweeps do not pile up figures.
    """
    path = Path(path)
    fmt = kwargs.pop("format", path.suffix.lstrip(".") or "png")
    out = atomic_write_with(path, lambda p: fig.savefig(p, dpi=dpi, format=fmt, **kwargs))
    if close:
        import matplotlib.pyplot as plt

        plt.close(fig)
    return out
