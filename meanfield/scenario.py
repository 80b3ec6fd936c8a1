"""Scenarios: every parameter of a closed-loop run, validated, round-tripping to TOML.

A :class:`Scenario` is a tree of small dataclasses, one per TOML table::

    name, seed, dt, t_final, record_every, record_humans
    [domain]      kind = "box" | "disk" | "polygon" and its sizes
    [grid]        cells = [nx, ny]
    [crowd]       n, initial ("uniform" | "gaussian"), initial_center, initial_std, sigma
    [robots]      n, layout ("grid" | "random" | "explicit"), positions, headings, u_max, omega_max, margin
    [kernel]      c, eta                       (K̄(ξ) = c exp(-|ξ|²/η))
    [interaction] kind ("none" | "gaussian"), strength, length
    [disturbance] kind ("none" | "constant" | "swirl"), velocity, strength
    [target]      center, std                  (Gaussian ρ_* restricted to Ω)
    [density]     bandwidth, boundary, method
    [controller]  alpha, alpha_schedule, rho_floor, k_u, k_omega, beta_gamma, dvd_dt, kind
    [controller.options]  options of a controller plugin (e.g. the NMPC horizon)
    [view]        radius ("none" | > 0), walk_speed, turning_rate   (local view, Unity study)
    [pedestrians] backend ("point-mass" | "jupedsim"), model, radius, max_speed, time_step

Every field is checked when the scenario is built (or read); a bad value raises
:class:`~meanfield.errors.ParameterError` naming the field and the allowed range, and an
unknown TOML key is refused.  The built-in ``paper`` scenario (:func:`paper_scenario`)
reproduces the paper's MATLAB study; the values the paper does not give are chosen and
justified in ``docs/scenarios.md``.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.domain import Domain
from meanfield.errors import ParameterError
from meanfield.plugins import available

__all__ = [
    "Scenario",
    "GridSpec",
    "CrowdSpec",
    "RobotSpec",
    "KernelSpec",
    "InteractionSpec",
    "DisturbanceSpec",
    "TargetSpec",
    "DensitySpec",
    "ControllerSpec",
    "ViewSpec",
    "PedestrianSpec",
    "PEDESTRIAN_MODELS",
    "paper_scenario",
    "paper_unity_scenario",
    "builtin_scenarios",
    "load_scenario",
]


# ---------------------------------------------------------------------- checks
def _num(
    name: str,
    value: Any,
    *,
    lo: float | None = None,
    lo_open: bool = False,
    hi: float | None = None,
    allowed: str | None = None,
) -> float:
    desc = allowed or _range_text(lo, lo_open, hi)
    if isinstance(value, bool):
        raise ParameterError(name, value, desc)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, value, desc) from None
    if not math.isfinite(x):
        raise ParameterError(name, value, desc)
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise ParameterError(name, value, desc)
    if hi is not None and x > hi:
        raise ParameterError(name, value, desc)
    return x


def _range_text(lo, lo_open, hi) -> str:
    if lo is None and hi is None:
        return "a finite number"
    if hi is None:
        return f"a finite number {'>' if lo_open else '>='} {lo:g}"
    return f"a number in [{lo:g}, {hi:g}]"


def _int(name: str, value: Any, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise ParameterError(name, value, f"an integer >= {lo}")
    if value < lo:
        raise ParameterError(name, value, f"an integer >= {lo}")
    return int(value)


def _choice(name: str, value: Any, options: tuple[str, ...]) -> str:
    if value not in options:
        raise ParameterError(name, value, "one of " + ", ".join(repr(o) for o in options))
    return value


def _point(name: str, value: Any) -> tuple[float, float]:
    try:
        a, b = value
    except (TypeError, ValueError):
        raise ParameterError(name, value, "a pair [x, y] of finite numbers") from None
    return (_num(f"{name}[0]", a), _num(f"{name}[1]", b))


def _optional_limit(name: str, value: Any, what: str = 'a number > 0, or "none" for no limit') -> float | None:
    if value is None or (isinstance(value, str) and value == "none"):
        return None
    return _num(name, value, lo=0.0, lo_open=True, allowed=what)


# ---------------------------------------------------------------------- sections
@dataclass
class GridSpec:
    """Finite-volume grid: ``cells = (nx, ny)``, each >= 2."""

    cells: tuple[int, int] = (30, 30)

    def __post_init__(self) -> None:
        try:
            nx, ny = self.cells
        except (TypeError, ValueError):
            raise ParameterError("grid.cells", self.cells, "a pair of integers >= 2") from None
        self.cells = (_int("grid.cells[0]", nx, 2), _int("grid.cells[1]", ny, 2))


@dataclass
class CrowdSpec:
    """Humans: count ``n >= 1``, initial distribution, diffusion ``σ >= 0``.

    ``field_evaluation`` is how ``v_r`` reaches the humans: ``"exact"`` (eq. (3) at each
    human, O(N n)), ``"sampled"`` (on a lattice twice as fine as the grid, interpolated
    bilinearly, O(N + n M): :mod:`meanfield.sampled_field`) or ``"auto"`` (sampled when
    ``N n > 2·10⁶``).
    """

    n: int = 200
    initial: str = "uniform"
    initial_center: tuple[float, float] = (0.5, 0.5)
    initial_std: float = 0.1
    sigma: float = 0.015
    field_evaluation: str = "auto"

    def __post_init__(self) -> None:
        self.n = _int("crowd.n", self.n, 1)
        self.initial = _choice("crowd.initial", self.initial, ("uniform", "gaussian"))
        self.initial_center = _point("crowd.initial_center", self.initial_center)
        self.initial_std = _num("crowd.initial_std", self.initial_std, lo=0.0, lo_open=True)
        self.sigma = _num("crowd.sigma", self.sigma, lo=0.0)
        self.field_evaluation = _choice("crowd.field_evaluation", self.field_evaluation, ("auto", "exact", "sampled"))


@dataclass
class RobotSpec:
    """Robots: count, initial layout and headings, speed limits, wall margin.

    ``layout = "grid"`` puts the robots on a regular lattice (the paper's 4×4),
    ``"random"`` draws them uniformly, ``"explicit"`` takes ``positions``.
    ``headings`` is ``"random"`` (uniform on [0, 2π), as in the paper) or a list.
    ``margin`` keeps robots at least that far inside the bounding walls of a box
    (a robot is a body; it cannot stand in a wall).
    """

    n: int = 16
    layout: str = "grid"
    positions: list[list[float]] | None = None
    headings: str | list[float] = "random"
    u_max: float | None = None
    omega_max: float | None = None
    margin: float = 0.0

    def __post_init__(self) -> None:
        self.n = _int("robots.n", self.n, 1)
        self.layout = _choice("robots.layout", self.layout, ("grid", "random", "explicit"))
        if self.layout == "explicit":
            if self.positions is None:
                raise ParameterError("robots.positions", None, "a list of n [x, y] pairs when layout = 'explicit'")
            pos = np.asarray(self.positions, dtype=float) if _all_numbers(self.positions) else None
            if pos is None or pos.shape != (self.n, 2) or not np.all(np.isfinite(pos)):
                raise ParameterError("robots.positions", self.positions, f"{self.n} finite [x, y] pairs")
            self.positions = pos.tolist()
        elif self.positions is not None:
            raise ParameterError("robots.positions", "given", "no positions unless layout = 'explicit'")
        if isinstance(self.headings, str):
            _choice("robots.headings", self.headings, ("random",))
        else:
            h = np.asarray(self.headings, dtype=float) if _all_numbers(self.headings) else None
            if h is None or h.shape != (self.n,) or not np.all(np.isfinite(h)):
                raise ParameterError("robots.headings", self.headings, f"'random' or {self.n} finite angles")
            self.headings = h.tolist()
        self.u_max = _optional_limit("robots.u_max", self.u_max)
        self.omega_max = _optional_limit("robots.omega_max", self.omega_max)
        self.margin = _num("robots.margin", self.margin, lo=0.0)


def _all_numbers(x: Any) -> bool:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        return False
    return arr.dtype.kind == "f"


@dataclass
class KernelSpec:
    """Navigation kernel ``K̄(ξ) = c exp(-|ξ|²/η)``: ``c > 0``, ``η > 0``."""

    c: float = 0.2
    eta: float = 0.05

    def __post_init__(self) -> None:
        self.c = _num("kernel.c", self.c, lo=0.0, lo_open=True)
        self.eta = _num("kernel.eta", self.eta, lo=0.0, lo_open=True)


@dataclass
class InteractionSpec:
    """Interaction potential W: ``"none"`` or ``"gaussian"`` (``s exp(-|z|²/ℓ²)``, ``s > 0`` repels)."""

    kind: str = "none"
    strength: float = 0.0
    length: float = 0.1

    def __post_init__(self) -> None:
        self.kind = _choice("interaction.kind", self.kind, ("none", "gaussian"))
        self.strength = _num("interaction.strength", self.strength)
        self.length = _num("interaction.length", self.length, lo=0.0, lo_open=True)
        if self.kind == "gaussian" and self.strength == 0:
            raise ParameterError("interaction.strength", 0.0, "a non-zero number when kind = 'gaussian'")


@dataclass
class DisturbanceSpec:
    """Bounded disturbance v_a: ``"none"``, ``"constant"`` (``velocity``) or ``"swirl"``
    (rotation about the domain centre with speed ``strength`` at unit distance)."""

    kind: str = "none"
    velocity: tuple[float, float] = (0.0, 0.0)
    strength: float = 0.0

    def __post_init__(self) -> None:
        self.kind = _choice("disturbance.kind", self.kind, ("none", "constant", "swirl"))
        self.velocity = _point("disturbance.velocity", self.velocity)
        self.strength = _num("disturbance.strength", self.strength)


@dataclass
class TargetSpec:
    """Target density: Gaussian with ``center`` and ``std > 0``, restricted to Ω, unit mass."""

    center: tuple[float, float] = (1.0, 1.0)
    std: float = 0.15

    def __post_init__(self) -> None:
        self.center = _point("target.center", self.center)
        self.std = _num("target.std", self.std, lo=0.0, lo_open=True)


@dataclass
class DensitySpec:
    """KDE: ``bandwidth`` h > 0 or ``"silverman"``; wall ``boundary``; evaluation ``method``."""

    bandwidth: float | str = 0.08
    boundary: str = "reflect"
    method: str = "auto"

    def __post_init__(self) -> None:
        if isinstance(self.bandwidth, str):
            _choice("density.bandwidth", self.bandwidth, ("silverman",))
        else:
            self.bandwidth = _num(
                "density.bandwidth", self.bandwidth, lo=0.0, lo_open=True, allowed='a number > 0, or "silverman"'
            )
        self.boundary = _choice("density.boundary", self.boundary, ("reflect", "renormalize", "none"))
        self.method = _choice("density.method", self.method, ("auto", "separable", "binned"))


@dataclass
class ControllerSpec:
    """Controller gains and options (paper, eqs. (6) and (8)).

    ``beta_gamma`` is ``"min-norm"`` (DESIGN.md §2) or an installed strategy plugin, such
    as ``"bounded"`` (the speed-limited program of :mod:`analysis.bounded`).  ``kind`` is
    ``"backstepping"`` (the paper's law) or an installed controller plugin, such as
    ``"nmpc"`` (:mod:`analysis.nmpc`); ``options`` is passed to that plugin, which
    validates it.  See :mod:`meanfield.plugins`.
    """

    alpha: float = 0.2
    alpha_schedule: str = "saturating"
    rho_floor: float = 2.0
    k_u: float = 10.0
    k_omega: float = 10.0
    beta_gamma: str = "min-norm"
    dvd_dt: str = "finite-difference"
    kind: str = "backstepping"
    options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.alpha = _num("controller.alpha", self.alpha, lo=0.0, lo_open=True)
        self.alpha_schedule = _choice("controller.alpha_schedule", self.alpha_schedule, ("constant", "saturating"))
        self.rho_floor = _num("controller.rho_floor", self.rho_floor, lo=0.0, lo_open=True)
        self.k_u = _num("controller.k_u", self.k_u, lo=0.0)
        self.k_omega = _num("controller.k_omega", self.k_omega, lo=0.0)
        self.beta_gamma = _choice("controller.beta_gamma", self.beta_gamma, ("min-norm", *available("beta_gamma")))
        self.dvd_dt = _choice("controller.dvd_dt", self.dvd_dt, ("model", "fokker-planck", "finite-difference"))
        self.kind = _choice("controller.kind", self.kind, ("backstepping", *available("controller")))
        if not isinstance(self.options, dict):
            raise ParameterError("controller.options", self.options, "a table of options for the controller kind")
        self.options = dict(self.options)


@dataclass
class ViewSpec:
    """The humans' local view (the paper's Unity study, Section V-B).

    A human follows the navigation field ``v_r`` (eq. (3)) only while some robot is within
    ``radius`` of it; otherwise it walks a persistent random walk at ``walk_speed`` whose
    heading diffuses with ``turning_rate`` (rad²/s, so the heading decorrelates as
    ``exp(-turning_rate t)``; see :mod:`meanfield.local_view`).  ``radius = "none"`` (the
    default) is the paper's model (eq. (1)): every human feels every robot.
    """

    radius: float | None = None
    walk_speed: float = 0.0
    turning_rate: float = 0.0

    def __post_init__(self) -> None:
        self.radius = _optional_limit("view.radius", self.radius, what='a view radius > 0, or "none" (no gating)')
        self.walk_speed = _num("view.walk_speed", self.walk_speed, lo=0.0)
        self.turning_rate = _num("view.turning_rate", self.turning_rate, lo=0.0)


# the JuPedSim operational models the pedestrian backend can use (meanfield.jupedsim_api)
PEDESTRIAN_MODELS = (
    "collision-free-speed",
    "collision-free-speed-v2",
    "collision-free-speed-v3",
    "anticipation-velocity",
    "generalized-centrifugal-force",
    "social-force",
    "warp-driver",
)


@dataclass
class PedestrianSpec:
    """The crowd backend: ``"point-mass"`` (the SDE of eq. (1), :mod:`meanfield.crowd`) or
    ``"jupedsim"`` (bodies of ``radius`` metres moved by a JuPedSim operational ``model``,
    :mod:`meanfield.pedestrian_crowd`).

    With ``"jupedsim"``, each control period ``dt`` every human gets a desired velocity
    (``v_r`` or its random walk) whose speed is capped at ``max_speed``; JuPedSim advances
    in steps of ``time_step`` (``dt`` must be a whole number of them).  ``radius``,
    ``max_speed``, ``time_step`` and ``model`` are ignored by the point-mass backend.
    """

    backend: str = "point-mass"
    model: str = "collision-free-speed"
    radius: float = 0.2
    max_speed: float = 1.34
    time_step: float = 0.01

    def __post_init__(self) -> None:
        self.backend = _choice("pedestrians.backend", self.backend, ("point-mass", "jupedsim"))
        self.model = _choice("pedestrians.model", self.model, PEDESTRIAN_MODELS)
        self.radius = _num("pedestrians.radius", self.radius, lo=0.0, lo_open=True)
        self.max_speed = _num("pedestrians.max_speed", self.max_speed, lo=0.0, lo_open=True)
        self.time_step = _num("pedestrians.time_step", self.time_step, lo=0.0, lo_open=True)


_SECTIONS: dict[str, type] = {
    "grid": GridSpec,
    "crowd": CrowdSpec,
    "robots": RobotSpec,
    "kernel": KernelSpec,
    "interaction": InteractionSpec,
    "disturbance": DisturbanceSpec,
    "target": TargetSpec,
    "density": DensitySpec,
    "controller": ControllerSpec,
    "view": ViewSpec,
    "pedestrians": PedestrianSpec,
}

_TOP_LEVEL = ("name", "seed", "dt", "t_final", "record_every", "record_humans")


def resolve_key(key: str, value: Any = None) -> str:
    """The dotted scenario key a short name stands for (``--set`` accepts either).

    A dotted key or a top-level field is returned as it is; a section with a count
    (``robots``, ``crowd``) stands for its ``n``; a field name found in exactly one section
    (``eta``, ``sigma``, ``u_max``) stands for that section's field.

    ``value`` is only quoted in the error.

    Raises
    ------
    ParameterError
        For a name in no section, or in several (the message lists the dotted keys).
    """
    if not isinstance(key, str) or not key:
        raise ParameterError("key", key, "a scenario field name")
    shown = key if value is None else value
    if "." in key or key in _TOP_LEVEL or key == "domain":
        return key
    if key in _SECTIONS and "n" in {f.name for f in fields(_SECTIONS[key])}:
        return f"{key}.n"
    found = [f"{sec}.{key}" for sec, cls in _SECTIONS.items() if key in {f.name for f in fields(cls)}]
    if len(found) == 1:
        return found[0]
    if found:
        raise ParameterError(key, shown, f"a dotted key, one of {', '.join(found)}")
    raise ParameterError(key, shown, "an existing scenario field (a dotted key such as robots.n or kernel.eta)")


@dataclass
class Scenario:
    """All parameters of one closed-loop run (see the module docstring for the layout).

    Cross-field checks run on construction: explicit robot positions and the initial
    crowd centre must lie in Ω, the target must put mass in Ω, ``dt < t_final``.
    """

    name: str = "custom"
    seed: int = 0
    dt: float = 0.01
    t_final: float = 40.0
    record_every: int = 10
    record_humans: int | str = 10_000
    domain: Domain = field(default_factory=lambda: Domain.box(1.0, 1.0))
    grid: GridSpec = field(default_factory=GridSpec)
    crowd: CrowdSpec = field(default_factory=CrowdSpec)
    robots: RobotSpec = field(default_factory=RobotSpec)
    kernel: KernelSpec = field(default_factory=KernelSpec)
    interaction: InteractionSpec = field(default_factory=InteractionSpec)
    disturbance: DisturbanceSpec = field(default_factory=DisturbanceSpec)
    target: TargetSpec = field(default_factory=TargetSpec)
    density: DensitySpec = field(default_factory=DensitySpec)
    controller: ControllerSpec = field(default_factory=ControllerSpec)
    view: ViewSpec = field(default_factory=ViewSpec)
    pedestrians: PedestrianSpec = field(default_factory=PedestrianSpec)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError("name", self.name, "a non-empty string")
        self.seed = _int("seed", self.seed, 0)
        self.dt = _num("dt", self.dt, lo=0.0, lo_open=True)
        self.t_final = _num("t_final", self.t_final, lo=0.0, lo_open=True)
        if self.dt > self.t_final:
            raise ParameterError("dt", self.dt, f"a step <= t_final = {self.t_final}")
        self.record_every = _int("record_every", self.record_every, 1)
        if self.record_humans != "all":
            if isinstance(self.record_humans, str):
                raise ParameterError("record_humans", self.record_humans, 'an integer >= 0, or "all"')
            self.record_humans = _int("record_humans", self.record_humans, 0)
        if not isinstance(self.domain, Domain):
            raise ParameterError("domain", self.domain, "a Domain")
        for key, cls in _SECTIONS.items():
            if not isinstance(getattr(self, key), cls):
                raise ParameterError(key, getattr(self, key), f"a {cls.__name__}")
        dom = self.domain
        if self.robots.layout == "explicit":
            pos = np.asarray(self.robots.positions)
            inside = dom.contains(pos[:, 0], pos[:, 1], tol=1e-12)
            if not inside.all():
                k = int(np.flatnonzero(~inside)[0])
                raise ParameterError(f"robots.positions[{k}]", pos[k].tolist(), "a point inside the domain")
        if self.crowd.initial == "gaussian":
            c = self.crowd.initial_center
            if not dom.contains(c[0], c[1]):
                raise ParameterError("crowd.initial_center", list(c), "a point inside the domain")
        if self.target_mass_in_domain() < 1e-6:
            raise ParameterError(
                "target.center",
                list(self.target.center),
                "a target Gaussian with mass in the domain (centre inside Ω or within a few std)",
            )
        self._check_pedestrians()
        if self.robots.margin > 0:
            x0, x1, y0, y1 = dom.bounds
            if 2 * self.robots.margin >= min(x1 - x0, y1 - y0):
                raise ParameterError(
                    "robots.margin", self.robots.margin, "less than half the domain's width and height"
                )

    def _check_pedestrians(self) -> None:
        """The JuPedSim backend's cross-field checks: whole sub-steps, bodies that fit."""
        p = self.pedestrians
        if p.backend != "jupedsim":
            return
        k = self.dt / p.time_step
        if round(k) < 1 or abs(k - round(k)) > 1e-9 * k:
            raise ParameterError(
                "pedestrians.time_step", p.time_step, f"a step that divides dt = {self.dt:g} a whole number of times"
            )
        cover = self.crowd.n * math.pi * p.radius**2 / self.domain.area
        if cover > 0.5:
            raise ParameterError(
                "pedestrians.radius",
                p.radius,
                f"a body radius whose {self.crowd.n} bodies cover at most half of the room "
                f"(they would cover {cover:.0%} of its area {self.domain.area:g})",
            )

    # ------------------------------------------------------------------ derived
    @property
    def steps(self) -> int:
        """Number of time steps ``round(t_final / dt)``."""
        return int(round(self.t_final / self.dt))

    def target_mass_in_domain(self, samples: int = 200) -> float:
        """Fraction of the (untruncated) target Gaussian's mass that lies in Ω."""
        x0, x1, y0, y1 = self.domain.bounds
        xs = np.linspace(x0, x1, samples)
        ys = np.linspace(y0, y1, samples)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        cx, cy = self.target.center
        s = self.target.std
        dens = np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) / (2 * math.pi * s * s)
        dens = np.where(self.domain.contains(X, Y), dens, 0.0)
        return float(dens.sum() * (xs[1] - xs[0]) * (ys[1] - ys[0]))

    def replace(self, **changes: Any) -> Scenario:
        """A copy with top-level fields replaced (validated again)."""
        return dataclasses.replace(self, **changes)

    def with_values(self, assignments: dict[str, Any]) -> Scenario:
        """A copy with dotted fields set, e.g. ``{"kernel.eta": 0.02, "robots.n": 9}``.

        Short names are read by :func:`resolve_key` (``{"eta": 0.02, "robots": 9}`` is the
        same).  Keys under ``controller.options.`` may be new (the controller plugin checks
        them).
        """
        d = self.to_dict()
        for short, value in assignments.items():
            key = resolve_key(short, value)
            parts = key.split(".")
            node = d
            for depth, p in enumerate(parts[:-1]):
                if parts[:depth + 1] == ["controller", "options"]:
                    node = node.setdefault(p, {})  # free-form: the controller plugin validates it
                    continue
                if p not in node or not isinstance(node[p], dict):
                    raise ParameterError(key, value, "an existing scenario field")
                node = node[p]
            if parts[-1] not in node and parts[:-1] != ["controller", "options"]:
                raise ParameterError(key, value, "an existing scenario field")
            node[parts[-1]] = value
        return Scenario.from_dict(d)

    # ------------------------------------------------------------------ TOML
    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (TOML-ready: no None values, tuples as lists)."""
        out: dict[str, Any] = {
            "name": self.name,
            "seed": self.seed,
            "dt": self.dt,
            "t_final": self.t_final,
            "record_every": self.record_every,
            "record_humans": self.record_humans,
            "domain": self.domain.to_dict(),
        }
        for key in _SECTIONS:
            sec = {}
            for f in fields(getattr(self, key)):
                v = getattr(getattr(self, key), f.name)
                if v is None:
                    if key == "robots" and f.name in ("u_max", "omega_max"):
                        sec[f.name] = "none"
                    continue
                if isinstance(v, dict):
                    if not v:
                        continue
                    v = dict(v)
                sec[f.name] = list(v) if isinstance(v, tuple) else v
            out[key] = sec
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Scenario:
        """Build and validate from a nested dict; unknown keys raise :class:`ParameterError`."""
        if not isinstance(d, dict):
            raise ParameterError("scenario", type(d).__name__, "a table of fields")
        top = {*_TOP_LEVEL, "domain", *_SECTIONS}
        unknown = set(d) - top
        if unknown:
            raise ParameterError(sorted(unknown)[0], d[sorted(unknown)[0]], f"a known key: one of {sorted(top)}")
        kwargs: dict[str, Any] = {k: d[k] for k in _TOP_LEVEL if k in d}
        if "domain" in d:
            if not isinstance(d["domain"], dict):
                raise ParameterError("domain", d["domain"], "a table")
            kwargs["domain"] = Domain.from_dict(d["domain"])
        for key, sec_cls in _SECTIONS.items():
            if key not in d:
                continue
            sec = d[key]
            if not isinstance(sec, dict):
                raise ParameterError(key, sec, "a table")
            names = {f.name for f in fields(sec_cls)}
            bad = set(sec) - names
            if bad:
                b = sorted(bad)[0]
                raise ParameterError(f"{key}.{b}", sec[b], f"a known key of [{key}]: one of {sorted(names)}")
            values = dict(sec)
            for k, v in values.items():
                if isinstance(v, list) and k in ("cells", "initial_center", "velocity", "center"):
                    values[k] = tuple(v)
            kwargs[key] = sec_cls(**values)
        return cls(**kwargs)

    def to_toml(self) -> str:
        """The scenario as TOML text."""
        import tomli_w

        return tomli_w.dumps(self.to_dict())

    @classmethod
    def from_toml(cls, text: str) -> Scenario:
        """Parse TOML text (see :meth:`from_dict`)."""
        try:
            d = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ParameterError("scenario file", str(exc), "valid TOML") from None
        return cls.from_dict(d)

    def save(self, path: str | Path) -> None:
        """Write the scenario to a TOML file (atomically)."""
        from meanfield.io import atomic_write_text

        atomic_write_text(Path(path), self.to_toml())


# ---------------------------------------------------------------------- built-ins
def paper_scenario(seed: int = 0) -> Scenario:
    """The paper's MATLAB study (Section V): 200 humans, 16 robots, unit square, 30×30 grid.

    Values the paper leaves open (c, η, σ, α, gains, h, speed limits, T, target width)
    are chosen in ``docs/scenarios.md``, where the reasons and the measured outcome are.
    """
    return Scenario(
        name="paper",
        seed=seed,
        dt=0.01,
        t_final=40.0,
        record_every=10,
        domain=Domain.box(1.0, 1.0),
        grid=GridSpec((30, 30)),
        crowd=CrowdSpec(n=200, initial="uniform", sigma=0.015),
        robots=RobotSpec(n=16, layout="grid", headings="random", u_max=0.2, omega_max=3.0),
        kernel=KernelSpec(c=0.2, eta=0.05),
        interaction=InteractionSpec(kind="none"),
        target=TargetSpec(center=(1.0, 1.0), std=0.15),
        density=DensitySpec(bandwidth=0.08, boundary="reflect"),
        controller=ControllerSpec(
            alpha=0.2,
            alpha_schedule="saturating",
            rho_floor=2.0,
            k_u=10.0,
            k_omega=10.0,
            beta_gamma="min-norm",
            dvd_dt="finite-difference",
        ),
    )


# the Unity study's room (metres) and the time unit that makes the kernel's peak speed a
# walking speed: paper-unity is the paper scenario under x -> L x, t -> T t (docs/scenarios.md)
UNITY_LENGTH = 150.0
UNITY_TIME = 25.0


def paper_unity_scenario(seed: int = 0) -> Scenario:
    """The paper's Unity study (Section V-B): 150 × 150 m, 200 humans, 16 robots, 30 m view.

    Every parameter of :func:`paper_scenario` is carried over by the similarity
    ``x -> L x``, ``t -> T t`` with ``L = 150 m`` and ``T = 25 s`` (so the kernel's peak
    speed ``c`` becomes 1.2 m/s): lengths scale by ``L``, speeds by ``L/T``, diffusions and
    ``α`` by ``L²/T``, rates by ``1/T``, densities by ``1/L²``, with one exception: the
    crowd's diffusion is a pedestrian's ``σ = 0.5 m²/s``, not the similar 13.5 m²/s (a
    random displacement of 5 m per second is not walking; JuPedSim bodies have no such
    noise, and a controller that assumes it concentrates them).  The crowd, the density
    estimate and the Step-I law (``v_d``, ``ṽ``) are then exactly similar to the paper
    scenario's; the robot law is not, because ``V₂`` adds ``∫ρ̃²`` (scaling as ``1/L²``) to
    ``∫|ṽ|²`` (scaling as ``L⁴/T²``), so its inputs depend on the unit of length.  The Unity study's own
    assumptions are added on top: a human follows the signs only within 30 m of a robot
    and otherwise walks randomly (1.0 m/s, heading persistence ``1/D_r`` = 20 s), and the
    crowd may be run as JuPedSim bodies (``pedestrians.backend = "jupedsim"``).  The
    reasons for each value, and how the outcome depends on them, are in
    ``docs/scenarios.md``.
    """
    base = paper_scenario(seed)
    L, T = UNITY_LENGTH, UNITY_TIME
    c = base.controller
    return Scenario(
        name="paper-unity",
        seed=seed,
        dt=base.dt * T,
        t_final=base.t_final * T,
        record_every=base.record_every,
        domain=Domain.box(L, L),
        grid=GridSpec(base.grid.cells),
        crowd=CrowdSpec(n=200, initial="uniform", sigma=0.5),
        robots=RobotSpec(
            n=16,
            layout="grid",
            headings="random",
            u_max=base.robots.u_max * L / T,
            omega_max=base.robots.omega_max / T,
        ),
        kernel=KernelSpec(c=base.kernel.c * L / T, eta=base.kernel.eta * L * L),
        interaction=InteractionSpec(kind="none"),
        target=TargetSpec(center=(L, L), std=base.target.std * L),
        density=DensitySpec(bandwidth=base.density.bandwidth * L, boundary="reflect"),
        controller=ControllerSpec(
            alpha=c.alpha * L * L / T,
            alpha_schedule=c.alpha_schedule,
            rho_floor=c.rho_floor / (L * L),
            k_u=c.k_u / T,
            k_omega=c.k_omega / T,
            beta_gamma=c.beta_gamma,
            dvd_dt=c.dvd_dt,
        ),
        view=ViewSpec(radius=30.0, walk_speed=1.0, turning_rate=0.05),
        pedestrians=PedestrianSpec(
            backend="point-mass", model="collision-free-speed", radius=0.2, max_speed=1.34, time_step=0.05
        ),
    )


STADIUM_CROWD = 1_000_000
"""Humans in the built-in ``stadium`` scenario."""


def stadium_scenario(seed: int = 0) -> Scenario:
    """The ``paper`` scenario with a stadium's crowd: 10⁶ humans, 64 robots, 128×128 grid.

    Everything else is ``paper``'s, except the KDE bandwidth (0.03: about four cells of
    the finer grid, where ``paper``'s 0.08 is 2.4 of its cells) and that the positions of
    10 000 evenly spaced humans are recorded rather than all (``record_humans``).  The
    navigation field is sampled on a lattice (``crowd.field_evaluation = "auto"``
    chooses it above 2·10⁶ human-robot pairs) and the KDE bins the crowd: a closed-loop
    step costs O(N + G log G) (docs/scale.md).
    """
    base = paper_scenario(seed)
    return base.replace(
        name="stadium",
        grid=GridSpec((128, 128)),
        crowd=dataclasses.replace(base.crowd, n=STADIUM_CROWD),
        robots=dataclasses.replace(base.robots, n=64),
        density=DensitySpec(bandwidth=0.03, boundary="reflect"),
        record_humans=10_000,
    )


def builtin_scenarios() -> dict[str, Any]:
    """Names of the built-in scenarios and their factories."""
    return {"paper": paper_scenario, "paper-unity": paper_unity_scenario, "stadium": stadium_scenario}


def load_scenario(spec: str | Path, seed: int | None = None) -> Scenario:
    """A built-in scenario by name, or a TOML file by path; ``seed`` overrides the file's."""
    spec = str(spec)
    table = builtin_scenarios()
    if spec in table:
        sc = table[spec]()
    else:
        path = Path(spec)
        if not path.is_file():
            raise ParameterError("scenario", spec, f"a built-in name ({', '.join(table)}) or an existing .toml file")
        sc = Scenario.from_toml(path.read_text())
    if seed is not None:
        sc = sc.replace(seed=seed)
    return sc
