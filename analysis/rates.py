"""Decay rates and ISS gains of Theorems 1 and 2, for a scenario or a finished run.

Conventions (stated once, used everywhere): ``V₁ = ∫ρ̃²`` (no factor ½), ``μ₂`` the first
non-zero Neumann eigenvalue of Ω and ``c₂ = √μ₂`` the paper's Poincaré constant
(``‖∇f‖ ≥ c₂‖f‖`` for mean-zero ``f``), ``α_inf = inf_{x,t} α(ρ(x, t))``.

Theorem 1 (``v_r = v_d``): ``dV₁/dt = −2∫α|∇ρ̃|² ≤ −2 α_inf μ₂ V₁``, so
``V₁(t) ≤ V₁(0) e^{−k_p t}`` with ``k_p = 2 α_inf μ₂``, and ``‖ρ̃‖`` decays at ``k_p/2``.

Theorem 2 (``v_r = v_d + ṽ``, disturbance ``v_a``, ``w = ṽ + v_a``):
``½ d‖ρ̃‖²/dt ≤ −α_inf‖∇ρ̃‖² + sup ρ ‖w‖ ‖∇ρ̃‖``.  For any ``c₁ ∈ (0, 1)``, whenever
``‖ρ̃‖ ≥ sup ρ ‖w‖ / (c₁ c₂ α_inf)`` the right side is at most ``−(1 − c₁) α_inf μ₂ ‖ρ̃‖²``,
so ``‖ρ̃‖`` is ultimately bounded by ``γ sup‖w‖`` with the ISS gain
``γ = sup ρ / (c₁ c₂ α_inf)``; it approaches ``sup ρ / (c₂ α_inf)`` as ``c₁ → 1``, at the
price of a vanishing rate ``(1 − c₁) α_inf μ₂`` outside the ball.

Floor plans (``docs/verification.md``, *Floor plans and exits*): both theorems need Ω in one
piece, and :func:`grid_pieces` says whether the grid keeps it so (a grid too coarse for a
narrow door splits it, and the discrete μ₂ of the whole grid is then 0).  With exits the mass
is not conserved and μ₂ no longer bounds the decay of ``‖ρ̃‖``; the exits' outflow (a Robin
condition on the exits, zero flux on the walls) makes the operator coercive without a
mean-zero condition instead, and its smallest eigenvalue ``λ_E`` (:func:`exit_eigenvalue`)
takes the place of ``α_inf μ₂`` in Theorem 2's bound.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.sparse.csgraph import connected_components

from analysis.poincare import _face_graph, neumann_eigenvalue
from meanfield.errors import ParameterError, positive_number
from meanfield.geometry.grid import Grid
from meanfield.geometry.target import gaussian_target
from meanfield.scenarios.scenario import Scenario
from meanfield.simulation.assembly import alpha_schedule_for, disturbance_for
from meanfield.simulation.result import SimulationResult

__all__ = [
    "decay_rate",
    "exit_eigenvalue",
    "grid_pieces",
    "iss_gain",
    "mass_quantile_level",
    "GainReport",
    "gains_for_scenario",
    "gains_from_run",
]


def decay_rate(alpha_inf: float, mu2: float) -> float:
    """``k_p = 2 α_inf μ₂``: the exponential rate of ``V₁ = ∫ρ̃²`` in Theorem 1.

    ``V₁(t) ≤ V₁(0) exp(−k_p t)``; the norm ``‖ρ̃‖`` decays at ``k_p / 2 = α_inf μ₂``.
    """
    return 2.0 * positive_number("alpha_inf", alpha_inf) * positive_number("mu2", mu2)


def iss_gain(sup_rho: float, alpha_inf: float, mu2: float, c1: float = 1.0) -> float:
    """The ISS gain ``γ = sup ρ / (c₁ c₂ α_inf)`` of Theorem 2, ``c₂ = √μ₂``.

    ``‖ρ̃‖`` is ultimately bounded by ``γ · sup‖ṽ + v_a‖``.  The proof needs
    ``c₁ ∈ (0, 1)``; ``c₁ = 1`` (default) gives the infimum of the gains, approached as
    the rate ``(1 − c₁) α_inf μ₂`` outside the ultimate ball goes to zero.
    """
    positive_number("sup_rho", sup_rho)
    c1 = float(c1)
    if not (0.0 < c1 <= 1.0):
        raise ParameterError("c1", c1, "a number in (0, 1] (c1 = 1 is the limiting gain)")
    return sup_rho / (c1 * math.sqrt(positive_number("mu2", mu2)) * positive_number("alpha_inf", alpha_inf))


@dataclass
class GainReport:
    """The constants of Theorems 1 and 2 for one domain and gain schedule.

    Attributes
    ----------
    source : str
        ``"scenario"`` (a priori, at the target density: the local constants near ρ_*) or
        ``"run"`` (over the densities a finished run went through).
    mu2, c2 : float
        Neumann eigenvalue of Ω and the Poincaré constant ``√μ₂``.
    rho_min, sup_rho : float
        Smallest and largest density over which α_inf and sup ρ were taken.
    alpha_inf : float
        ``inf α(ρ)`` over that range (for the saturating schedule ``α₀ ρ_min/(ρ_min + ρ_floor)``).
    k_p : float
        ``2 α_inf μ₂``, the rate of ``V₁ = ∫ρ̃²`` (Theorem 1).
    norm_rate : float
        ``α_inf μ₂``, the rate of ``‖ρ̃‖``.
    iss_gain : float
        ``sup ρ / (c₂ α_inf)`` (Theorem 2, ``c₁ → 1``).
    bulk : dict
        Not a guarantee: the same constants with ``ρ_min`` replaced by the density level
        below which lies 5 % of the mass (``rho_level``, ``alpha``, ``k_p``, ``iss_gain``).
        With a density-scheduled α the rigorous ``α_inf`` is that of the emptiest cell,
        which is nearly zero, and the guaranteed rate is vacuous; this is the rate the
        bulk of the crowd sees.
    observed : dict
        For a run: ``sup_v_tilde`` (largest ‖ṽ‖ over the second half), ``rho_error_final``,
        ``ultimate_bound`` = ``iss_gain · sup_v_tilde`` and ``bound_holds``.
    """

    source: str
    mu2: float
    c2: float
    rho_min: float
    sup_rho: float
    alpha_inf: float
    k_p: float
    norm_rate: float
    iss_gain: float
    bulk: dict[str, float]
    observed: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready), with the conventions spelled out."""
        d = asdict(self)
        d["conventions"] = {
            "V1": "integral of rho_tilde^2 (no factor 1/2)",
            "k_p": "2 alpha_inf mu2: V1(t) <= V1(0) exp(-k_p t) (Theorem 1)",
            "iss_gain": "sup rho / (c2 alpha_inf): ultimate ||rho_tilde|| <= gain * sup||v_tilde + v_a|| (Theorem 2)",
            "c2": "sqrt(mu2), mu2 the first non-zero Neumann eigenvalue of the domain",
        }
        return d


