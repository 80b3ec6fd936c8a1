"""A plan's inner doors (:mod:`meanfield.geometry.doors`): a door crosses the plan from wall to wall, and one that
does not is refused naming ``doors[k]`` and what is allowed; the doors go with the plan through its table, and a
block keeps those it leaves standing."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from meanfield.errors import ParameterError
from meanfield.geometry.doors import door_segments
from meanfield.geometry.plan import Plan, plan_from_table

# two 4 m x 4 m rooms side by side, a 0.2 m wall between them with a 1 m opening at y in [1.5, 2.5]
TWO_ROOMS = shapely.from_wkt(
    "POLYGON ((0 0, 4 0, 4 1.5, 4.2 1.5, 4.2 0, 8.2 0, 8.2 4, 4.2 4, 4.2 2.5, 4 2.5, 4 4, 0 4, 0 0))"
)
DOOR = ((4.1, 1.5), (4.1, 2.5))
EXIT = ((8.2, 1.0), (8.2, 2.0))


def test_a_door_across_the_opening_is_kept_and_read_back():
    plan = Plan(TWO_ROOMS, [EXIT], doors=[DOOR])
    assert plan.doors == (DOOR,)
    np.testing.assert_array_equal(door_segments(plan), [DOOR])
    again = plan_from_table(**{k: v for k, v in plan.to_dict().items() if k != "kind"})
    assert again == plan and again.doors == (DOOR,)
    assert door_segments(Plan(TWO_ROOMS, [EXIT])).shape == (0, 2, 2)


@pytest.mark.parametrize(
    ("doors", "allowed"),
    [
        ([((4.1, 1.5), (4.1, 1.5))], "two distinct finite points"),
        ([((4.1, 1.5), (4.1, np.nan))], "two distinct finite points"),
        ([((4.1, 1.6), (4.1, 2.5))], "two ends lie on the plan's walls"),
        ([((1.0, 0.0), (1.0, 5.0))], "two ends lie on the plan's walls"),
        ([((0.0, 1.0), (0.0, 3.0))], "across the plan from one wall to another"),  # along a wall
        ([((8.2, 1.0), (4.2, 1.0))], "clear of exits[0]"),
        ([DOOR, DOOR], "clear of doors[0]"),
        ([((4.1, 1.5),)], "a segment [[x0, y0], [x1, y1]]"),
        ("door", "a list of segments"),
    ],
)
def test_a_door_that_does_not_cross_the_plan_is_refused_naming_it(doors, allowed):
    with pytest.raises(ParameterError) as exc:
        Plan(TWO_ROOMS, [EXIT], doors=doors)
    assert exc.value.name.startswith("doors")
    assert allowed in str(exc.value)


def test_a_block_keeps_the_doors_it_leaves_standing():
    from meanfield.geometry.blocking import blocked_region

    second = ((2.0, 0.0), (2.0, 4.0))  # across the west room
    plan = Plan(TWO_ROOMS, [EXIT, ((0.0, 1.0), (0.0, 2.0))], doors=[DOOR, second])
    kept = blocked_region(plan, shapely.box(1.0, 3.0, 3.0, 4.0))  # the second door would end inside the block
    assert kept.doors == (DOOR,)
    shut = blocked_region(plan, shapely.box(3.9, 1.2, 4.3, 2.8))  # the opening walled up: two rooms, two exits
    assert shut.doors == (second,)
