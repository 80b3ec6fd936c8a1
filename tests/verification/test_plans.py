"""Theorems 1–3 checked on floor plans (an L-shaped room, a room with a pillar) and with exits:
μ₂ of the plan, what applies when mass leaves, and the guards (docs page *Verifying the paper's claims*)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from analysis.poincare import neumann_eigenvalue
from meanfield import ConstantAlpha, Domain, Grid, load_scenario
from meanfield.controllers.backstepping import BacksteppingController
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.plan import Plan
from verification.plant import RobotLoopTrajectory, fokker_planck_trajectory
from verification.theorem1 import check_theorem1
from verification.theorem2 import check_theorem2, iss_bound, iss_bound_with_exits
from verification.theorem3 import check_theorem3, exits_verdict, lyapunov_verdict

L_ROOM = "POLYGON ((0 0, 1 0, 1 0.4, 0.4 0.4, 0.4 1, 0 1, 0 0))"
PILLAR_ROOM = "POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0), (0.4 0.4, 0.6 0.4, 0.6 0.6, 0.4 0.6, 0.4 0.4))"
# the paper's scenario elsewhere (σ, kernel, gains, saturating α); no speed limits, a small grid
SCENARIO = """
name = "{name}"
units = "dimensionless"
t_final = 2.0

[domain]
kind = "plan"
wkt = "{wkt}"
{exits}

[grid]
cells = [16, 16]

[target]
center = [{cx}, {cy}]
std = 0.15
"""
PLANS = {
    "l-room": (L_ROOM, (0.85, 0.2)),  # the safe zone at the end of the lower arm
    "pillar-room": (PILLAR_ROOM, (0.8, 0.8)),  # the safe zone beyond the pillar
}


def _scenario(tmp_path, name: str, exits: str = ""):
    wkt, (cx, cy) = PLANS[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(SCENARIO.format(name=name, wkt=wkt, exits=exits, cx=cx, cy=cy))
    return load_scenario(path)


@pytest.mark.parametrize("name", list(PLANS))
def test_theorems_1_and_2_hold_on_a_plan_with_its_own_mu2(tmp_path, name):
    sc = _scenario(tmp_path, name)
    assert isinstance(sc.domain, Plan)
    mu2 = neumann_eigenvalue(Grid(sc.domain, (16, 16)))
    assert 0 < mu2 < math.pi**2  # below the unit square's: the corner (pillar) slows the slowest mode
    r1 = check_theorem1(sc, tmp_path, quick=True)
    assert r1.verdict == "holds", r1.summary
    assert r1.bound["mu2_discrete"] == pytest.approx(mu2, rel=1e-12)
    hyp = r1.measured["hypotheses"]
    assert hyp["region"] == "plan" and not hyp["convex"] and hyp["connected"] and hyp["mass_conserved"]
    assert "not convex" in r1.summary
    constant = [k for k in r1.cases if k["case"].startswith("constant") and k["plant"].startswith("Fokker")]
    assert constant[0]["k_p"] == pytest.approx(2 * 0.2 * mu2, rel=1e-12)
    assert not constant[0]["vacuous"] and constant[0]["V1_final"] < 0.1 * constant[0]["V1_initial"]
    r2 = check_theorem2(sc, tmp_path, quick=True)
    assert r2.verdict == "holds", r2.summary
    constant = [k for k in r2.cases if k["case"].startswith("constant")][0]
    assert not constant["vacuous"] and "lambda_E" not in constant


@pytest.mark.parametrize("name", list(PLANS))
def test_theorem_3_runs_on_a_plan(tmp_path, name):
    r = check_theorem3(_scenario(tmp_path, name), tmp_path, quick=True, robot_counts=(4,))
    assert r.verdict in ("holds", "fails"), r.reason
    case = r.cases[0]
    assert case["certificate"], case  # Step II's inequality along the plant, up to the model mismatch
    assert case["max_identity_excess"] <= 0.01 and "exit_term_positive_fraction" not in case


def test_with_exits_each_claim_says_whether_it_applies(tmp_path):
    """A door in the L's west wall: mass leaves.  Theorem 1 does not apply; Theorem 2 as stated does
    not, its corollary with the outflow as an input does (and is judged); Theorem 3's identity does."""
    sc = _scenario(tmp_path, "l-room", exits="exits = [[[0.0, 0.8], [0.0, 1.0]]]")
    r1 = check_theorem1(sc, tmp_path, quick=True)
    assert r1.verdict == "inconclusive" and "mass is not conserved" in r1.reason
    assert r1.measured["hypotheses"]["exits"] == 1 and not r1.measured["hypotheses"]["mass_conserved"]
    assert all(k["plant"].startswith("Fokker") and k["mass_out"] > 0.01 for k in r1.cases)  # no exit-less model
    for k in r1.cases:  # ‖ρ̃‖² ≥ (mass out)²/|Ω| (Cauchy–Schwarz): no convergence to ρ_*
        assert k["V1_final"] >= k["V1_floor_final"] > 0

    r2 = check_theorem2(sc, tmp_path, quick=True, speed=0.01)
    assert r2.verdict == "inconclusive" and "mass is not conserved" in r2.reason
    assert "Judged instead" in r2.summary
    constant = [k for k in r2.cases if k["case"].startswith("constant")][0]
    assert constant["verdict"] == "holds" and not constant["vacuous"], constant
    assert 0 < constant["lambda_E"] < constant["alpha_inf_mu2"]  # a small door: weaker than α μ₂
    assert constant["rho_error_final"] >= constant["rho_error_floor_final"] > 0

    r3 = check_theorem3(sc, tmp_path, quick=True, robot_counts=(4,))
    assert r3.verdict == "inconclusive" and "mass is not conserved" in r3.reason
    case = r3.cases[0]
    assert case["verdict"] == "holds" and case["certificate"] and case["mass_out"] > 0
    assert "exit_term_positive_fraction" in case