BULK_FRACTION = 0.05
"""Mass fraction left out of the ``bulk`` constants (the emptiest cells holding 5 %)."""


def mass_quantile_level(rho: np.ndarray, volume: np.ndarray, fraction: float = BULK_FRACTION) -> float:
    """The density level below which the cells hold ``fraction`` of the mass ``∫ρ``."""
    order = np.argsort(rho, axis=None)
    r = rho.ravel()[order]
    cum = np.cumsum(r * volume.ravel()[order])
    return float(r[min(int(np.searchsorted(cum, fraction * cum[-1])), r.size - 1)])


def _report(
    source: str, mu2: float, rho_min: float, sup_rho: float, rho_level: float, scenario: Scenario
) -> GainReport:
    schedule = alpha_schedule_for(scenario)
    alpha = schedule.alpha(np.array([rho_min, rho_level]))  # α(ρ) is non-decreasing in ρ
    alpha_inf = float(alpha[0])
    k_p = decay_rate(alpha_inf, mu2)
    bulk_k = decay_rate(float(alpha[1]), mu2)
    return GainReport(
        source=source,
        mu2=mu2,
        c2=math.sqrt(mu2),
        rho_min=rho_min,
        sup_rho=sup_rho,
        alpha_inf=alpha_inf,
        k_p=k_p,
        norm_rate=k_p / 2,
        iss_gain=iss_gain(sup_rho, alpha_inf, mu2),
        bulk={
            "mass_fraction_below": BULK_FRACTION,
            "rho_level": rho_level,
            "alpha": float(alpha[1]),
            "k_p": bulk_k,
            "iss_gain": iss_gain(sup_rho, float(alpha[1]), mu2),
        },
        observed={},
    )


