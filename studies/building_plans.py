"""The WKT of the shipped plans ``office``, ``hall`` and ``rimea-10`` (meanfield/scenarios/*.toml), built with shapely.

Run from the repository's root:  python studies/building_plans.py

Walls are 0.5 m thick and every coordinate is a multiple of 0.5 m (rimea-10: 0.2 m and 0.05 m on
its 0.1 m grid, the doors' edges in the cells' middles), so that the walls lie on
the lines of the scenarios' grids (a wall thinner than a cell would put both of its
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


def rimea_10() -> shapely.Polygon:
    """RiMEA test 10's floor, as JuPedSim's system test (rimea_tests/test_10) draws it: twelve rooms on a 1 m
    corridor (y in [5, 6], x in [0, 18]) with 0.9 m doors, and a 1.2 m passage north to the main exit; walls
    0.2 m thick on the rooms' side (the corridor and the passage keep their widths), on a 0.1 m grid."""
    parts = [box(0, 5, 18, 6), box(6, 6, 7.2, 11)]  # the corridor and the passage to the main exit
    north = ((0, 2.9), (3.1, 5.8), (7.4, 8.9), (9.1, 11.9), (12.1, 14.9), (15.1, 18))
    south = ((0, 2.9), (3.1, 5.9), (6.1, 8.9), (9.1, 11.9), (12.1, 14.9), (15.1, 18))
    north_doors = (1.05, 4.05, 7.65, 10.05, 13.05, 16.05)
    south_doors = (1.05, 4.05, 7.05, 10.05, 13.05, 16.05)
    for (a, b), d in zip(north, north_doors, strict=True):
        parts += [box(a, 6.2, b, 11), box(d, 6, d + 0.9, 6.2)]
    for (a, b), d in zip(south, south_doors, strict=True):
        parts += [box(a, 0, b, 4.8), box(d, 4.8, d + 0.9, 5)]
    return shapely.normalize(shapely.set_precision(unary_union(parts), 0.05))  # (multiples of 0.05 m, no round-off)


def main() -> None:
    from meanfield.scenarios.scenario import builtin_scenarios

    for name, plan in (("office", office()), ("hall", hall()), ("rimea-10", rimea_10())):
        shipped = builtin_scenarios()[name]().domain.polygon
        print(f"{name}: area {plan.area:g} m², same as the shipped plan: {plan.equals(shipped)}")
        print(plan.wkt)


if __name__ == "__main__":
    main()
