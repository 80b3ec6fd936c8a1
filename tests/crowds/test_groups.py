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
        ([{"region": WEST, "n": 2, "exit": 1}], {"crowd.kind": "fokker-planck"}, "crowd.groups[0].exit"),
        ([{"region": WEST, "n": 2}], {"crowd.initial": "uniform"}, "crowd.groups"),
    ],
)
def test_bad_groups_are_refused_naming_the_field(groups, values, field):
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(_hall(groups, **values))
    assert exc.value.name == field


def test_a_crowd_that_places_no_groups_is_refused_naming_crowd_initial():
    """A crowd kind whose record says no ``places_groups`` (a plugin's) is refused with groups, naming
    ``crowd.initial``."""
    from meanfield import plugins
    from meanfield.capabilities import CrowdCapabilities
    from meanfield.crowds.agent_crowd import point_mass_crowd

    def plain_crowd(ctx):  # the point masses without their capabilities
        return point_mass_crowd(ctx)

    plugins.register("crowd", "plain-test-crowd", plain_crowd, capabilities=CrowdCapabilities())
    try:
        with pytest.raises(ParameterError) as exc:
            _hall([{"region": WEST, "n": 2}], **{"crowd.kind": "plain-test-crowd"})
        assert exc.value.name == "crowd.initial"
    finally:
        plugins.unregister("crowd", "plain-test-crowd")


@pytest.mark.requires("jupedsim")
def test_jupedsim_bodies_stand_in_their_groups_regions_without_overlap_and_walk_to_their_group_s_exit():
    """JuPedSim's bodies place groups (``places_groups``) and keep each group's exit (``group_exits``): 30 bodies by the
    west wall sent to the east door all cross the hall and leave by it; the 20 by the east wall, without an exit of
    their own, leave by the nearest."""
    from meanfield.crowds.jupedsim_engine import max_body_overlap

    sc = _hall([{"region": WEST, "n": 30, "exit": 3}, {"region": EAST, "n": 20}], t_final=60.0,
               **{"crowd.kind": "jupedsim", "crowd.options": {"jupedsim": {"radius": 0.2, "time_step": 0.05}}})
    loop = ClosedLoop(sc)
    x = loop.crowd.engine.positions.copy()
    west, east = shapely.from_wkt(WEST), shapely.from_wkt(EAST)
    assert shapely.contains_xy(west, x[:30, 0], x[:30, 1]).all()
    assert shapely.contains_xy(east, x[30:, 0], x[30:, 1]).all()
    assert max_body_overlap(x[:, 0], x[:, 1], 0.2)[0] == 0.0
    loop.run(progress=False)
    e = loop.crowd.engine
    assert (e.exit_index[:30] == 3).all() and (e.exit_index[30:] >= 0).all()


def test_groups_whose_bodies_do_not_fit_are_refused_naming_the_group():
    from meanfield.crowds.jupedsim_engine import place_groups

    small = "POLYGON ((1 1, 2 1, 2 2, 1 2, 1 1))"  # 1 m²: not 40 bodies of 0.2 m
    domain = builtin_scenarios()["hall"]().domain
    groups = [{"region": WEST, "n": 5}, {"region": small, "n": 40}]
    with pytest.raises(ParameterError) as exc:
        place_groups(groups, 0.2, domain, np.random.default_rng(0))
    assert exc.value.name == "crowd.groups[1].n"
    ok = place_groups(groups[:1] + [{"region": small, "n": 3}], 0.2, domain, np.random.default_rng(0))
    assert ok.shape == (8, 2)


def test_groups_are_needed_with_initial_groups():
    with pytest.raises(ParameterError) as exc:
        builtin_scenarios()["hall"](seed=0).with_values({"crowd.initial": "groups"})
    assert exc.value.name == "crowd.groups"


def test_the_density_starts_as_the_groups_do_each_uniform_in_its_region():
    """``crowd.initial = "groups"`` for the density (issue 42, item 6): group ``g`` carries ``n_g / N`` of the mass,
    uniform on its region (cells across the region's edge take their share), none elsewhere; its run goes."""
    from meanfield.crowds.density_crowd import initial_density
    from meanfield.geometry.grid import Grid

    groups = [{"region": WEST, "n": 150}, {"region": "POLYGON ((23.3 1, 29 1, 29 19, 23.3 19, 23.3 1))", "n": 50}]
    sc = _hall(groups, **{"crowd.kind": "fokker-planck"})
    grid = Grid(sc.domain, tuple(sc.grid.cells))
    rho = initial_density(sc, grid)
    X, Y = grid.centers
    west = (X < 6) & (Y > 1) & (Y < 19)
    east = (X > 23.3) & (X < 29) & (Y > 1) & (Y < 19)
    assert grid.integrate(rho) == pytest.approx(1.0, rel=1e-12)
    assert (grid.volume * rho)[west].sum() == pytest.approx(0.75, rel=1e-9)  # cell edges on the region's: exact
    assert (grid.volume * rho)[~west].sum() == pytest.approx(0.25, rel=1e-9)
    x0 = grid.domain.bounds[0]
    left = x0 + np.floor((23.3 - x0) / grid.dx) * grid.dx  # the column of cells the region's west edge crosses
    across = np.isclose(X, left + grid.dx / 2) & (Y > 1) & (Y < 19)
    inside = (X > left + grid.dx) & (X < 28) & (Y > 2) & (Y < 18)
    share = (left + grid.dx - 23.3) / grid.dx
    np.testing.assert_allclose(rho[across], share * rho[inside].max(), rtol=1e-9)  # its share of a full cell
    assert rho[east | across].min() > 0 and rho[~(west | east | across)].max() == 0.0
    inner = (X > 2) & (X < 5) & (Y > 2) & (Y < 18)
    assert np.ptp(rho[inner]) < 1e-12 * rho.max() and rho[inner][0] == pytest.approx(0.75 / (5 * 18), rel=1e-9)
    s = ClosedLoop(sc.with_values({"t_final": 2.0})).run(progress=False).summary
    assert s["status"] == "completed"


def test_the_density_and_the_points_start_with_the_same_share_in_each_group_s_region():
    groups = [{"region": WEST, "n": 30}, {"region": EAST, "n": 10}]
    sc = _hall(groups)
    x = initial_positions(sc, sc.crowd.n, np.random.default_rng(0))
    in_west = shapely.contains_xy(shapely.from_wkt(WEST), x[:, 0], x[:, 1])
    assert in_west.sum() == 30 and (~in_west).sum() == 10
