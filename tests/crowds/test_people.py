"""People are not all alike: pre-movement times and compliance (meanfield.crowds.agent_crowd.Individuals).

Docs pages *Buildings*, "People are not all alike", and *Scenarios*, "People who wait, people who
do not follow".

* RiMEA's test 5 (10 persons in an 8 m × 5 m room, pre-movement times uniform between 10 and
  100 s): each person starts moving within one step of its drawn time and not before, for the
  point masses (whose noise does not move a waiting person) and for JuPedSim's bodies;
* the laws: uniform times in their range, lognormal times with their median and spread;
* the defaults draw nothing: a short ``paper`` run with ``crowd.premovement = "none"`` and
  ``crowd.compliance = 1.0`` written out is bit for bit the run without them; with the options,
  the draws come after every draw the model made before (humans, robots' headings, walkers'
  headings are the defaults');
* compliance 0.95: the share of non-followers over many humans is within binomial error of 5 %,
  and a non-follower never receives the robots' field (it walks the random walk of ``[view]``,
  and no sign reaches it);
* RSET counts from the alarm: a constant pre-movement time adds itself to the evacuation time;
* a seed gives the same times, the same non-followers and the same run;
* the refusals name the field: a compliance outside [0, 1] or not a number, pre-movement times
  below 0 (a law with low < 0, high < low, an unknown law, a median <= 0, ...), compliance with a
  baseline guidance, either option on a crowd that does not model individuals (the density),
  and the command line exits with status 2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario
from meanfield.cli.app import main
from meanfield.crowds.agent_crowd import Individuals, draw_premovement, premovement_law
from meanfield.geometry.plan import Plan
from meanfield.scenarios.scenario import builtin_scenarios
from meanfield.scenarios.sections import TargetSpec
from meanfield.signs.robots import navigation_velocity

RIMEA_5 = {"law": "uniform", "low": 10.0, "high": 100.0}


def rimea_room(kind: str = "point-mass", seed: int = 1, **extra):
    """RiMEA's test 5: a room 8 m × 5 m, a 1 m exit in the middle of a short wall, 10 persons."""
    room = Plan.from_wkt("POLYGON ((0 0, 8 0, 8 5, 0 5, 0 0))")
    room = Plan(room.polygon, [((8.0, 2.0), (8.0, 3.0))])
    sc = builtin_scenarios()["l-room"](seed=seed).replace(
        domain=room, target=TargetSpec(center=(8.0, 2.5), std=2.0), t_final=110.0
    )
    values = {
        "grid.cells": [16, 10],
        "crowd.kind": kind,
        "crowd.n": 10,
        "crowd.congestion": "none",
        "crowd.premovement": RIMEA_5,
        "robots.n": 1,
        "controller.kind": "static-signs",
        "record_every": 1,
        **extra,
    }
    return sc.with_values(values)


def first_moves(loop: ClosedLoop, until: float) -> tuple[np.ndarray, np.ndarray]:
    """The start time of each human's first step that moved it, and its position until then."""
    n = loop.crowd.n
    x0 = loop.crowd.positions.copy()
    start = np.full(n, np.nan)
    still = np.ones(n, dtype=bool)  # not moved yet
    while loop.t < until:
        t = loop.t
        loop.step()
        x = loop.crowd.positions
        moved = still & ~np.all(np.abs(x - x0) <= 1e-12, axis=1)  # (NaN: it left, so it moved)
        start[moved] = t
        still &= ~moved
    return start, still


@pytest.mark.parametrize("kind", ["point-mass", pytest.param("jupedsim", marks=pytest.mark.requires("jupedsim"))])
def test_rimea_5_each_person_starts_within_one_step_of_its_time_and_not_before(kind):
    sc = rimea_room(kind)
    assert sc.crowd.sigma > 0  # the point masses have noise: it must not move those who wait
    loop = ClosedLoop(sc)
    start, still = first_moves(loop, 101.0)
    tau = loop.crowd.individuals.times
    assert tau.shape == (10,) and np.all((tau >= 10.0) & (tau <= 100.0)) and len(np.unique(tau)) == 10
    assert not still.any()  # everyone moved by t = 101 s
    assert np.all(start >= tau)  # not before its time: its position unchanged at every step until then
    assert np.all(start < tau + sc.dt)  # within one step
    s = loop.crowd.summary()
    assert s["premovement_law"] == "uniform" and s["premovement_max"] == tau.max()


