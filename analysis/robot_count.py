"""How many robots: the paper's coverage estimate against the empirical minimum.

The paper's discussion asks for "enough robots" and estimates the number by coverage:
robot ``i``'s field ``|K(x − R_i, θ_i)| = c exp(−|x − R_i|²/η)`` exceeds ``ε`` on a disk of
radius ``r_ε = √(η ln(c/ε))``, and those disks should cover Ω, so that every human feels
at least ``ε`` from some sign.  :func:`coverage_estimate` gives the smallest regular
(square-lattice) arrangement whose disks cover Ω; :func:`empirical_robot_count` runs the
closed loop over robot counts and reports the smallest count that meets a success
criterion.  The coverage estimate is a *rough lower estimate* in the paper: it says where
the robots' reach ends, not whether their law can steer the crowd.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from analysis.parallel import map_jobs
from meanfield.errors import ParameterError, positive_number
from meanfield.geometry.domain import Domain
from meanfield.geometry.region import Region
from meanfield.scenarios.scenario import Scenario
from meanfield.signs.kernels import GaussianKernel

__all__ = [
    "coverage_radius",
    "CoverageLayout",
    "coverage_layout",
    "coverage_estimate",
    "RobotCountStudy",
    "empirical_robot_count",
]


def coverage_radius(c: float, eta: float, eps: float) -> float:
    """``r_ε = √(η ln(c/ε))``: where one robot's field ``c exp(−|ξ|²/η)`` exceeds ``ε``.

    Raises
    ------
    ParameterError
        Unless ``c > 0``, ``η > 0`` (named ``kernel.c``, ``kernel.eta``) and ``0 < ε < c``.
    """
    kernel = GaussianKernel(c, eta)
    eps = positive_number("eps", eps)
    if eps >= kernel.c:
        raise ParameterError("eps", eps, f"a field level below the kernel's peak c = {kernel.c} (0 < eps < c)")
    return kernel.radius(eps)


@dataclass
class CoverageLayout:
    """A square-lattice arrangement whose disks of radius ``radius`` cover Ω.

    Attributes
    ----------
    n : int
        Robots: lattice cells of the bounding box that meet Ω (one robot per cell).
    cols, rows : int
        Lattice size over Ω's bounding box.
    spacing : (float, float)
        Cell sizes ``(w/cols, h/rows)``; each cell's half-diagonal is at most ``radius``.
    radius : float
    positions : ndarray, shape (n, 2)
        Cell centres, projected onto Ω where a centre lies outside.
    """

    n: int
    cols: int
    rows: int
    spacing: tuple[float, float]
    radius: float
    positions: np.ndarray = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["positions"] = self.positions.tolist()
        return d


def _cells_meeting(domain: Domain, cols: int, rows: int) -> np.ndarray:
    """Mask (cols, rows) of the lattice cells of Ω's bounding box that meet Ω."""
    x0, x1, y0, y1 = domain.bounds
    return domain.cells_meeting(np.linspace(x0, x1, cols + 1), np.linspace(y0, y1, rows + 1))


def coverage_layout(domain: Domain, radius: float, max_robots: int = 100_000) -> CoverageLayout:
    """The smallest square-lattice arrangement whose disks of ``radius`` cover Ω.

    A ``cols × rows`` cell-centred lattice over the bounding box ``w × h`` covers it when
    each cell's half-diagonal ``½√((w/cols)² + (h/rows)²) ≤ radius``; only cells that meet
    Ω need a robot.  Every ``cols`` is tried with its smallest admissible ``rows``; the
    arrangement with the fewest robots wins (ties: the squarer cells).  Any region works
    (a floor plan too); the disks are Euclidean, so on a plan a sign may count as covering a
    point behind a wall: there the count is a lower estimate.
    """
    if not isinstance(domain, Region):
        raise ParameterError("domain", type(domain).__name__, "a region (a Domain or a Plan)")
    radius = positive_number("radius", radius)
    x0, x1, y0, y1 = domain.bounds
    w, h = x1 - x0, y1 - y0
    best: tuple[int, float, int, int] | None = None
    cols = 1
    while True:
        sx = w / cols
        if sx < 2 * radius:
            rows = max(1, math.ceil(h / math.sqrt(4 * radius * radius - sx * sx) - 1e-12))
            if best is not None and cols > best[0]:
                break  # more columns than the best count cannot beat it
            n = int(_cells_meeting(domain, cols, rows).sum())
            if n > max_robots:
                raise ParameterError("radius", radius, f"a radius that needs at most {max_robots} robots")
            aspect = abs(math.log(sx / (h / rows)))
            if best is None or (n, aspect) < (best[0], best[1]):
                best = (n, aspect, cols, rows)
        cols += 1
        if cols > max_robots:
            raise ParameterError("radius", radius, f"a radius that needs at most {max_robots} robots")
    n, _, cols, rows = best
    mask = _cells_meeting(domain, cols, rows)
    xs = x0 + (np.arange(cols) + 0.5) * w / cols
    ys = y0 + (np.arange(rows) + 0.5) * h / rows
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X[mask], Y[mask]])
    pts = domain.project(pts.copy())
    return CoverageLayout(n, cols, rows, (w / cols, h / rows), radius, pts)


