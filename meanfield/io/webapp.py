"""JuPedSim web-app exports as files: read one safely, and write it back with a run's trajectory.

JuPedSim's web editor exports a scenario as a ZIP holding two files at its root, a JSON (the
exits, distributions of people, journeys and the model's settings) and a WKT (the walkable
area).  The same pair may sit in a folder, or the JSON may carry the geometry itself, under the
key ``walkable_area_wkt`` ("self-contained"): the three shapes that ``jupedsim_scenarios.load_scenario``
(jupedsim-scenarios 0.7) reads.  :func:`read_export` reads any of them into a :class:`WebAppExport`,
the export's bytes and its parsed JSON; what the export *means* for a run is
:mod:`meanfield.scenarios.webapp`.

An export is data from elsewhere, so the archive is read defensively: a member whose path is
absolute or climbs out of the archive (``../``) is refused, as is an archive that declares more
than :data:`MAX_ARCHIVE_BYTES` or a member read (the JSON, the WKT) larger than
:data:`MAX_MEMBER_BYTES`, declared or actually decompressed (a ZIP bomb may lie about its sizes).
Every refusal is a :class:`~meanfield.errors.ParameterError` naming the file and what is wrong.

:func:`write_export_with_trajectory` writes the export back with a run's ``trajectory.sqlite``
beside its JSON and WKT (the file jupedsim-scenarios' ``jps-scenarios run EXPORT --out
trajectory.sqlite`` writes), atomically.
"""

from __future__ import annotations

import json
import posixpath
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from meanfield.errors import ParameterError
from meanfield.io.atomic import atomic_write_with

__all__ = [
    "WebAppExport",
    "read_export",
    "looks_like_export",
    "write_export_with_trajectory",
    "MAX_MEMBER_BYTES",
    "MAX_ARCHIVE_BYTES",
    "MAX_MEMBERS",
    "TRAJECTORY_MEMBER",
]

MAX_MEMBER_BYTES = 64 * 2**20
"""The largest JSON or WKT read from an export (64 MiB; an export drawn in the web app is a few kB to a few MB)."""
MAX_ARCHIVE_BYTES = 4 * 2**30
"""The most an archive may declare in all (4 GiB: a run's trajectory beside the export included)."""
MAX_MEMBERS = 1000
"""The most members an archive may hold."""
TRAJECTORY_MEMBER = "trajectory.sqlite"
"""The name of the run's trajectory in the archive :func:`write_export_with_trajectory` writes."""


@dataclass(frozen=True)
class WebAppExport:
    """A JuPedSim web-app export as read (:func:`read_export`).

    Attributes
    ----------
    source : Path
        The ZIP, folder or JSON file it was read from.
    data : dict
        The JSON, parsed.
    walkable_wkt : str
        The walkable area's WKT (the WKT file's text, or the JSON's ``walkable_area_wkt``).
    json_name, wkt_name : str
        The names of the JSON and WKT in the archive or folder (``wkt_name`` is made up, from the JSON's
        name, for a self-contained JSON).
    json_bytes, wkt_bytes : bytes
        Their bytes as read, written back unchanged by :func:`write_export_with_trajectory`.
    """

    source: Path
    data: dict[str, Any]
    walkable_wkt: str
    json_name: str
    wkt_name: str
    json_bytes: bytes
    wkt_bytes: bytes


def _refuse(source: Path, what: str) -> ParameterError:
    return ParameterError("scenario", str(source), f"a JuPedSim web-app export ({what})")


def looks_like_export(spec: str | Path) -> bool:
    """Whether ``spec`` names what :func:`read_export` reads rather than a TOML scenario: an existing ``.zip`` or
    ``.json`` file, or a folder."""
    path = Path(spec)
    return path.is_dir() or (path.is_file() and path.suffix.lower() in (".zip", ".json"))


def read_export(path: str | Path) -> WebAppExport:
    """Read a JuPedSim web-app export: a ZIP or a folder holding one ``*.json`` and one ``*.wkt``, or a
    self-contained JSON (with ``walkable_area_wkt``).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    WebAppExport

    Raises
    ------
    ParameterError
        Named ``scenario``, its value the file: not a ZIP, not one JSON and one WKT, a member path that escapes
        the archive, sizes above :data:`MAX_MEMBER_BYTES` or :data:`MAX_ARCHIVE_BYTES`, a JSON that is not an
        object, text that is not UTF-8.
    """
    source = Path(path)
    if source.is_dir():
        return _read_folder(source)
    if not source.is_file():
        raise _refuse(source, "no such file or folder")
    if source.suffix.lower() == ".json":
        raw = _read_file(source, source)
        data = _parse_json(source, source.name, raw)
        wkt = data.get("walkable_area_wkt")
        if not isinstance(wkt, str) or not wkt.strip():
            raise _refuse(
                source,
                "a JSON on its own must carry the walkable area as 'walkable_area_wkt'; for a JSON and a WKT "
                "give their folder or their ZIP",
            )
        wkt_bytes = wkt.strip().encode()
        return WebAppExport(source, data, wkt.strip(), source.name, f"{source.stem}.wkt", raw, wkt_bytes)
    return _read_zip(source)


def _read_file(source: Path, file: Path) -> bytes:
    size = file.stat().st_size
    if size > MAX_MEMBER_BYTES:
        raise _refuse(source, f"{file.name} is {size} bytes, more than the {MAX_MEMBER_BYTES} read from an export")
    with open(file, "rb") as fh:
        raw = fh.read(MAX_MEMBER_BYTES + 1)
    if len(raw) > MAX_MEMBER_BYTES:
        raise _refuse(source, f"{file.name} is more than the {MAX_MEMBER_BYTES} bytes read from an export")
    return raw


