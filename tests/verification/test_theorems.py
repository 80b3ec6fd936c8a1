"""verification: the Theorem 1–3 checks against exact answers, the runner, the report and
``meanfield verify`` (verdicts, exit codes, non-convex polygons, crashing checks)."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

from analysis.poincare import neumann_eigenvalue
from meanfield import ConstantAlpha, Domain, Grid, load_scenario, paper_scenario
from meanfield.cli.app import main
from meanfield.controllers.backstepping import BacksteppingController
from verification import runner
from verification.plant import RobotLoopTrajectory, model_trajectory
from verification.result import CheckResult, jsonable, worst
from verification.theorem1 import exponential_verdict, feedback_step, fitted_rate
from verification.theorem2 import C1_GRID, iss_bound
from verification.theorem3 import lyapunov_verdict


# ---------------------------------------------------------------------- decision rules
def test_exponential_verdict_on_exact_exponentials():
    t = np.linspace(0, 3, 31)
    V = 5.0 * np.exp(-2.0 * t)
    assert fitted_rate(t, V) == pytest.approx(2.0, rel=1e-12)
    verdict, fig = exponential_verdict(t, V, k_p=1.9)
    assert verdict == "holds" and fig["worst_ratio_to_bound"] == pytest.approx(1.0)
    verdict, fig = exponential_verdict(t, V, k_p=2.1)
    assert verdict == "fails" and fig["worst_ratio_to_bound"] == pytest.approx(math.exp(0.1 * 3), rel=1e-12)
    bumpy = V.copy()
    bumpy[5] = bumpy[4] * 1.01  # a rise, although under a loose bound
    assert exponential_verdict(t, bumpy, k_p=0.1)[0] == "fails"
    assert exponential_verdict(t, V, k_p=1e-5)[1]["vacuous"]


def test_iss_bound_is_the_minimum_over_c1():
    t = np.array([0.0, 1.0, 10.0])
    b = iss_bound(t, rho0_error=2.0, sup_w=0.1, sup_rho=3.0, alpha_inf=0.5, mu2=4.0)
    c1 = C1_GRID[:, None]
    expected = np.maximum(2.0 * np.exp(-(1 - c1) * 0.5 * 4.0 * t), 3.0 * 0.1 / (c1 * 2.0 * 0.5)).min(0)
    np.testing.assert_allclose(b, expected, rtol=1e-15)
    # at t = 0 the bound is at least ‖ρ̃₀‖, and it never falls below the c₁ → 1 gain times sup‖w‖
    assert b[0] >= 2.0 and b.min() >= 3.0 * 0.1 / (2.0 * 0.5)
    assert np.isinf(iss_bound(t, 2.0, 0.1, 3.0, 0.0, 4.0)).all()


def test_feedback_step():
    assert feedback_step(0.1, 0.2, 1.0) == pytest.approx(0.9 * 0.01 / 0.8)
    assert feedback_step(0.1, 0.2, 1e-3) == 1e-3


def _loop_trajectory(dV2, claim, V2) -> RobotLoopTrajectory:
    n = len(V2)
    one = np.ones(n)
    return RobotLoopTrajectory(
        np.linspace(0, 1, n),
        np.asarray(V2, float),
        one,
        np.asarray(V2, float) ** 0.5,
        np.asarray(dV2, float),
        np.asarray(claim, float),
        one,
        one,
        0 * one,
        one,
        0 * one,
    )


def test_lyapunov_verdict():
    V2 = np.exp(-np.linspace(0, 1, 11))
    ok = _loop_trajectory(-np.ones(11), -np.ones(11), V2)
    assert lyapunov_verdict(ok)[0] == "holds"
    rate_up = _loop_trajectory(np.r_[-np.ones(10), 0.5], -np.ones(11), V2)
    verdict, fig = lyapunov_verdict(rate_up)
    assert verdict == "fails" and not fig["certificate"]
    stalled = _loop_trajectory(-np.ones(11), -np.ones(11), np.r_[V2[:6], np.full(5, V2[5])])
    verdict, fig = lyapunov_verdict(stalled)
    assert verdict == "fails" and fig["certificate"] and not fig["converging"]


# ---------------------------------------------------------------------- the semi-discrete plant, exactly
def test_model_trajectory_decays_at_the_discrete_neumann_rate():
    """ρ̃₀ = ε cos(πx) is an eigenvector of the discrete Neumann Laplacian, so with constant α
    V₁(t) = V₁(0) exp(−2 α μ₂,h t) with μ₂,h = (2/h)² sin²(πh/2) — and it is the grid's μ₂."""
    n, alpha = 16, 0.3
    grid = Grid(Domain.box(1.0, 1.0), (n, n))
    target = grid.normalize(np.ones(grid.shape))
    ctrl = BacksteppingController(grid, target, 0.01, ConstantAlpha(alpha))
    X, _ = grid.centers
    rho0 = target + 0.2 * np.cos(np.pi * X)
    mu2h = (2 * n) ** 2 * math.sin(math.pi / (2 * n)) ** 2
    assert neumann_eigenvalue(grid) == pytest.approx(mu2h, rel=1e-9)
    t = np.linspace(0, 1.0, 11)
    tr = model_trajectory(ctrl, rho0, t, rtol=1e-10)
    np.testing.assert_allclose(tr.V1, tr.V1[0] * np.exp(-2 * alpha * mu2h * t), rtol=1e-6)
    np.testing.assert_allclose(tr.dV1_dt, -2 * tr.dissipation, rtol=1e-9)
    assert exponential_verdict(tr.t, tr.V1, 2 * alpha * mu2h * (1 - 1e-5))[0] == "holds"


