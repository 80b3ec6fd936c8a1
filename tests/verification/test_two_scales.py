"""The check of one crowd at two scales (``meanfield verify``, key ``two_scales``): its decision rule, its
reading of runs whose answer is known, and the scaled bottleneck it runs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from meanfield.geometry.exits import exit_segments
from meanfield.scenarios.scenario import builtin_scenarios
from verification import runner
from verification.result import CHECK_NAMES
from verification.two_scales import (
    LIMIT_WIDTH,
    TOLERANCE,
    bottleneck,
    informed,
    refined,
    summarise,
    two_scales_verdict,
)


def test_the_rule_holds_when_every_gap_is_small_and_the_limit_falls():
    assert two_scales_verdict([{"t50": 0.05, "t90": -0.09}], [0.08, 0.04, 0.02]) == ("holds", "")


def test_one_gap_beyond_the_tolerance_fails_naming_it():
    verdict, reason = two_scales_verdict([{"t50": 0.02}, {"J": -1.5 * TOLERANCE}], [0.08, 0.04])
    assert verdict == "fails" and f"{1.5 * TOLERANCE:.1%}" in reason


def test_a_limit_that_does_not_fall_fails_even_when_every_case_agrees():
    verdict, reason = two_scales_verdict([{"t50": 0.0}], [0.04, 0.05, 0.03])
    assert verdict == "fails" and "does not fall" in reason


def test_a_missing_time_or_a_single_scale_is_inconclusive():
    assert two_scales_verdict([{"t90": math.nan}], [0.1, 0.05])[0] == "inconclusive"
    assert two_scales_verdict([{"t90": 0.0}], [0.1])[0] == "inconclusive"


def _rows(case: str, density: tuple[float, float, float], agents: list[tuple[float, float, float]], people: int):
    row = {"case": case, "kind": "density", "seed": 0, "people": people}
    out = [{**row, **dict(zip(("t10", "t50", "t90"), density, strict=True))}]
    for seed, times in enumerate(agents):
        out.append({**row, "kind": "agents", "seed": seed, **dict(zip(("t10", "t50", "t90"), times, strict=True))})
    return out


def test_the_gaps_are_the_agents_median_over_the_density_and_the_flow_is_between_10_and_90_percent():
    # the density: 160 of 200 between 10 s and 90 s, J = 2 persons/s; the agents' medians: t50 60 s, t90 99 s,
    # and J from each seed's own t10 and t90: 160/80, 160/100, 160/88 -> median 160/88
    judged = f"bottleneck {LIMIT_WIDTH:g} m"  # the limit reads it at L = 1
    rows = _rows(judged, (10.0, 50.0, 90.0), [(10.0, 65.0, 90.0), (9.0, 40.0, 109.0), (11.0, 60.0, 99.0)],
                 200)  # fmt: skip
    rows += _rows("limit L=2", (20.0, 100.0, 180.0), [(22.0, 100.0, 180.0)] * 3, 800)
    cases, limit = summarise(rows, {judged: ("t50", "t90", "J")}, (1, 2))
    (case,) = cases
    assert case["gaps"]["t50"] == pytest.approx(60.0 / 50.0 - 1.0)
    assert case["gaps"]["t90"] == pytest.approx(99.0 / 90.0 - 1.0)
    assert case["gaps"]["J"] == pytest.approx((160.0 / 88.0) / 2.0 - 1.0)
    assert case["agents_worst_seed"]["t90"] == 109.0 and case["verdict"] == "fails"  # t50 is 20 % late
    assert [r["scale"] for r in limit] == [1, 2]
    assert limit[0]["gap"] == pytest.approx(0.20)  # t50's 20 %, the largest of the three at L = 1
    assert limit[1]["gap"] == pytest.approx(0.10)  # t10's 22/20
    assert limit[1]["agents_median_over_L"]["t50"] == pytest.approx(50.0)


def test_the_scaled_bottleneck_is_the_built_in_one_times_l():
    base = builtin_scenarios()["bottleneck"]()
    one = bottleneck(1.0, 1)
    assert shapely.equals(one.domain.polygon, base.domain.polygon)
    for scale in (2, 4):
        sc = bottleneck(0.8, scale)
        plan = sc.domain.polygon
        assert plan.area == pytest.approx(scale**2 * (80.0 + 2 * 0.8))
        (((x0, y0), (x1, y1)),) = exit_segments(sc.domain)
        assert x0 == x1 == 12.0 * scale and abs(y1 - y0) == pytest.approx(0.8 * scale)
        assert sc.crowd.n == 200 * scale**2 and sc.t_final == 400.0 * scale
        assert tuple(sc.grid.cells) == (120, 80)  # 0.1 L m cells
        room = shapely.from_wkt(sc.crowd.groups[0]["region"])
        assert room.area == pytest.approx(80.0 * scale**2) and plan.contains(room.buffer(-1e-9))


def test_the_informed_crowd_is_on_the_fastest_route_and_the_agents_on_the_forward_cell():
    agents, density = (informed(builtin_scenarios()["hall"](), kind) for kind in ("point-mass", "fokker-planck"))
    assert agents.crowd.guidance == density.crowd.guidance == "fastest-route"
    assert agents.crowd.door_model == "forward-cell" and density.crowd.kind == "fokker-planck"


def test_the_plans_run_on_cells_halved_at_both_scales():
    office = builtin_scenarios()["office"]()
    for kind in ("point-mass", "fokker-planck"):
        assert refined(informed(office, kind)).grid.cells == (120, 56)  # the office's 60 × 28, halved


def test_the_check_is_registered_in_report_order():
    assert "two_scales" in runner.CHECKS and list(runner.CHECKS) == list(CHECK_NAMES)
    assert np.all([k in runner.CLAIMS for k in runner.CHECKS])
