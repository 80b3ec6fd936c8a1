"""A baseline controller: robots park on a lattice over Ω and point their signs at the target.

No density feedback at all: each robot drives to its own station of a regular lattice over
the region the robots may stand in (:meth:`meanfield.geometry.domain.Domain.lattice`, the paper's 4×4
for 16 robots), then stays there, and turns its sign towards the target's centre.  It is
the "static signage" baseline a density-feedback law has to beat: humans near a sign walk
towards the target, humans far from every sign are never fetched.

The whole controller is this module plus its registration line (last line).  A scenario
selects it by name once the module is imported, e.g. from TOML::

    plugins = ["parked_robots.py"]     # relative to the TOML file
    [controller]
    kind = "parked"
    [controller.options.parked]
    k_position = 1.0
    k_heading = 2.0

read with ``meanfield run FILE.toml --allow-plugins`` or ``load_scenario(path, allow_plugins=True)``
(a scenario file imports no module unless the user allows it).

Run the comparison with the paper's law (a few seconds)::

    python docs/examples/parked_robots.py 10.0     # argument: t_final
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from meanfield import plugins
from meanfield.capabilities import ControllerCapabilities
from meanfield.errors import num, options_table
from meanfield.interfaces import Command, ControllerParts, Observation


@dataclass
class ParkedOptions:
    """``[controller.options.parked]``: the gains of the drive to the station and of the turn, 1/s, > 0 (checked
    when the scenario is read, naming ``controller.options.parked.<field>``)."""

    k_position: float = 1.0
    k_heading: float = 2.0

    def __post_init__(self) -> None:
        for name in ("k_position", "k_heading"):
            setattr(self, name, num(f"controller.options.parked.{name}", getattr(self, name), lo=0.0, lo_open=True))


class ParkedRobots:
    """Robots driven to fixed stations, signs turned towards a point.

    Parameters
    ----------
    stations : ndarray, shape (n, 2)
        Where each robot parks.
    aim : (float, float)
        The point every sign points at (the target's centre).
    k_position : float
        Gain of the drive to the station, 1/s: ``u_i = k_position (P_i − R_i)``.
    k_heading : float
        Gain of the turn, 1/s: ``ω_i = k_heading · wrap(bearing_i − θ_i)``.
    """

    capabilities = ControllerCapabilities(options=ParkedOptions)
    """What it can do: a scenario may set :class:`ParkedOptions` (the core checks the table when the scenario is read);
    it does not run on a group's knowledge, needs no exits and has no stability step (the record's defaults)."""

    def __init__(self, stations: np.ndarray, aim: tuple[float, float], k_position: float = 1.0, k_heading: float = 2.0):
        self.stations = np.asarray(stations, float)
        self.aim = np.asarray(aim, float)
        self.k_position = float(k_position)
        self.k_heading = float(k_heading)

    @classmethod
    def from_parts(cls, parts: ControllerParts) -> ParkedRobots:
        """The registry's factory: stations on the robots' region, aim at the target's centre."""
        o = options_table("controller.options.parked", ParkedOptions, dict(parts.options))
        stations = parts.robot_region.lattice(parts.robots.n)
        return cls(stations, parts.target_center, k_position=o.k_position, k_heading=o.k_heading)

    def bearings(self, positions: np.ndarray) -> np.ndarray:
        """The direction from each robot to the aim point (rad)."""
        d = self.aim - positions
        return np.arctan2(d[:, 1], d[:, 0])

    def act(self, observation: Observation) -> Command:
        """Drive to the stations, turn the signs to the aim point (no use of the density)."""
        positions, headings = observation.field.positions, observation.field.headings
        u = self.k_position * (self.stations - positions)
        turn = np.angle(np.exp(1j * (self.bearings(positions) - headings)))  # wrapped to (−π, π]
        return Command(u, self.k_heading * turn)

    def reset(self) -> None:
        """No memory."""


plugins.register("controller", "parked", ParkedRobots.from_parts)


if __name__ == "__main__":
    from meanfield import paper_scenario, run

    t_final = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
    base = paper_scenario(seed=0).replace(t_final=t_final)
    for kind in ("parked", "backstepping"):
        s = run(base.with_values({"controller.kind": kind}), progress=False).summary
        print(f"{kind:>13}: in target {s['fraction_in_target']:.3f}, ‖ρ̃‖ {s['l2_error_final']:.3f}, "
              f"time to 90 % {s['time_to_90']}")
