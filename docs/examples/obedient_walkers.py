"""A toy crowd: humans who walk where a sign points, at the sign's full speed, or stand still.

Every human reads the robots' navigation field ``v_r`` (eq. (3)) at its position; where the
field is stronger than a tenth of a sign's peak speed ``c`` it walks at speed ``c`` in the
field's direction, elsewhere it stands.  No noise, no interaction; the walls reflect.  The
robots see the crowd through the scenario's kernel density estimate, as they see the SDE
agents.  A caricature, but a useful one: it shows which humans a controller never reaches
(they stand where no sign is strong enough).

The whole crowd is this module plus its registration line (last line).  A scenario selects
it by name once the module is imported, e.g. from TOML::

    plugins = ["obedient_walkers.py"]     # relative to the TOML file
    [crowd]
    kind = "obedient-walkers"

or ``meanfield run docs/examples/obedient_walkers.toml --allow-plugins --out runs/walkers``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield import KernelDensityEstimator, plugins
from meanfield.capabilities import CrowdCapabilities
from meanfield.crowds.agent_crowd import initial_positions
from meanfield.geometry.region import Region
from meanfield.geometry.target import fraction_in_disk
from meanfield.interfaces import CrowdContext
from meanfield.signs.robots import navigation_velocity

THRESHOLD = 0.1
"""A sign is followed where ``|v_r| > THRESHOLD · c``."""


class ObedientWalkers:
    """Humans who follow the strongest sign at its peak speed, or stand (a :class:`~meanfield.interfaces.Crowd`).

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Initial positions inside Ω.
    domain : Region
        Ω; the walls reflect.
    kernel : NavigationKernel
        The robots' kernel (its strength ``c`` is the walking speed).
    kde : KernelDensityEstimator
        How the robots see the crowd.
    """

    def __init__(self, positions: np.ndarray, domain: Region, kernel: Any, kde: KernelDensityEstimator):
        self.positions = np.array(positions, float)
        self.domain = domain
        self.kernel = kernel
        self.kde = kde
        self.speed = float(kernel.c)
        self.walking = np.zeros(len(self.positions), bool)

    capabilities = CrowdCapabilities()
    """What it can do: nothing beyond the :class:`~meanfield.interfaces.Crowd` protocol (the record's defaults)."""

    @classmethod
    def from_context(cls, ctx: CrowdContext) -> ObedientWalkers:
        """The registry's factory: the scenario's initial law, its kernel and KDE."""
        sc = ctx.scenario
        bw = None if sc.density.bandwidth == "silverman" else sc.density.bandwidth
        kde = KernelDensityEstimator(ctx.grid, bw, sc.density.boundary, sc.density.method)
        return cls(initial_positions(sc, sc.crowd.n, ctx.rng), sc.domain, ctx.kernel, kde)

    @property
    def n(self) -> int:
        return len(self.positions)

    def advance(self, robots: Any, t: float, dt: float) -> None:
        """Walk ``c dt`` along ``v_r`` where it is strong enough; reflect at the walls."""
        v = navigation_velocity(self.kernel, robots.positions, robots.headings, self.positions)
        strength = np.hypot(v[:, 0], v[:, 1])
        self.walking = strength > THRESHOLD * self.speed
        w = self.walking
        self.positions[w] += (self.speed * dt / strength[w])[:, None] * v[w]
        self.domain.reflect(self.positions)

    def density(self) -> np.ndarray:
        return self.kde(self.positions)

    def fraction_in_disk(self, center: tuple[float, float], radius: float) -> float:
        return fraction_in_disk(self.positions, center, radius)

    def summary(self) -> dict[str, Any]:
        """The fraction of humans walking at the last step."""
        return {"walking_fraction_final": float(self.walking.mean())}


plugins.register("crowd", "obedient-walkers", ObedientWalkers.from_context)
