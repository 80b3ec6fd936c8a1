"""Events during a run (``[[events]]``, issue 31 item 3): an exit closes mid-run.

* nobody leaves through a closed exit after it closes; the others take everyone;
* the informed crowd plans again (its routes no longer end at the closed exit), and so does a
  controller that plans to the exits (the evacuation controller's potential), as they learn of it;
* static signs keep their stations and headings;
* closing the last exit ends the run, reported as "no exit left";
* summary.json lists the events, the evacuation figure draws them;
* a scenario's events survive TOML; bad events are refused naming ``events[i]...`` (a warning for a
  time outside the run), and the command line exits with 2;
* JuPedSim's bodies: none is routed through the closed exit;
* the density: the closed exit takes no mass in any of the ways its exits act (the solver's sink, the
  congested doors, the sink once per period, a drift's outflow), mass is conserved, and its guidance
  plans again.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from meanfield.cli.app import main
from meanfield.errors import ParameterError
from meanfield.scenarios.scenario import Scenario, builtin_scenarios
from meanfield.simulation.loop import ClosedLoop

CLOSE_AT = 5.0


def hall(**values):
    """The shipped hall (four 2 m doors), 200 informed point masses, exit 0 closing at 5 s."""
    return builtin_scenarios()["hall"](seed=0).with_values(
        {"crowd.guidance": "geodesic", "events": [{"time": CLOSE_AT, "close_exit": 0}], **values}
    )


@pytest.mark.parametrize("guidance", ["geodesic", "fastest-route", "hughes"])
def test_nobody_leaves_through_an_exit_after_it_closes_and_the_others_take_everyone(guidance):
    loop = ClosedLoop(hall(**{"crowd.guidance": guidance}))
    s = loop.run(progress=False).summary
    engine = loop.crowd.engine
    through_0 = engine.exit_time[engine.exit_index == 0]
    assert len(through_0) > 0 and through_0.max() <= CLOSE_AT + 1e-9  # some left before, none after
    assert s["evacuation_time_100"] is not None and engine.remaining() == 0
    assert s["events"] == [{"time": CLOSE_AT, "at": CLOSE_AT, "close_exit": 0, "exits_open": 3}]
    assert s["no_exit_left"] is False
    open_run = ClosedLoop(hall(events=[], **{"crowd.guidance": guidance})).run(progress=False).summary
    assert "events" not in open_run
    assert s["evacuated_per_exit"][0] < open_run["evacuated_per_exit"][0]


def test_the_informed_crowd_and_the_evacuation_controller_plan_again():
    loop = ClosedLoop(hall(**{"controller.kind": "evacuation"}))
    x0, x1, y0, y1 = loop.scenario.domain.bounds
    mid = np.mean(np.asarray(loop.scenario.domain.exits[0], float), axis=0)
    inward = np.array([x0 + x1, y0 + y1]) / 2 - mid
    near_door = (mid + 0.5 * inward / np.linalg.norm(inward))[None]  # half a metre inside the door that closes
    controller = loop.controller
    before = loop.crowd.guidance.routes.distance(near_door)[0]
    grad_before = controller.grad_phi
    while loop.t < CLOSE_AT + 0.5 * loop.dt:
        loop.step()
    after = loop.crowd.guidance.routes.distance(near_door)[0]
    assert before < 1.0 and after > 5.0  # the nearest exit is now another door, metres away
    assert len(loop.crowd.guidance.routes.segs) == 3 and len(controller.eikonal.segs) == 3
    assert controller.grad_phi is not grad_before


def test_static_signs_keep_their_stations_and_headings():
    loop = ClosedLoop(hall(**{"crowd.guidance": "signs", "controller.kind": "static-signs"}))
    c = loop.controller
    stations, bearings = c.stations.copy(), c.bearings.copy()
    while loop.t < CLOSE_AT + 3.0:
        loop.step()
    assert loop.events_done
    np.testing.assert_array_equal(c.stations, stations)
    np.testing.assert_array_equal(c.bearings, bearings)  # pointing where they pointed, to the closed exit too
    turn = np.angle(np.exp(1j * (loop.robots.headings - bearings)))
    np.testing.assert_allclose(turn, 0.0, atol=1e-3)


def test_closing_the_last_exit_ends_the_run_with_no_exit_left():
    events = [{"time": 2.0, "close_exit": k} for k in range(4)]
    result = ClosedLoop(hall(events=events)).run(progress=False)
    s = result.summary
    assert s["status"] == "completed" and s["no_exit_left"] is True
    assert "no exit left" in s["message"] and s["events"][-1]["at"] == 2.0 and s["time_final"] < 2.2
    assert [e["exits_open"] for e in s["events"]] == [3, 2, 1, 0]


def test_events_survive_toml_and_are_drawn(tmp_path):
    sc = hall()
    again = Scenario.from_toml(sc.to_toml())
    assert again.events == sc.events and again == sc
    out = tmp_path / "run"
    assert main(["run", "hall", "--out", str(out), "--quiet", "--set", "crowd.guidance=geodesic",
                 "--set", "events=[{time = 5.0, close_exit = 0}]", "--set", "t_final=8.0"]) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    assert summary["events"][0]["close_exit"] == 0 and (out / "evacuation.png").stat().st_size > 0


@pytest.mark.parametrize(
    "event, field",
    [
        ({"time": 1.0, "close_exit": 4}, "events[0].close_exit"),  # the hall has exits 0-3
        ({"time": 1.0, "close_exit": -1}, "events[0].close_exit"),
        ({"time": 1.0, "block": "POLYGON ((40 40, 41 40, 41 41, 40 40))"}, "events[0].block"),  # outside the hall
        ({"time": 1.0}, "events[0]"),
        ({"close_exit": 0}, "events[0].time"),
        ({"time": 1.0, "close_exit": 0, "open_exit": 1}, "events[0].open_exit"),
        ({"time": float("nan"), "close_exit": 0}, "events[0].time"),
    ],
)
def test_bad_events_are_refused_naming_them(event, field, tmp_path):
    with pytest.raises(ParameterError) as exc:
        hall(events=[event])
    assert exc.value.name == field
    toml = json.dumps([event]).replace('": ', " = ").replace('{"', "{").replace(', "', ", ").replace("NaN", "nan")
    out = tmp_path / "o"
    assert main(["run", "hall", "--out", str(out), "--quiet", "--set", f"events={toml}"]) == 2


def test_an_event_outside_the_run_is_a_warning():
    with pytest.warns(UserWarning, match=r"events\[0\]\.time = 500"):
        hall(events=[{"time": 500.0, "close_exit": 0}])


@pytest.mark.requires("jupedsim")
def test_jupedsim_s_bodies_stop_leaving_through_a_closed_exit():
    """No body is routed through the closed exit after the event (the last passage is at the event's step) and the
    informed bodies all get out by the other three."""
    loop = ClosedLoop(hall(**{"crowd.kind": "jupedsim"}))
    s = loop.run(progress=False).summary
    engine = loop.crowd.engine
    through_0 = engine.exit_time[engine.exit_index == 0]
    assert len(through_0) > 0 and through_0.max() <= CLOSE_AT + 1e-9
    assert s["evacuation_time_100"] is not None and s["evacuated_per_exit"][0] == len(through_0)
    assert engine.open_exits.tolist() == [False, True, True, True]


@pytest.mark.parametrize(
    ("guidance", "congestion"),
    [
        ("geodesic", "none"),  # a drift of the guidance's own: the sink with its outflow, after each solver step
        ("geodesic", "linear"),  # the congested doors
        ("signs", "none"),  # the sink once per control period
        ("hughes", "none"),  # a drift that depends on the density: its outflow refreshed every period
        ("hughes", "linear"),
    ],
)
def test_the_density_s_exit_closes_in_every_way_its_exits_act(guidance, congestion):
    """The density: no mass leaves through exit 0 after it closes, the mass in Ω plus the mass out is the initial
    mass to round-off, the other exits go on taking mass, and a guidance that walks to the exits plans again."""
    sc = hall(**{"crowd.kind": "fokker-planck", "crowd.guidance": guidance, "crowd.congestion": congestion,
                 "t_final": 12.0})  # fmt: skip
    loop = ClosedLoop(sc)
    crowd = loop.crowd
    X, Y = loop.grid.centers
    above_exit_0 = (np.abs(X - 15.25) < 0.3) & (np.abs(Y - 1.25) < 0.3)  # exit 0: the south door, x in [14, 16]
    while loop.t < CLOSE_AT - 1e-9:
        loop.step()
    at_event = crowd.out_per_exit.copy()
    assert at_event[0] > 0
    drift_before = crowd.velocity(loop.robots)
    loop.step()  # the event is applied before this step
    drift_after = crowd.velocity(loop.robots)
    while loop.t < sc.t_final - 1e-9:
        loop.step()
    out = crowd.out_per_exit
    assert out[0] == pytest.approx(at_event[0], rel=0, abs=1e-15)
    assert (out[1:] > at_event[1:]).all()
    total = loop.grid.integrate(crowd.rho) + out.sum()
    assert total == pytest.approx(crowd.initial_mass, rel=1e-12)
    if guidance != "signs":  # down the route just above the south door: towards it before, away after
        assert drift_before[1][above_exit_0[:, :-1]].mean() < 0 < drift_after[1][above_exit_0[:, :-1]].mean()
