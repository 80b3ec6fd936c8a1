"""Checks of the paper's claims (verification.mean_field, .robot_count, .agents): rules and contracts."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis.robot_count import coverage_estimate
from meanfield import SimulationDiverged, paper_scenario
from meanfield.scenarios.scenario import RobotSpec
from verification import agents as agents_mod
from verification import mean_field as mean_field_mod
from verification.agents import agents_verdict, check_agents, check_pedestrians, pedestrians_verdict
from verification.mean_field import check_mean_field, mean_field_verdict
from verification.result import CheckResult
from verification.robot_count import EPS_FRACTIONS, check_robot_count, robot_count_verdict

ALLOWED = {"holds", "fails", "inconclusive"}


@pytest.fixture(scope="module")
def tiny():
    """The paper scenario shrunk to a fraction of a second per closed-loop run."""
    return paper_scenario().with_values({"crowd.n": 50, "grid.cells": [16, 16], "robots.n": 4}).replace(t_final=0.3)


def _assert_contract(res: CheckResult, key: str, out: Path) -> dict:
    assert isinstance(res, CheckResult)
    assert res.key == key
    assert res.verdict in ALLOWED
    assert res.claim and res.criterion and res.summary
    if res.verdict == "inconclusive":
        assert res.reason
    for rel in res.figures:
        assert not Path(rel).is_absolute() and rel.startswith("figures/") and rel.endswith(".png")
        assert Path(rel).name.startswith(f"{key}_")
        assert (out / rel).is_file() and (out / rel).stat().st_size > 0
    d = res.to_dict()
    json.dumps(d, allow_nan=False)  # plain JSON, no NaN/inf
    return d


# ---------------------------------------------------------------------- mean field
def test_mean_field_slope_of_exact_monte_carlo_errors_is_minus_one_half():
    n = [100, 1_000, 10_000, 100_000]
    verdict, slope = mean_field_verdict(n, [3.0 * k**-0.5 for k in n])
    assert verdict == "holds"
    assert slope == pytest.approx(-0.5, abs=1e-12)


@pytest.mark.parametrize(
    "errors, expected, slope",
    [
        ([1.0, 0.1, 0.01], "fails", -1.0),  # too fast: not a Monte-Carlo rate
        ([1.0, 10**-0.1, 10**-0.2], "fails", -0.1),  # too slow: a floor
        ([1.0, 10**-0.3, 10**-0.6], "holds", -0.3),  # slow, inside the range
        ([1.0, 10**-0.7, 10**-1.4], "holds", -0.7),  # fast, inside the range
    ],
)
def test_mean_field_slope_range(errors, expected, slope):
    verdict, s = mean_field_verdict([100, 1_000, 10_000], errors)
    assert s == pytest.approx(slope, abs=1e-12)
    assert verdict == expected


def test_mean_field_needs_a_strict_decrease_even_with_a_good_slope():
    # slope -0.5 overall, but the last size does not improve on the one before
    n = [100, 1_000, 10_000, 100_000]
    errors = [1.0, 0.1, 0.05, 0.05]
    verdict, s = mean_field_verdict(n, errors)
    assert -0.75 <= s <= -0.25
    assert verdict == "fails"


@pytest.mark.parametrize(
    "n, errors",
    [([100], [0.1]), ([100, 1000], [0.1, 0.0]), ([100, 1000], [0.1, math.nan]), ([1000, 100], [0.1, 0.3])],
)
def test_mean_field_without_a_fittable_slope_is_inconclusive(n, errors):
    verdict, s = mean_field_verdict(n, errors)
    assert verdict == "inconclusive" and math.isnan(s)


def test_check_mean_field_contract(tiny, tmp_path):
    res = check_mean_field(tiny, tmp_path, quick=True)
    d = _assert_contract(res, "mean_field", tmp_path)
    assert res.figures == ["figures/mean_field_error_vs_n.png"]
    assert d["measured"]["n_agents"] == [100, 1_000, 10_000]
    assert len(d["measured"]["error_to_expected_mean"]) == 3
    assert len(d["measured"]["error_to_pde_mean"]) == 3
    verdict, slope = mean_field_verdict(d["measured"]["n_agents"], d["measured"]["error_to_expected_mean"])
    assert (res.verdict, res.measured["slope"]) == (verdict, pytest.approx(slope))


def test_check_mean_field_passes_the_scenarios_interaction(tiny, tmp_path, monkeypatch):
    seen = {}

    def fake(scenario, n_agents, **kwargs):
        seen.update(kwargs)
        raise SimulationDiverged("boom", 0)

    monkeypatch.setattr(mean_field_mod, "compare_agents_pde", fake)
    sc = tiny.with_values({"interaction.kind": "gaussian", "interaction.strength": 0.5, "interaction.length": 0.1})
    res = check_mean_field(sc, tmp_path, quick=True)
    assert (seen["interaction"].strength, seen["interaction"].length) == (0.5, 0.1)
    assert res.verdict == "inconclusive" and "diverged" in res.reason  # never a crash
    _assert_contract(res, "mean_field", tmp_path)


# ---------------------------------------------------------------------- robot count
def test_coverage_at_half_the_peak_reproduces_the_papers_sixteen_robots():
    sc = paper_scenario()
    lay = coverage_estimate(sc.domain, sc.kernel.c, sc.kernel.eta, EPS_FRACTIONS["c/2"] * sc.kernel.c)
    assert (lay.n, lay.cols, lay.rows) == (16, 4, 4) == (sc.robots.n, 4, 4)


def test_robot_count_rule():
    cov = {"c/10": 6, "c/4": 9, "c/2": 16}
    assert robot_count_verdict(cov, 16) == ("holds", {"c/10": "holds", "c/4": "holds", "c/2": "holds"})
    assert robot_count_verdict(cov, 9) == ("fails", {"c/10": "holds", "c/4": "holds", "c/2": "fails"})
    assert robot_count_verdict(cov, 4) == ("fails", {"c/10": "fails", "c/4": "fails", "c/2": "fails"})
    assert robot_count_verdict(cov, None) == ("inconclusive", dict.fromkeys(cov, "inconclusive"))
    assert robot_count_verdict(cov, 7, deciding="c/10")[0] == "holds"


def test_check_robot_count_contract(tiny, tmp_path):
    res = check_robot_count(tiny, tmp_path, quick=True, workers=1)
    d = _assert_contract(res, "robot_count", tmp_path)
    assert res.figures == ["figures/robot_count_fraction_vs_n.png"]
    assert [c["eps"] for c in d["cases"]] == ["c/10", "c/4", "c/2"]
    assert {c["coverage_n"] for c in d["cases"]} == {6, 9, 16}
    # 0.3 time units is far too short to gather the crowd: no count succeeds
    assert res.verdict == "inconclusive" and res.measured["empirical_minimum"] is None


def test_check_robot_count_refuses_explicit_robots(tmp_path):
    robots = RobotSpec(n=1, layout="explicit", positions=[[0.5, 0.5]], headings=[0.0])
    sc = paper_scenario().replace(robots=robots)
    res = check_robot_count(sc, tmp_path, quick=True, workers=1)
    assert res.verdict == "inconclusive" and "explicit" in res.reason
    _assert_contract(res, "robot_count", tmp_path)


# ---------------------------------------------------------------------- agents
def test_agents_rule():
    done = ["completed"] * 3
    assert agents_verdict([0.95, 0.9, 0.5], [0.4, 0.5, 1.2], done) == ("holds", 0.9, 0.5)
    assert agents_verdict([0.95, 0.85, 0.5], [0.4, 0.5, 1.2], done)[0] == "fails"  # fraction below 0.9
    assert agents_verdict([0.95, 0.95, 0.95], [0.4, 1.0, 1.2], done)[0] == "fails"  # ratio not < 1
    assert agents_verdict([0.95, 0.95, 0.95], [0.4, None, None], done)[0] == "fails"  # no ratio: not decreased


def test_agents_rule_counts_a_diverged_seed_as_a_failure():
    fr, rr = [0.95, 0.95, 0.95], [0.4, 0.4, 0.4]
    assert agents_verdict(fr, rr, ["completed", "completed", "diverged"]) == ("holds", 0.95, 0.4)
    verdict, med_f, med_r = agents_verdict(fr, rr, ["completed", "diverged", "diverged"])
    assert (verdict, med_f, med_r) == ("fails", 0.0, math.inf)
    assert agents_verdict([], [], [])[0] == "inconclusive"


def test_check_agents_contract(tiny, tmp_path):
    res = check_agents(tiny, tmp_path, quick=True, workers=1)
    d = _assert_contract(res, "agents", tmp_path)
    assert res.figures == ["figures/agents_time_series.png"]
    assert [c["seed"] for c in d["cases"]] == [0, 1, 2]
    for c in d["cases"]:
        assert {"fraction_in_target", "l2_error_ratio", "time_to_90", "status"} <= set(c)
    # 0.3 time units: the crowd has not moved to the corner
    assert res.verdict == "fails"
    assert res.measured["median_fraction_in_target"] < 0.9


def test_check_agents_reports_a_diverged_run(tiny, tmp_path, monkeypatch):
    def fake(job):
        _, seed = job
        t = np.linspace(0.0, 1.0, 5)
        status = "diverged" if seed == 1 else "completed"
        return {
            "seed": seed, "status": status, "message": "non-finite" if seed == 1 else "",
            "fraction_in_target": 0.97, "l2_error_ratio": 0.3, "l2_error_initial": 1.0, "l2_error_final": 0.3,
            "time_to_90": 0.5, "time_final": 1.0, "wall_seconds": 0.0,
            "time": t, "fraction_series": np.linspace(0.1, 0.97, 5), "error_series": np.linspace(1.0, 0.3, 5),
        }

    monkeypatch.setattr(agents_mod, "_run_seed", fake)
    res = check_agents(tiny, tmp_path, quick=True, workers=1)
    _assert_contract(res, "agents", tmp_path)
    assert res.measured["diverged_seeds"] == [1]
    assert res.verdict == "holds"  # two of three seeds succeed: the medians still pass
    assert [c["verdict"] for c in res.cases] == ["holds", "fails", "holds"]


# ---------------------------------------------------------------------- pedestrians
def test_pedestrians_rule():
    done = ["completed"] * 3
    assert pedestrians_verdict([0.9, 0.8, 0.2], done, [0.0, 0.004, 0.01]) == ("holds", 0.8, 0.01)
    assert pedestrians_verdict([0.9, 0.79, 0.5], done, [0.0, 0.0, 0.0]) == ("fails", 0.79, 0.0)  # median fraction < 0.8
    verdict, med, worst_overlap = pedestrians_verdict([0.9, 0.9, 0.9], done, [0.0, 0.02, 0.0])
    assert (verdict, med, worst_overlap) == ("fails", 0.9, 0.02)  # bodies overlap by 2 % of a diameter
    assert pedestrians_verdict([0.9, 0.9, 0.9], done, [0.0, None, 0.0]) == ("fails", 0.9, math.inf)  # unknown
    assert pedestrians_verdict([], [], [])[0] == "inconclusive"
    assert pedestrians_verdict([0.9], ["completed", "completed"], [0.0])[0] == "inconclusive"


def test_pedestrians_rule_fails_on_a_diverged_run():
    # the median of the fractions would pass, but one run did not complete
    verdict, med, worst_overlap = pedestrians_verdict([0.95, 0.95, 0.95], ["completed", "diverged", "completed"],
                                                      [0.0, None, 0.0])
    assert (verdict, med, worst_overlap) == ("fails", 0.95, 0.0)


def test_pedestrians_without_jupedsim_is_inconclusive_with_the_install_command(tiny, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "jupedsim", None)  # import jupedsim now raises ImportError
    res = check_pedestrians(tiny, tmp_path, quick=True, workers=1)
    _assert_contract(res, "pedestrians", tmp_path)
    assert res.verdict == "inconclusive"
    assert "pip install" in res.reason and "JuPedSim" in res.reason
    assert res.figures == [] and res.cases == []
    assert "paper_unity_scenario" in res.measured["settings"]["scenario"]


@pytest.mark.requires("jupedsim")
def test_check_pedestrians_end_to_end_on_a_short_horizon(tiny, tmp_path, monkeypatch):
    real = agents_mod.paper_unity_scenario
    monkeypatch.setattr(agents_mod, "paper_unity_scenario", lambda seed=0: real(seed).replace(t_final=25.0))
    res = check_pedestrians(tiny, tmp_path, quick=True, workers=1)  # the tiny scenario is ignored
    d = _assert_contract(res, "pedestrians", tmp_path)
    assert res.verdict in ("holds", "fails")  # 25 s is too short to judge the claim: not asserted
    assert res.figures == ["figures/pedestrians_fraction_in_target.png"]
    assert [(c["run"], c["seed"], c["role"]) for c in d["cases"]] == [
        ("JuPedSim bodies, 30 m view", s, "judged") for s in (0, 1, 2)
    ]
    settings = res.measured["settings"]
    assert (settings["t_final_s"], settings["humans"], settings["robots"], settings["view_radius_m"]) == (
        25.0, 200, 16, 30.0)
    assert settings["jupedsim_version"]
    for c in d["cases"]:
        assert c["status"] == "completed" and c["time_final"] == pytest.approx(25.0)
        assert 0.0 <= c["fraction_in_target"] <= 1.0 and c["body_overlap_max_relative"] is not None
    verdict, med, worst_overlap = pedestrians_verdict(
        res.measured["fraction_in_target"], res.measured["status"], [c["body_overlap_max_relative"] for c in d["cases"]]
    )
    assert (res.verdict, res.measured["median_fraction_in_target"]) == (verdict, pytest.approx(med))