def test_the_exits_bound_is_the_papers_with_lambda_e_for_alpha_mu2():
    t = np.linspace(0.0, 5.0, 11)
    paper = iss_bound(t, 2.0, 0.1, 3.0, 0.5, 4.0)
    np.testing.assert_allclose(iss_bound_with_exits(t, 2.0, 0.1, 3.0, 0.5, 0.5 * 4.0, 0.0), paper, rtol=1e-14)
    more = iss_bound_with_exits(t, 2.0, 0.1, 3.0, 0.5, 2.0, 0.3)  # the target's outflow as a second input
    assert (more >= paper).all() and more[-1] > paper[-1]
    assert np.isinf(iss_bound_with_exits(t, 2.0, 0.1, 3.0, 0.5, 0.0, 0.0)).all()


def _exit_trajectory(dV2, claim, exit_term) -> RobotLoopTrajectory:
    n = len(dV2)
    one = np.ones(n)
    V2 = np.exp(-np.linspace(0, 1, n))
    return RobotLoopTrajectory(
        np.linspace(0, 1, n), V2, one, V2**0.5, np.asarray(dV2, float), np.asarray(claim, float),
        one, one, 0 * one, one, 0 * one, exit_term=np.asarray(exit_term, float), mass=np.linspace(1, 0.9, n),
    )  # fmt: skip


def test_exits_verdict_takes_the_exits_share_apart():
    claim = -np.ones(11)
    share = np.full(11, 0.5)  # positive: the certificate's sign is lost, the identity is not
    verdict, fig = lyapunov_verdict(_exit_trajectory(claim + share, claim, share))
    assert verdict == "holds" and fig["certificate"] and fig["exit_term_positive_fraction"] == 1.0
    assert fig["mass_out"] == pytest.approx(0.1) and "converging" not in fig  # not judged: mass leaves
    verdict, fig = exits_verdict(_exit_trajectory(claim + 2 * share, claim, share))  # a share the law lost
    assert verdict == "fails" and not fig["certificate"]
    assert lyapunov_verdict(_exit_trajectory(claim + share, claim, 0 * share))[0] == "fails"  # share not taken apart


def test_a_grid_that_splits_omega_makes_the_theorems_inconclusive(tmp_path, monkeypatch):
    import verification.hypotheses as hypotheses

    sc = _scenario(tmp_path, "pillar-room")
    monkeypatch.setattr(hypotheses, "grid_pieces", lambda grid: (2, 0.25))
    for check in (check_theorem1, check_theorem2, check_theorem3):
        r = check(sc, tmp_path, quick=True)
        assert r.verdict == "inconclusive" and "2 pieces" in r.reason and "refine grid.cells" in r.reason
        assert not r.measured["hypotheses"]["connected"]


def test_the_plant_stops_where_rho_vanishes_and_the_check_does_not_judge_it():
    from verification.theorem1 import _case

    grid = Grid(Domain.box(1.0, 1.0), (8, 8))
    target = grid.normalize(np.ones(grid.shape))
    ctrl = BacksteppingController(grid, target, 0.01, ConstantAlpha(0.2))
    rho0 = target.copy()
    rho0[3:5, 3] = 0.0  # an empty face between two cells: v_d = −(α∇ρ̃ − ∇(σρ))/ρ is undefined there
    fp = FokkerPlanck(grid, 0.01, method="split")
    tr = fokker_planck_trajectory(ctrl, fp, rho0, 0.1, 0.01)
    assert "ρ reached 0" in tr.info["stopped"] and len(tr.t) == 1
    case = _case("constant", tr, 1.0, "Fokker–Planck")
    assert case["verdict"] == "inconclusive" and "ρ reached 0" in case["reason"]


def test_verify_command_on_a_plan(tmp_path):
    from meanfield.cli.app import main

    wkt, (cx, cy) = PLANS["l-room"]
    path = tmp_path / "l.toml"
    path.write_text(SCENARIO.format(name="l-room", wkt=wkt, exits="", cx=cx, cy=cy))
    out = tmp_path / "out"
    assert main(["verify", str(path), "--out", str(out), "--quick", "--quiet", "--checks", "theorem1,theorem2"]) == 0
    data = json.loads((out / "verdicts.json").read_text())
    assert [(v["key"], v["verdict"]) for v in data["verdicts"]] == [("theorem1", "holds"), ("theorem2", "holds")]
