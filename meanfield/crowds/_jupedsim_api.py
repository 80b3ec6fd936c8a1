"""A small adapter over JuPedSim's Python API: the only module that touches ``jupedsim``.

JuPedSim (Forschungszentrum Jülich, LGPL) simulates pedestrians as bodies moved by an
operational model.  The toolkit uses it through *direct steering*: every control period it
gives each agent a target point and a desired speed, and lets the model avoid collisions.
With exits, an agent may instead be put on the journey of an *exit stage*
(``Simulation.add_exit_stage``): JuPedSim then routes it to the exit's area and removes it
when its centre is inside.
JuPedSim's API moves between versions, and its next major version renames the steering
attributes (``Agent.target`` becomes ``Agent.final_target``, PR #1626; ``v0`` became
``desired_speed`` in 1.x).  Everything that depends on those names is here, resolved once
when the simulation is built; the rest of the toolkit calls :class:`JuPedSimAdapter`.

Tested with JuPedSim 1.4.2.  Install (see the README for why ``--no-deps``)::

    pip install "meanfield-crowd[pedestrians]"
    pip install --no-deps "jupedsim==1.4.2"
"""

from __future__ import annotations

import gc
import importlib
import itertools
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np

from meanfield.errors import ParameterError

__all__ = [
    "JuPedSimAdapter",
    "JuPedSimUnavailable",
    "INSTALL_HINT",
    "jupedsim_version",
    "load_jupedsim",
    "MODELS",
    "MODEL_PARAMETERS",
    "REPULSION",
    "PEDESTRIAN_MODELS",
]

INSTALL_HINT = (
    'pip install "meanfield-crowd[pedestrians]" && pip install --no-deps "jupedsim==1.4.2" '
    "(JuPedSim's wheel also asks for PySide6 and VTK, about 1.9 GB, for its viewer; the simulation "
    "needs neither, hence --no-deps; see the README)"
)

# scenario name -> (model class, agent-parameters class) in JuPedSim's namespace
MODELS: dict[str, tuple[str, str]] = {
    "collision-free-speed": ("CollisionFreeSpeedModel", "CollisionFreeSpeedModelAgentParameters"),
    "collision-free-speed-v2": ("CollisionFreeSpeedModelV2", "CollisionFreeSpeedModelV2AgentParameters"),
    "collision-free-speed-v3": ("CollisionFreeSpeedModelV3", "CollisionFreeSpeedModelV3AgentParameters"),
    "anticipation-velocity": ("AnticipationVelocityModel", "AnticipationVelocityModelAgentParameters"),
    "generalized-centrifugal-force": (
        "GeneralizedCentrifugalForceModel",
        "GeneralizedCentrifugalForceModelAgentParameters",
    ),
    "social-force": ("SocialForceModel", "SocialForceModelAgentParameters"),
    "warp-driver": ("WarpDriverModel", "WarpDriverModelAgentParameters"),
}

PEDESTRIAN_MODELS: tuple[str, ...] = tuple(MODELS)
"""The operational models ``crowd.options.jupedsim.model`` may name (the keys of :data:`MODELS`)."""

REPULSION: tuple[str, ...] = (
    "strength_neighbor_repulsion",
    "range_neighbor_repulsion",
    "strength_geometry_repulsion",
    "range_geometry_repulsion",
)
"""The repulsion parameters of the collision-free speed models, by JuPedSim's names (neighbours' first)."""

MODEL_PARAMETERS: dict[str, dict[str, str]] = {
    "collision-free-speed": {"time_gap": "agent", **dict.fromkeys(REPULSION, "model")},
    "collision-free-speed-v2": {"time_gap": "agent", **dict.fromkeys(REPULSION, "agent")},
    "collision-free-speed-v3": {"time_gap": "agent", **dict.fromkeys(REPULSION, "agent")},
    "anticipation-velocity": dict.fromkeys(("time_gap", *REPULSION[:2]), "agent"),
    "generalized-centrifugal-force": {},
    "social-force": {},
    "warp-driver": {},
}
"""The parameters of each model that ``[crowd.options.jupedsim]`` may set, and where JuPedSim takes each: on the
model's class (``"model"``: ``CollisionFreeSpeedModel(strength_neighbor_repulsion=...)``, the same for every body)
or on every agent's parameters (``"agent"``: ``CollisionFreeSpeedModelAgentParameters(time_gap=...)``).  The
names are JuPedSim's (1.4.2); a parameter left unset keeps JuPedSim's default."""


