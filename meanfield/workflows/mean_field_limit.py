"""Agents beside the Fokker–Planck equation: the mean-field limit, measured.

The paper's argument runs on the PDE (eq. (4)) while its crowd is a finite set of SDE
agents (eq. (1)).  This module runs both from the same initial density under the same
robot trajectories (recorded from a closed-loop run of the scenario and replayed), and
measures, at regular times, the L² distance on the grid between

* the agents' kernel density estimate ``ρ̂_N`` and the PDE density ``ρ`` ("to PDE"), and
* ``ρ̂_N`` and the estimator's mean under the PDE law, ``E[ρ̂] = H_h * ρ`` ("to E[KDE]"),

for several crowd sizes ``N``.  The second distance is the estimator's sampling noise
plus the agents' departure from the PDE (finite-``N`` chaos, time-step and grid errors);
it falls like ``N^(-1/2)`` until those floors.  The first adds the estimator's smoothing
bias ``‖H_h * ρ - ρ‖``, a floor independent of ``N``.

With a repulsive interaction ``W``, the PDE is also run with the paper's written sign
(``∇W * ρ``, the opposite of the SDE's mean-field limit): that run does not approach the
agents as ``N`` grows, which settles the sign convention.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meanfield.crowds.agent_crowd import AgentCrowd, initial_positions
from meanfield.crowds.density_crowd import DensityCrowd, initial_density
from meanfield.crowds.kde import KernelDensityEstimator
from meanfield.crowds.local_view import LocalView
from meanfield.crowds.point_mass import PointMassEngine
from meanfield.errors import ParameterError, SimulationDiverged, positive_number
from meanfield.fokker_planck.solver import FokkerPlanck
from meanfield.geometry.grid import Grid
from meanfield.scenarios.scenario import Scenario
from meanfield.signs.interaction import GaussianPotential, InteractionField
from meanfield.signs.kernels import GaussianKernel
from meanfield.simulation.assembly import disturbance_for
from meanfield.simulation.loop import ClosedLoop

__all__ = [
    "AgentsPdeComparison",
    "ComparisonReport",
    "RobotTrajectory",
    "compare_agents_pde",
    "fit_slope",
    "record_robot_trajectory",
    "run_comparison",
    "fit_slope",
]


@dataclass(frozen=True)
class _RobotStates:
    """The robots' states at one step of a replayed trajectory (what a crowd reads of them)."""

    positions: np.ndarray
    headings: np.ndarray


@dataclass(frozen=True)
class RobotTrajectory:
    """Robot states at every step of a closed-loop run: ``positions[k]`` at ``times[k]``."""

    times: np.ndarray  # (K+1,)
    positions: np.ndarray  # (K+1, n, 2)
    headings: np.ndarray  # (K+1, n)

    @property
    def steps(self) -> int:
        """Number of steps ``K``."""
        return len(self.times) - 1


def record_robot_trajectory(
    scenario: Scenario, t_final: float | None = None, progress: bool = False
) -> RobotTrajectory:
    """Run the scenario's closed loop and keep the robot states of every step.

    Parameters
    ----------
    scenario : Scenario
        The closed loop to run (its own crowd of ``scenario.crowd.n`` agents).
    t_final : float, optional
        Stop earlier than ``scenario.t_final``.
    progress : bool
        Show a progress bar.
    """
    from tqdm.auto import tqdm

    loop = ClosedLoop(scenario)
    steps = scenario.steps if t_final is None else min(scenario.steps, int(round(t_final / scenario.dt)))
    pos = np.empty((steps + 1, scenario.robots.n, 2))
    head = np.empty((steps + 1, scenario.robots.n))
    pos[0], head[0] = loop.robots.positions, loop.robots.headings
    for k in tqdm(range(steps), disable=not progress, desc="closed loop (robot trajectories)", unit="step"):
        loop.step()
        pos[k + 1], head[k + 1] = loop.robots.positions, loop.robots.headings
    return RobotTrajectory(np.arange(steps + 1) * scenario.dt, pos, head)


