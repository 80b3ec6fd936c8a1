"""Robots that know only what they and their group see: the centralized limit, blindness, locality."""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ClosedLoop, ParameterError, paper_scenario
from meanfield.controllers.local_sensing import LocalSensing, groups
from meanfield.interfaces import Observation
from meanfield.signs.robots import NavigationField


@pytest.mark.parametrize("kind", ["backstepping", "coverage"])
def test_unlimited_radii_give_the_centralized_controller_exactly(kind):
    central = ClosedLoop(paper_scenario(seed=3).with_values({"controller.kind": kind}))
    local = ClosedLoop(
        paper_scenario(seed=3).with_values({"controller.kind": kind, "sensing.radius": 1e9, "sensing.comm_radius": 1e9})
    )
    assert isinstance(local.controller, LocalSensing)
    for _ in range(20):
        central.step()
        local.step()
    np.testing.assert_array_equal(local.robots.positions, central.robots.positions)
    np.testing.assert_array_equal(local.robots.headings, central.robots.headings)


def test_a_group_that_sees_no_one_holds_still_and_says_so():
    sc = paper_scenario(seed=0).with_values({"sensing.radius": 0.001, "t_final": 0.05})  # narrower than a cell
    loop = ClosedLoop(sc)
    start = loop.robots.positions.copy(), loop.robots.headings.copy()
    s = loop.run(progress=False).summary
    np.testing.assert_array_equal(loop.robots.positions, start[0])
    np.testing.assert_array_equal(loop.robots.headings, start[1])
    assert s["sensing_blind_fraction"] == 1.0 and s["sensing_groups_mean"] == 1.0


def test_a_group_s_command_depends_only_on_what_its_members_see():
    sc = paper_scenario(seed=1).with_values({"sensing.radius": 0.2, "sensing.comm_radius": 0.2})
    loop = ClosedLoop(sc)
    c = loop.controller
    R, th = loop.robots.positions, loop.robots.headings
    labels = groups(R, 0.2)
    assert labels.max() == 15  # the 4x4 lattice (spacing 0.25): every robot talks to no one
    seen_by = {g: c._window(R[labels == g]) > 0 for g in np.unique(labels)}
    g0 = labels[0]
    others = np.zeros_like(seen_by[g0])
    for g, w in seen_by.items():
        if g != g0:
            others |= w
    elsewhere = others & ~seen_by[g0]  # seen by another group, not by robot 0's
    assert elsewhere.any()

    def command(density):
        field = NavigationField(loop.kernel, loop.grid, R, th)
        for ctrl in c.controllers:
            ctrl.reset()
        return c.act(Observation(density, field, 0.0, sc.dt))

    base = loop.density.copy()
    changed = base.copy()
    changed[elsewhere] *= 3.0
    a, b = command(base), command(changed)
    mine = labels == g0
    np.testing.assert_array_equal(a.u[mine], b.u[mine])  # robot 0's group does not see the change
    assert not np.allclose(a.u[~mine], b.u[~mine])  # the group that sees it reacts


def test_bad_sensing_is_refused_naming_the_field():
    with pytest.raises(ParameterError) as exc:
        paper_scenario(seed=0).with_values({"sensing.comm_radius": -1.0})
    assert exc.value.name == "sensing.comm_radius"
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(paper_scenario(seed=0).with_values({"sensing.radius": 0.3, "controller.kind": "static-signs"}))
    assert exc.value.name == "sensing" and "coverage" in str(exc.value)


def test_a_group_that_sees_all_the_mass_still_assumes_a_positive_density_elsewhere():
    sc = paper_scenario(seed=0).with_values({"sensing.radius": 0.35, "sensing.comm_radius": 0.7})
    loop = ClosedLoop(sc)
    c = loop.controller
    window = c._window(loop.robots.positions[:1])
    known = c._known(loop.density, window, seen=1.0)  # everything seen: no mass left to spread
    assert (known > 0).all() and np.array_equal(known[window > 0], loop.density[window > 0])
