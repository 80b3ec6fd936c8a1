"""Atomic output: a file is either complete or absent, never half-written; a folder's
``summary.json`` describes exactly the run beside it.

Each writer writes to a temporary file in the destination's directory, flushes it to
disk and renames it over the destination (``os.replace`` is atomic on POSIX).
:func:`write_complete_folder` writes a run's folder (an earlier run's summary removed
first, ``summary.json`` last with each file's SHA-256), :func:`check_complete_folder`
checks one; :func:`check_output_dir` checks an ``--out`` before any work starts.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = [
    "atomic_write_text",
    "atomic_write_json",
    "atomic_write_with",
    "save_figure",
    "subplots",
    "check_output_dir",
    "check_output_file",
    "write_complete_folder",
    "check_complete_folder",
    "sha256_of",
    "folder_lock",
]


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


def strict_json(data: Any) -> Any:
    """``data`` with every non-finite number (``inf``, ``nan``, in floats, numpy scalars and arrays) as None.

    JSON has no infinity and no NaN: a strict reader refuses ``Infinity``, so they are written as ``null``.
    """
    import numpy as np

    if isinstance(data, dict):
        return {k: strict_json(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [strict_json(v) for v in data]
    if isinstance(data, np.ndarray):
        return strict_json(data.tolist())
    if isinstance(data, np.generic):
        data = data.item()
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


def atomic_write_json(path: Path, data: Any) -> Path:
    """Write ``data`` as indented, strict JSON atomically (numpy scalars and arrays allowed; a non-finite number is
    written as ``null``, :func:`strict_json`)."""
    text = json.dumps(strict_json(data), indent=2, default=_json_default, allow_nan=False)
    return atomic_write_text(Path(path), text + "\n")


def save_figure(fig: Any, path: str | Path, *, dpi: int = 110, close: bool = True, **kwargs: Any) -> Path:
    """Save a matplotlib figure atomically (the one figure writer of the toolkit).

    The format follows ``path``'s suffix (PNG by default); ``kwargs`` go to
    :meth:`matplotlib.figure.Figure.savefig` (e.g. ``bbox_inches="tight"``).  The figure is
    closed afterwards unless ``close=False``, so that scripts and sweeps do not pile up figures.
    """
    path = Path(path)
    fmt = kwargs.pop("format", path.suffix.lstrip(".") or "png")
    out = atomic_write_with(path, lambda p: fig.savefig(p, dpi=dpi, format=fmt, **kwargs))
    if close and getattr(fig.canvas, "manager", None) is not None:  # a pyplot figure: let pyplot forget it
        import matplotlib.pyplot as plt

        plt.close(fig)
    return out


def subplots(
    nrows: int = 1,
    ncols: int = 1,
    *,
    figsize: tuple[float, float] | None = None,
    constrained_layout: bool = False,
    squeeze: bool = True,
    **kwargs: Any,
) -> tuple[Any, Any]:
    """A figure and its axes, like :func:`matplotlib.pyplot.subplots` but without pyplot.

    The figure belongs to no GUI backend and is never registered with pyplot, so drawing it
    neither changes nor needs the user's backend (a notebook's inline plots stay on); it is
    written by :func:`save_figure` and, returned into a notebook cell, displays as usual.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained" if constrained_layout else None)
    return fig, fig.subplots(nrows, ncols, squeeze=squeeze, **kwargs)


# ---------------------------------------------------------------------- output folders
def _nearest_existing(path: Path) -> Path:
    """The deepest of ``path`` and its parents that exists, a symbolic link that leads nowhere included."""
    p = path.absolute()
    while not os.path.lexists(p) and p != p.parent:
        p = p.parent
    return p


ROOM_FOR_FILES = 300
"""Bytes an output folder's path leaves under the system's ``PATH_MAX`` for what a command writes in
it: a temporary file ``.<name>.XXXXXXXX.part.<suffix>``, a sweep's ``runs/<key>.json`` (its key at
most about 140 bytes)."""


def _path_limits() -> tuple[int, int]:
    """The system's longest name of one path component and longest path, in bytes (255 and 4096 on Linux)."""
    try:
        return os.pathconf("/", "PC_NAME_MAX"), os.pathconf("/", "PC_PATH_MAX")
    except (OSError, ValueError, AttributeError):  # pragma: no cover - no pathconf (Windows)
        return 255, 4096


