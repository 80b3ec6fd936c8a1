"""The ``meanfield`` command: exit statuses, error messages naming the field, outputs."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from meanfield import Scenario, paper_scenario
from meanfield.cli.app import main
from tests.scenarios.test_scenario import BAD_TOML

TINY = """\
t_final = 0.05
dt = 0.01
record_every = 5
[crowd]
n = 40
[robots]
n = 4
[grid]
cells = [12, 12]
"""


@pytest.mark.parametrize(("text", "name"), BAD_TOML)
def test_bad_scenario_file_exits_2_naming_the_field(text, name, tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "out"
    status = main(["run", str(path), "--out", str(out), "--quiet", "--no-figures"])
    err = capsys.readouterr().err
    assert status == 2
    assert name in err
    assert not out.exists()  # refused before anything ran


@pytest.mark.parametrize(
    ("args", "name"),
    [
        (["--set", "crowd.sigma=-1"], "crowd.sigma"),
        (["--set", "kernel.eta=0"], "kernel.eta"),
        (["--set", "kernel.nope=1"], "kernel.nope"),
        (["--set", "dt"], "--set"),
        (["--seed", "-3"], "--seed"),
    ],
)
def test_bad_overrides_exit_2(args, name, tmp_path, capsys):
    out = tmp_path / "out"
    status = main(["run", "paper", "--out", str(out), "--quiet", "--no-figures", *args])
    assert status == 2
    assert name in capsys.readouterr().err
    assert not out.exists()


def test_unknown_scenario_name_exits_2(tmp_path, capsys):
    assert main(["run", "no-such-scenario", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "scenario" in capsys.readouterr().err


def test_run_writes_outputs_and_exits_0(tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    out = tmp_path / "out"
    status = main(["run", str(path), "--out", str(out), "--seed", "4", "--no-figures", "--set", "kernel.c=0.4"])
    assert status == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["seed"] == 4 and summary["steps"] == 5
    assert summary["scenario"]["kernel"]["c"] == 0.4
    assert (out / "timeseries.nc").exists()
    assert '"fraction_in_target"' in printed


def test_a_plan_run_prints_the_evacuation_not_the_target(tmp_path, capsys):
    """On a plan with exits ``meanfield run`` prints who is out, when, the flow per exit and RSET over the bound
    (issue 43, item 6): not the target's figures, which read 0 and null there as if the run had failed."""
    out = tmp_path / "l-room"
    assert main(["run", "l-room", "--out", str(out), "--no-figures", "--set", "t_final=80"]) == 0
    printed = json.loads(capsys.readouterr().out.split("outputs in")[0])
    summary = json.loads((out / "summary.json").read_text())
    assert list(printed)[:6] == ["status", "fraction_evacuated", "evacuation_time_95", "evacuation_time_100",
                                 "rset_over_bound", "flow_per_exit"]  # fmt: skip
    assert "fraction_in_target" not in printed and "w2_to_target_final" not in printed
    assert printed["fraction_evacuated"] == summary["fraction_evacuated"] == 1.0
    assert printed["evacuation_time_100"] == summary["evacuation_time_100"]
    flows = [f["persons_per_metre_second"] for f in summary["exit_flows"]]
    assert printed["flow_per_exit"] == [round(f, 3) for f in flows] and len(flows) == 1


def test_scenario_command_prints_parseable_toml(capsys):
    assert main(["scenario", "paper"]) == 0
    text = capsys.readouterr().out
    assert Scenario.from_toml(text).to_dict() == paper_scenario().to_dict()


def test_installed_command_exit_status(tmp_path):
    """As a separate process (``python -m meanfield.cli.app``, what the ``meanfield`` script runs):
    exit status 2 and the field named on stderr."""
    path = tmp_path / "bad.toml"
    path.write_text("[crowd]\nsigma = -0.5\n")
    proc = subprocess.run(
        [sys.executable, "-m", "meanfield.cli.app", "run", str(path), "--out", str(tmp_path / "o"), "--quiet"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "crowd.sigma" in proc.stderr
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------------- CLI habits (issue 16, item 11)
def test_version_and_the_list_of_built_in_scenarios(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"meanfield {version('meanfield-crowd')}"
    assert main(["scenario", "--list"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    names = ["bottleneck", "hall", "hall-crowded-west", "l-room", "office", "paper", "paper-unity", "rimea-10",
             "rimea-12", "rimea-9", "stadium"]  # fmt: skip
    assert [line.split()[0] for line in lines] == names
    assert all(len(line.split(maxsplit=1)) == 2 for line in lines)  # a name and what it is


def test_the_help_lists_every_built_in_scenario(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split()).replace("- ", "-")  # (argparse may wrap a name at a hyphen)
    names = ("bottleneck, hall, hall-crowded-west, l-room, office, paper, paper-unity, rimea-10, rimea-12, rimea-9, "
             "stadium")
    assert f"a built-in scenario ({names}), a TOML file, or a JuPedSim web-app export" in text


def test_the_paper_s_own_warning_is_kept_in_the_summary_and_printed_only_when_dt_changes(tmp_path, capsys):
    """``meanfield run paper`` printed the dt warning at every run (issue "Nothing lost", item 12)."""
    out = tmp_path / "a"
    assert main(["run", "paper", "--set", "t_final=0.05", "--out", str(out), "--quiet", "--no-figures"]) == 0
    assert "Step-I" not in capsys.readouterr().err
    assert any("Step-I" in w for w in json.loads((out / "summary.json").read_text())["warnings"])
    argv = ["run", "paper", "--set", "t_final=0.05", "--set", "dt=0.02", "--out", str(tmp_path / "b"), "--quiet"]
    assert main([*argv, "--no-figures"]) == 0
    assert "meanfield: warning: dt = 0.02 exceeds the sampled Step-I" in capsys.readouterr().err


def test_a_seed_beyond_64_bits_is_refused_before_the_run(tmp_path, capsys):
    """A 26-digit seed ran the whole run, then failed to write it (issue "Nothing lost", item 4)."""
    out = tmp_path / "r"
    assert main(["run", "paper", "--seed", "9" * 26, "--out", str(out), "--quiet", "--no-figures"]) == 2
    assert "--seed" in capsys.readouterr().err and not out.exists()


def test_the_crowd_is_chosen_by_crowd_and_the_old_backend_flag_warns(tmp_path, capsys):
    """``--crowd`` sets ``crowd.kind`` for one run; ``--backend``, its name before 0.2.0, does the same with a warning
    naming ``--crowd`` and the release that removes it; both at once are refused, naming ``--backend``."""
    import json
    import warnings

    args = ["run", "paper", "--set", "t_final=0.02", "--quiet", "--no-figures"]
    assert main([*args, "--crowd", "fokker-planck", "--out", str(tmp_path / "a")]) == 0
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["backend"] == "fokker-planck"
    assert "deprecated" not in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # (the command prints each warning as one line)
        assert main([*args, "--backend", "fokker-planck", "--out", str(tmp_path / "b")]) == 0
    said = "meanfield: warning: --backend is deprecated and removed in 0.3.0: use --crowd (it sets crowd.kind)"
    assert said in capsys.readouterr().err.splitlines()
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["backend"] == "fokker-planck"
    assert main([*args, "--crowd", "point-mass", "--backend", "point-mass", "--out", str(tmp_path / "c")]) == 2
    assert "--backend" in capsys.readouterr().err and not (tmp_path / "c").exists()
