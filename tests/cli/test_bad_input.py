"""Bad input found by trying the newer features as a new user would (issue 41): each ends in a refusal naming the field
(exit 2, one line) or in one complete run whose ``summary.json`` is strict JSON.

Each test is the reproduction the issue gives; each failed before its fix (a segfault, ``Infinity`` in the summary,
a traceback with exit 1, a string silently taken for a number, a raw ``UserWarning`` line).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from meanfield.cli.app import main
from meanfield.errors import ParameterError, ScenarioWarning
from meanfield.scenarios.scenario import builtin_scenarios


def _strict(text: str) -> dict:
    """``json.loads`` refusing ``Infinity``, ``-Infinity`` and ``NaN``, as a strict JSON reader does."""

    def refuse(constant: str):
        raise ValueError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def _run(tmp_path, capsys, *sets: str, scenario: str = "bottleneck", t_final: float = 0.5) -> tuple[int, str]:
    argv = ["run", scenario, "--out", str(tmp_path / "out"), "--quiet", "--no-figures", "--set", f"t_final={t_final}"]
    for s in sets:
        argv += ["--set", s]
    code = main(argv)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("setting", "field", "scenario", "says"),
    [
        ("crowd.congestion_radius=1e-9", "crowd.congestion_radius", "bottleneck", ">= 0.05 m"),  # segfaulted
        ("crowd.congestion_radius=1e-5", "crowd.congestion_radius", "bottleneck", ">= 0.05 m"),  # "diverged", exit 1
        ("crowd.congestion_radius=1e6", "crowd.congestion_radius", "bottleneck", "plan's size"),  # congestion off
        ("crowd.rho_max=1e-300", "crowd.rho_max", "bottleneck", "persons/m²"),  # everyone frozen
        ("crowd.rho_max=1e6", "crowd.rho_max", "bottleneck", "persons/m²"),
        ('crowd.compliance="0.5"', "crowd.compliance", "hall", "[0, 1]"),  # strings for numbers ran
        ('t_final="5"', "t_final", "bottleneck", "number"),
        ('crowd.premovement={law="lognormal", median="2", sigma=0.5}', "crowd.premovement.median", "bottleneck", "> 0"),
        ('crowd.premovement={law="lognormal", median=2, sigma=1e3}', "crowd.premovement.sigma", "bottleneck", "[0, 5]"),
        ('crowd.premovement={law="uniform", low=1, high=inf}', "crowd.premovement.high", "bottleneck", "a finite time"),
    ],
)
def test_a_meaningless_or_mistyped_value_exits_2_naming_its_field(setting, field, scenario, says, tmp_path, capsys):
    code, err = _run(tmp_path, capsys, setting, scenario=scenario)
    assert code == 2
    assert f"invalid {field} =" in err and says in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "summary.json").exists()


def test_the_congestion_radius_s_range_is_stated():
    sc = builtin_scenarios()["bottleneck"](seed=0)
    with pytest.raises(ParameterError, match="at most the plan's size"):
        sc.with_values({"crowd.congestion_radius": 20.0})
    assert sc.with_values({"crowd.congestion_radius": 0.05}).crowd.congestion_radius == 0.05


def test_the_disk_share_of_a_disk_below_its_lattice_s_cell_is_finite():
    """The cause of the segfault: a disk that missed every sample of its cell divided by a zero weight sum (NaN)."""
    from meanfield.geometry.disk_share import disk_share

    sc = builtin_scenarios()["bottleneck"](seed=0)
    share = disk_share(sc.domain, 1e-9)
    assert np.all(np.isfinite(share.table)) and share.table.max() == 1.0


def test_integer_fields_take_a_whole_float_and_refuse_a_fraction():
    hall = builtin_scenarios()["hall"](seed=0)
    region = "POLYGON ((1 1, 9 1, 9 9, 1 9, 1 1))"
    groups = [{"region": region, "n": 100.0}]
    sc = hall.with_values({"crowd.initial": "groups", "crowd.n": 100, "crowd.groups": groups})
    assert sc.crowd.groups[0]["n"] == 100 and isinstance(sc.crowd.groups[0]["n"], int)
    with pytest.raises(ParameterError) as info:
        hall.with_values({"crowd.initial": "groups", "crowd.n": 100, "crowd.groups": [{"region": region, "n": 100.5}]})
    assert info.value.name == "crowd.groups[0].n"
    assert hall.with_values({"events": [{"time": 5.0, "close_exit": 1.0}]}).events[0].close_exit == 1
    with pytest.raises(ParameterError) as info:
        hall.with_values({"events": [{"time": 5.0, "close_exit": 1.5}]})
    assert info.value.name == "events[0].close_exit"


def test_summary_json_is_strict_even_when_a_figure_is_infinite(tmp_path):
    from meanfield.io.atomic import atomic_write_json

    path = atomic_write_json(tmp_path / "s.json", {"a": math.inf, "b": [np.float64("nan"), 1.0], "c": np.inf})
    assert _strict(path.read_text()) == {"a": None, "b": [None, 1.0], "c": None}


@pytest.mark.parametrize("body", ['raise RuntimeError("boom")\n', "def broken(:\n"])
def test_a_plugin_that_fails_to_import_is_one_line_and_exit_2(body, tmp_path, capsys):
    plugin = tmp_path / "plugin_that_fails.py"
    plugin.write_text(body)
    code = main(["run", "paper", "--plugin", str(plugin), "--out", str(tmp_path / "out"), "--quiet", "--no-figures"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("meanfield: error: invalid --plugin") and "a module that imports" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.parametrize("time", [0.5, 0.7])  # at t_final exactly, and after it
def test_an_event_at_or_after_the_end_warns_in_one_line(time, tmp_path, capsys):
    with pytest.warns(ScenarioWarning, match="it never happens"):
        builtin_scenarios()["hall"](seed=0).with_values({"t_final": 0.5, "events": [{"time": time, "close_exit": 0}]})
    code, err = _run(tmp_path, capsys, f"events=[{{time={time}, close_exit=0}}]", "crowd.n=20", scenario="hall")
    assert code == 0
    assert f"meanfield: warning: events[0].time = {time:g} is outside the run" in err
    assert "UserWarning" not in err and ".py:" not in err


def test_an_output_name_that_is_a_folder_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "out"
    (out / "timeseries.nc").mkdir(parents=True)
    code = main(["run", "paper", "--out", str(out), "--quiet", "--no-figures", "--set", "t_final=0.05"])
    err = capsys.readouterr().err
    assert code == 2 and "invalid --out" in err and "timeseries.nc" in err and "is a folder" in err
    assert sorted(p.name for p in out.iterdir()) == ["timeseries.nc"]  # no journal, no summary: nothing ran


def test_the_file_names_a_run_writes_are_all_known_before_it(tmp_path):
    """The names checked before a run (``SimulationResult.FILE_NAMES``) hold every file a run writes, figures and
    animation included, on a plan with exits (its evacuation figure) and on the paper's room."""
    from meanfield.simulation.result import SimulationResult

    for scenario, extra in (("paper", []), ("hall", ["--set", "crowd.n=20"])):
        out = tmp_path / scenario
        assert main(["run", scenario, "--out", str(out), "--quiet", "--animate", "--set", "t_final=0.2", *extra]) == 0
        written = {p.name for p in out.iterdir()}
        assert written <= set(SimulationResult.FILE_NAMES), written - set(SimulationResult.FILE_NAMES)