def _one(source: Path, names: list[str], kind: str) -> str:
    if len(names) != 1:
        found = ", ".join(names) if names else "none"
        raise _refuse(source, f"exactly one {kind} file; found {found}")
    return names[0]


def _parse_json(source: Path, name: str, raw: bytes) -> dict[str, Any]:
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _refuse(source, f"{name} is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise _refuse(source, f"{name} holds a JSON {type(data).__name__}, not an object")
    return data


def _text(source: Path, name: str, raw: bytes) -> str:
    try:
        return raw.decode("utf-8").strip()
    except UnicodeDecodeError as exc:
        raise _refuse(source, f"{name} is not UTF-8 text: {exc}") from None


def _read_folder(source: Path) -> WebAppExport:
    json_file = source / _one(source, sorted(p.name for p in source.glob("*.json")), "*.json")
    wkt_file = source / _one(source, sorted(p.name for p in source.glob("*.wkt")), "*.wkt")
    raw_json, raw_wkt = _read_file(source, json_file), _read_file(source, wkt_file)
    data = _parse_json(source, json_file.name, raw_json)
    return WebAppExport(source, data, _text(source, wkt_file.name, raw_wkt), json_file.name, wkt_file.name,
                        raw_json, raw_wkt)  # fmt: skip


def _safe_member(source: Path, name: str) -> None:
    """Refuse a member whose path is absolute or leaves the archive's folder (``../``)."""
    normal = posixpath.normpath(name.replace("\\", "/"))
    if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":") or normal == ".." or normal.startswith("../"):
        raise _refuse(source, f"the member {name!r} has a path that leaves the archive's folder")


def _read_member(source: Path, zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> bytes:
    if info.file_size > MAX_MEMBER_BYTES:
        raise _refuse(source, f"{info.filename} declares {info.file_size} bytes, more than the {MAX_MEMBER_BYTES} "
                              "read from an export")  # fmt: skip
    with zf.open(info) as fh:
        raw = fh.read(MAX_MEMBER_BYTES + 1)  # the declared size may lie: the bytes read are capped too
    if len(raw) > MAX_MEMBER_BYTES:
        raise _refuse(source, f"{info.filename} decompresses to more than the {MAX_MEMBER_BYTES} bytes read "
                              "from an export (a ZIP bomb?)")  # fmt: skip
    return raw


def _read_zip(source: Path) -> WebAppExport:
    try:
        zf = zipfile.ZipFile(source)
    except (zipfile.BadZipFile, OSError) as exc:
        raise _refuse(source, f"not a ZIP archive: {exc}") from None
    with zf:
        infos = [i for i in zf.infolist() if not i.is_dir()]
        if len(infos) > MAX_MEMBERS:
            raise _refuse(source, f"{len(infos)} members, more than {MAX_MEMBERS}")
        for info in infos:
            _safe_member(source, info.filename)
        declared = sum(i.file_size for i in infos)
        if declared > MAX_ARCHIVE_BYTES:
            raise _refuse(source, f"its members declare {declared} bytes, more than {MAX_ARCHIVE_BYTES} (a ZIP bomb?)")
        by_name = {i.filename: i for i in infos}
        json_name = _one(source, sorted(n for n in by_name if n.lower().endswith(".json")), "*.json")
        wkt_name = _one(source, sorted(n for n in by_name if n.lower().endswith(".wkt")), "*.wkt")
        try:
            raw_json = _read_member(source, zf, by_name[json_name])
            raw_wkt = _read_member(source, zf, by_name[wkt_name])
        except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, RuntimeError, OSError) as exc:
            raise _refuse(source, f"a member cannot be read: {exc}") from None
    data = _parse_json(source, json_name, raw_json)
    return WebAppExport(source, data, _text(source, wkt_name, raw_wkt), json_name, wkt_name, raw_json, raw_wkt)


def write_export_with_trajectory(export: WebAppExport, trajectory: str | Path, out: str | Path) -> Path:
    """Write ``export`` (its JSON and WKT, byte for byte, under their names) and a run's trajectory as
    ``trajectory.sqlite`` (:data:`TRAJECTORY_MEMBER`) into the ZIP ``out``, atomically: a ZIP that
    ``jupedsim_scenarios.load_scenario`` reads as the export, and whose trajectory PedPy and JuPedSim's viewer load.

    Members are written flat, at the archive's root (a JSON and a WKT inside a folder of the original
    archive come out at the root).

    Parameters
    ----------
    export : WebAppExport
    trajectory : str or Path
        The run's trajectories in JuPedSim's SQLite format (``trajectories.sqlite`` of a run folder).
    out : str or Path
        The ZIP to write (replaced if it exists; nothing is left half-written if the process stops).

    Returns
    -------
    Path
        ``out``.
    """
    trajectory = Path(trajectory)
    if not trajectory.is_file():
        raise ParameterError("trajectory", str(trajectory), "a run's trajectories.sqlite (the run recorded no humans?)")
    names = [posixpath.basename(export.json_name), posixpath.basename(export.wkt_name)]

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            zf.writestr(names[0], export.json_bytes)
            zf.writestr(names[1], export.wkt_bytes)
            zf.write(trajectory, TRAJECTORY_MEMBER)

    return atomic_write_with(Path(out), write)