def test_the_laws_draw_in_their_range_and_with_their_median():
    rng = np.random.default_rng(7)
    u = draw_premovement(premovement_law(RIMEA_5), 100_000, rng)
    assert u.min() >= 10.0 and u.max() <= 100.0 and np.mean(u) == pytest.approx(55.0, abs=0.5)
    law = premovement_law({"law": "lognormal", "median": 30, "sigma": 0.6})
    assert law == {"law": "lognormal", "median": 30.0, "sigma": 0.6}
    t = draw_premovement(law, 100_000, rng)
    assert t.min() > 0 and np.median(t) == pytest.approx(30.0, rel=0.01)
    assert np.std(np.log(t)) == pytest.approx(0.6, rel=0.01)
    fixed = draw_premovement(premovement_law({"law": "uniform", "low": 5, "high": 5}), 4, rng)
    assert np.all(fixed == 5.0)
    assert premovement_law("none") is None


def _short_paper(**values):
    sc = paper_scenario(seed=3).with_values({"t_final": 0.3, **values})
    loop = ClosedLoop(sc)
    loop.run(progress=False)
    return loop


def test_the_defaults_leave_a_paper_run_bit_for_bit_the_same():
    plain = _short_paper()
    explicit = _short_paper(**{"crowd.premovement": "none", "crowd.compliance": 1.0})
    assert explicit.scenario.crowd.premovement == "none" and explicit.scenario.crowd.compliance == 1.0
    assert plain.crowd.individuals is None and explicit.crowd.individuals is None
    assert explicit.crowd.engine.standing is None
    np.testing.assert_array_equal(plain.crowd.positions, explicit.crowd.positions)
    np.testing.assert_array_equal(plain.robots.positions, explicit.robots.positions)
    np.testing.assert_array_equal(plain.robots.headings, explicit.robots.headings)
    assert plain.crowd.summary() == explicit.crowd.summary()
    assert "premovement_law" not in plain.crowd.summary() and "non_followers" not in plain.crowd.summary()
    # and the options do change the run: the same scenario with people who wait is another run
    waiting = _short_paper(**{"crowd.premovement": {"law": "uniform", "low": 0.1, "high": 0.2}})
    assert not np.array_equal(plain.crowd.positions, waiting.crowd.positions)


def test_the_draws_come_after_every_draw_the_model_made_before():
    """Humans, robots' headings and walkers' headings are the defaults'; then the times and who follows."""
    base = builtin_scenarios()["l-room"](seed=4).with_values({"crowd.n": 60})
    a = ClosedLoop(base)
    b = ClosedLoop(base.with_values({"crowd.premovement": RIMEA_5, "crowd.compliance": 0.8}))
    np.testing.assert_array_equal(a.crowd.positions, b.crowd.positions)
    np.testing.assert_array_equal(a.robots.headings, b.robots.headings)
    assert b.crowd.individuals.times is None  # nothing drawn before the first step
    x0 = b.crowd.positions.copy()
    for loop in (a, b):  # the first step's velocities: the walkers' headings are drawn first
        loop.crowd.drift(loop.robots, 0.0, base.dt)
    np.testing.assert_array_equal(a.crowd.view.headings, b.crowd.view.headings)
    assert b.crowd.individuals.times is not None and b.crowd.individuals.ignores is not None
    b.step()
    np.testing.assert_array_equal(b.crowd.positions, x0)  # everyone still waits (τ >= 10 s)


def test_the_share_of_non_followers_is_within_binomial_error():
    n, p = 200_000, 0.05
    people = Individuals(n, "none", 0.95, np.random.default_rng(11))
    people.start()
    share = people.ignores.mean()
    assert abs(share - p) < 4.0 * math.sqrt(p * (1 - p) / n)
    assert len(people.walkers) == people.ignores.sum() and people.walk.headings.shape == (len(people.walkers),)


