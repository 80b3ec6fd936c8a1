"""The figures evacuation engineers judge a run by: who is out when, flows, crush risk, the bound.

:class:`EvacuationTracker` observes a closed loop whose region has exits (docs page
*Buildings*, "Evacuation measures") and adds to ``summary.json``:

``fraction_evacuated``
    The share of the crowd out (final); the time series is ``fraction_evacuated`` of
    ``timeseries.nc``.
``evacuation_time_95``, ``evacuation_time_100``
    The first time 95 % / everyone is out (s; null if not reached).  For the density,
    "everyone" means less than half a person left (``1 − 0.5/N`` of the mass out).
``exit_flows``
    Per exit: persons out, its width (m), and the flow during the central 90 % of its
    passages (between the 5 % and the 95 % of its own total), in persons/s and
    persons/(m·s) (the specific flow; about 1.3 through a door for real bodies).
``peak_density``, ``peak_density_time``, ``crush_risk``
    The largest local density seen by the robots' estimate, in persons/m² (``N ρ`` on the
    grid; the KDE smooths, so a body-scale peak is higher), when, and whether it passed
    ``CRUSH_DENSITY`` = 4 persons/m².
``evacuation_lower_bound`` (with ``lower_bound_walk`` and ``lower_bound_flow``)
    ``max(max_j d(X_j)/v_free, N/(W · 2.5))``: the longest route to an exit at the free
    walking speed (``crowd.free_speed``; ``d`` the route length of
    :class:`~meanfield.geometry.geodesic.ExitRoutes`, the geodesic distance to O(h)), and the
    crowd through the total exit width ``W`` at the largest specific flow people were measured
    to pass, :data:`SPECIFIC_FLOW` = 2.5 persons/(m·s) (docs page *Congestion*).  Point masses
    without congestion have no door capacity and beat the flow term; a crowd that queues as
    people do does not.
``design_flow_time`` (with ``design_specific_flow``)
    ``N/(W · 1.3)``: the crowd through the exits at the design guides' specific flow
    :data:`DESIGN_SPECIFIC_FLOW` = 1.3 persons/(m·s), an engineer's estimate, not a bound:
    the bottleneck experiments measured 1.6–2.5, so a crowd may well beat it.
``rset_over_bound``
    ``evacuation_time_100`` over the bound (null if not everyone left).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from meanfield.interfaces import EvacuatingCrowd

__all__ = ["EvacuationTracker", "SPECIFIC_FLOW", "DESIGN_SPECIFIC_FLOW", "CRUSH_DENSITY"]

SPECIFIC_FLOW = 2.5
"""The largest specific flow through a door, persons/(m·s), for the evacuation lower bound: the top of
the range the bottleneck experiments measured for widths of 0.8–2.5 m, 1.6–2.5 (Seyfried et al.
2009; Kretz et al. 2006; Müller 1981; Liddle et al.'s flows reach 2.22; docs page *Congestion*).
It was 1.3, the design guides' value, which real crowds beat (the bodies of docs page
*Pedestrians* pass 2.0 through a 1 m door): a bound at 1.3 was no bound."""
DESIGN_SPECIFIC_FLOW = 1.3
"""The design guides' specific flow through a door, persons/(m·s) (design notes, section 6): the
``design_flow_time`` an engineer would estimate, reported beside the bound, not a bound."""
CRUSH_DENSITY = 4.0
"""Local density above which a crowd risks crushing, persons/m²."""


class EvacuationTracker:
    """Observer of the evacuation measures (module docstring); a no-op without exits."""

    def __init__(self) -> None:
        self.active = False
        self.times: list[float] = []
        self.out: list[np.ndarray] = []  # persons out through each exit, at each step
        self.peak = 0.0
        self.peak_time = 0.0
        self.bound: dict[str, float] = {}

    # ------------------------------------------------------------------ the observer
    def start(self, loop: Any) -> None:
        from meanfield.geometry.exits import exit_segments

        segs = exit_segments(loop.parts.region)
        self.active = bool(len(segs)) and isinstance(loop.crowd, EvacuatingCrowd)
        if not self.active:
            return
        self.segs = segs
        self.widths = np.hypot(*(segs[:, 1] - segs[:, 0]).T)
        self.n = loop.crowd.n if loop.crowd.n is not None else loop.scenario.crowd.n
        self.agents = loop.crowd.positions is not None  # whole persons (else the density's mass)
        self.free_speed = loop.scenario.crowd.free_speed
        self.bound = self._lower_bound(loop)
        self._record(loop)

    def step(self, loop: Any, record: Any) -> None:
        if self.active:
            self._record(loop)

    def _record(self, loop: Any) -> None:
        self.times.append(loop.t)
        self.out.append(loop.crowd.persons_out(len(self.segs)))
        peak = self.n * float(np.max(loop.density))
        if peak > self.peak:
            self.peak, self.peak_time = peak, loop.t

    def _lower_bound(self, loop: Any) -> dict[str, float]:
        from meanfield.geometry.geodesic import ExitRoutes

        routes = ExitRoutes(loop.grid, self.segs, loop.parts.sight)
        positions = loop.crowd.positions
        if positions is not None:
            d = routes.distance(positions[np.isfinite(positions).all(axis=1)])
        else:  # the density: every cell holding more than a thousandth of a person
            g = loop.grid
            X, Y = g.centers
            held = g.active & (loop.density * g.volume * self.n > 1e-3)
            d = routes.distance(np.column_stack([X[held], Y[held]]))
        walk = float(d.max()) / self.free_speed if len(d) else 0.0
        width = float(self.widths.sum())
        flow = self.n / (width * SPECIFIC_FLOW)
        return {
            "evacuation_lower_bound": max(walk, flow),
            "lower_bound_walk": walk,
            "lower_bound_flow": flow,
            "design_flow_time": self.n / (width * DESIGN_SPECIFIC_FLOW),
        }

    # ------------------------------------------------------------------ results
    def fraction_evacuated(self) -> np.ndarray:
        """The share out at each step (from the start)."""
        return np.array([o.sum() for o in self.out]) / self.n

    def _first_time(self, fraction: np.ndarray, level: float) -> float | None:
        reached = np.flatnonzero(fraction >= level - 1e-12)
        return float(self.times[reached[0]]) if len(reached) else None

    def _flows(self) -> list[dict[str, Any]]:
        out = np.array(self.out)  # (steps, exits)
        t = np.asarray(self.times)
        flows = []
        for k, width in enumerate(self.widths):
            total = float(out[-1, k])
            entry: dict[str, Any] = {"exit": k, "width": float(width), "persons": total}
            entry["persons_per_second"] = entry["persons_per_metre_second"] = None
            if total >= 2.0:
                t05 = t[np.flatnonzero(out[:, k] >= 0.05 * total)[0]]
                t95 = t[np.flatnonzero(out[:, k] >= 0.95 * total)[0]]
                if t95 > t05:
                    q = 0.9 * total / (t95 - t05)
                    entry["persons_per_second"] = float(q)
                    entry["persons_per_metre_second"] = float(q / width)
            flows.append(entry)
        return flows

    def summary(self) -> dict[str, Any]:
        """The keys of the module docstring (empty without exits)."""
        if not self.active:
            return {}
        frac = self.fraction_evacuated()
        everyone = 1.0 if self.agents else 1.0 - 0.5 / self.n
        t100 = self._first_time(frac, everyone)
        bound = self.bound["evacuation_lower_bound"]
        return {
            "fraction_evacuated": float(frac[-1]),
            "evacuation_time_95": self._first_time(frac, 0.95),
            "evacuation_time_100": t100,
            "exit_flows": self._flows(),
            "peak_density": self.peak,
            "peak_density_time": self.peak_time,
            "crush_risk": bool(self.peak > CRUSH_DENSITY),
            **self.bound,
            "free_speed": self.free_speed,
            "specific_flow": SPECIFIC_FLOW,
            "design_specific_flow": DESIGN_SPECIFIC_FLOW,
            "rset_over_bound": t100 / bound if t100 is not None and bound > 0 else None,
        }
