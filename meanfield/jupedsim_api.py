"""A small adapter over JuPedSim's Python API: the only module that touches ``jupedsim``.

JuPedSim (Forschungszentrum Jülich, LGPL) simulates pedestrians as bodies moved by an
operational model.  The toolkit uses it through *direct steering*: every control period it
gives each agent a target point and a desired speed, and lets the model avoid collisions.
JuPedSim's API moves between versions, and its next major version renames the steering
attributes (``Agent.target`` becomes ``Agent.final_target``, PR #1626; ``v0`` became
``desired_speed`` in 1.x).  Everything that depends on those names is here, resolved once
when the simulation is built; the rest of the toolkit calls :class:`JuPedSimAdapter`.

Tested with JuPedSim 1.4.2.  Install (see the README for why ``--no-deps``)::

    pip install "meanfield-crowd[pedestrians]"
    pip install --no-deps "jupedsim==1.4.2"
"""

from __future__ import annotations

import importlib
import itertools
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
"""The operational models ``pedestrians.model`` may name (the keys of :data:`MODELS`)."""


class JuPedSimUnavailable(ParameterError):
    """``pedestrians.backend = "jupedsim"`` without JuPedSim installed (the CLI exits with 2)."""

    def __init__(self, reason: str):
        allowed = f"an installed JuPedSim ({reason}); install: {INSTALL_HINT}"
        super().__init__("pedestrians.backend", "jupedsim", allowed)


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
        "this version is not supported by meanfield.jupedsim_api"
    )


class JuPedSimAdapter:
    """One JuPedSim simulation of bodies under direct steering.

    Parameters
    ----------
    geometry : shapely.Polygon
        The walkable area.
    model : str
        One of :data:`MODELS` (the scenario's ``pedestrians.model``).
    time_step : float
        JuPedSim's step (s).
    seed : int
        Seed of the models that draw random numbers (anticipation velocity).
    """

    def __init__(self, geometry: Any, model: str, time_step: float, seed: int = 0):
        jps = load_jupedsim()
        if model not in MODELS:
            raise ParameterError("pedestrians.model", model, "one of " + ", ".join(MODELS))
        self.jps = jps
        self.model_name = model
        self.version = str(getattr(jps, "__version__", "?"))
        model_cls, params_cls = (getattr(jps, name, None) for name in MODELS[model])
        if model_cls is None or params_cls is None:
            raise ParameterError("pedestrians.model", model, f"a model this JuPedSim ({self.version}) provides")
        kwargs = {"rng_seed": int(seed)} if model == "anticipation-velocity" else {}
        self._params_cls = params_cls
        self.sim = jps.Simulation(model=model_cls(**kwargs), geometry=geometry, dt=float(time_step))
        stage = self.sim.add_direct_steering_stage()
        self._stage = stage
        self._journey = self.sim.add_journey(jps.JourneyDescription([stage]))
        self._handles: list[Any] = []
        self._states: list[Any] = []
        self._speeds = np.empty(0)

    # ------------------------------------------------------------------ agents
    def add_agents(self, positions: np.ndarray, radius: float, desired_speed: float) -> None:
        """Add one agent per row of ``positions`` (all at once, before the first step).

        The agents are kept in this order: row ``j`` of :meth:`positions` is agent ``j``.
        """
        if self._handles:
            raise RuntimeError("add_agents may be called once, before the simulation starts")
        ids = []
        for x, y in np.asarray(positions, float):
            ids.append(self.sim.add_agent(self._agent_parameters((float(x), float(y)), radius, desired_speed)))
        native = self.sim._obj  # the bound C++ simulation: its agent handles skip the Python wrappers
        self._handles = [native.agent(i) for i in ids]
        self._states = [h.model for h in self._handles]
        # the renamed attributes, resolved once; their bound setters and getter are called
        # directly in the per-step loops (no attribute look-up per agent)
        agent_type, state_type = type(self._handles[0]), type(self._states[0])
        target = _first_attribute(agent_type, ("final_target", "target"), "the direct-steering target")
        speed = _first_attribute(state_type, ("desired_speed", "v0"), "the desired speed")
        self._set_target = getattr(agent_type, target).fset
        self._set_speed = getattr(state_type, speed).fset
        self._get_position = agent_type.position.fget
        self._speeds = np.full(len(self._handles), float(desired_speed))

    def _agent_parameters(self, position: tuple[float, float], radius: float, speed: float) -> Any:
        common = {"position": position, "journey_id": self._journey, "stage_id": self._stage}
        if self.model_name == "generalized-centrifugal-force":  # an ellipse: make it a disk of `radius`
            shape = {"a_min": radius, "b_min": radius, "b_max": radius, "a_v": 0.0}
            return self._params_cls(**common, desired_speed=speed, **shape)
        return self._params_cls(**common, desired_speed=speed, radius=radius)

    @property
    def n(self) -> int:
        """Number of agents."""
        return len(self._handles)

    # ------------------------------------------------------------------ steering
    def steer(self, targets: np.ndarray, speeds: np.ndarray) -> None:
        """Set every agent's target point (N, 2), inside the walkable area, and desired speed (N,).

        Only the speeds that changed since the last call cross into JuPedSim.
        """
        if len(targets) != len(self._handles) or len(speeds) != len(self._handles):
            raise ValueError(f"steer: {len(self._handles)} targets and speeds expected")
        list(map(self._set_target, self._handles, targets.tolist()))
        changed = np.flatnonzero(speeds != self._speeds)
        if len(changed):
            states = self._states
            list(map(self._set_speed, [states[i] for i in changed], speeds[changed].tolist()))
            self._speeds[changed] = speeds[changed]

    def positions(self, out: np.ndarray | None = None) -> np.ndarray:
        """Agent positions, shape (N, 2), in the order they were added (written into ``out``)."""
        n = len(self._handles)
        flat = np.fromiter(itertools.chain.from_iterable(map(self._get_position, self._handles)), float, 2 * n)
        if out is None:
            return flat.reshape(n, 2)
        out[:] = flat.reshape(n, 2)
        return out

    def iterate(self, count: int = 1) -> None:
        """Advance JuPedSim by ``count`` of its steps."""
        self.sim.iterate(count)

    @property
    def elapsed_time(self) -> float:
        """JuPedSim's clock (s)."""
        return float(self.sim.elapsed_time())