def test_non_followers_never_receive_the_robots_field():
    """l-room, 2000 humans, compliance 0.95: about 5 % walk the random walk of [view] at its speed,
    whatever the signs say, and no sign reaches them; the others follow the field."""
    sc = builtin_scenarios()["l-room"](seed=2).with_values(
        {"crowd.n": 2000, "crowd.compliance": 0.95, "crowd.congestion": "none", "t_final": 5.0}
    )
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    n = sc.crowd.n
    seen: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    step = crowd.engine.step

    def spy(drift: np.ndarray, t: float, dt: float) -> None:  # what the engine is given, and the walk then
        seen.append((crowd.positions.copy(), drift.copy(), crowd.individuals.walk.headings.copy()))
        step(drift, t, dt)

    crowd.engine.step = spy
    for _ in range(5):
        loop.step()
        x, drift, theta = seen[-1]
        w = crowd.individuals.walkers
        assert abs(len(w) / n - 0.05) < 4.0 * math.sqrt(0.05 * 0.95 / n)
        here = np.isfinite(x[w, 0])
        walk = 0.7 * np.column_stack([np.cos(theta), np.sin(theta)])
        np.testing.assert_allclose(drift[w][here], walk[here], atol=1e-12)
        field = navigation_velocity(crowd.kernel, loop.robots.positions, loop.robots.headings, x[w][here], None)
        assert (np.hypot(*field.T) > 0.1).any()  # a sign is strong where some of them stand ...
        assert not crowd.reached[w].any() and crowd.reached.sum() > 0  # ... and reaches none of them
    s = crowd.summary()
    assert s["non_followers"] == len(crowd.individuals.walkers) and s["compliance"] == 0.95


@pytest.mark.requires("jupedsim")
def test_jupedsim_bodies_ignore_the_signs_as_the_point_masses_do():
    """The bodies' desired velocity: the walk of [view] for the non-followers, 0 for those who wait."""
    sc = rimea_room("jupedsim", **{"crowd.n": 40, "crowd.compliance": 0.5, "crowd.premovement": "none"})
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    given: list[tuple[np.ndarray, np.ndarray]] = []
    step = crowd.engine.step

    def spy(drift: np.ndarray, t: float, dt: float) -> None:
        given.append((drift.copy(), crowd.individuals.walk.headings.copy()))
        step(drift, t, dt)

    crowd.engine.step = spy
    for _ in range(10):
        loop.step()
        drift, theta = given[-1]
        w = crowd.individuals.walkers
        assert 0 < len(w) < 40 and not crowd.reached[w].any()
        here = crowd.engine.active[w]  # (who is still in the room after the step)
        walk = 0.7 * np.column_stack([np.cos(theta), np.sin(theta)])
        np.testing.assert_allclose(drift[w][here], walk[here], atol=1e-12)
    assert crowd.summary()["non_followers"] == len(crowd.individuals.walkers)


def test_rset_counts_from_the_alarm_a_constant_wait_adds_itself():
    """An informed crowd in a corridor, no noise: everyone waiting 5 s leaves 5 s later, to the step."""
    room = Plan.from_wkt("POLYGON ((0 0, 10 0, 10 2, 0 2, 0 0))")
    room = Plan(room.polygon, [((10.0, 0.0), (10.0, 2.0))])
    sc = builtin_scenarios()["l-room"](seed=3).replace(
        domain=room, target=TargetSpec(center=(10.0, 1.0), std=2.0), t_final=25.0
    )
    values = {
        "grid.cells": [20, 4],
        "crowd.n": 30,
        "crowd.sigma": 0.0,
        "crowd.guidance": "geodesic",
        "crowd.congestion": "none",
        "robots.n": 2,
        "controller.kind": "static-signs",
    }
    now = ClosedLoop(sc.with_values(values)).run(progress=False).summary
    later = ClosedLoop(sc.with_values({**values, "crowd.premovement": {"law": "uniform", "low": 5, "high": 5}}))
    s = later.run(progress=False).summary
    assert now["fraction_evacuated"] == s["fraction_evacuated"] == 1.0
    assert s["evacuation_time_100"] == pytest.approx(now["evacuation_time_100"] + 5.0, abs=1e-9)
    assert s["evacuation_time_95"] == pytest.approx(now["evacuation_time_95"] + 5.0, abs=1e-9)


def test_a_seed_gives_the_same_people_and_the_same_run():
    values = {
        "crowd.n": 80,
        "crowd.premovement": {"law": "lognormal", "median": 1.0, "sigma": 0.5},
        "crowd.compliance": 0.8,
        "t_final": 3.0,
    }

    def run(seed: int) -> ClosedLoop:
        loop = ClosedLoop(builtin_scenarios()["l-room"](seed=seed).with_values(values))
        loop.run(progress=False)
        return loop

    a, b, other = run(5), run(5), run(6)
    np.testing.assert_array_equal(a.crowd.individuals.times, b.crowd.individuals.times)
    np.testing.assert_array_equal(a.crowd.individuals.ignores, b.crowd.individuals.ignores)
    np.testing.assert_array_equal(a.crowd.positions, b.crowd.positions)
    assert a.crowd.summary() == b.crowd.summary()
    assert not np.array_equal(a.crowd.individuals.times, other.crowd.individuals.times)


