"""Decay rates and ISS gains (analysis.rates), against their closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.rates import GainReport, decay_rate, gains_for_scenario, gains_from_run, iss_gain, mass_quantile_level
from meanfield import ClosedLoop, Domain, ParameterError, paper_scenario


def test_decay_rate_is_twice_alpha_mu2():
    assert decay_rate(0.2, math.pi**2) == pytest.approx(2 * 0.2 * math.pi**2, rel=1e-15)


def test_iss_gain_formula_and_c1():
    g = iss_gain(3.0, 0.1, 4.0)  # sup ρ / (c₂ α_inf), c₂ = 2
    assert g == pytest.approx(3.0 / (2.0 * 0.1), rel=1e-15)
    assert iss_gain(3.0, 0.1, 4.0, c1=0.5) == pytest.approx(2 * g, rel=1e-15)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: decay_rate(0.0, 1.0), "alpha_inf"),
        (lambda: decay_rate(0.1, -1.0), "mu2"),
        (lambda: iss_gain(-1.0, 0.1, 1.0), "sup_rho"),
        (lambda: iss_gain(1.0, 0.1, 1.0, c1=0.0), "c1"),
        (lambda: iss_gain(1.0, 0.1, 1.0, c1=1.5), "c1"),
    ],
)
def test_bad_arguments(call, name):
    with pytest.raises(ParameterError) as exc:
        call()
    assert exc.value.name == name


def test_scenario_gains_constant_alpha_on_the_unit_square():
    """Constant α: α_inf = α₀ and k_p = 2 α₀ π² with μ₂ = π² of the unit square."""
    sc = paper_scenario().with_values({"controller.alpha_schedule": "constant", "controller.alpha": 0.3})
    r = gains_for_scenario(sc, cells=64)
    assert isinstance(r, GainReport)
    assert r.mu2 == pytest.approx(math.pi**2, rel=2e-3)
    assert r.alpha_inf == pytest.approx(0.3, rel=1e-15)
    assert r.k_p == pytest.approx(2 * 0.3 * r.mu2, rel=1e-15)
    assert r.norm_rate == pytest.approx(r.k_p / 2)
    assert r.iss_gain == pytest.approx(r.sup_rho / (math.sqrt(r.mu2) * 0.3), rel=1e-12)
    assert r.to_dict()["conventions"]["V1"].startswith("integral of rho_tilde^2")


def test_scenario_gains_saturating_alpha_at_the_target_minimum():
    sc = paper_scenario()  # saturating, α₀ = 0.2, ρ_floor = 2
    r = gains_for_scenario(sc, mu2=math.pi**2)
    assert r.alpha_inf == pytest.approx(0.2 * r.rho_min / (r.rho_min + 2.0), rel=1e-12)
    assert 0 < r.rho_min < r.sup_rho


def test_gains_from_run_use_the_recorded_densities():
    sc = paper_scenario(seed=1).with_values({"t_final": 0.5, "record_every": 5})
    res = ClosedLoop(sc).run(progress=False)
    r = gains_from_run(res, mu2=math.pi**2)
    dens = res.dataset["density"].values
    assert r.sup_rho == pytest.approx(float(dens.max()), rel=1e-15)
    assert r.rho_min == pytest.approx(float(dens.min()), rel=1e-15)
    obs = r.observed
    assert obs["disturbance_l2"] == 0.0
    assert obs["ultimate_bound"] == pytest.approx(r.iss_gain * obs["sup_v_tilde_second_half"], rel=1e-12)
    assert obs["bound_holds"] == (obs["rho_error_final"] <= obs["ultimate_bound"])


def test_disturbance_enters_the_bound():
    sc = paper_scenario(seed=1).with_values(
        {"t_final": 0.2, "disturbance.kind": "constant", "disturbance.velocity": [0.03, -0.04]}
    )
    r = gains_from_run(ClosedLoop(sc).run(progress=False), mu2=math.pi**2)
    assert r.observed["disturbance_l2"] == pytest.approx(0.05, rel=1e-12)  # |v_a| on a unit area


def test_disk_domain_uses_its_own_eigenvalue():
    sc = paper_scenario().replace(domain=Domain.disk(0.5, (0.5, 0.5)))
    sc = sc.with_values({"target.center": [0.6, 0.6], "robots.layout": "random", "crowd.initial": "uniform"})
    r = gains_for_scenario(sc, cells=64)
    j11 = 1.8411837813406593
    assert r.mu2 == pytest.approx((j11 / 0.5) ** 2, rel=5e-3)
    assert np.isfinite(r.iss_gain)


def test_mass_quantile_level_on_a_hand_example():
    rho = np.array([4.0, 1.0, 3.0, 2.0])
    vol = np.full(4, 0.1)  # masses 0.4, 0.1, 0.3, 0.2 of 1.0
    assert mass_quantile_level(rho, vol, 0.05) == 1.0
    assert mass_quantile_level(rho, vol, 0.1) == 1.0  # the cell holding 1.0 brings 10 %
    assert mass_quantile_level(rho, vol, 0.25) == 2.0
    assert mass_quantile_level(rho, vol, 1.0) == 4.0


def test_bulk_constants_are_finite_where_the_rigorous_ones_are_vacuous():
    """The saturating α of the paper scenario vanishes with ρ: the theorem's α_inf is ~0."""
    r = gains_for_scenario(paper_scenario(), mu2=math.pi**2)
    assert r.alpha_inf < 1e-12  # the target's far corner is nearly empty
    b = r.bulk
    assert b["rho_level"] > r.rho_min
    assert b["alpha"] == pytest.approx(0.2 * b["rho_level"] / (b["rho_level"] + 2.0), rel=1e-12)
    assert b["k_p"] == pytest.approx(2 * b["alpha"] * math.pi**2, rel=1e-12)