def test_a_sweep_refuses_a_bad_combination_before_any_run(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", "hall", "--set", "crowd.guidance=signs,geodesic", "--set", "crowd.compliance=1,0.5",
            "--set", "t_final=0.5", "--seeds", "1", "--out", str(out), "--quiet"]  # fmt: skip
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and "invalid crowd.compliance = 0.5" in err and "crowd.guidance = 'geodesic'" in err
    assert not out.exists() or not any(out.iterdir())


def test_a_block_in_a_room_without_exits_is_built(tmp_path, capsys):
    """The paper's room has no exits: no piece can be cut off from one, and a block there runs."""
    block = 'events=[{time=0.05, block="POLYGON ((0.4 0.4, 0.6 0.4, 0.6 0.6, 0.4 0.6, 0.4 0.4))"}]'
    code, err = _run(tmp_path, capsys, block, scenario="paper", t_final=0.1)
    assert code == 0, err
    summary = _strict((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["events"][0]["block"].startswith("POLYGON")


@pytest.mark.parametrize(
    ("block", "says"),
    [
        ("POLYGON ((5 5, 5.001 5, 5.001 5.001, 5 5.001, 5 5))", "a block covering more than"),  # 1 mm² in the hall
        ("MULTIPOLYGON (((1 1, 2 1, 2 2, 1 2, 1 1)), ((3 3, 4 3, 4 4, 3 4, 3 3)))", "exactly one polygon in WKT"),
    ],
)
def test_a_block_s_refusal_says_what_is_wrong(block, says):
    with pytest.raises(ParameterError) as info:
        builtin_scenarios()["hall"](seed=0).with_values({"events": [{"time": 1.0, "block": block}]})
    assert info.value.name == "events[0].block" and says in str(info.value)


@pytest.mark.parametrize(("controllers", "says"), [("", "''"), ("coverage,coverage", "'coverage' twice")])
def test_the_study_refuses_no_controller_and_a_controller_twice(controllers, says, tmp_path, capsys):
    code = main(["study", "controllers", "paper", "--controllers", controllers, "--seeds", "1", "--out",
                 str(tmp_path / "study"), "--quiet"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "invalid --controllers" in err and says in err


def test_the_study_s_help_prints_percent_signs_once(capsys):
    with pytest.raises(SystemExit):
        main(["study", "--help"])
    out = capsys.readouterr().out
    assert "90 % (or 95 % out)" in out.replace("\n", " ").replace("  ", " ") and "%%" not in out


def test_numba_that_cannot_start_is_said_on_stderr(tmp_path):
    """``NUMBA_NUM_THREADS=0``: numba refuses to import; the run goes on in numpy and says so, in one line."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_NUM_THREADS": "0"}
    env.pop("MEANFIELD_COMPILED", None)
    argv = [sys.executable, "-m", "meanfield.cli.app", "run", "paper", "--set", "t_final=0.05", "--out",
            str(tmp_path / "out"), "--quiet", "--no-figures"]  # fmt: skip
    proc = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "meanfield: warning: numba could not be imported" in proc.stderr
    assert "NUMBA_NUM_THREADS must be >= 1" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize("name", ["bottleneck", "hall", "hall-crowded-west", "l-room", "office", "paper", "paper-unity",
                                  "rimea-10", "rimea-12", "rimea-9", "stadium"])  # fmt: skip
def test_every_shipped_scenario_s_summary_is_strict_json(name, tmp_path, capsys):
    """Ten steps of each built-in scenario (the stadium with 10⁴ of its 10⁶ humans); its summary parses strictly."""
    from meanfield.cli.arguments import builtin_names
    from meanfield.scenarios.scenario import load_scenario

    assert name in builtin_names()
    sc = load_scenario(name)
    extra = ["--set", "crowd.n=10000"] if name == "stadium" else []
    code, err = _run(tmp_path, capsys, *extra[1:], scenario=name, t_final=10 * sc.dt)
    assert code == 0, err
    summary = _strict((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["steps"] == 10


def test_the_shipped_list_above_is_every_built_in():
    from meanfield.cli.arguments import builtin_names

    names = test_every_shipped_scenario_s_summary_is_strict_json.pytestmark[0].args[1]
    assert sorted(names) == sorted(builtin_names())