def gains_for_scenario(scenario: Scenario, mu2: float | None = None, cells: int = 128) -> GainReport:
    """A-priori constants of a scenario, taken at its target density ``ρ_*``.

    The theorems take ``α_inf`` and ``sup ρ`` along the whole trajectory, which is not
    known before a run; at the target (the equilibrium) they are ``α(min ρ_*)`` and
    ``max ρ_*``: the local rate and gain near ρ_*.  Use :func:`gains_from_run` for the
    values along an actual run.

    Parameters
    ----------
    scenario : Scenario
    mu2 : float, optional
        The Neumann eigenvalue of Ω, if already known (else computed at ``cells``²).
    cells : int
        Grid for :func:`~analysis.poincare.neumann_eigenvalue` (>= 4).
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError("scenario", type(scenario).__name__, "a Scenario")
    if mu2 is None:
        mu2 = neumann_eigenvalue(scenario.domain, cells=(cells, cells))
    grid = Grid(scenario.domain, scenario.grid.cells)
    target = gaussian_target(grid, scenario.target.center, scenario.target.std)
    inside = grid.active
    level = mass_quantile_level(target[inside], grid.volume[inside])
    return _report("scenario", float(mu2), float(target[inside].min()), float(target[inside].max()), level, scenario)


def gains_from_run(result: SimulationResult, mu2: float | None = None, cells: int = 128) -> GainReport:
    """Constants along a finished run: ``α_inf`` and ``sup ρ`` over its recorded density estimates.

    ``observed`` holds the largest ``‖ṽ‖`` over the second half of the run, the final
    ``‖ρ̃‖`` and Theorem 2's ultimate bound ``iss_gain · sup‖ṽ‖`` (``v_a = 0`` unless the
    scenario has a disturbance, whose size is then added).  The run's density is a KDE of
    the agents, not the PDE the theorems speak of: read the comparison as indicative.
    """
    if not isinstance(result, SimulationResult):
        raise ParameterError("result", type(result).__name__, "a SimulationResult")
    ds = result.dataset
    sc = result.scenario
    if mu2 is None:
        mu2 = neumann_eigenvalue(sc.domain, cells=(cells, cells))
    grid = Grid(sc.domain, sc.grid.cells)
    rho = np.asarray(ds["density"].values)[:, grid.active]
    v = np.asarray(ds["v_error_l2"].values, float)
    half = v[len(v) // 2 :]
    sup_v = float(np.nanmax(half)) if np.isfinite(half).any() else float("nan")
    disturbance = _disturbance_size(sc)
    level = min(mass_quantile_level(frame, grid.volume[grid.active]) for frame in rho)
    report = _report("run", float(mu2), float(rho.min()), float(rho.max()), level, sc)
    bound = report.iss_gain * (sup_v + disturbance)
    final = float(ds["rho_error_l2"].values[-1])
    report.observed = {
        "sup_v_tilde_second_half": sup_v,
        "disturbance_l2": disturbance,
        "rho_error_final": final,
        "ultimate_bound": bound,
        "bound_holds": bool(final <= bound),
    }
    return report


def _disturbance_size(scenario: Scenario) -> float:
    """``‖v_a‖_{L²(Ω)}`` of the scenario's disturbance at t = 0 (0 without one; the built-in
    disturbances do not depend on time)."""
    va = disturbance_for(scenario)
    if va is None:
        return 0.0
    grid = Grid(scenario.domain, scenario.grid.cells)
    X, Y = grid.centers
    vx, vy = va(X, Y, 0.0)
    return float(np.sqrt(grid.integrate(vx * vx + vy * vy)))


# ---------------------------------------------------------------------- floor plans and exits
_DENSE_LIMIT = 1500  # up to this many active cells, a dense generalized eigensolve


def _check_grid(grid: object) -> Grid:
    if not isinstance(grid, Grid):
        raise ParameterError("grid", type(grid).__name__, "a meanfield.Grid")
    return grid


def grid_pieces(grid: Grid) -> tuple[int, float]:
    """How many pieces the grid's active cells form through its open faces, and the share of
    Ω's area outside the largest.

    Parameters
    ----------
    grid : Grid

    Returns
    -------
    (int, float)
        The number of pieces (1: connected) and the area share of all but the largest.
    """
    grid = _check_grid(grid)
    adjacency, active = _face_graph(grid)
    ncomp, labels = connected_components(adjacency, directed=False)
    area = np.bincount(labels, weights=grid.volume[active])
    return int(ncomp), float(1.0 - area.max() / area.sum())


def exit_eigenvalue(grid: Grid, alpha: float, rates: np.ndarray) -> float:
    """The smallest eigenvalue ``λ_E`` of ``α L + K`` in the cell volumes' inner product.

    ``L = Gᵀ W G`` is the grid's Neumann stiffness (:func:`analysis.poincare.neumann_eigenvalue`:
    ``uᵀ L u = ∫|∇_h u|²`` on the faces), ``K = diag(k V)`` the exits' outflow, ``k`` the rate
    at which each cell an exit crosses loses its density (:class:`~meanfield.geometry.exits.ExitSink`,
    ``σ ℓ / (d V)``).  So ``α ∫|∇u|² + ∫k u² >= λ_E ∫u²`` for every ``u``, with no mean-zero
    condition: the semi-discrete form of ``−αΔ`` with zero flux on the walls and the exits'
    Robin outflow (as the grid is refined, the Dirichlet condition ``ρ = 0`` on the exits:
    a ``1 × w`` strip with an exit across one end has ``λ_E → α π²/4``).  ``λ_E = 0``
    without exits (the constants), or when a piece of the grid reaches no exit.

    Parameters
    ----------
    grid : Grid
        The grid the density lives on (all its active cells are unknowns).
    alpha : float
        The diffusion gain, ``> 0`` (Theorem 2: the smallest face gain ``α_inf``).
    rates : ndarray
        ``k`` on ``grid.shape`` (1/time), ``>= 0``; zero away from the exits.

    Returns
    -------
    float
        ``λ_E`` (1/time), ``>= 0``.
    """
    grid = _check_grid(grid)
    if not (isinstance(alpha, int | float | np.floating) and math.isfinite(alpha) and alpha > 0):
        raise ParameterError("alpha", alpha, "a finite number > 0")
    k = np.asarray(rates, float)
    if k.shape != grid.shape or not np.all(np.isfinite(k)) or (k < 0).any():
        raise ParameterError("rates", getattr(k, "shape", k), f"finite rates >= 0 on grid.shape {grid.shape}")
    adjacency, active = _face_graph(grid)
    volume = grid.volume[active]
    stiffness = sp.diags(np.asarray(adjacency.sum(axis=1)).ravel()) - adjacency
    operator = (alpha * stiffness + sp.diags(k[active] * volume)).tocsc()
    n = operator.shape[0]
    if n <= _DENSE_LIMIT:
        lam = scipy.linalg.eigh(operator.toarray(), np.diag(volume), eigvals_only=True, subset_by_index=[0, 0])[0]
    else:
        shift = -1e-3 * alpha * math.pi**2 / grid.domain.diameter**2  # σ < 0: α L + K − σM is definite
        vals = sla.eigsh(operator, k=1, M=sp.diags(volume).tocsc(), sigma=shift, which="LM", return_eigenvectors=False)
        lam = vals[0]
    return max(float(lam), 0.0)
