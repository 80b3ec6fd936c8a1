"""Robot count (analysis.robot_count): coverage radius and layouts, the empirical study."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.robot_count import coverage_estimate, coverage_layout, coverage_radius, empirical_robot_count
from meanfield import Domain, GaussianKernel, ParameterError, kernel_value, paper_scenario


def test_coverage_radius_is_where_the_field_equals_eps():
    c, eta, eps = 0.2, 0.05, 0.02
    r = coverage_radius(c, eta, eps)
    assert r == pytest.approx(math.sqrt(eta * math.log(10.0)), rel=1e-15)
    # |K(ξ)| = c exp(-|ξ|²/η) at |ξ| = r is exactly ε, by the toolkit's own kernel
    kx, ky = kernel_value(GaussianKernel(c, eta), np.array(r), np.array(0.0), np.array(0.3))
    assert float(np.hypot(kx, ky)) == pytest.approx(eps, rel=1e-12)


@pytest.mark.parametrize(
    "args, name",
    [((0.2, 0.05, 0.2), "eps"), ((0.2, 0.05, 0.3), "eps"), ((0.2, 0.05, 0.0), "eps"), ((0.2, -1.0, 0.1), "kernel.eta"),
     ((0.0, 0.05, 0.1), "kernel.c")],
)
def test_coverage_radius_refuses_bad_levels(args, name):
    with pytest.raises(ParameterError) as exc:
        coverage_radius(*args)
    assert exc.value.name == name


@pytest.mark.parametrize("radius", [0.1, 0.186, 0.263, 0.339, 0.5, 0.8])
def test_box_layout_is_the_smallest_covering_lattice(radius):
    lay = coverage_layout(Domain.box(1.0, 1.0), radius)
    sx, sy = lay.spacing
    assert 0.5 * math.hypot(sx, sy) <= radius * (1 + 1e-12)  # covers
    # brute force over every lattice: none with fewer robots covers
    best = min(
        c * r
        for c in range(1, 40)
        for r in range(1, 40)
        if 0.5 * math.hypot(1 / c, 1 / r) <= radius * (1 + 1e-12)
    )
    assert lay.n == best
    # every point of Ω is within the radius of a robot
    pts = np.random.default_rng(0).uniform(0, 1, size=(4000, 2))
    d = np.min(np.linalg.norm(pts[:, None, :] - lay.positions[None], axis=-1), axis=1)
    assert d.max() <= radius * (1 + 1e-9)


def test_paper_kernel_at_a_tenth_of_its_peak_needs_the_papers_four_by_four():
    lay = coverage_estimate(Domain.box(1.0, 1.0), 0.2, 0.05, 0.02 * 5)  # ε = c/2
    assert (lay.n, lay.cols, lay.rows) == (16, 4, 4)


def test_disk_layout_covers_the_disk():
    dom = Domain.disk(1.0)
    r = 0.1
    lay = coverage_layout(dom, r)
    pts = dom.sample_uniform(5000, np.random.default_rng(1))
    d = np.min(np.linalg.norm(pts[:, None, :] - lay.positions[None], axis=-1), axis=1)
    assert lay.n < lay.cols * lay.rows  # corner cells outside the disk need no robot
    assert np.all(dom.contains(lay.positions[:, 0], lay.positions[:, 1], tol=1e-12))
    # projecting a centre onto convex Ω moves it no farther from any point of Ω ∩ cell
    assert d.max() <= r * (1 + 1e-9)


def test_layout_refuses_bad_input():
    with pytest.raises(ParameterError):
        coverage_layout("square", 0.2)
    with pytest.raises(ParameterError):
        coverage_layout(Domain.box(1, 1), -0.1)


def test_empirical_study_runs_and_finds_the_minimum():
    sc = paper_scenario().with_values({"t_final": 0.3})
    study = empirical_robot_count(sc, counts=(1, 4), seeds=(0,), threshold=0.0, workers=1, progress=False)
    assert study.counts == [1, 4]
    assert study.minimum == 1  # threshold 0: the smallest count succeeds
    assert set(study.values) == {1, 4} and all(len(v) == 1 for v in study.values.values())
    impossible = empirical_robot_count(sc, counts=(1,), seeds=(0,), threshold=1.01, workers=1, progress=False)
    assert impossible.minimum is None
    assert impossible.to_dict()["medians"]["1"] == impossible.values[1][0]


def test_empirical_study_refuses_bad_input():
    sc = paper_scenario()
    with pytest.raises(ParameterError):
        empirical_robot_count(sc, counts=(0, 1), progress=False)
    with pytest.raises(ParameterError):
        empirical_robot_count(sc, seeds=(), progress=False)
    with pytest.raises(ParameterError):
        empirical_robot_count(sc, metric="speed", progress=False)