class JuPedSimUnavailable(ParameterError):
    """``crowd.kind = "jupedsim"`` without JuPedSim installed (the CLI exits with 2)."""

    def __init__(self, reason: str):
        allowed = f"an installed JuPedSim ({reason}); install: {INSTALL_HINT}"
        super().__init__("crowd.kind", "jupedsim", allowed)


@contextmanager
def _collector_paused() -> Iterator[None]:
    """Pause Python's cyclic garbage collector over a per-agent loop, then restore it.

    Steering and reading 10,000 agents creates some 20,000 short-lived lists and tuples per
    step; each is freed by its reference count (none is in a cycle), but their creation
    triggers collections, and a full one walks every object of the process.  In a process
    that holds many (measured after the Fokker–Planck benchmarks: 377,000), that doubled the
    adapter's cost per agent-step at 10,000 agents (2.9 µs against 1.5 µs paused).
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def load_jupedsim() -> Any:
    """The ``jupedsim`` module, or :class:`JuPedSimUnavailable` with the install command."""
    try:
        return importlib.import_module("jupedsim")
    except ImportError as exc:  # also a broken install (e.g. a missing 'deprecated')
        raise JuPedSimUnavailable(f"import failed: {exc}") from None


def jupedsim_version() -> str | None:
    """The installed JuPedSim version, or None when it cannot be imported."""
    try:
        return str(load_jupedsim().__version__)
    except JuPedSimUnavailable:
        return None


def _first_attribute(obj: Any, names: tuple[str, ...], what: str) -> str:
    for name in names:
        if hasattr(obj, name):
            return name
    version = getattr(importlib.import_module("jupedsim"), "__version__", "?")
    raise RuntimeError(
        f"JuPedSim {version}: none of the attributes {names} ({what}) exists; "
        "this version is not supported by meanfield.crowds._jupedsim_api"
    )


def _split_parameters(model: str, parameters: Mapping[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """The keyword arguments of the model's class and of every agent's parameters (:data:`MODEL_PARAMETERS`)."""
    where = MODEL_PARAMETERS[model]
    on = {"model": {}, "agent": {}}
    for name, value in parameters.items():
        if name not in where:
            allowed = ", ".join(where) or "none"
            raise ParameterError(
                f"crowd.options.jupedsim.{name}",
                value,
                f"no value (the model {model} has no such parameter; it has: {allowed})",
            )
        on[where[name]][name] = float(value)
    return on["model"], on["agent"]


class JuPedSimAdapter:
    """One JuPedSim simulation of bodies under direct steering.

    Parameters
    ----------
    geometry : shapely.Polygon
        The walkable area.
    model : str
        One of :data:`MODELS` (the scenario's ``crowd.options.jupedsim.model``).
    time_step : float
        JuPedSim's step (s).
    seed : int
        Seed of the models that draw random numbers (anticipation velocity).
    exit_areas : sequence of shapely.Polygon
        One exit stage per area, in this order (the exit's index); each inside ``geometry``.
    parameters : mapping of str to float, optional
        The model's parameters that differ from JuPedSim's defaults, by their names in
        :data:`MODEL_PARAMETERS` (``crowd.options.jupedsim.time_gap``, ...); another name is refused.

    Attributes
    ----------
    alive : ndarray of bool, shape (N,)
        The agents still in the simulation.
    route : ndarray of int, shape (N,)
        The exit each agent walks to (-1: direct steering).
    left_at : ndarray, shape (N,)
        When each agent's centre was first in its exit's area (NaN: still here); JuPedSim
        removes it at its next step.
    left_by : ndarray of int, shape (N,)
        Through which exit each agent left (-1: still here).

    Notes
    -----
    JuPedSim keeps its agents in an array and erases the removed ones, which moves the
    others: the native handles are fetched again after every removal (:meth:`_refresh`).
    """

    def __init__(
        self,
        geometry: Any,
        model: str,
        time_step: float,
        seed: int = 0,
        exit_areas: Any = (),
        parameters: Mapping[str, float] | None = None,
    ):
        jps = load_jupedsim()
        if model not in MODELS:
            raise ParameterError("crowd.options.jupedsim.model", model, "one of " + ", ".join(MODELS))
        on_model, self._agent_kwargs = _split_parameters(model, parameters or {})
        self.jps = jps
        self.model_name = model
        self.version = str(getattr(jps, "__version__", "?"))
        model_cls, params_cls = (getattr(jps, name, None) for name in MODELS[model])
        if model_cls is None or params_cls is None:
            raise ParameterError(
                "crowd.options.jupedsim.model", model, f"a model this JuPedSim ({self.version}) provides"
            )
        kwargs = {"rng_seed": int(seed)} if model == "anticipation-velocity" else {}
        kwargs.update(on_model)
        self.parameters = dict(parameters or {})
        self._params_cls = params_cls
        self.sim = jps.Simulation(model=model_cls(**kwargs), geometry=geometry, dt=float(time_step))
        self.time_step = float(time_step)
        stage = self.sim.add_direct_steering_stage()
        self._stage = stage
        self._journey = self.sim.add_journey(jps.JourneyDescription([stage]))
        # one journey per exit, of its exit stage alone (a direct steering stage must be alone in its journey)
        self.exit_areas = tuple(exit_areas)
        self._exit_routes: list[tuple[int, int]] = []
        for area in self.exit_areas:
            exit_stage = self.sim.add_exit_stage(area)
            self._exit_routes.append((self.sim.add_journey(jps.JourneyDescription([exit_stage])), exit_stage))
        self._ids: list[int] = []
        self._row: dict[int, int] = {}
        self._handles: list[Any] = []
        self._states: list[Any] = []
        self._speeds = np.empty(0)
        self.alive = np.ones(0, dtype=bool)
        self.route = np.full(0, -1, dtype=np.intp)
        self.left_at = np.full(0, np.nan)
        self.left_by = np.full(0, -1, dtype=np.intp)
        self._stale = self._removal_reported = False

    # ------------------------------------------------------------------ agents
    def add_agents(self, positions: np.ndarray, radius: float, desired_speed: float) -> None:
        """Add one agent per row of ``positions`` (all at once, before the first step).

        The agents are kept in this order: row ``j`` of :meth:`positions` is agent ``j``.
        """
        if self._ids:
            raise RuntimeError("add_agents may be called once, before the simulation starts")
        ids = []
        for x, y in np.asarray(positions, float):
            ids.append(self.sim.add_agent(self._agent_parameters((float(x), float(y)), radius, desired_speed)))
        n = len(ids)
        self._ids = ids
        self._row = {agent_id: row for row, agent_id in enumerate(ids)}
        self.alive = np.ones(n, dtype=bool)
        self.route = np.full(n, -1, dtype=np.intp)
        self.left_at = np.full(n, np.nan)
        self.left_by = np.full(n, -1, dtype=np.intp)
        self._fetch_handles()
        # the renamed attributes, resolved once; their bound setters and getter are called
        # directly in the per-step loops (no attribute look-up per agent)
        agent_type, state_type = type(self._handles[0]), type(self._states[0])
        target = _first_attribute(agent_type, ("final_target", "target"), "the direct-steering target")
        speed = _first_attribute(state_type, ("desired_speed", "v0"), "the desired speed")
        self._set_target = getattr(agent_type, target).fset
        self._set_speed = getattr(state_type, speed).fset
        self._get_position = agent_type.position.fget
        self._speeds = np.full(n, float(desired_speed))

    def _fetch_handles(self) -> None:
        """The native handles of the agents still in the simulation (None for those gone)."""
        native = self.sim._obj  # the bound C++ simulation: its agent handles skip the Python wrappers
        self._handles = [native.agent(i) if here else None for i, here in zip(self._ids, self.alive, strict=True)]
        self._states = [None if h is None else h.model for h in self._handles]
        self._stale = False

    def _refresh(self) -> None:
        """Fetch the handles again if JuPedSim erased agents since they were fetched."""
        if self._stale:
            self._fetch_handles()

    def _agent_parameters(self, position: tuple[float, float], radius: float, speed: float) -> Any:
        common = {"position": position, "journey_id": self._journey, "stage_id": self._stage, **self._agent_kwargs}
        if self.model_name == "generalized-centrifugal-force":  # an ellipse: make it a disk of `radius`
            shape = {"a_min": radius, "b_min": radius, "b_max": radius, "a_v": 0.0}
            return self._params_cls(**common, desired_speed=speed, **shape)
        return self._params_cls(**common, desired_speed=speed, radius=radius)

    @property
    def n(self) -> int:
        """Number of agents added (those gone included)."""
        return len(self._ids)

    # ------------------------------------------------------------------ steering
    def steer(self, targets: np.ndarray, speeds: np.ndarray, routes: np.ndarray | None = None) -> None:
        """Set every agent's target point (N, 2), inside the walkable area, and desired speed (N,).

        ``routes`` (N,) puts an agent on the journey of exit ``routes[j]`` (JuPedSim walks it
        there; its target is then ignored) or, for -1, back to direct steering.  The rows of
        the agents gone are ignored.  Only the speeds that changed since the last call cross
        into JuPedSim.
        """
        if len(targets) != len(self._ids) or len(speeds) != len(self._ids):
            raise ValueError(f"steer: {len(self._ids)} targets and speeds expected")
        self._refresh()
        if routes is not None:
            self._switch(np.flatnonzero(self.alive & (routes != self.route)), routes)
        handles = self._handles
        direct = np.flatnonzero(self.alive & (self.route < 0))
        with _collector_paused():
            if len(direct) == len(handles):  # everyone here and steered directly (no exits, or none near)
                list(map(self._set_target, handles, targets.tolist()))
            else:
                list(map(self._set_target, [handles[i] for i in direct], targets[direct].tolist()))
        changed = np.flatnonzero(self.alive & (speeds != self._speeds))
        if len(changed):
            states = self._states
            with _collector_paused():
                list(map(self._set_speed, [states[i] for i in changed], speeds[changed].tolist()))
            self._speeds[changed] = speeds[changed]

    def _switch(self, rows: np.ndarray, routes: np.ndarray) -> None:
        """Put the agents of ``rows`` on the journeys of ``routes[rows]`` (-1: direct steering)."""
        for row in rows.tolist():
            k = int(routes[row])
            journey, stage = self._exit_routes[k] if k >= 0 else (self._journey, self._stage)
            self.sim.switch_agent_journey(self._ids[row], journey, stage)
            self.route[row] = k

    def positions(self, out: np.ndarray | None = None) -> np.ndarray:
        """Agent positions, shape (N, 2), in the order they were added (written into ``out``).

        The rows of the agents gone are NaN.
        """
        self._refresh()
        n = len(self._ids)
        out = np.empty((n, 2)) if out is None else out
        if self.alive.all():
            with _collector_paused():
                flat = np.fromiter(itertools.chain.from_iterable(map(self._get_position, self._handles)), float, 2 * n)
            out[:] = flat.reshape(n, 2)
            return out
        here = np.flatnonzero(self.alive)
        handles = [self._handles[i] for i in here]
        with _collector_paused():
            flat = np.fromiter(itertools.chain.from_iterable(map(self._get_position, handles)), float, 2 * len(here))
        out[:] = np.nan
        out[here] = flat.reshape(-1, 2)
        return out

    def iterate(self, count: int = 1) -> None:
        """Advance JuPedSim by ``count`` of its steps, and record who left through an exit.

        JuPedSim removes an agent on an exit's journey at the start of the step after the one
        that brought its centre into the exit's area: that earlier step's end is ``left_at``.
        Those inside their exit's area after the last step have left too (JuPedSim removes
        them at its next step).
        """
        native = self.sim._obj
        for _ in range(count):
            native.iterate()
            removed = native.removed_agents()
            # handles are invalid once JuPedSim erased an agent (in this step or the next one)
            if removed or self._removal_reported:
                self._stale = True
            self._removal_reported = bool(removed)
            if removed:
                t = native.elapsed_time() - self.time_step
                for agent_id in removed:
                    self._leave(self._row[agent_id], t)
        if self._exit_routes:
            self._leave_arrived()

    def _leave(self, row: int, t: float) -> None:
        if self.alive[row]:
            self.alive[row] = False
            self.left_at[row] = t
            self.left_by[row] = self.route[row]

    def _leave_arrived(self) -> None:
        """The agents already in their exit's area leave now (JuPedSim removes them at its next step)."""
        import shapely

        walking = np.flatnonzero(self.alive & (self.route >= 0))
        if not len(walking):
            return
        self._refresh()
        xy = np.array([self._get_position(self._handles[i]) for i in walking.tolist()], float)
        t = self.elapsed_time
        for k, area in enumerate(self.exit_areas):
            mine = self.route[walking] == k
            inside = shapely.contains_xy(area, xy[mine, 0], xy[mine, 1])
            for row in walking[mine][inside].tolist():
                self._leave(row, t)

    @property
    def elapsed_time(self) -> float:
        """JuPedSim's clock (s)."""
        return float(self.sim.elapsed_time())
