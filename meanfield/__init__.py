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

from meanfield._namespace import install_moved_modules, lazy_namespace

# Names are imported on first use (PEP 562): ``import meanfield`` and ``meanfield --help`` cost
# a few milliseconds, not the ~0.6 s of SciPy, xarray and the solvers (docs page *Command line*).
_LAZY = {
    "BacksteppingController": "meanfield.controllers.backstepping",
    "ConstantAlpha": "meanfield.controllers.backstepping",
    "ExtraInputs": "meanfield.controllers.backstepping",
    "MinimumNormBetaGamma": "meanfield.controllers.backstepping",
    "SaturatingAlpha": "meanfield.controllers.backstepping",
    "UserBetaGamma": "meanfield.controllers.backstepping",
    "PointMassEngine": "meanfield.crowds.point_mass",
    "Crowd": "meanfield.interfaces",
    "MeanfieldDeprecationWarning": "meanfield.errors",
    "KernelDensityEstimator": "meanfield.crowds.kde",
    "silverman_bandwidth": "meanfield.crowds.kde",
    "Domain": "meanfield.geometry.domain",
    "ParameterError": "meanfield.errors",
    "SimulationDiverged": "meanfield.errors",
    "FokkerPlanck": "meanfield.fokker_planck.solver",
    "Grid": "meanfield.geometry.grid",
    "InteractionField": "meanfield.signs.interaction",
    "CustomKernel": "meanfield.signs.kernels",
    "GaussianKernel": "meanfield.signs.kernels",
    "GaussianPotential": "meanfield.signs.interaction",
    "kernel_jacobian_theta": "meanfield.signs.kernels",
    "kernel_jacobian_xi": "meanfield.signs.kernels",
    "kernel_value": "meanfield.signs.kernels",
    "ClosedLoop": "meanfield.simulation.loop",
    "run": "meanfield.simulation.loop",
    "fraction_in_disk": "meanfield.geometry.target",
    "gaussian_target": "meanfield.geometry.target",
    "target_region_radius": "meanfield.geometry.target",
    "SimulationResult": "meanfield.simulation.result",
    "NavigationField": "meanfield.signs.robots",
    "RobotTeam": "meanfield.signs.robots",
    "navigation_velocity": "meanfield.signs.robots",
    "Scenario": "meanfield.scenarios.scenario",
    "load_scenario": "meanfield.scenarios.scenario",
    "paper_scenario": "meanfield.scenarios.scenario",
}

# ``meanfield.Crowd`` is the crowd's protocol (meanfield.interfaces.Crowd) since 0.2.0; before, it was a deprecated
# name of the point-mass engine, PointMassEngine.
__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)
install_moved_modules()  # old module paths (meanfield.crowd, meanfield.control, ...) keep working


__version__ = "0.2.0"

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
    "MeanfieldDeprecationWarning",
    "MinimumNormBetaGamma",
    "NavigationField",
    "ParameterError",
    "PointMassEngine",
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
