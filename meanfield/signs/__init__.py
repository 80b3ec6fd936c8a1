"""The robots and the navigation velocity field their signs make (paper, eqs. (2)–(3)).

Navigation kernels and interaction potentials (:mod:`~meanfield.signs.kernels`), the robot team and its
field (:mod:`~meanfield.signs.robots`), the field sampled on a lattice (:mod:`~meanfield.signs.sampled_field`)
and the mean interaction velocity (:mod:`~meanfield.signs.interaction`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "AT_LIMIT_RTOL": "meanfield.signs.robots",
    "CustomKernel": "meanfield.signs.kernels",
    "GaussianKernel": "meanfield.signs.kernels",
    "GaussianPotential": "meanfield.signs.kernels",
    "InteractionField": "meanfield.signs.interaction",
    "InteractionPotential": "meanfield.signs.kernels",
    "NavigationField": "meanfield.signs.robots",
    "NavigationKernel": "meanfield.signs.kernels",
    "RobotTeam": "meanfield.signs.robots",
    "SampledNavigationField": "meanfield.signs.sampled_field",
    "kernel_jacobian_theta": "meanfield.signs.kernels",
    "kernel_jacobian_xi": "meanfield.signs.kernels",
    "kernel_value": "meanfield.signs.kernels",
    "limited_inputs": "meanfield.signs.robots",
    "navigation_velocity": "meanfield.signs.robots",
    "saturate_inputs": "meanfield.signs.robots",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
