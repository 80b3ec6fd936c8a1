"""Shared helpers for the test suite: small grids and smooth positive densities."""

from __future__ import annotations

import os

import matplotlib
import numpy as np
import pytest
from hypothesis import Phase, settings

from meanfield import Domain, Grid

matplotlib.use("Agg")

# ---------------------------------------------------------------------- hypothesis profiles
# Select with HYPOTHESIS_PROFILE (default "ci"); a decorator's own settings (e.g. an explicit
# max_examples) still take precedence over the profile.
#   ci       deterministic (derandomize, no example database); tests/verification/test_properties.py
#            takes ~15 s on 2 cores
#   dev      more examples, random seeds; the local example database replays failures
#   release  10x ci, random seeds: the broad search before a release (a few minutes)
#   mutation ci without shrinking: verification.mutation only asks *whether* a test fails
settings.register_profile("ci", max_examples=200, derandomize=True, database=None, deadline=None, print_blob=True)
settings.register_profile("dev", max_examples=500, deadline=None, print_blob=True)
settings.register_profile("release", max_examples=2000, deadline=None, print_blob=True)
settings.register_profile(
    "mutation", parent=settings.get_profile("ci"), phases=(Phase.explicit, Phase.reuse, Phase.generate)
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# A convex pentagon used wherever a polygon domain is needed (counter-clockwise).
PENTAGON = [(0.0, 0.0), (1.0, -0.1), (1.3, 0.6), (0.6, 1.1), (-0.2, 0.7)]


def smooth_density(grid: Grid, floor: float = 0.05) -> np.ndarray:
    """A smooth, strictly positive density of unit mass: two Gaussian bumps plus a floor."""
    X, Y = grid.centers
    x0, x1, y0, y1 = grid.domain.bounds
    w, h = x1 - x0, y1 - y0
    f = (
        floor
        + np.exp(-((X - x0 - 0.3 * w) ** 2 + (Y - y0 - 0.35 * h) ** 2) / (2 * (0.15 * w) ** 2))
        + 0.6 * np.exp(-((X - x0 - 0.7 * w) ** 2 + (Y - y0 - 0.6 * h) ** 2) / (2 * (0.2 * w) ** 2))
    )
    return f / grid.integrate(f)


def lyapunov_v2(ctrl, kernel, rho, positions, headings) -> float:
    """``V₂ = ½‖ρ − ρ_*‖² + ½‖v_r − v_d‖²`` on ``ctrl``'s grid (complex arguments allowed, for complex steps)."""
    from meanfield import NavigationField

    g = ctrl.grid
    v_r = NavigationField(kernel, g, positions, headings).velocity()
    v_d = ctrl.virtual_velocity(rho)
    vt = (v_r[0] - v_d[0], v_r[1] - v_d[1])
    rt = rho - ctrl.target
    return 0.5 * g.inner(rt, rt) + 0.5 * g.face_inner(vt, vt)


def all_domains() -> list[Domain]:
    """One domain of each shape: an offset box, a disk and a convex pentagon."""
    return [
        Domain.box(1.1, 0.9, origin=(-0.3, 0.7)),
        Domain.disk(0.8, center=(0.2, -0.1)),
        Domain.polygon(PENTAGON),
    ]


@pytest.fixture(params=["box", "disk", "polygon"])
def domain(request) -> Domain:
    """Each domain shape in turn."""
    return dict(zip(["box", "disk", "polygon"], all_domains(), strict=True))[request.param]


@pytest.fixture
def rng() -> np.random.Generator:
    """A fixed-seed generator (tests are deterministic)."""
    return np.random.default_rng(20240611)