# ---------------------------------------------------------------------- result and runner
def test_check_result_validation_and_json():
    with pytest.raises(ValueError, match="verdict"):
        CheckResult("x", "claim", "maybe")
    with pytest.raises(ValueError, match="reason"):
        CheckResult("x", "claim", "inconclusive")
    r = CheckResult("x", "c", "holds", measured={"a": np.float64(1.5), "b": np.array([1, 2]), "n": float("nan")})
    d = r.to_dict()
    assert list(d)[:4] == ["key", "claim", "verdict", "measured"]
    assert json.loads(json.dumps(d))["measured"] == {"a": 1.5, "b": [1, 2], "n": None}
    assert worst(["holds", "inconclusive"]) == "inconclusive" and worst(["holds", "fails", "inconclusive"]) == "fails"
    assert jsonable({1: (np.int64(2), True)}) == {"1": [2, True]}


def test_runner_refuses_unknown_checks(tmp_path):
    with pytest.raises(Exception, match="checks"):
        runner.verify(paper_scenario(), tmp_path, checks=["theorem9"])


def _tiny_toml(tmp_path, vertices=None):
    sc = paper_scenario().with_values({"grid.cells": [12, 12], "t_final": 0.5, "crowd.n": 50})
    text = sc.to_toml()
    if vertices is not None:
        start = text.index("[domain]")
        end = text.index("[grid]")
        text = text[:start] + f'[domain]\nkind = "polygon"\nvertices = {vertices}\n\n' + text[end:]
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


def test_verify_command_writes_report_and_verdicts(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "jupedsim", None)  # pedestrians: inconclusive at once, not 3 Unity runs
    out = tmp_path / "out"
    code = main(
        [
            "verify",
            str(_tiny_toml(tmp_path)),
            "--out",
            str(out),
            "--quick",
            "--quiet",
            "--checks",
            "theorem1,theorem2,pedestrians",
        ]
    )
    assert code == 0
    data = json.loads((out / "verdicts.json").read_text())
    assert data["status"] == "completed"
    keys = [v["key"] for v in data["verdicts"]]
    assert keys == ["theorem1", "theorem2", "pedestrians"]
    for v in data["verdicts"]:
        assert {"claim", "verdict", "measured", "bound"} <= set(v)
        assert v["verdict"] in ("holds", "fails", "inconclusive")
        for fig in v["figures"]:
            assert (out / fig).is_file()
    report = (out / "report.md").read_text()
    assert "| claim | verdict | result |" in report and "figures/theorem1.png" in report


def test_an_unusable_domain_is_refused_and_a_non_convex_one_is_a_plan(tmp_path, capsys):
    """A vertex list that is no room (a bow tie crosses itself) is refused naming the field, exit 2;
    handed to :func:`verify` as the exception, every claim is inconclusive with the reason.  A vertex
    list that is merely not convex is a floor plan, on which the checks run (tests/verification/test_plans.py)."""
    from meanfield.errors import ParameterError
    from meanfield.geometry.plan import Plan

    path = _tiny_toml(tmp_path, vertices=[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    out = tmp_path / "out"
    assert main(["verify", str(path), "--out", str(out), "--quick", "--quiet"]) == 2
    assert "domain.vertices" in capsys.readouterr().err and not out.exists()
    with pytest.raises(ParameterError) as exc:
        load_scenario(path)
    run = runner.verify(exc.value, out, quick=True)
    assert [r.key for r in run.results] == list(runner.CHECKS)
    assert all(r.verdict == "inconclusive" and "self-intersecting" in r.reason for r in run.results)
    notch = _tiny_toml(tmp_path, vertices=[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 0.4], [0.0, 1.0]])
    assert isinstance(load_scenario(notch).domain, Plan)


def test_a_crashing_check_is_an_error_and_exit_1(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("boom")

    def fine(scenario, out_dir, **kwargs):  # a check that runs (the real one takes a minute)
        return CheckResult.inconclusive("pedestrians", "claim", "stub")

    monkeypatch.setitem(runner.CHECKS, "theorem1", broken)
    monkeypatch.setitem(runner.CHECKS, "pedestrians", fine)
    out = tmp_path / "out"
    code = main(
        [
            "verify",
            str(_tiny_toml(tmp_path)),
            "--out",
            str(out),
            "--quick",
            "--quiet",
            "--checks",
            "theorem1,pedestrians",
        ]
    )
    assert code == 1
    data = json.loads((out / "verdicts.json").read_text())
    assert [v["verdict"] for v in data["verdicts"]] == ["error", "inconclusive"]
    assert "boom" in data["verdicts"][0]["reason"]


@pytest.mark.parametrize(
    ("argv", "name"),
    [(["--checks", "theorem9"], "--checks"), (["--checks", ","], "--checks"), (["--workers", "0"], "--workers")],
)
def test_verify_bad_input_exits_2(tmp_path, capsys, argv, name):
    assert main(["verify", "paper", "--out", str(tmp_path / "o"), *argv]) == 2
    assert name in capsys.readouterr().err


def test_the_check_names_of_the_command_line_are_the_runner_s():
    from verification.result import CHECK_NAMES

    assert tuple(runner.CHECKS) == CHECK_NAMES