@dataclass
class AgentsPdeComparison:
    """One agents-versus-PDE comparison (one interaction ``W``).

    Attributes
    ----------
    dataset : xarray.Dataset
        ``error_to_pde`` and ``error_to_expected`` on ``(n_agents, time)``;
        ``error_to_expected_paper_sign`` when ``W ≠ 0``; ``pde_density`` on
        ``(time, x, y)``; ``agents_density`` on ``(n_agents, time, x, y)``.
    summary : dict
        Time-mean errors per ``N``, fitted slopes, status, timings.
    """

    label: str
    dataset: Any
    summary: dict[str, Any] = field(default_factory=dict)

    def mean_errors(self, name: str = "error_to_expected") -> np.ndarray:
        """Time-mean of ``name`` for each ``N``."""
        return self.dataset[name].mean("time").values


def _crowd_sizes(n_agents) -> tuple[int, ...]:
    """Distinct crowd sizes >= 2, sorted, or a :class:`ParameterError`."""
    sizes = tuple(int(n) for n in n_agents)
    if not sizes or any(n < 2 for n in sizes) or len(set(sizes)) != len(sizes):
        raise ParameterError("n_agents", n_agents, "distinct integers >= 2")
    return tuple(sorted(sizes))


def compare_agents_pde(
    scenario: Scenario,
    n_agents: tuple[int, ...] = (100, 1_000, 10_000, 100_000),
    *,
    interaction: GaussianPotential | None = None,
    trajectory: RobotTrajectory | None = None,
    t_final: float | None = None,
    cells: tuple[int, int] = (64, 64),
    bandwidth: float | None = None,
    record_interval: float = 1.0,
    method: str | None = None,
    seed: int | None = None,
    progress: bool = False,
    label: str | None = None,
) -> AgentsPdeComparison:
    """Agents (SDE, eq. (1)) and the Fokker–Planck PDE (eq. (4)) under the same robots.

    Parameters
    ----------
    scenario : Scenario
        Domain, σ, kernel, disturbance, initial density, ``dt``.
    n_agents : tuple of int
        Crowd sizes ``N`` (each >= 2).
    interaction : GaussianPotential, optional
        ``W`` for both agents and PDE (None: ``W = 0``).  Overrides the scenario's.
    trajectory : RobotTrajectory, optional
        Robot states to replay; default: recorded from the scenario's closed loop.
    t_final : float, optional
        Horizon (default: the trajectory's end).
    cells : (int, int)
        Grid of the PDE and of the density estimates.
    bandwidth : float, optional
        KDE bandwidth ``h`` (default: the scenario's, or 0.08 if it uses Silverman's rule).
    record_interval : float
        Time between measurements.
    method : str
        :class:`~meanfield.fokker_planck.solver.FokkerPlanck` time integrator (default: the
        solver's, ADI on a box, split on cut-cell grids).
    seed : int, optional
        Seed of the agents' initial positions and noise (default: the scenario's).
    progress : bool
        Show a progress bar.
    """
    import xarray as xr
    from tqdm.auto import tqdm

    if not isinstance(scenario, Scenario):
        raise ParameterError("scenario", type(scenario).__name__, "a Scenario")
    sizes = _crowd_sizes(n_agents)
    rec_int = positive_number("record_interval", record_interval)
    if trajectory is None:
        trajectory = record_robot_trajectory(scenario, t_final, progress=progress)
    dt = scenario.dt
    steps = trajectory.steps if t_final is None else min(trajectory.steps, int(round(float(t_final) / dt)))
    if steps < 1:
        raise ParameterError("t_final", t_final, f"a horizon of at least one step (dt = {dt})")
    every = max(1, int(round(rec_int / dt)))
    if bandwidth is None:
        bw = scenario.density.bandwidth
        bandwidth = 0.08 if bw == "silverman" else float(bw)
    seed = scenario.seed if seed is None else int(seed)
    grid = Grid(scenario.domain, cells)
    kernel = GaussianKernel(scenario.kernel.c, scenario.kernel.eta)
    kde = KernelDensityEstimator(grid, bandwidth, scenario.density.boundary)
    sigma = scenario.crowd.sigma
    disturbance = disturbance_for(scenario)
    field_w = InteractionField(grid, interaction) if interaction is not None else None
    fp = FokkerPlanck(grid, sigma, interaction=field_w, disturbance=disturbance, method=method)
    method = fp.method
    rho0 = initial_density(scenario, grid)
    # the crowds behind the Crowd interface, under the replayed robots: the PDE, and N agents each
    pde = DensityCrowd(fp, rho0, kernel)
    pde_flipped = None
    if interaction is not None:  # the paper's written sign: ∇W * ρ = -u_W[ρ] for even W
        flipped = GaussianPotential(-interaction.strength, interaction.length)
        fp_flip = FokkerPlanck(grid, sigma, interaction=flipped, disturbance=disturbance, method=method)
        pde_flipped = DensityCrowd(fp_flip, rho0, kernel)
    crowds = {}
    for n in sizes:
        rng = np.random.default_rng([seed, n])
        engine = PointMassEngine(initial_positions(scenario, n, rng), scenario.domain, sigma, rng)
        view = LocalView(n, None, 0.0, 0.0, scenario.domain, rng)  # everyone sees the signs
        crowds[n] = AgentCrowd(engine, kernel, kde, view, field_w, disturbance)

    times: list[float] = []
    pde_frames: list[np.ndarray] = []
    agent_frames: list[np.ndarray] = []
    e_pde: list[list[float]] = []
    e_exp: list[list[float]] = []
    e_flip: list[list[float]] = []

    def measure(t: float) -> None:
        rho = pde.density()
        times.append(t)
        pde_frames.append(rho.copy())
        expected = kde.expected(rho)
        expected_flip = kde.expected(pde_flipped.density()) if pde_flipped is not None else None
        frames, a, b, c = [], [], [], []
        for n in sizes:
            est = kde(crowds[n].positions)
            frames.append(est)
            a.append(grid.norm(est - rho))
            b.append(grid.norm(est - expected))
            if expected_flip is not None:
                c.append(grid.norm(est - expected_flip))
        agent_frames.append(np.array(frames))
        e_pde.append(a)
        e_exp.append(b)
        e_flip.append(c)

    status, message = "completed", ""
    start = time.perf_counter()
    measure(0.0)
    bar = tqdm(total=steps, disable=not progress, desc=f"agents vs PDE ({label or 'W'})", unit="step", mininterval=0.5)
    try:
        for k in range(steps):
            t = k * dt
            robots = _RobotStates(trajectory.positions[k], trajectory.headings[k])
            for crowd in (*crowds.values(), pde, *([pde_flipped] if pde_flipped is not None else [])):
                crowd.advance(robots, t, dt)
            if (k + 1) % every == 0 or k + 1 == steps:
                measure((k + 1) * dt)
            bar.update(1)
    except KeyboardInterrupt:
        status, message = "interrupted", f"interrupted at t = {len(times) and times[-1]:.4g}"
    except (FloatingPointError, SimulationDiverged) as exc:  # pragma: no cover - defensive
        status, message = "diverged", str(exc)
    finally:
        bar.close()
    wall = time.perf_counter() - start

    coords = {"n_agents": list(sizes), "time": times, "x": grid.x, "y": grid.y}
    data = {
        "error_to_pde": (("n_agents", "time"), np.array(e_pde).T),
        "error_to_expected": (("n_agents", "time"), np.array(e_exp).T),
        "pde_density": (("time", "x", "y"), np.array(pde_frames)),
        "agents_density": (("n_agents", "time", "x", "y"), np.array(agent_frames).transpose(1, 0, 2, 3)),
    }
    if pde_flipped is not None:
        data["error_to_expected_paper_sign"] = (("n_agents", "time"), np.array(e_flip).T)
    label = label or (
        "W = 0" if interaction is None else f"W: strength {interaction.strength}, length {interaction.length}"
    )
    ds = xr.Dataset(data, coords=coords, attrs={"label": label, "bandwidth": bandwidth, "method": method})
    result = AgentsPdeComparison(label, ds)
    ns = np.array(sizes, float)
    fit = (ns >= 100) & (ns <= 10_000)
    summary: dict[str, Any] = {
        "label": label,
        "status": status,
        "message": message,
        "interaction": None
        if interaction is None
        else {"strength": interaction.strength, "length": interaction.length},
        "n_agents": list(sizes),
        "time_final": times[-1],
        "bandwidth": bandwidth,
        "cells": list(cells),
        "pde_method": method,
        "pde_mass_drift": float(
            abs(grid.integrate(pde.density()) - grid.integrate(pde_frames[0])) / grid.integrate(pde_frames[0])
        ),
        "pde_min": float(pde.density().min()),
        "wall_seconds": wall,
    }
    names = ["error_to_expected", "error_to_pde"]
    if pde_flipped is not None:
        names.append("error_to_expected_paper_sign")
    for name in names:
        m = result.mean_errors(name)
        summary[f"{name}_mean"] = dict(zip(map(str, sizes), map(float, m), strict=True))
        summary[f"{name}_slope_1e2_1e4"] = fit_slope(ns[fit], m[fit]) if fit.sum() >= 2 else None
        summary[f"{name}_slope_all"] = fit_slope(ns, m)
    result.summary = summary
    return result