def _shown(text: str) -> str:
    """A path short enough for a message: its start and end, and its length."""
    return text if len(text) <= 80 else f"{text[:40]}...{text[-24:]} ({len(text)} characters)"


def _check_path_length(path: Path, name: str) -> None:
    """Refuse a path the system cannot create, before any call that would raise ``OSError`` on it."""
    from meanfield.errors import ParameterError

    name_max, path_max = _path_limits()
    full = os.fsencode(path.absolute())
    longest = max((len(os.fsencode(part)) for part in path.parts), default=0)
    if longest > name_max:
        raise ParameterError(
            name, _shown(str(path)), f"a folder path whose every name is at most {name_max} bytes (one has {longest})"
        )
    if len(full) + ROOM_FOR_FILES > path_max:
        raise ParameterError(
            name,
            _shown(str(path)),
            f"a folder path of at most {path_max - ROOM_FOR_FILES} bytes from the root (this one has {len(full)}): "
            f"the system's limit is {path_max}, and the files written in the folder need room under it",
        )


def check_output_names(folder: str | Path, names: tuple[str, ...], name: str = "--out") -> None:
    """Refuse, before any work, a ``folder`` where one of the files a run will write, ``names``, is a folder
    (or anything but a file): the run would find it only when saving, after all its work."""
    from meanfield.errors import ParameterError

    folder = Path(folder)
    for file in names:
        path = folder / file
        if path.exists() and not path.is_file():
            raise ParameterError(
                name, str(folder), f"a folder where the run can write {file} ({path} is a folder, not a file)"
            )


def check_output_dir(path: str | Path, name: str = "--out") -> Path:
    """``path`` as a folder a run can write into, checked before any work starts (nothing is created).

    Raises
    ------
    ParameterError
        Named ``name``: the path is a file, or lies under a file, or the folder (or the
        nearest existing one above it) is not writable, or the path is longer than the system
        allows (a name over ``NAME_MAX`` bytes, or a path that leaves less than
        :data:`ROOM_FOR_FILES` bytes under ``PATH_MAX``), or the system refuses to look at it.
    """
    from meanfield.errors import ParameterError

    if isinstance(path, str) and not path.strip():
        raise ParameterError(name, path, "a folder to write into (an empty path names none; '.' is the current one)")
    path = Path(path)
    _check_path_length(path, name)
    try:
        if path.is_symlink() and not path.exists():
            target = os.readlink(path)
            raise ParameterError(
                name, str(path), f"a folder to write into (a symbolic link to {target}, which is missing)"
            )
        base = _nearest_existing(path)
        if base.is_symlink() and not base.exists():  # a link above the folder that leads nowhere
            raise ParameterError(
                name,
                str(path),
                f"a folder to write into ({base} is a symbolic link to {os.readlink(base)}, which is missing "
                "or a loop of links)",
            )
        if base == path.absolute() and not base.is_dir():
            raise ParameterError(name, str(path), "a folder to write into (this path is a file)")
        if not base.is_dir():
            raise ParameterError(name, str(path), f"a folder to write into ({base} is a file, not a folder)")
        writable = os.access(base, os.W_OK | os.X_OK)
    except OSError as exc:  # a loop of links, a name the file system refuses, ...: not a traceback
        raise ParameterError(
            name, _shown(str(path)), f"a folder the system can write into ({exc.strerror or exc})"
        ) from None
    if not writable:
        raise ParameterError(name, str(path), f"a folder to write into ({base} is not writable)")
    return path


@contextmanager
def folder_lock(path: str | Path, name: str = "--out") -> Iterator[Path]:
    """Hold the output folder for one run: an exclusive lock (``flock``) on the folder itself while
    the block runs, so that a second run into the same folder is refused at once instead of
    mixing its files with the first's.  The folder is created if needed, and removed again if the
    block wrote nothing into it (a run stopped before it saved).  The lock goes with the process:
    a run killed with SIGKILL leaves no stale lock.  Without ``fcntl`` (not POSIX) nothing is locked.

    Raises
    ------
    ParameterError
        Named ``name`` when another run holds the folder.
    """
    from meanfield.errors import ParameterError

    path = Path(path)
    created = not path.exists()
    path.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        fcntl = None
    fd = os.open(path, os.O_RDONLY)
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise ParameterError(
                    name, str(path), "a folder no other run is writing into (another meanfield run holds its lock)"
                ) from None
        yield path
    finally:
        os.close(fd)  # releases the lock
        if created and path.is_dir() and not any(path.iterdir()):
            path.rmdir()


