"""The robots' controllers, each registered by name (``controller.kind``).

The paper's backstepping density feedback (:mod:`~meanfield.controllers.backstepping`, with its α schedules
:mod:`~meanfield.controllers.alpha_schedules`, its β/γ rules :mod:`~meanfield.controllers.beta_gamma` and its
congested plant :mod:`~meanfield.controllers.congested_plant`), the evacuation
controller towards the exits (:mod:`~meanfield.controllers.evacuation`), Lloyd coverage
(:mod:`~meanfield.controllers.coverage`), the static-signs baseline (:mod:`~meanfield.controllers.static_signs`)
and robots that know only what they sense (:mod:`~meanfield.controllers.local_sensing`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "AlphaSchedule": "meanfield.controllers.backstepping",
    "BacksteppingController": "meanfield.controllers.backstepping",
    "CongestedPlant": "meanfield.controllers.congested_plant",
    "BetaGammaStrategy": "meanfield.controllers.backstepping",
    "ConstantAlpha": "meanfield.controllers.alpha_schedules",
    "ControlState": "meanfield.controllers.backstepping",
    "CoverageController": "meanfield.controllers.coverage",
    "DVD_DT_OPTIONS": "meanfield.controllers.backstepping",
    "EvacuationController": "meanfield.controllers.evacuation",
    "ExtraInputs": "meanfield.controllers.backstepping",
    "LocalSensing": "meanfield.controllers.local_sensing",
    "MinimumNormBetaGamma": "meanfield.controllers.beta_gamma",
    "SaturatingAlpha": "meanfield.controllers.alpha_schedules",
    "StaticSigns": "meanfield.controllers.static_signs",
    "UNSEEN_FLOOR": "meanfield.controllers.local_sensing",
    "UserBetaGamma": "meanfield.controllers.beta_gamma",
    "V_D": "meanfield.controllers.coverage",
    "WEIGHTS": "meanfield.controllers.coverage",
    "exit_distance": "meanfield.controllers.evacuation",
    "groups": "meanfield.controllers.local_sensing",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
