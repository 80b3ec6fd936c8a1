"""The compiled law's kernel factors by the recurrence (L1) of :func:`meanfield.controllers._law_loops.paper_law`.

``paper_law`` walks the Gaussian's 1-D factors ``c exp(-(x_k - r)²/η)`` along the centres and the
faces of each axis (two exact exponentials per robot and segment, two multiplications per point).
With ``ρ = ρ_*`` uniform and σ = 0 the virtual velocity is 0, so ``ṽ`` on the faces is the signs'
field ``v_r`` itself: for one robot, ``ṽ_x = cos θ · f_x(x-face) f_y(y-centre)`` and
``ṽ_y = sin θ · f_x(x-centre) f_y(y-face)``, each a product of two factors of the walk.  Against
the exact product (in extended precision):

* wherever it exceeds ``1e-20 c``, ṽ is within ``PRODUCT_ULPS`` ulps of it (two factors of a few
  hundred ulps each, and three roundings);
* everywhere, within ``2⁻⁴² c`` of it (a segment's start carries its exponent's round-off,
  ``|d|²/η`` ulps, to the whole segment: far from the robot the relative error grows, the
  absolute one does not; a segment whose start underflows is 0, its points more than 21
  bandwidths away, ``f < c e^{-233}``);

on the paper's grid, on fine grids with many segments per lattice, on coarse grids where segments
have one or two points and a ratio's exponent passes ``exp``'s range (the segment's start is 0 then),
with the robot inside, on a wall and in a corner.
"""

from __future__ import annotations

import numpy as np
import pytest

from meanfield import Domain, GaussianKernel, Grid, NavigationField
from meanfield._compiled import core as compiled
from meanfield.controllers.backstepping import BacksteppingController, ConstantAlpha

PRODUCT_ULPS = 1024
"""The bound on ṽ's relative error above ``1e-20 c``, in ulps (2⁻⁵²): measured up to 550 for the two factors
(``exp(-(d·d)/η)`` evaluated directly in double is itself off by up to 260 ulps per factor on these grids)."""

needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")
needs_long = pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="no extended precision here")

CASES = [  # (box width, height, cells, η): the paper's grid; fine (segments of 64 points); coarse (1 or 2)
    (1.0, 1.0, (30, 30), 0.05),
    (1.0, 0.75, (400, 300), 0.002),
    (2.0, 1.0, (160, 90), 0.0005),
    (1.0, 1.0, (20, 20), 1e-4),
    (1.0, 1.0, (12, 7), 2e-5),
]
ROBOTS = [(0.31, 0.27), (0.0, 0.5), (1.0, 0.0)]  # inside, on a wall, in a corner (times the box)


def _exact(points: np.ndarray, r: float, c: float, eta: float) -> np.ndarray:
    d = points.astype(np.longdouble) - np.longdouble(r)
    return np.longdouble(c) * np.exp(-(d * d) / np.longdouble(eta))


@needs_numba
@needs_long
@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("robot", ROBOTS)
def test_the_walked_factors_agree_with_exact_exponentials(case, robot):
    width, height, cells, eta = case
    grid = Grid(Domain.box(width, height), cells=cells)
    target = np.ones(grid.shape)
    law = BacksteppingController(grid, target, 0.0, ConstantAlpha(1.0))
    kernel = GaussianKernel(0.7, eta)
    theta = 0.6
    r = (robot[0] * width, robot[1] * height)
    field = NavigationField(kernel, grid, [r], [theta])
    assert law.fused.which(target, field) == ("paper", None)
    state = law.robot_inputs(target.copy(), field, 0.0)
    from meanfield.controllers._law_loops import paper_law

    assert paper_law._ready and not compiled.status()["fallbacks"]  # it ran compiled
    assert np.all(state.v_d[0] == 0.0) and np.all(state.v_d[1] == 0.0)  # so ṽ is v_r
    for vt, e, fx, fy in (
        (state.v_tilde[0], field.cos[0], _exact(grid.x_faces, r[0], kernel.c, eta), _exact(grid.y, r[1], 1.0, eta)),
        (state.v_tilde[1], field.sin[0], _exact(grid.x, r[0], kernel.c, eta), _exact(grid.y_faces, r[1], 1.0, eta)),
    ):
        exact = np.longdouble(e) * fx[:, None] * fy[None, :]
        err = np.abs(vt.astype(np.longdouble) - exact)
        big = np.abs(exact) > 1e-20 * kernel.c
        rel = float(np.max(err[big] / np.abs(exact[big]), initial=0.0))
        assert rel <= PRODUCT_ULPS * 2.0**-52, (rel / 2.0**-52, "ulps")
        assert float(np.max(err)) <= 2.0**-42 * kernel.c