def coverage_estimate(domain: Domain, c: float, eta: float, eps: float) -> CoverageLayout:
    """Robots needed so that every point of Ω feels a field of at least ``ε`` from some robot.

    ``coverage_layout(domain, coverage_radius(c, eta, eps))`` (paper, discussion of the
    number of robots).
    """
    return coverage_layout(domain, coverage_radius(c, eta, eps))


# ---------------------------------------------------------------------- empirical minimum
@dataclass
class RobotCountStudy:
    """Closed-loop outcome over robot counts.

    Attributes
    ----------
    counts : list of int
    seeds : list of int
    metric : str
        Summary key judged (default ``fraction_in_target``).
    threshold : float
        Success when the median of ``metric`` over seeds is at least this.
    values : dict
        ``{n: [metric per seed]}``.
    l2_ratio : dict
        ``{n: [l2_error_ratio per seed]}``.
    minimum : int or None
        Smallest count whose median meets the threshold (None: none did).
    """

    counts: list[int]
    seeds: list[int]
    metric: str
    threshold: float
    values: dict[int, list[float]]
    l2_ratio: dict[int, list[float]]
    minimum: int | None

    def medians(self) -> dict[int, float]:
        """Median of the metric per robot count."""
        return {n: float(np.median(v)) for n, v in self.values.items()}

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["values"] = {str(k): v for k, v in self.values.items()}
        d["l2_ratio"] = {str(k): v for k, v in self.l2_ratio.items()}
        d["medians"] = {str(k): v for k, v in self.medians().items()}
        return d


def _run_one(args: tuple[dict, int, int]) -> tuple[int, int, dict]:
    from meanfield.simulation.loop import ClosedLoop

    d, n, seed = args
    sc = Scenario.from_dict(d).with_values({"robots.n": n, "seed": seed})
    s = ClosedLoop(sc).run(progress=False).summary
    return n, seed, {k: s[k] for k in ("fraction_in_target", "l2_error_ratio", "status")}


def empirical_robot_count(
    scenario: Scenario,
    counts: Sequence[int] = (1, 2, 4, 6, 9, 12, 16),
    seeds: Sequence[int] = (0, 1, 2),
    threshold: float = 0.9,
    metric: str = "fraction_in_target",
    workers: int | None = None,
    progress: bool = True,
) -> RobotCountStudy:
    """Run the closed loop for each robot count and seed; the smallest count that succeeds.

    The robots keep the scenario's layout rule (``"grid"``: a regular lattice of ``n``).
    Runs are spread over ``workers`` processes (default: the number of cores).

    Parameters
    ----------
    scenario : Scenario
    counts : sequence of int
        Robot counts to try (each >= 1).
    seeds : sequence of int
        Seeds per count (the median over them is judged).
    threshold : float
        Success level of ``metric``'s median.
    metric : {"fraction_in_target"}
        The summary entry judged.
    workers : int, optional
        Worker processes (1: run in this process).
    progress : bool
        Show a progress bar.
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError("scenario", type(scenario).__name__, "a Scenario")
    counts = sorted({int(n) for n in counts})
    if not counts or counts[0] < 1:
        raise ParameterError("counts", counts, "robot counts, each >= 1")
    seeds = [int(s) for s in seeds]
    if not seeds or min(seeds) < 0:
        raise ParameterError("seeds", seeds, "at least one seed >= 0")
    if metric != "fraction_in_target":
        raise ParameterError("metric", metric, "'fraction_in_target'")
    if scenario.robots.layout == "explicit":
        raise ParameterError("scenario.robots.layout", "explicit", "'grid' or 'random' (the count must be free)")
    jobs = [(scenario.to_dict(), n, s) for n in counts for s in seeds]
    results = map_jobs(_run_one, jobs, workers, "robot count", progress)
    values: dict[int, list[float]] = {n: [] for n in counts}
    ratios: dict[int, list[float]] = {n: [] for n in counts}
    for n, _, s in sorted(results, key=lambda r: (r[0], r[1])):
        values[n].append(float(s[metric]))
        ratios[n].append(float(s["l2_error_ratio"]))
    minimum = next((n for n in counts if np.median(values[n]) >= threshold), None)
    return RobotCountStudy(counts, seeds, metric, float(threshold), values, ratios, minimum)