BAD = [
    ({"crowd.compliance": 1.5}, "crowd.compliance"),
    ({"crowd.compliance": -0.1}, "crowd.compliance"),
    ({"crowd.compliance": "most"}, "crowd.compliance"),
    ({"crowd.compliance": True}, "crowd.compliance"),
    ({"crowd.compliance": float("nan")}, "crowd.compliance"),
    ({"crowd.premovement": {"law": "uniform", "low": -1, "high": 10}}, "crowd.premovement.low"),
    ({"crowd.premovement": {"law": "uniform", "low": 20, "high": 10}}, "crowd.premovement.high"),
    ({"crowd.premovement": {"law": "uniform", "low": 1}}, "crowd.premovement.high"),
    ({"crowd.premovement": {"law": "uniform", "low": 1, "high": 2, "mean": 3}}, "crowd.premovement.mean"),
    ({"crowd.premovement": {"law": "weibull", "low": 1, "high": 2}}, "crowd.premovement.law"),
    ({"crowd.premovement": {"low": 1, "high": 2}}, "crowd.premovement.law"),
    ({"crowd.premovement": {"law": "lognormal", "median": 0, "sigma": 0.5}}, "crowd.premovement.median"),
    ({"crowd.premovement": {"law": "lognormal", "median": -3, "sigma": 0.5}}, "crowd.premovement.median"),
    ({"crowd.premovement": {"law": "lognormal", "median": 30, "sigma": -1}}, "crowd.premovement.sigma"),
    ({"crowd.premovement": {"law": "lognormal", "median": "soon", "sigma": 1}}, "crowd.premovement.median"),
    ({"crowd.premovement": "some"}, "crowd.premovement"),
    ({"crowd.premovement": 30}, "crowd.premovement"),
]


@pytest.mark.parametrize("values, field", BAD)
def test_bad_input_is_refused_naming_the_field(values, field):
    with pytest.raises(ParameterError) as info:
        paper_scenario(seed=0).with_values(values)
    assert info.value.name == field


def test_either_option_on_a_crowd_of_no_individuals_is_refused_naming_it():
    for values, field in [
        ({"crowd.compliance": 0.9}, "crowd.compliance"),
        ({"crowd.premovement": RIMEA_5}, "crowd.premovement"),
    ]:
        with pytest.raises(ParameterError) as info:
            paper_scenario(seed=0).with_values({"crowd.kind": "fokker-planck", **values})
        assert info.value.name == field and "models_individuals" in str(info.value)
    # the density with the defaults, and the agents with the options, are accepted
    assert paper_scenario(seed=0).with_values({"crowd.kind": "fokker-planck"}).crowd.compliance == 1.0
    sc = paper_scenario(seed=0).with_values({"crowd.kind": "point-mass", "crowd.compliance": 0.9})
    assert sc.crowd.compliance == 0.9


def test_compliance_with_a_baseline_is_refused_and_pre_movement_is_not():
    with pytest.raises(ParameterError) as info:  # when the scenario is read, so that a sweep refuses it before a run
        builtin_scenarios()["l-room"](seed=0).with_values({"crowd.guidance": "geodesic", "crowd.compliance": 0.9})
    assert info.value.name == "crowd.compliance" and "signs" in str(info.value)
    waiting = builtin_scenarios()["l-room"](seed=0).with_values(
        {"crowd.guidance": "geodesic", "crowd.premovement": RIMEA_5}
    )
    assert ClosedLoop(waiting).crowd.individuals is not None


def test_the_command_line_exits_with_status_2_naming_the_field(capsys, tmp_path):
    out = str(tmp_path / "never-written")
    assert main(["run", "paper", "--out", out, "--set", "crowd.compliance=1.5"]) == 2
    assert "crowd.compliance" in capsys.readouterr().err
    bad = 'crowd.premovement={law="uniform", low=-5, high=10}'
    assert main(["run", "paper", "--out", out, "--set", bad]) == 2
    assert "crowd.premovement.low" in capsys.readouterr().err
    assert not (tmp_path / "never-written").exists()
