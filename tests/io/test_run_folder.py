"""A folder with a summary.json holds one complete run; --out is checked before any work (issue 16, items 1-2)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from meanfield import paper_scenario, run
from meanfield.cli.app import main
from meanfield.errors import ParameterError
from meanfield.io.atomic import check_complete_folder, check_output_dir, check_output_file


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    base = paper_scenario(seed=0).replace(t_final=0.05)
    return run(base, progress=False), run(base.replace(seed=1), progress=False)


def test_every_file_carries_the_run_id_and_reruns_keep_it(two_runs):
    a, b = two_runs
    assert a.summary["run_id"] != b.summary["run_id"]
    again = run(paper_scenario(seed=0).replace(t_final=0.05), progress=False)
    assert again.summary["run_id"] == a.summary["run_id"]  # the id is what the run is
    assert a.dataset.attrs["run_id"] == a.summary["run_id"] and a.dataset.attrs["status"] == "completed"


def test_a_reader_detects_a_file_of_another_run(two_runs, tmp_path):
    a, b = two_runs
    a.save(tmp_path / "a")
    b.save(tmp_path / "b")
    assert check_complete_folder(tmp_path / "a") == []
    shutil.copy(tmp_path / "b" / "timeseries.nc", tmp_path / "a" / "timeseries.nc")
    problems = check_complete_folder(tmp_path / "a")
    assert len(problems) == 1 and "timeseries.nc" in problems[0] and "another run" in problems[0]
    (tmp_path / "a" / "summary.json").unlink()
    assert "no summary.json" in check_complete_folder(tmp_path / "a")[0]


def test_saving_over_an_earlier_run_removes_what_only_the_earlier_run_wrote(two_runs, tmp_path):
    from meanfield.plotting.figures import save_run_figures

    a, b = two_runs
    out = tmp_path / "run"
    a.save(out, artifacts=[save_run_figures])
    (out / ".timeseries.abc.part.nc").write_bytes(b"killed write")  # a temporary of a killed save
    b.save(out)  # no figures this time: a's figures must not stay beside b's summary
    names = {p.name for p in out.iterdir()}
    assert names == {"summary.json", "timeseries.nc", "scenario.toml"}
    s = json.loads((out / "summary.json").read_text())
    assert s["seed"] == 1 and check_complete_folder(out) == []


def test_out_is_checked_before_anything_runs(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    with pytest.raises(ParameterError) as exc:
        check_output_dir(afile)
    assert exc.value.name == "--out" and "is a file" in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        check_output_dir(afile / "under")
    assert "is a file, not a folder" in str(exc.value)
    assert check_output_dir(tmp_path / "new" / "deep") == tmp_path / "new" / "deep"
    assert not (tmp_path / "new").exists()  # a check creates nothing
    with pytest.raises(ParameterError) as exc:
        check_output_file(tmp_path)
    assert "a file path" in str(exc.value)


def test_an_empty_out_and_a_dangling_link_are_refused_before_anything_runs(tmp_path, capsys):
    """``--out ""`` named no folder and wrote into the current one; a link to a missing folder was
    accepted, then failed with FileExistsError after the whole run (issue "Nothing lost", item 4)."""
    with pytest.raises(ParameterError) as exc:
        check_output_dir("")
    assert exc.value.name == "--out" and "empty path" in str(exc.value)
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "missing")
    with pytest.raises(ParameterError) as exc:
        check_output_dir(link)
    assert "symbolic link" in str(exc.value) and "missing" in str(exc.value)
    with pytest.raises(SystemExit) as code:
        main(["run", "paper", "--out", str(link), "--quiet"])
    assert code.value.code == 2
    assert "symbolic link" in capsys.readouterr().err and not (tmp_path / "missing").exists()


def test_more_robots_than_int16_holds_are_counted_without_overflow(tmp_path):
    """33,000 robots overflowed the int16 count of robots at a limit after the whole run."""
    sc = paper_scenario(seed=0).replace(t_final=0.02).with_values({"robots.n": 33000})
    result = run(sc, progress=False)
    assert result.summary["status"] == "completed"
    at_limit = result.dataset["robots_at_limit"]
    assert at_limit.dtype.itemsize >= 4 and int(at_limit.max()) <= 33000
    result.save(tmp_path / "out")
    check_complete_folder(tmp_path / "out")


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "paper"],
        ["compare", "paper"],
        ["analyze", "paper", "--quick"],
        ["verify", "paper", "--quick"],
        ["sweep", "paper", "--set", "robots=4"],
    ],
)
def test_every_command_refuses_a_bad_out_with_status_2(argv, tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--out", str(afile)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--out" in err and str(afile) in err and "is a file" in err


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (lambda tmp: "a" * 300, "every name is at most"),  # one name over NAME_MAX, relative to the cwd
        (lambda tmp: str(tmp / "/".join(["b" * 200] * 25)), "from the root"),  # 5000 characters in all
        (lambda tmp: str(tmp / "/".join(["c" * 200] * 19)), "from the root"),  # under PATH_MAX, no room for files
    ],
    ids=["name", "path", "no-room"],
)
def test_an_over_long_out_is_refused_naming_out_before_anything_runs(make, says, tmp_path, capsys, monkeypatch):
    """Over-long ``--out`` paths ended in OSError tracebacks (issue "Nothing lost", item 8)."""
    monkeypatch.chdir(tmp_path)
    out = make(tmp_path)
    with pytest.raises(ParameterError) as exc:
        check_output_dir(out)
    assert exc.value.name == "--out" and says in exc.value.allowed and len(exc.value.value) < 120
    for argv in (["run", "paper", "--quiet", "--no-figures"], ["sweep", "paper", "--set", "robots=4"]):
        with pytest.raises(SystemExit) as code:
            main([*argv, "--out", out])
        assert code.value.code == 2
        err = capsys.readouterr().err
        assert "argument --out" in err and says in err and "Traceback" not in err
    with pytest.raises(SystemExit) as code:
        main(["bench", "--out", str(Path(out) / "report.json")])
    assert code.value.code == 2 and "argument --out" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # nothing was created


def test_an_over_long_report_name_is_refused(tmp_path):
    with pytest.raises(ParameterError) as exc:
        check_output_file(tmp_path / ("r" * 300 + ".json"))
    assert exc.value.name == "--out" and "a file name of at most" in exc.value.allowed


def test_a_link_above_the_folder_that_leads_nowhere_is_refused_not_a_traceback(tmp_path):
    """Accepted before, then an OSError (ELOOP) or FileExistsError when the run created its folder."""
    loop = tmp_path / "loop"
    loop.symlink_to(loop)  # a link to itself: ELOOP when the system follows it
    with pytest.raises(ParameterError) as exc:
        check_output_dir(loop / "run")
    assert exc.value.name == "--out" and "a loop of links" in exc.value.allowed
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "missing")
    with pytest.raises(ParameterError) as exc:  # a link that leads nowhere, above the folder
        check_output_dir(dangling / "deeper" / "run")
    assert "symbolic link" in exc.value.allowed and not (tmp_path / "missing").exists()


def test_bench_refuses_a_folder_as_its_report(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "--out", str(tmp_path)])
    assert exc.value.code == 2 and "a file path" in capsys.readouterr().err


def test_a_second_run_into_a_folder_another_run_holds_is_refused(tmp_path, capsys):
    """Two runs into one --out at once lost one run or crashed (issue "Nothing lost", item 3): the
    folder is locked for the whole of a run, and the second is refused at once naming the lock."""
    from meanfield.io.atomic import folder_lock

    out = tmp_path / "run"
    argv = ["run", "paper", "--set", "t_final=0.05", "--out", str(out), "--quiet", "--no-figures"]
    with folder_lock(out):  # another run holds it
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "--out" in err and "lock" in err
        assert list(out.iterdir()) == []  # the refused run wrote nothing
    assert not out.exists()  # the holder wrote nothing either: no empty folder is left
    assert main(argv) == 0 and check_complete_folder(out) == []  # free again


def test_a_run_never_overwrites_its_own_scenario_file(tmp_path, capsys):
    """``run my/scenario.toml --out my`` replaced the user's file with the normalised scenario."""
    own = tmp_path / "scenario.toml"
    own.write_text(paper_scenario().replace(t_final=0.02).to_toml() + "# my notes\n")
    before = own.read_text()
    assert main(["run", str(own), "--out", str(tmp_path), "--quiet", "--no-figures"]) == 2
    assert "--out" in capsys.readouterr().err and own.read_text() == before


@pytest.mark.parametrize("file", ["/proc/self/mem", "a" * 5000 + ".geojson", "/dev/null"])
def test_a_plan_file_that_cannot_be_read_is_refused_not_a_traceback(file):
    """Over-long paths and special files as a plan ended in OSError tracebacks (item 8)."""
    from meanfield.scenarios.scenario import Scenario

    with pytest.raises(ParameterError) as exc:
        Scenario.from_dict({"domain": {"kind": "plan", "file": file}})
    assert exc.value.name == "domain.file" and len(str(exc.value)) < 600


def test_a_path_the_system_will_not_look_at_is_a_refusal_not_a_traceback(tmp_path, monkeypatch):
    """A folder under one the user may not search (EACCES; as root nothing is refused, hence the stand-in)."""

    def refuse(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "is_symlink", refuse)
    with pytest.raises(ParameterError) as exc:
        check_output_dir(tmp_path / "run")
    assert exc.value.name == "--out" and "the system can write into (Permission denied)" in exc.value.allowed
