"""meanfield: mean-field control of human crowds by robots with navigation signs.

Implements Zheng et al., "Multi-Robot-Assisted Human Crowd Evacuation using Navigation
Velocity Fields": the human SDE crowd, robots and their navigation velocity fields, KDE
density estimation, the backstepping density-feedback controller, the closed loop and a
finite-volume Fokker–Planck solver of the crowd's mean-field limit.

Quick start::

    from meanfield import paper_scenario, run
    result = run(paper_scenario(seed=0))
    result.summary["fraction_in_target"]
"""

from meanfield.control import (
    BacksteppingController,
    ConstantAlpha,
    ExtraInputs,
    MinimumNormBetaGamma,
    SaturatingAlpha,
    UserBetaGamma,
)
from meanfield.crowd import Crowd
from meanfield.density import KernelDensityEstimator, silverman_bandwidth
from meanfield.domain import Domain
from meanfield.errors import ParameterError, SimulationDiverged
from meanfield.fokker_planck import FokkerPlanck
from meanfield.grid import Grid
from meanfield.interaction import InteractionField
from meanfield.kernels import (
    CustomKernel,
    GaussianKernel,
    GaussianPotential,
    kernel_jacobian_theta,
    kernel_jacobian_xi,
    kernel_value,
)
from meanfield.loop import ClosedLoop, run
from meanfield.metrics import fraction_in_disk, gaussian_target, target_region_radius
from meanfield.result import SimulationResult
from meanfield.robots import NavigationField, RobotTeam, navigation_velocity
from meanfield.scenario import Scenario, load_scenario, paper_scenario

__version__ = "0.1.0"

__all__ = [
    "BacksteppingController",
    "ClosedLoop",
    "ConstantAlpha",
    "Crowd",
    "CustomKernel",
    "Domain",
    "ExtraInputs",
    "FokkerPlanck",
    "GaussianKernel",
    "GaussianPotential",
    "Grid",
    "InteractionField",
    "KernelDensityEstimator",
    "MinimumNormBetaGamma",
    "NavigationField",
    "ParameterError",
    "RobotTeam",
    "SaturatingAlpha",
    "Scenario",
    "SimulationDiverged",
    "SimulationResult",
    "UserBetaGamma",
    "fraction_in_disk",
    "gaussian_target",
    "kernel_jacobian_theta",
    "kernel_jacobian_xi",
    "kernel_value",
    "load_scenario",
    "navigation_velocity",
    "paper_scenario",
    "run",
    "silverman_bandwidth",
    "target_region_radius",
]