@dataclass
class ComparisonReport:
    """The ``meanfield compare`` output: one comparison per interaction case."""

    scenario: Scenario
    cases: list[AgentsPdeComparison]

    @property
    def summary(self) -> dict[str, Any]:
        """Per-case summaries, plus the scenario."""
        return {"cases": [c.summary for c in self.cases], "scenario": self.scenario.to_dict()}

    def save(self, out: str | Path, artifacts: Any = ()) -> dict[str, Path]:
        """Write ``comparison_<k>.nc`` per case, the ``artifacts`` (e.g.
        :func:`meanfield.plotting.figures.save_comparison_figures`), and ``summary.json`` last, listing
        every file with its SHA-256 (:func:`meanfield.io.atomic.write_complete_folder`)."""
        from meanfield.io.atomic import atomic_write_text, atomic_write_with, write_complete_folder

        def write_files(folder: Path) -> dict[str, Path]:
            written: dict[str, Path] = {}
            for k, case in enumerate(self.cases):
                path = folder / f"comparison_{k}.nc"
                atomic_write_with(path, lambda p, ds=case.dataset: ds.to_netcdf(p, engine="h5netcdf"))
                written[f"comparison_{k}"] = path
            written["scenario"] = atomic_write_text(folder / "scenario.toml", self.scenario.to_toml())
            for writer in artifacts:
                written.update(writer(self, folder))
            return written

        return write_complete_folder(out, write_files, self.summary)


