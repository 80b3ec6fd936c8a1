"""The WKT of the shipped plans ``office`` and ``hall`` (meanfield/scenarios/*.toml), built with shapely.

Run from the repository's root:  python studies/building_plans.py

Walls are 0.5 m thick and every coordinate is a multiple of 0.5 m, so that the walls lie on
the lines of the scenarios' 0.5 m grids (a wall thinner than a cell would put both of its
sides in one cut cell).  The printed WKT is what the TOML files hold; the script checks it.
"""

from __future__ import annotations

import shapely
from shapely import box
from shapely.ops import unary_union


def office() -> shapely.Polygon:
    """30 m × 14 m: eight 7 m × 5.5 m rooms on both sides of a 2 m corridor, 1 m doors."""
    parts = [box(0, 6, 30, 8)]  # the corridor
    for a, b in ((0, 7), (7.5, 14.5), (15, 22), (22.5, 30)):
        parts += [box(a, 0, b, 5.5), box(a, 8.5, b, 14)]  # the rooms, south and north
        door = round((a + b) / 2 * 2) / 2 - 0.5
        parts += [box(door, 5.5, door + 1, 6), box(door, 8, door + 1, 8.5)]  # through the corridor's walls
    return shapely.normalize(unary_union(parts))


def hall() -> shapely.Polygon:
    """30 m × 20 m with six 1 m square pillars."""
    room = box(0, 0, 30, 20)
    for cx in (7.5, 15, 22.5):
        for cy in (6.5, 13.5):
            room = room.difference(box(cx - 0.5, cy - 0.5, cx + 0.5, cy + 0.5))
    return shapely.normalize(room)


def main() -> None:
    from meanfield.scenarios.scenario import builtin_scenarios

    for name, plan in (("office", office()), ("hall", hall())):
        shipped = builtin_scenarios()[name]().domain.polygon
        print(f"{name}: area {plan.area:g} m², same as the shipped plan: {plan.equals(shipped)}")
        print(plan.wkt)


if __name__ == "__main__":
    main()