def check_output_file(path: str | Path, name: str = "--out") -> Path:
    """``path`` as a file that can be (re)written, checked before any work starts."""
    from meanfield.errors import ParameterError

    path = Path(path)
    check_output_dir(path.parent, name)  # first: refuses a path too long to ask the system about
    if len(os.fsencode(path.name)) > _path_limits()[0]:
        raise ParameterError(name, _shown(str(path)), f"a file name of at most {_path_limits()[0]} bytes")
    if path.is_dir():
        raise ParameterError(name, str(path), "a file path (this is a folder)")
    return path


def sha256_of(path: Path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


SAVE_JOURNAL = ".meanfield-save.json"
"""The journal of a save under way in a run folder (:func:`write_complete_folder`)."""


def write_complete_folder(
    out: str | Path, write_files: Callable[[Path], dict[str, Path]], summary: dict[str, Any]
) -> dict[str, Path]:
    """Write one run into ``out`` so that a ``summary.json`` there always describes what is beside it.

    0. A save that was killed (it left its journal, ``.meanfield-save.json``) is cleaned up: the
       files it wrote, which no summary lists, are removed (the folder's other files stay).
    1. An earlier run's ``summary.json`` is removed first, then the files it listed: from
       here until step 3 the folder holds no summary, i.e. no complete run.  The journal is
       written: the folder's files before this save.
    2. ``write_files(out)`` writes this run's files (each atomically) and returns them by name.
    3. ``summary.json`` is written last, with ``files``: each file's name and SHA-256, so a
       reader can check that every file beside it belongs to this run
       (:func:`check_complete_folder`); then the journal is removed.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for tmp in out.glob(".*.part*"):  # temporaries of a write that was killed (atomic_write_with's names)
        tmp.unlink(missing_ok=True)
    journal = out / SAVE_JOURNAL
    if journal.exists():  # a save was killed: what it wrote is not listed by any summary, remove it
        try:
            before = set(json.loads(journal.read_text()).get("before", ()))
        except (OSError, ValueError, AttributeError):
            before = None
        if before is not None:
            for stray in out.iterdir():
                if stray.is_file() and stray.name not in before and stray != journal:
                    stray.unlink()
        journal.unlink()
    old = out / "summary.json"
    if old.exists():
        try:
            listed = json.loads(old.read_text()).get("files", {})
        except (OSError, ValueError, AttributeError):
            listed = {}
        old.unlink()
        for name in listed if isinstance(listed, dict) else ():
            stale = out / name
            if stale.parent == out and stale.is_file():
                stale.unlink()
    # what the folder holds before this save writes: a save killed from here on leaves the journal,
    # and the next save removes whatever is not in it (the user's own files stay)
    atomic_write_json(journal, {"before": sorted(p.name for p in out.iterdir() if p.is_file())})
    paths = write_files(out)
    files = {p.name: sha256_of(p) for p in paths.values()}
    paths["summary"] = atomic_write_json(out / "summary.json", {**summary, "files": files})
    journal.unlink()
    return paths


def check_complete_folder(folder: str | Path) -> list[str]:
    """What is wrong with a folder written by :func:`write_complete_folder` (an empty list: nothing).

    Checks that ``summary.json`` exists (else the run is incomplete: interrupted while saving,
    or never finished), and that every file it lists exists with the listed SHA-256.
    """
    folder = Path(folder)
    summary = folder / "summary.json"
    if not summary.exists():
        return [f"{folder}: no summary.json (no complete run: interrupted while saving, or never saved)"]
    try:
        listed = json.loads(summary.read_text()).get("files")
    except (OSError, ValueError, AttributeError) as exc:
        return [f"{summary}: unreadable ({exc})"]
    if not isinstance(listed, dict):
        return [f"{summary}: no 'files' list (written before files were checked, or not by meanfield)"]
    problems = []
    for name, digest in listed.items():
        p = folder / name
        if not p.is_file():
            problems.append(f"{p}: listed in summary.json but missing")
        elif sha256_of(p) != digest:
            problems.append(f"{p}: not the file summary.json lists (another run's, or changed)")
    return problems
