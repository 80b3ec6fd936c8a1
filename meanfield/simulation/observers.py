"""Observers of the closed loop: what a run records and measures, apart from the loop itself.

* :class:`TargetTracker` — the fraction of the crowd in the target region after every step
  and the first time it reaches 90 %;
* :class:`InputStatistics` — the largest applied speed and turn rate, how often the limits
  cut a command or bind;
* :class:`Recorder` — the frames of ``timeseries.nc`` (robot states, humans, density, the
  Lyapunov functions V₁ = ∫ρ̃² and V₂ = ∫½ρ̃² + ½|ṽ|², the law's scalars), described once as a
  :class:`~meanfield.io.netcdf.NetCDFDataset` (written with h5netcdf, an xarray Dataset on request).

Each has ``start(loop)`` and ``step(loop, record)`` (:class:`meanfield.simulation.loop.Observer`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Protocol

import numpy as np

from meanfield.interfaces import Command, ControlState, Crowd, CrowdOfAgents, EvacuatingCrowd, Observation
from meanfield.io.netcdf import NetCDFDataset, NetCDFVariable
from meanfield.scenarios.scenario import Scenario
from meanfield.signs._robot_loops import input_report
from meanfield.signs.robots import AT_LIMIT_RTOL, RobotTeam
from meanfield.simulation.assembly import Parts

__all__ = [
    "LoopView",
    "Observer",
    "StepRecord",
    "TargetTracker",
    "InputStatistics",
    "Recorder",
    "recorded_humans",
]


class LoopView(Protocol):
    """What an observer reads of the loop (:class:`meanfield.simulation.loop.ClosedLoop` has it all)."""

    parts: Parts
    scenario: Scenario
    crowd: Crowd
    robots: RobotTeam
    controller: Any
    grid: Any
    density: np.ndarray
    t: float
    step_index: int

    @property
    def target(self) -> np.ndarray: ...

    def observe(self) -> Observation: ...


@dataclass
class StepRecord:
    """What happened in one step, as observers see it.

    Attributes
    ----------
    index : int
        The step's index ``k`` (from ``t_k = k dt`` to ``t_{k+1}``).
    observation : Observation
        What the controller saw at ``t_k``.
    command : Command
        What it asked for.
    u, omega : ndarray
        The inputs applied (within the speed limits).
    robots : RobotTeam
        The robots (their limits).
    report : tuple, optional
        What the limits did, as :func:`~meanfield.signs.robots.limited_inputs` returns it.
    """

    index: int
    observation: Observation
    command: Command
    u: np.ndarray
    omega: np.ndarray
    robots: RobotTeam
    report: tuple | None = None

    @cached_property
    def limits(self) -> tuple[float, float, bool, int]:
        """``(max ‖u_i‖, max |ω_i|, saturated, at_limit)`` of this step: the ``report`` the loop's
        :func:`~meanfield.signs.robots.limited_inputs` made, else one pass
        (:func:`meanfield.signs._robot_loops.input_report`)."""
        if self.report is not None:
            return self.report[:4]
        c, r = self.command, self.robots
        u_cmd, w_cmd = np.asarray(c.u, float), np.asarray(c.omega, float)
        return input_report(u_cmd, w_cmd, self.u, self.omega, float(r.u_max), float(r.omega_max), AT_LIMIT_RTOL)

    @property
    def saturated(self) -> bool:
        """Whether the limits cut the command (some robot's speed or turn rate reduced)."""
        return bool(self.limits[2])

    @property
    def at_limit(self) -> int:
        """How many robots' commands reached a speed or turn-rate limit (:meth:`RobotTeam.at_limit`)."""
        return int(self.limits[3])

    @cached_property
    def shortfall_applied(self) -> float:
        """The part of ``A`` the applied inputs did not cancel (NaN without the law's quantities)."""
        state = self.command.state
        return math.nan if state is None else state.applied_shortfall(self.u, self.omega)


class Observer(Protocol):
    """Watches the loop; never changes it."""

    def start(self, loop: LoopView) -> None:
        """The initial state (before the first step)."""
        ...

    def step(self, loop: LoopView, record: StepRecord) -> None:
        """After each step (the loop holds the new state)."""
        ...


class TargetTracker:
    """Fraction of the crowd within the target region, and the time it first reaches ``level``."""

    def __init__(self, level: float = 0.9):
        self.level = level
        self.fraction = float("nan")
        self.time_to_level: float | None = None

    def _measure(self, loop: LoopView) -> None:
        p = loop.parts
        self.fraction = loop.crowd.fraction_in_disk(p.target_center, p.target_radius)
        if self.time_to_level is None and self.fraction >= self.level:
            self.time_to_level = loop.t

    def start(self, loop: LoopView) -> None:
        self._measure(loop)

    def step(self, loop: LoopView, record: StepRecord) -> None:
        self._measure(loop)


class InputStatistics:
    """Largest applied robot speed and turn rate; steps where the limits cut or bind."""

    def __init__(self) -> None:
        self.max_speed = 0.0
        self.max_turn_rate = 0.0
        self.saturated_steps = 0
        self.binding_steps = 0
        self.steps = 0

    def start(self, loop: LoopView) -> None:
        pass

    def step(self, loop: LoopView, record: StepRecord) -> None:
        top_speed, top_turn, saturated, at_limit = record.limits
        if top_speed > self.max_speed:  # (NaN never is: a diverged step does not reach the observers)
            self.max_speed = float(top_speed)
        if top_turn > self.max_turn_rate:
            self.max_turn_rate = float(top_turn)
        self.saturated_steps += bool(saturated)
        self.binding_steps += at_limit > 0
        self.steps += 1


def recorded_humans(n: int, record_humans: int | str) -> np.ndarray:
    """Indices of the humans whose positions a run records: all, or ``record_humans`` spaced ones.

    The humans are exchangeable (drawn i.i.d. from the initial law), so evenly spaced
    indices are a sample of the crowd; the density, the fraction in the target and every
    summary figure still use all ``n``.
    """
    if record_humans == "all" or record_humans >= n:
        return np.arange(n)
    # spacing (n - 1)/(k - 1) > 1 for k < n: the rounded indices are distinct and increasing
    return np.linspace(0, n - 1, int(record_humans)).round().astype(np.intp)


_CONTROL_KEYS = ("V1", "V2", "rho_error_l2", "v_error_l2", "A", "shortfall", "dissipation")


class Recorder:
    """Frames every ``record_every`` steps (and the last); control quantities at the frame's state.

    Parameters
    ----------
    target : TargetTracker
        Supplies the fraction in the target at each frame.
    """

    KEYS = (
        "time",
        "robot_x",
        "robot_y",
        "robot_heading",
        "robot_speed",
        "robot_turn_rate",
        "human_x",
        "human_y",
        "density",
        *_CONTROL_KEYS,
        "fraction_in_target",
        "saturated",
        "robots_at_limit",
        "shortfall_applied",
        "seen_fraction",
    )

    def __init__(self, target: TargetTracker):
        self.target = target
        self.frames: dict[str, list] = {k: [] for k in self.KEYS}
        self.last_recorded_step = -1
        self.first_V2: float | None = None
        self.last_state: ControlState | None = None  # the law's quantities at the last step
        self.humans: np.ndarray | None = None
        self.loop: LoopView | None = None
        self.exits = False  # the region has exits: record the fraction out
        self.agents = False  # the crowd is one of agents (CrowdOfAgents)

    def start(self, loop: LoopView) -> None:
        self.loop = loop
        self._every = (loop.scenario.record_every, loop.scenario.steps)  # the run's settings, read once
        region_has_exits = any(p.kind == "exit" for p in loop.parts.region.boundary_parts())
        self.exits = region_has_exits and isinstance(loop.crowd, EvacuatingCrowd)
        self.agents = isinstance(loop.crowd, CrowdOfAgents)  # what the crowd can say of its people (read once)
        if loop.crowd.positions is not None:
            self.humans = recorded_humans(loop.crowd.n, loop.scenario.record_humans)
        self.record_state()

    def step(self, loop: LoopView, record: StepRecord) -> None:
        every, last = self._every
        self.last_state = record.command.state
        if record.index % every == 0:
            self.record_control(record)
        if loop.step_index % every == 0 or loop.step_index == last:
            self.record_state()

    def finish(self) -> None:
        """Drop a frame an interrupt cut short, then record the final state if the last step did not.

        A Ctrl-C (or SIGTERM) can land between two of a frame's appends; the frames are
        then cut to the ones every series holds, so the dataset stays whole.
        """
        series = [values for values in self.frames.values() if values]  # (no humans recorded: theirs stay empty)
        complete = min(len(values) for values in series)
        cut = any(len(values) > complete for values in series)
        for values in series:
            del values[complete:]
        if cut or self.last_recorded_step != self.loop.step_index:
            self.record_state()

    def _lyapunov_values(self, state: ControlState | None) -> dict[str, float]:
        """‖ρ̃‖, ‖ṽ‖, V₁ = ∫ρ̃², V₂ = ∫½ρ̃² + ½|ṽ|² and the law's scalars at one state."""
        if state is None:
            return {k: np.nan for k in _CONTROL_KEYS}
        g = self.loop.grid
        rt = g.norm(state.rho_tilde)
        vt = g.face_norm(state.v_tilde)
        w_rho, w_v = state.v2_weights  # (1, 1) but for the law in the kernel's units
        return {
            "V1": rt * rt,
            "V2": 0.5 * w_rho * rt * rt + 0.5 * w_v * vt * vt,
            "rho_error_l2": rt,
            "v_error_l2": vt,
            "A": state.A,
            "shortfall": state.shortfall,
            "dissipation": state.dissipation,
        }

    def record_control(self, record: StepRecord) -> None:
        """Fill the latest frame with the control computed at its state (before the step)."""
        u, w = record.u, record.omega
        vals: dict[str, Any] = self._lyapunov_values(record.command.state)
        if self.first_V2 is None:
            self.first_V2 = vals["V2"]
        vals.update(
            robot_speed=np.hypot(u[:, 0], u[:, 1]),
            robot_turn_rate=w,
            saturated=record.saturated,
            robots_at_limit=record.at_limit,
            shortfall_applied=record.shortfall_applied,
        )
        idx = len(self.frames["time"]) - 1
        for key, v in vals.items():
            self.frames[key][idx] = v

    def record_state(self) -> None:
        loop = self.loop
        n = loop.robots.n
        f = self.frames
        f["time"].append(loop.t)
        f["robot_x"].append(loop.robots.positions[:, 0].copy())
        f["robot_y"].append(loop.robots.positions[:, 1].copy())
        f["robot_heading"].append(loop.robots.headings.copy())
        if self.humans is not None:
            f["human_x"].append(loop.crowd.positions[self.humans, 0])
            f["human_y"].append(loop.crowd.positions[self.humans, 1])
        f["density"].append(loop.density.copy())
        f["fraction_in_target"].append(self.target.fraction)
        f["seen_fraction"].append(loop.crowd.seen_fraction() if self.agents else np.nan)
        if self.exits:
            f.setdefault("fraction_evacuated", []).append(1.0 - loop.crowd.remaining_fraction())
        for key in ("robot_speed", "robot_turn_rate"):
            f[key].append(np.full(n, np.nan))
        for key in _CONTROL_KEYS:
            f[key].append(np.nan)
        f["saturated"].append(False)
        f["robots_at_limit"].append(-1)
        f["shortfall_applied"].append(np.nan)
        self.last_recorded_step = loop.step_index

    def timeseries(self) -> NetCDFDataset:
        """The frames as the contents of ``timeseries.nc`` (the last frame's control evaluated at the final state).

        One description of the file, variables, dims, dtypes and CF attributes: :meth:`SimulationResult.save
        <meanfield.simulation.result.SimulationResult.save>` writes it with h5netcdf
        (:meth:`~meanfield.io.netcdf.NetCDFDataset.write_netcdf`), :meth:`dataset` turns it into an
        xarray Dataset.

        Returns
        -------
        NetCDFDataset
        """
        loop = self.loop
        f = self.frames
        g = loop.grid
        if np.isnan(f["V2"][-1]):
            try:
                state = loop.controller.act(loop.observe()).state
                for key, v in self._lyapunov_values(state).items():
                    f[key][-1] = v
            except (FloatingPointError, ValueError):
                pass
        stack = np.asarray
        data: dict[str, NetCDFVariable] = {
            "robot_x": NetCDFVariable(("time", "robot"), stack(f["robot_x"])),
            "robot_y": NetCDFVariable(("time", "robot"), stack(f["robot_y"])),
            "robot_heading": NetCDFVariable(("time", "robot"), stack(f["robot_heading"])),
            "robot_speed": NetCDFVariable(("time", "robot"), stack(f["robot_speed"])),
            "robot_turn_rate": NetCDFVariable(("time", "robot"), stack(f["robot_turn_rate"])),
        }
        coords: dict[str, np.ndarray] = {"time": stack(f["time"], float), "x": g.x, "y": g.y}
        coords["robot"] = np.arange(loop.robots.n)
        if self.humans is not None:
            data["human_x"] = NetCDFVariable(("time", "human"), stack(f["human_x"]))
            data["human_y"] = NetCDFVariable(("time", "human"), stack(f["human_y"]))
            coords["human"] = self.humans
        data["density"] = NetCDFVariable(("time", "x", "y"), stack(f["density"]))
        data["target_density"] = NetCDFVariable(("x", "y"), loop.target)
        for key in (*_CONTROL_KEYS[:4], "fraction_in_target", *_CONTROL_KEYS[4:]):
            data[key] = NetCDFVariable(("time",), stack(f[key], float))
        data["saturated"] = NetCDFVariable(("time",), stack(f["saturated"], np.int8))
        count = np.int16 if loop.robots.n <= np.iinfo(np.int16).max else np.int32  # the smallest that holds n
        data["robots_at_limit"] = NetCDFVariable(("time",), stack(f["robots_at_limit"], count))
        data["shortfall_applied"] = NetCDFVariable(("time",), stack(f["shortfall_applied"], float))
        data["seen_fraction"] = NetCDFVariable(("time",), stack(f["seen_fraction"], float))
        if "fraction_evacuated" in f:
            data["fraction_evacuated"] = NetCDFVariable(("time",), stack(f["fraction_evacuated"], float))
        p = loop.parts
        ds = NetCDFDataset(
            data_vars=data,
            coords={name: NetCDFVariable((name,), np.array(values)) for name, values in coords.items()},  # (copies)
            attrs={
                "title": "meanfield closed-loop run (Zheng et al., robot-assisted crowd evacuation)",
                "scenario_toml": loop.scenario.to_toml(),
                "seed": loop.scenario.seed,
                "target_center_x": p.target_center[0],
                "target_center_y": p.target_center[1],
                "target_radius": p.target_radius,
                "V1_definition": "V1 = integral of rho_tilde^2 (no factor 1/2)",
                "V2_definition": "V2 = integral of rho_tilde^2/2 + |v_tilde|^2/2",
                "backend": loop.scenario.crowd.kind,
                "body_radius": loop.crowd.body_radius if self.agents else 0.0,
                "humans_total": loop.crowd.n if loop.crowd.n is not None else 0,
                "humans_recorded": len(self.humans) if self.humans is not None else 0,
                "units_system": loop.scenario.units,
                "Conventions": CF_CONVENTIONS,
            },
        )
        if self.humans is not None:
            ds["human"].attrs["description"] = (
                "index of the human in the crowd (a spaced subset when record_humans < humans_total)"
            )
        _label_variables(ds, loop.scenario.units)
        ds["robot_speed"].attrs["description"] = "applied (saturated) speed |u_i| during the step from this frame"
        ds["shortfall"].attrs["description"] = "A minus what the strategy's (unclipped) extra inputs cancel"
        ds["shortfall_applied"].attrs["description"] = (
            "A minus what the applied (saturated) inputs cancel: dV2/dt = -diss - sum k_u|b|^2 - sum k_w g^2 + this"
        )
        ds["seen_fraction"].attrs["description"] = (
            "fraction of humans with a robot within the view radius (1 without gating); recorded at the frame's step"
        )
        ds["robots_at_limit"].attrs["description"] = (
            "robots whose commanded input reached a speed or turn-rate limit in the step from this frame"
            " (-1: none recorded)"
        )
        return ds

    def dataset(self) -> Any:
        """The frames as an xarray Dataset: :meth:`timeseries` as :meth:`~meanfield.io.netcdf.NetCDFDataset.to_xarray`
        builds it (imports xarray)."""
        return self.timeseries().to_xarray()


# CF ``units`` (UDUNITS) of each variable in SI scenarios, and its ``long_name``; "1" marks a
# dimensionless quantity, and every unit is "1" in the paper's dimensionless scenarios
_CF: dict[str, tuple[str, str]] = {
    "time": ("s", "time"),
    "x": ("m", "x of the cell centre"),
    "y": ("m", "y of the cell centre"),
    "robot_x": ("m", "robot position, x"),
    "robot_y": ("m", "robot position, y"),
    "robot_heading": ("rad", "sign heading theta_i"),
    "robot_speed": ("m s-1", "applied robot speed |u_i|"),
    "robot_turn_rate": ("rad s-1", "applied turn rate omega_i"),
    "human_x": ("m", "human position, x"),
    "human_y": ("m", "human position, y"),
    "density": ("m-2", "crowd density (estimate) on the grid, unit mass"),
    "target_density": ("m-2", "target density rho_*"),
    "V1": ("m-2", "V1 = integral of rho_tilde^2"),
    "rho_error_l2": ("m-1", "L2 norm of rho_tilde"),
    "v_error_l2": ("m2 s-1", "L2 norm of v_tilde"),
    "fraction_in_target": ("1", "fraction of the crowd in the target region"),
    "seen_fraction": ("1", "fraction of humans with a robot in view"),
    "fraction_evacuated": ("1", "fraction of the crowd out through the exits"),
}


CF_CONVENTIONS = "CF-1.8"
"""The ``Conventions`` attribute of ``timeseries.nc``: the newest CF version the CF checker
(``cfchecker`` 4.1, the reference checker of cfconventions.org) knows, and all the file needs (later
versions add nothing it uses).  ``tests/io/test_cf_conventions.py`` runs the checker on a saved run."""

_INDEX_COORDINATES = {"robot": "index of the robot", "human": "index of the human in the crowd"}
"""Integer coordinates: counts, CF ``units = "1"``."""


def _label_variables(ds: NetCDFDataset, units: str) -> None:
    """CF attributes: ``long_name`` everywhere, ``units`` in SI or ``"1"`` when dimensionless.

    V2, A and the shortfalls mix 1/L² with L⁴/T² (docs page *The paper's slips*, units): they
    get no physical unit, only their ``long_name``.  The index coordinates ``robot`` and ``human``
    are counts (``"1"``); coordinate variables carry no ``_FillValue`` (CF 2.5.1: a coordinate has
    no missing values; :mod:`meanfield.io.netcdf` writes none).
    """
    for name, long_name in _INDEX_COORDINATES.items():
        if name in ds:
            ds[name].attrs.setdefault("long_name", long_name)
            ds[name].attrs["units"] = "1"
    for name, (unit, long_name) in _CF.items():
        if name in ds:
            ds[name].attrs.setdefault("long_name", long_name)
            ds[name].attrs["units"] = unit if units == "SI" else "1"
    for name, long_name in (
        ("V2", "V2 = integral of rho_tilde^2/2 + |v_tilde|^2/2 (mixes 1/L^2 and L^4/T^2)"),
        ("A", "cross term A of the robot law, eq. (8)"),
        ("shortfall", "part of A the strategy leaves uncancelled"),
        ("shortfall_applied", "part of A the applied inputs leave uncancelled"),
    ):  # no single unit: each says why (CF: a comment, no units attribute)
        if name in ds:
            ds[name].attrs.setdefault("long_name", long_name)
            ds[name].attrs["comment"] = _MIXED_UNITS
    if "dissipation" in ds:  # d/dt of V1: V1's unit per second
        ds["dissipation"].attrs.setdefault("long_name", "integral of alpha |grad rho_tilde|^2")
        ds["dissipation"].attrs["units"] = "m-2 s-1" if units == "SI" else "1"
    if "robots_at_limit" in ds:  # a count
        ds["robots_at_limit"].attrs.setdefault("long_name", "robots whose command reached a limit")
        ds["robots_at_limit"].attrs["units"] = "1"
    if "saturated" in ds:  # a flag
        var = ds["saturated"]
        var.attrs.setdefault("long_name", "1 if the limits cut a command in this step")
        var.attrs.update(units="1", flag_values=np.array([0, 1], dtype=var.dtype), flag_meanings="within_limits cut")


_MIXED_UNITS = (
    "mixes rho_tilde^2 (1/L^2) with |v_tilde|^2 (L^4/T^2) as the paper's V2 does: no single unit "
    "(docs page The paper's slips, units); in the kernel's units (controller.scaling = kernel) both are 1"
)
