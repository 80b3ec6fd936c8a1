"""`meanfield analyze` (analysis.cli), through the meanfield CLI's plugin mechanism."""

from __future__ import annotations

import json
import math

import pytest

from meanfield.cli.app import main


def test_quick_analysis_writes_json_and_the_mode_figure(tmp_path, capsys):
    out = tmp_path / "an"
    rc = main(["analyze", "paper", "--out", str(out), "--quick", "--set", "t_final=0.3"])
    assert rc == 0
    d = json.loads((out / "analysis.json").read_text())
    assert d["status"] == "completed"
    p = d["poincare"]
    assert p["exact"] == pytest.approx(math.pi**2, rel=1e-15)
    assert abs(p["mu2"] - math.pi**2) / math.pi**2 < 1e-3  # 64² on the unit square
    assert p["payne_weinberger"] == pytest.approx(math.pi**2 / 2, rel=1e-12)  # diameter √2
    assert d["gains_scenario"]["k_p"] == pytest.approx(2 * d["gains_scenario"]["alpha_inf"] * p["mu2"], rel=1e-12)
    assert set(d["coverage"]) == {"0.5", "0.2", "0.1", "0.05"}
    assert d["coverage"]["0.5"]["n"] == 16  # the paper's 4×4 at half the kernel's peak
    assert "robot_count" not in d and "limits" not in d
    assert (out / "poincare_mode.png").stat().st_size > 0
    assert "mu2 =" in capsys.readouterr().out


def test_quick_analysis_of_an_l_shaped_plan_reports_payne_weinberger_as_not_applicable(tmp_path, capsys):
    from analysis.poincare import neumann_eigenvalue
    from meanfield import paper_scenario
    from meanfield.scenarios.scenario import Scenario

    table = paper_scenario(seed=0).to_dict()
    table["domain"] = {"kind": "plan", "wkt": "POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0))"}
    table["target"]["center"] = [0.85, 0.2]
    sc = Scenario.from_dict(table)
    path = tmp_path / "l.toml"
    path.write_text(sc.to_toml())
    out = tmp_path / "an"
    assert main(["analyze", str(path), "--out", str(out), "--quick", "--set", "t_final=0.3"]) == 0
    d = json.loads((out / "analysis.json").read_text())
    p = d["poincare"]
    assert p["payne_weinberger"] is None and p["exact"] is None
    assert p["mu2"] == pytest.approx(neumann_eigenvalue(sc.domain, (64, 64)), rel=1e-12)
    assert p["mu2"] < math.pi**2 / 2  # below π²/diam² (diameter √2): the bound would be false here
    assert d["gains_scenario"]["k_p"] == pytest.approx(2 * d["gains_scenario"]["alpha_inf"] * p["mu2"], rel=1e-12)
    assert d["coverage"]["0.5"]["n"] >= 1
    assert "Payne–Weinberger bound not applicable (Ω not convex)" in capsys.readouterr().out


def test_studies_write_their_figures(tmp_path):
    out = tmp_path / "an"
    rc = main(
        [
            "analyze",
            "paper",
            "--out",
            str(out),
            "--quiet",
            "--cells",
            "16",
            "--set",
            "t_final=0.2",
            "--robot-counts",
            "1,4",
            "--seeds",
            "0",
            "--limits",
            "0.1",
            "--workers",
            "1",
        ]
    )
    assert rc == 0
    d = json.loads((out / "analysis.json").read_text())
    assert d["robot_count"]["counts"] == [1, 4]
    rows = d["limits"]["table"]
    assert [(r["strategy"], r["u_max"]) for r in rows] == [("min-norm", 0.1), ("bounded", 0.1)]
    for r in d["limits"]["runs"]:
        assert r["max_robot_speed"] <= 0.1
    assert (out / "robot_count.png").stat().st_size > 0
    assert (out / "speed_limits.png").stat().st_size > 0


@pytest.mark.parametrize(
    "args, word",
    [
        (["--cells", "3"], "--cells"),
        (["--eps", "1.5"], "--eps"),
        (["--eps", "x"], "--eps"),
        (["--limits", "-0.1"], "--limits"),
        (["--robot-counts", "0,2"], "--robot-counts"),
        (["--seeds", "a-b"], "--seeds"),
        (["--workers", "0"], "--workers"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_bad_input_exits_2_naming_the_argument(tmp_path, capsys, args, word):
    rc = main(["analyze", "paper", "--out", str(tmp_path / "x"), "--quick", "--quiet", *args])
    assert rc == 2
    assert word in capsys.readouterr().err
    assert not (tmp_path / "x" / "analysis.json").exists()


def test_unknown_scenario_exits_2(tmp_path, capsys):
    assert main(["analyze", "no-such-room", "--out", str(tmp_path), "--quick"]) == 2
    assert "scenario" in capsys.readouterr().err
