"""The crowd: every model of the humans the closed loop can step.

The agents under the signs (:mod:`~meanfield.crowds.agent_crowd`) moved by an engine: point masses
(:mod:`~meanfield.crowds.point_mass`) or JuPedSim's bodies (:mod:`~meanfield.crowds.jupedsim_engine`);
the density itself (:mod:`~meanfield.crowds.density_crowd`, eq. (4)); the kernel density estimate the
robots see (:mod:`~meanfield.crowds.kde`); what the humans follow (:mod:`~meanfield.crowds.guidance`)
and their local view (:mod:`~meanfield.crowds.local_view`); congestion's speed–density relations
(:mod:`~meanfield.crowds.congestion`) and each human's local density (:mod:`~meanfield.crowds.local_density`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "AgentCrowd": "meanfield.crowds.agent_crowd",
    "AgentEngine": "meanfield.crowds.agent_crowd",
    "BinnedLayout": "meanfield.crowds.kde",
    "DENSITY_RADIUS": "meanfield.crowds.local_density",
    "DensityCrowd": "meanfield.crowds.density_crowd",
    "FREE_SPEED": "meanfield.crowds.congestion",
    "FundamentalDiagram": "meanfield.crowds.congestion",
    "GeodesicGuidance": "meanfield.crowds.guidance",
    "Guidance": "meanfield.crowds.guidance",
    "JuPedSimEngine": "meanfield.crowds.jupedsim_engine",
    "JuPedSimOptions": "meanfield.crowds.jupedsim_engine",
    "KernelDensityEstimator": "meanfield.crowds.kde",
    "Linear": "meanfield.crowds.congestion",
    "LocalDensity": "meanfield.crowds.local_density",
    "LocalView": "meanfield.crowds.local_view",
    "NoCongestion": "meanfield.crowds.congestion",
    "PEDESTRIAN_MODELS": "meanfield.crowds.jupedsim_engine",
    "PointMassEngine": "meanfield.crowds.point_mass",
    "RandomWalkGuidance": "meanfield.crowds.guidance",
    "SAMPLED_FIELD_ABOVE": "meanfield.crowds.agent_crowd",
    "WEIDMANN_GAMMA": "meanfield.crowds.congestion",
    "WEIDMANN_RHO_MAX": "meanfield.crowds.congestion",
    "Weidmann": "meanfield.crowds.congestion",
    "binned_layout": "meanfield.crowds.kde",
    "check_scenario": "meanfield.crowds.jupedsim_engine",
    "door_areas": "meanfield.crowds.jupedsim_engine",
    "geodesic": "meanfield.crowds.guidance",
    "initial_density": "meanfield.crowds.density_crowd",
    "initial_positions": "meanfield.crowds.agent_crowd",
    "jupedsim_crowd": "meanfield.crowds.jupedsim_engine",
    "kde_direct": "meanfield.crowds.kde",
    "local_density": "meanfield.crowds.local_density",
    "max_body_overlap": "meanfield.crowds.jupedsim_engine",
    "persons_per_m2": "meanfield.crowds.congestion",
    "place_bodies": "meanfield.crowds.jupedsim_engine",
    "point_mass_crowd": "meanfield.crowds.agent_crowd",
    "random_walk": "meanfield.crowds.guidance",
    "robots_in_view": "meanfield.crowds.local_view",
    "signs": "meanfield.crowds.guidance",
    "silverman_bandwidth": "meanfield.crowds.kde",
}

# names before 0.2.0 (a floor plan is a Plan), read with a warning until 0.3.0
_DEPRECATED = {
    "BinnedPlan": ("meanfield.crowds.kde", "BinnedLayout"),
    "binned_plan": ("meanfield.crowds.kde", "binned_layout"),
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY, _DEPRECATED)

__all__ = sorted(_LAZY)
