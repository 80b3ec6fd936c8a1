"""People in groups (``crowd.initial = "groups"``, :mod:`meanfield.crowds.groups`).

* each group's people stand in its region, in group order, the same for the same seed;
* the informed crowd walks each person's route to its group's exit; an assigned exit that closes
  sends its people to the nearest open one;
* a scenario with groups survives TOML; bad groups are refused naming ``crowd.groups[i]...``.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from meanfield import ClosedLoop, ParameterError
from meanfield.crowds.agent_crowd import initial_positions
from meanfield.crowds.groups import assigned_exits
from meanfield.scenarios.scenario import Scenario, builtin_scenarios

WEST = "POLYGON ((1 1, 6 1, 6 19, 1 19, 1 1))"
EAST = "POLYGON ((24 1, 29 1, 29 19, 24 19, 24 1))"


def _hall(groups, **values):
    """The hall (exits 0 south, 1 north, 2 west, 3 east), informed, with these groups."""
    n = max(sum(g.get("n", 1) for g in groups), 1)  # (a bad group's own n is the error to find)
    return builtin_scenarios()["hall"](seed=3).with_values(
        {"crowd.initial": "groups", "crowd.groups": groups, "crowd.n": n, "crowd.guidance": "geodesic", **values}
    )


def test_each_group_stands_in_its_region_in_order_and_a_seed_gives_the_same_places():
    sc = _hall([{"region": WEST, "n": 30, "exit": 3}, {"region": EAST, "n": 20}])
    x = initial_positions(sc, sc.crowd.n, np.random.default_rng(5))
    west, east = shapely.from_wkt(WEST), shapely.from_wkt(EAST)
    assert shapely.contains_xy(west, x[:30, 0], x[:30, 1]).all()
    assert shapely.contains_xy(east, x[30:, 0], x[30:, 1]).all()
    np.testing.assert_array_equal(x, initial_positions(sc, sc.crowd.n, np.random.default_rng(5)))
    assert assigned_exits(sc.crowd.groups).tolist() == [3] * 30 + [-1] * 20


def test_the_informed_crowd_walks_to_its_group_s_exit_and_to_the_nearest_when_it_closes():
    """People by the west wall sent to the east door cross the hall to it; those without an exit take the nearest
    (the east group: the east door). Then the east door closes early: the west group turns to the nearest open."""
    loop = ClosedLoop(_hall([{"region": WEST, "n": 30, "exit": 3}, {"region": EAST, "n": 20}], t_final=90.0))
    loop.run(progress=False)
    e = loop.crowd.engine
    assert (e.exit_index == 3).all()
    closing = _hall([{"region": WEST, "n": 30, "exit": 3}], t_final=90.0, events=[{"time": 0.5, "close_exit": 3}])
    loop = ClosedLoop(closing)
    loop.run(progress=False)
    e = loop.crowd.engine
    assert (e.exit_index >= 0).all() and not (e.exit_index == 3).any()
    assert loop.crowd.guidance.exit_of.tolist() == [-1] * 30


def test_groups_survive_toml():
    sc = _hall([{"region": WEST, "n": 3, "exit": 0}, {"region": EAST, "n": 2}])
    again = Scenario.from_toml(sc.to_toml())
    assert again.crowd.groups == sc.crowd.groups and again == sc


@pytest.mark.parametrize(
    ("groups", "values", "field"),
    [
        ([{"region": WEST}], {}, "crowd.groups[0].n"),
        ([{"n": 2}], {}, "crowd.groups[0].region"),
        ([{"region": WEST, "n": 2, "door": 1}], {}, "crowd.groups[0].door"),
        ([{"region": WEST, "n": 0}], {}, "crowd.groups[0].n"),
        ([{"region": "POLYGON ((0 0, 1 0))", "n": 2}], {}, "crowd.groups[0].region"),
        ([{"region": "POLYGON ((40 40, 45 40, 45 45, 40 45, 40 40))", "n": 2}], {}, "crowd.groups[0].region"),
        ([{"region": WEST, "n": 2, "exit": 4}], {}, "crowd.groups[0].exit"),
        ([{"region": WEST, "n": 2, "exit": -1}], {}, "crowd.groups[0].exit"),
        ([{"region": WEST, "n": 2}], {"crowd.n": 3}, "crowd.n"),
        ([{"region": WEST, "n": 2}], {"crowd.kind": "fokker-planck"}, "crowd.initial"),
        ([{"region": WEST, "n": 2}], {"crowd.initial": "uniform"}, "crowd.groups"),
    ],
)
def test_bad_groups_are_refused_naming_the_field(groups, values, field):
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(_hall(groups, **values))
    assert exc.value.name == field


def test_groups_are_needed_with_initial_groups():
    with pytest.raises(ParameterError) as exc:
        builtin_scenarios()["hall"](seed=0).with_values({"crowd.initial": "groups"})
    assert exc.value.name == "crowd.groups"
