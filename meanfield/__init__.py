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

from meanfield.lazy import lazy_namespace

# Names are imported on first use (PEP 562): ``import meanfield`` and ``meanfield --help`` cost
# a few milliseconds, not the ~0.6 s of SciPy, xarray and the solvers (docs page *Command line*).
_LAZY = {
    "BacksteppingController": "meanfield.control",
    "ConstantAlpha": "meanfield.control",
    "ExtraInputs": "meanfield.control",
    "MinimumNormBetaGamma": "meanfield.control",
    "SaturatingAlpha": "meanfield.control",
    "UserBetaGamma": "meanfield.control",
    "Crowd": "meanfield.crowd",
    "KernelDensityEstimator": "meanfield.density",
    "silverman_bandwidth": "meanfield.density",
    "Domain": "meanfield.domain",
    "ParameterError": "meanfield.errors",
    "SimulationDiverged": "meanfield.errors",
    "FokkerPlanck": "meanfield.fokker_planck",
    "Grid": "meanfield.grid",
    "InteractionField": "meanfield.interaction",
    "CustomKernel": "meanfield.kernels",
    "GaussianKernel": "meanfield.kernels",
    "GaussianPotential": "meanfield.kernels",
    "kernel_jacobian_theta": "meanfield.kernels",
    "kernel_jacobian_xi": "meanfield.kernels",
    "kernel_value": "meanfield.kernels",
    "ClosedLoop": "meanfield.loop",
    "run": "meanfield.loop",
    "fraction_in_disk": "meanfield.metrics",
    "gaussian_target": "meanfield.metrics",
    "target_region_radius": "meanfield.metrics",
    "SimulationResult": "meanfield.result",
    "NavigationField": "meanfield.robots",
    "RobotTeam": "meanfield.robots",
    "navigation_velocity": "meanfield.robots",
    "Scenario": "meanfield.scenario",
    "load_scenario": "meanfield.scenario",
    "paper_scenario": "meanfield.scenario",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)


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
