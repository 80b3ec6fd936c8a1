"""The hughes2d peer (``benchmarks/hughes2d_peer.py``): the same room, crowd, diagram and door in both codes.

Exact and fast: the translation, not the runs (``meanfield bench --only hughes2d`` runs them).  The tests that build
hughes2d's mesh need it (``@pytest.mark.requires("hughes2d")``, ``tests/optional.py``).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from benchmarks import hughes2d_peer as peer
from meanfield import plugins

V0, RHO_MAX = 1.34, 5.4


def test_our_scenario_is_the_problem():
    from meanfield.crowds.density_crowd import initial_density
    from meanfield.geometry.exits import exit_segments
    from meanfield.geometry.grid import Grid

    sc = peer.scenario(10)
    c = sc.crowd
    assert (c.kind, c.guidance, sc.congestion_model, c.n) == ("fokker-planck", "hughes", "linear", peer.PERSONS)
    assert (c.free_speed, c.rho_max, c.sigma, sc.dt) == (V0, RHO_MAX, peer.SIGMA, 0.05)
    assert peer.scenario(40).dt == 0.0125  # the period follows the cell
    np.testing.assert_array_equal(exit_segments(sc.domain), [peer.DOOR])
    grid = Grid(sc.domain, sc.grid.cells)
    persons = c.n * initial_density(sc, grid)  # persons/m² on 0.1 m cells, the block on their edges
    x, y = grid.centers
    x0, y0, x1, y1 = peer.BLOCK
    inside = (x > x0) & (x < x1) & (y > y0) & (y < y1)
    np.testing.assert_allclose(persons[inside], 2.0, rtol=1e-12)
    assert not persons[~inside].any()
    assert float(grid.integrate(persons)) == pytest.approx(peer.PERSONS, rel=1e-12)
    diagram = plugins.load("congestion", "linear")(free_speed=V0, rho_max=RHO_MAX)
    assert diagram.capacity()[0] == pytest.approx(V0 * RHO_MAX / 4, rel=1e-12)  # 1.809 persons/(m·s)


def test_the_peers_diagram_and_cost_are_ours_on_the_normalised_density():
    from meanfield.crowds.crowd_routes import SPEED_FLOOR

    speed, cost = peer.peer_functions(V0)
    diagram = plugins.load("congestion", "linear")(free_speed=V0, rho_max=RHO_MAX)
    rho = np.linspace(0.0, RHO_MAX, 55)  # persons/m²
    ours = V0 * np.asarray(diagram.speed_factor(rho), float)
    np.testing.assert_allclose([speed(r / RHO_MAX) for r in rho], ours, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose([cost(r / RHO_MAX) for r in rho], 1 / np.maximum(ours, SPEED_FLOOR * V0), rtol=1e-12)
    assert peer.SPEED_FLOOR == SPEED_FLOOR


def test_without_hughes2d_the_bench_is_skipped_naming_the_install(monkeypatch):
    from benchmarks import bench_hughes2d

    monkeypatch.setitem(sys.modules, "hughes2d", None)  # `import hughes2d` now raises ImportError
    monkeypatch.setattr(peer, "run_ours", lambda *a, **k: pytest.fail("nothing runs without hughes2d"))
    records = bench_hughes2d.suite_records(quick=True)
    assert len(records) == 1
    assert records[0]["skipped"] is True and "pip install" in records[0]["note"] and "hughes2d" in records[0]["note"]


@pytest.mark.requires("hughes2d")
def test_the_peers_mesh_holds_the_same_crowd_and_door():
    mesh = peer.peer_mesh(0.5)
    exits = np.asarray(mesh.exit_edges)
    ends = np.asarray(mesh.vertices, float)[np.asarray(mesh.edges)[exits]]  # (E, 2, 2)
    np.testing.assert_allclose(ends[:, :, 0], 5.0, atol=1e-12)
    assert ends[:, :, 1].min() == pytest.approx(1.5, abs=1e-12) and ends[:, :, 1].max() == pytest.approx(2.5, abs=1e-12)
    assert float(np.asarray(mesh.edge_length)[exits].sum()) == pytest.approx(peer.door_width(), rel=1e-12)
    rho = peer.peer_initial(mesh, RHO_MAX)
    areas = np.asarray(mesh.cell_areas, float)
    assert RHO_MAX * float(rho @ areas) == pytest.approx(peer.PERSONS, rel=1e-12)
    assert rho.min() == 0.0 and rho.max() == pytest.approx(2.0 / RHO_MAX, rel=1e-12)  # 2 persons/m², normalised
    dt = peer.peer_dt(mesh, V0)
    assert 3 * dt * V0 * mesh.max_edge_length == pytest.approx(mesh.min_cell_area, rel=1e-12)  # its CFL, at the limit


@pytest.mark.requires("hughes2d")
def test_the_peers_door_triangles_walk_straight_out():
    """hughes2d puts ``u = 0`` on every vertex of the door, so a triangle with an edge on it walks along the door's
    normal: its door passes the demand ``f(min(ρ, ρ_c))`` uncut (the benchmark's explanation of the σ = 0 gap)."""
    from hughes2d import CellValueMap, PedestrianSolver

    mesh = peer.peer_mesh(0.5)
    rho = CellValueMap(mesh)
    rho.values = peer.peer_initial(mesh, RHO_MAX).tolist()
    speed, cost = peer.peer_functions(V0)
    solver = PedestrianSolver(mesh, peer.peer_dt(mesh, V0), rho, speed, cost, options={"model": "hughes"})
    exits = set(np.asarray(mesh.exit_edges).tolist())
    at_door = [k for k, edges in enumerate(np.asarray(mesh.triangles_with_edges)) if exits & set(edges.tolist())]
    assert at_door
    np.testing.assert_allclose(np.asarray(solver.directions)[at_door], [[1.0, 0.0]] * len(at_door), atol=1e-12)
