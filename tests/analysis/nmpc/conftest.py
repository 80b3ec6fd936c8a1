"""Shared by the tests of :mod:`analysis.nmpc`: a small coarse model and random data on it, and a
small closed loop with its NMPC controllers."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.nmpc import CoarseFokkerPlanck, NMPCController
from meanfield import ClosedLoop, GaussianKernel
from meanfield.scenarios.scenario import (
    ControllerSpec,
    CrowdSpec,
    GridSpec,
    KernelSpec,
    RobotSpec,
    Scenario,
    TargetSpec,
)

BOUNDS = (-0.3, 0.8, 0.7, 1.6)  # an offset, non-square box
KERNEL = GaussianKernel(0.2, 0.05)


def model(cells=(7, 5), sigma=0.02, step=0.3, flux="upwind", n=3) -> CoarseFokkerPlanck:
    return CoarseFokkerPlanck(BOUNDS, cells, sigma, KERNEL, n, step, flux)


def random_density(m: CoarseFokkerPlanck, rng: np.random.Generator) -> np.ndarray:
    rho = rng.uniform(0.1, 2.0, m.shape)
    return rho / m.mass(rho)


def random_robots(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    x0, x1, y0, y1 = BOUNDS
    pos = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    return pos, rng.uniform(0, 2 * np.pi, n)


def zero_velocity(m: CoarseFokkerPlanck) -> tuple[np.ndarray, np.ndarray]:
    nx, ny = m.shape
    return np.zeros((nx - 1, ny)), np.zeros((nx, ny - 1))


def small_scenario(**options) -> Scenario:
    """A crowd on the left, the target on the right, four robots next to the crowd."""
    opts = {"horizon": 3, "cells": 6, "period": 0.1, **options}
    return Scenario(
        name="nmpc-test",
        seed=3,
        dt=0.05,
        t_final=0.5,
        record_every=2,
        grid=GridSpec((12, 12)),
        crowd=CrowdSpec(n=100, initial="gaussian", initial_center=(0.3, 0.5), initial_std=0.1, sigma=0.01),
        robots=RobotSpec(
            n=4,
            layout="explicit",
            positions=[[0.2, 0.35], [0.2, 0.65], [0.4, 0.35], [0.4, 0.65]],
            headings=[0.0, 1.0, 2.0, 3.0],
            u_max=0.05,
            omega_max=0.5,
        ),
        kernel=KernelSpec(c=0.3, eta=0.05),
        target=TargetSpec(center=(0.8, 0.5), std=0.12),
        controller=ControllerSpec(kind="nmpc", options=opts),
    )


@pytest.fixture(scope="module")
def small_loop() -> ClosedLoop:
    return ClosedLoop(small_scenario())


def controller_for(lp: ClosedLoop, **options) -> NMPCController:
    """An NMPC controller on ``lp``'s parts with ``options`` (1.5 s horizon of 3 steps, 6×6 cells)."""
    opts = {"horizon": 3, "cells": 6, "step": 0.5, **options}
    return NMPCController(
        lp.grid,
        lp.target,
        lp.kernel,
        lp.parts.sigma,
        lp.robots,
        lp.controller.backstepping,
        opts,
        lp.parts.robot_region.bounds,
    )


def solved_instance(lp: ClosedLoop, **options):
    """The small instance solved to a tight tolerance: the controller, its data and the plan."""
    c = controller_for(lp, **{"max_iter": 300, "tol": 1e-12, **options})
    rho_c = c.restrict(lp.crowd.density())
    pos, heads = lp.robots.positions.copy(), lp.robots.headings.copy()
    return c, rho_c, pos, heads, c.solve(rho_c, pos, heads)
