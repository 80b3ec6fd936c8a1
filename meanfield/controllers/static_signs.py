"""The static-signage baseline: robots parked on a lattice, each sign turned along the route out.

No density feedback: each robot drives to its station of a regular lattice over the region
robots may stand in (:meth:`~meanfield.geometry.region.Region.lattice`, where the ``grid`` layout
puts them at the start) and turns its sign along the informed walker's route at its station
(:class:`~meanfield.geometry.geodesic.ExitRoutes`: towards the nearest exit, around walls), or, in a
room without exits, towards the target's centre.  It is what a building does with fixed
"THIS WAY" signs; robot guidance by density feedback is judged against it (docs page
*Buildings*).  Registered as controller ``static-signs``; options ``k_position`` and
``k_heading`` (1/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from meanfield.capabilities import ControllerCapabilities
from meanfield.errors import ParameterError, num, options_table
from meanfield.interfaces import Command, ControllerParts, Observation

__all__ = ["StaticSigns", "StaticSignsOptions"]


@dataclass
class StaticSignsOptions:
    """``[controller.options.static-signs]``: the gains of the robots' walk to their stations and turn to their
    bearings, 1/s, > 0."""

    k_position: float = 1.0
    k_heading: float = 2.0

    def __post_init__(self) -> None:
        for name in ("k_position", "k_heading"):
            setattr(self, name, num(f"controller.options.static-signs.{name}", getattr(self, name), lo=0.0,
                                    lo_open=True, allowed="a finite number > 0 (1/s)"))  # fmt: skip


class StaticSigns:
    """Robots driven to fixed stations, each sign turned to a fixed bearing.

    Parameters
    ----------
    stations : ndarray, shape (n, 2)
        Where each robot parks.
    bearings : ndarray, shape (n,)
        The heading of each robot's sign once parked (rad).
    k_position : float
        Gain of the drive to the station, 1/s: ``u_i = k_position (P_i − R_i)``.
    k_heading : float
        Gain of the turn, 1/s: ``ω_i = k_heading · wrap(bearing_i − θ_i)``.
    """

    capabilities: ClassVar[ControllerCapabilities] = ControllerCapabilities(
        changes_walls=True,  # the signs keep their stations and bearings (held at a block's edge by the robots' region)
        options=StaticSignsOptions,  # [controller.options.static-signs]
    )
    """What it can do (:class:`~meanfield.capabilities.ControllerCapabilities`): a region can become wall during a
    run (``[[events]] block``)."""

    def __init__(self, stations: np.ndarray, bearings: np.ndarray, k_position: float = 1.0, k_heading: float = 2.0):
        for name, k in (("k_position", k_position), ("k_heading", k_heading)):
            if not (isinstance(k, (int, float)) and math.isfinite(k) and k > 0):
                raise ParameterError(f"controller.options.static-signs.{name}", k, "a finite number > 0 (1/s)")
        self.stations = np.asarray(stations, float)
        self.bearings = np.asarray(bearings, float)
        self.k_position = float(k_position)
        self.k_heading = float(k_heading)

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> StaticSigns:
        """Registry factory: stations on the robots' lattice, bearings along the routes out."""
        from meanfield.geometry.exits import exit_segments
        from meanfield.geometry.geodesic import ExitRoutes

        o = options_table("controller.options.static-signs", StaticSignsOptions, dict(parts.options))
        stations = parts.robot_region.lattice(parts.robots.n)
        segs = exit_segments(parts.region)
        if len(segs):
            e = ExitRoutes(parts.grid, segs, parts.sight).heading(stations)
        else:
            e = np.asarray(parts.target_center, float) - stations
        bearings = np.arctan2(e[:, 1], e[:, 0])
        return cls(stations, bearings, k_position=o.k_position, k_heading=o.k_heading)

    def act(self, observation: Observation) -> Command:
        """Drive to the stations and turn the signs to their bearings (the density is not used)."""
        positions, headings = observation.field.positions, observation.field.headings
        u = self.k_position * (self.stations - positions)
        turn = np.angle(np.exp(1j * (self.bearings - headings)))  # wrapped to (−π, π]
        return Command(u, self.k_heading * turn)

    def reset(self) -> None:
        """No memory."""