def run_comparison(
    scenario: Scenario,
    n_agents: tuple[int, ...] = (100, 1_000, 10_000, 100_000),
    *,
    repulsion: tuple[float, float] | None = (0.5, 0.1),
    t_final: float | None = None,
    cells: tuple[int, int] = (64, 64),
    record_interval: float = 1.0,
    seed: int | None = None,
    progress: bool = False,
) -> ComparisonReport:
    """``W = 0`` and (unless ``repulsion`` is None) a repulsive Gaussian ``W``, same robots.

    ``repulsion = (strength, length)`` of ``W(z) = strength · exp(-|z|²/length²)``,
    ``strength > 0`` (repulsive under the SDE's convention).
    """
    _crowd_sizes(n_agents)  # checked before the closed loop runs, not after
    positive_number("record_interval", record_interval)
    if repulsion is not None:
        s, ell = (float(v) for v in repulsion)
        if not (math.isfinite(s) and s > 0 and math.isfinite(ell) and ell > 0):
            raise ParameterError("repulsion", repulsion, "(strength > 0, length > 0)")
    common = {
        "trajectory": record_robot_trajectory(scenario, t_final, progress=progress),
        "t_final": t_final,
        "cells": cells,
        "record_interval": record_interval,
        "seed": seed,
        "progress": progress,
    }
    cases = [compare_agents_pde(scenario, n_agents, label="W = 0", **common)]
    if repulsion is not None and cases[0].summary["status"] == "completed":
        w = GaussianPotential(s, ell)
        label = f"repulsive W (strength {s:g}, length {ell:g})"
        cases.append(compare_agents_pde(scenario, n_agents, interaction=w, label=label, **common))
    return ComparisonReport(scenario, cases)


def fit_slope(n: np.ndarray, err: np.ndarray) -> float:
    """Least-squares slope of ``log err`` against ``log n`` (NaN with fewer than two points)."""
    n = np.asarray(n, float)
    err = np.asarray(err, float)
    if len(n) < 2:
        return math.nan
    return float(np.polyfit(np.log(n), np.log(err), 1)[0])
