"""The navigation field sampled on a lattice: exactness, the error bound, the closed loop."""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import ParameterError, paper_scenario
from meanfield.signs.kernels import CustomKernel, GaussianKernel
from meanfield.signs.robots import navigation_velocity
from meanfield.signs.sampled_field import SampledNavigationField
from meanfield.simulation.loop import ClosedLoop


def test_bilinear_functions_are_reproduced_exactly():
    f = SampledNavigationField(GaussianKernel(1.0, 1.0), (-1.0, 2.0, 0.0, 1.0), (7, 5))
    X, Y = np.meshgrid(f.xs, f.ys, indexing="ij")
    f.vx = 1.0 + 2.0 * X - 3.0 * Y + 0.5 * X * Y
    f.vy = -X * Y
    p = np.random.default_rng(0).uniform((-1.0, 0.0), (2.0, 1.0), (500, 2))
    v = f.at_points(p)
    np.testing.assert_allclose(v[:, 0], 1 + 2 * p[:, 0] - 3 * p[:, 1] + 0.5 * p[:, 0] * p[:, 1], atol=1e-13)
    np.testing.assert_allclose(v[:, 1], -p[:, 0] * p[:, 1], atol=1e-13)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_interpolation_error_is_within_the_bound_and_the_bound_is_tight(seed):
    rng = np.random.default_rng(seed)
    kernel = GaussianKernel(0.2, 0.05)
    robots, headings = rng.uniform(0, 1, (16, 2)), rng.uniform(0, 2 * np.pi, 16)
    f = SampledNavigationField(kernel, (0.0, 1.0, 0.0, 1.0), (61, 61))
    f.update(robots, headings)
    p = rng.uniform(0, 1, (40_000, 2))
    err = np.abs(f.at_points(p) - navigation_velocity(kernel, robots, headings, p)).max()
    bound = f.error_bound()
    assert err <= bound
    assert err >= bound / 10  # the bound says how large the error is, not just that it is finite


def test_nodes_are_exact_and_other_kernels_use_second_differences():
    kernel = CustomKernel(lambda x, y: 0.3 / (1 + (x * x + y * y) / 0.02), lambda x, y: (0 * x, 0 * y))
    robots, headings = np.array([[0.3, 0.6], [0.7, 0.2]]), np.array([0.4, 2.0])
    f = SampledNavigationField(kernel, (0.0, 1.0, 0.0, 1.0), (41, 41))
    f.update(robots, headings)
    X, Y = np.meshgrid(f.xs, f.ys, indexing="ij")
    nodes = np.column_stack([X.ravel(), Y.ravel()])
    np.testing.assert_allclose(f.at_points(nodes), navigation_velocity(kernel, robots, headings, nodes), atol=1e-14)
    p = np.random.default_rng(3).uniform(0, 1, (20_000, 2))
    err = np.abs(f.at_points(p) - navigation_velocity(kernel, robots, headings, p)).max()
    assert err <= 1.5 * f.error_bound()  # estimated from the samples: a little slack


def test_bad_lattices_are_refused():
    with pytest.raises(ParameterError):
        SampledNavigationField(GaussianKernel(1, 1), (0, 1, 0, 1), (1, 5))
    with pytest.raises(ParameterError):
        SampledNavigationField(GaussianKernel(1, 1), (0, 0, 0, 1), (5, 5))


def test_closed_loop_with_sampled_field_is_statistically_the_exact_one():
    # same seed: the sampled field perturbs v_r by <= its bound (~1 % of c on the paper's
    # 30² grid, whose lattice has spacing 1/60), so the
    # two crowds stay close over a short horizon; and their density error after a longer
    # run differs far less than between two seeds of the exact loop
    base = paper_scenario(seed=4).with_values({"crowd.n": 2000, "t_final": 3.0})
    runs = {}
    for mode, seed in (("exact", 4), ("sampled", 4), ("exact", 5)):
        loop = ClosedLoop(base.with_values({"crowd.field_evaluation": mode, "seed": seed}))
        for _ in range(20):
            loop.step()
        runs[(mode, seed)] = (loop, loop.crowd.positions.copy())
    gap_20 = np.abs(runs[("exact", 4)][1] - runs[("sampled", 4)][1]).max()
    assert gap_20 < 1e-3  # 20 steps of dt = 0.01 at speeds ~0.2: displacements ~0.04
    errors = {}
    for key, (loop, _) in runs.items():
        res = loop.run(progress=False)
        errors[key] = res.summary["l2_error_final"]
        assert res.summary["field_evaluation"] == key[0]
    assert runs[("sampled", 4)][0].crowd.sampled_field.error_bound() < 0.02 * base.kernel.c
    same_seed = abs(errors[("exact", 4)] - errors[("sampled", 4)])
    other_seed = abs(errors[("exact", 4)] - errors[("exact", 5)])
    assert same_seed < 0.5 * other_seed
