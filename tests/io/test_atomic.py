"""Atomic output: a file is either complete or absent."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meanfield.io.atomic import atomic_write_json, atomic_write_text, atomic_write_with


class _Boom(RuntimeError):
    pass


def test_interrupted_write_leaves_nothing(tmp_path):
    dest = tmp_path / "sub" / "data.nc"

    def writer(p):
        p.write_bytes(b"half of a file")
        raise _Boom("disk full")

    with pytest.raises(_Boom):
        atomic_write_with(dest, writer)
    assert not dest.exists()
    assert list(dest.parent.iterdir()) == []  # no temporary file remains


def test_interrupted_write_keeps_the_old_file(tmp_path):
    dest = tmp_path / "summary.json"
    atomic_write_text(dest, "old\n")

    def writer(p):
        p.write_text("new but incomplete")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write_with(dest, writer)
    assert dest.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_writer_sees_the_destination_suffix(tmp_path):
    seen = []
    atomic_write_with(tmp_path / "a.png", lambda p: (seen.append(p.suffix), p.write_bytes(b"x")))
    assert seen == [".png"]
    assert (tmp_path / "a.png").read_bytes() == b"x"


def test_json_with_numpy_values(tmp_path):
    data = {"a": np.float64(1.5), "b": np.arange(3), "c": (1, 2), "d": np.int64(7)}
    atomic_write_json(tmp_path / "x.json", data)
    assert json.loads((tmp_path / "x.json").read_text()) == {"a": 1.5, "b": [0, 1, 2], "c": [1, 2], "d": 7}


def test_a_killed_save_leaves_nothing_beside_the_next_run(tmp_path):
    """A save killed half-way, then a run that writes fewer files into the same folder: the first
    run's files stayed, unlisted, beside a "complete" summary (issue "Nothing lost", item 2).  The
    save's journal now names what was there before, and the next save removes the rest."""
    from meanfield.io.atomic import SAVE_JOURNAL, atomic_write_text, check_complete_folder, write_complete_folder

    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("the user's own file")

    def many(folder):
        paths = {k: atomic_write_text(folder / f"{k}.txt", k) for k in ("timeseries", "trajectories", "figure")}
        raise KeyboardInterrupt  # the kill, after the files and before the summary
        return paths  # pragma: no cover

    with pytest.raises(KeyboardInterrupt):
        write_complete_folder(out, many, {"status": "completed"})
    assert (out / SAVE_JOURNAL).exists() and not (out / "summary.json").exists()
    def fewer(folder):
        return {"t": atomic_write_text(folder / "timeseries.txt", "new")}

    write_complete_folder(out, fewer, {"status": "completed"})
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "summary.json", "timeseries.txt"]
    assert check_complete_folder(out) == [] and (out / "timeseries.txt").read_text() == "new"
