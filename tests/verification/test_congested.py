"""The check of Steps I and II on the congested plant (``meanfield verify``, key ``congested``): its decision rule
on made-up runs, and the check end to end on its reference plant (quick: about 4 s)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from meanfield import paper_scenario
from verification import runner
from verification.congested import (
    CLAIM,
    IDENTITY_RTOL,
    PLANT_TOL,
    V1_RTOL,
    CongestedRun,
    TrackingRun,
    check_congested,
    congested_verdict,
    reference_plant,
)


def _run(n: int = 6, **changes) -> CongestedRun:
    """A run that meets every claim: identities to round-off, dV₂/dt well below 0, nothing capped."""
    t = np.linspace(0.0, 1.0, n)
    cols = {
        "t": t,
        "V2": np.linspace(10.0, 9.0, n),
        "step1_excess": np.full(n, 1e-16),
        "step2_excess": np.full(n, -2e-16),
        "plant_rate": np.full(n, -0.5),
        "plant_excess": np.full(n, 1e-12),
        "capped_mass": np.zeros(n),
        "residual_share": np.zeros(n),
        "g_least": np.full(n, 0.6),
        "peak": np.full(n, 2.0),
        "speed": np.full(n, 100.0),
    }
    cols.update(changes)
    return CongestedRun(**cols)


def _tracking(n: int = 6, V1=None, capped=None) -> TrackingRun:
    t = np.linspace(0.0, 1.0, n)
    return TrackingRun(
        t, np.geomspace(1.0, 0.5, n) if V1 is None else V1, np.zeros(n) if capped is None else capped, 0.03
    )


def test_a_run_that_meets_every_claim_holds_for_both_laws():
    for law in ("compensate", "ignore"):
        verdict, figures = congested_verdict(_run(), _tracking(), law)
        assert verdict == "holds" and figures["V2_monotone"] and figures["V1_monotone_alone"]


def test_an_identity_off_by_more_than_round_off_fails():
    for col in ("step1_excess", "step2_excess"):
        bad = np.full(6, 0.1 * IDENTITY_RTOL)
        bad[3] = 10 * IDENTITY_RTOL
        verdict, figures = congested_verdict(_run(**{col: bad}), _tracking(), "compensate")
        assert verdict == "fails" and "misses its claim" in figures["reason"]
    within = np.full(6, 0.5 * IDENTITY_RTOL)
    assert congested_verdict(_run(step1_excess=within), _tracking(), "compensate")[0] == "holds"


def test_capped_mass_makes_the_compensating_law_inconclusive_and_never_excuses_the_papers():
    """Where g < g_min the compensating law's guarantee has no sign: a rising V₂ there is inconclusive, with the share
    of the mass in the reason; the paper's law claims its identity everywhere, so the same run fails for it."""
    capped = np.array([0.0, 0.0, 0.12, 0.2, 0.0, 0.0])
    rate = np.full(6, -0.5)
    rate[3] = 2 * PLANT_TOL  # V₂ rises along the solver at a capped record
    verdict, figures = congested_verdict(_run(capped_mass=capped, plant_rate=rate), _tracking(), "compensate")
    assert verdict == "inconclusive" and "jams on up to 20% of the mass" in figures["reason"]
    assert "V₂ rose" in figures["reason"] and not figures["V2_monotone"]
    assert congested_verdict(_run(capped_mass=capped, plant_rate=rate), _tracking(), "ignore")[0] == "fails"
    rate[3], rate[1] = -0.5, 2 * PLANT_TOL  # the same rise where nothing is capped: the guarantee applied, and failed
    assert congested_verdict(_run(capped_mass=capped, plant_rate=rate), _tracking(), "compensate")[0] == "fails"


def test_v1_rising_under_the_tracked_field_alone_fails_where_nothing_is_capped():
    V1 = np.array([1.0, 0.9, 0.8, 0.8 + 10 * V1_RTOL, 0.7, 0.6])
    verdict, figures = congested_verdict(_run(), _tracking(V1=V1), "compensate")
    assert verdict == "fails" and "V₁ rose" in figures["reason"]
    capped = np.array([0.0, 0.0, 0.1, 0.1, 0.0, 0.0])  # the rise between two capped records: not judged
    assert congested_verdict(_run(), _tracking(V1=V1, capped=capped), "compensate")[0] == "inconclusive"
    small = np.array([1.0, 0.9, 0.8, 0.8 + 0.5 * V1_RTOL, 0.7, 0.6])
    assert congested_verdict(_run(), _tracking(V1=small), "compensate")[0] == "holds"


def test_the_reference_plant_is_congested_in_metres():
    sc = reference_plant("compensate", 3000, 5.0)
    assert sc.units == "SI" and sc.congestion_model == "linear" and sc.crowd.kind == "fokker-planck"
    assert sc.robots.u_max is None and sc.controller.dvd_dt == "model"
    assert reference_plant("ignore", 3000, 5.0).controller.congestion == "ignore"


@pytest.fixture(scope="module")
def quick_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("congested")
    return out, check_congested(paper_scenario(), out, quick=True)


def test_the_check_end_to_end(quick_result):
    """On the dense crowd the compensating law holds (identities to round-off) and the paper's fails (its Step-I
    identity misses the share of g); on the jammed crowd the compensating law is inconclusive, naming the mass."""
    out, r = quick_result
    assert r.key == "congested" and r.claim == CLAIM and r.verdict == "holds", r.summary
    verdicts = {(k["crowd"], k["law"]): k for k in r.cases}
    dense, paper = verdicts[("dense", "compensate")], verdicts[("dense", "ignore")]
    assert dense["verdict"] == "holds" and dense["step1_identity_excess"] <= IDENTITY_RTOL
    assert dense["capped_mass_max"] == 0 and 0.1 < dense["g_least"] < 0.9  # g matters, never below g_min
    assert paper["verdict"] == "fails" and paper["step1_identity_excess"] > 0.05
    jammed = verdicts[("jammed", "compensate")]
    assert jammed["verdict"] == "inconclusive" and jammed["capped_mass_max"] > 0.05
    assert "jams on up to" in jammed["reason"] and jammed["step2_identity_excess"] <= IDENTITY_RTOL
    assert (out / "figures" / "congested.png").is_file()
    assert json.loads(json.dumps(r.to_dict()))["verdict"] == "holds"
    assert r.seconds < 60


def test_the_check_is_registered():
    assert runner.CHECKS["congested"] is check_congested and runner.CLAIMS["congested"] == CLAIM
