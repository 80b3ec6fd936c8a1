"""The robots' controllers, each registered by name (``controller.kind``).

The paper's backstepping density feedback (:mod:`~meanfield.controllers.backstepping`), the evacuation
controller towards the exits (:mod:`~meanfield.controllers.evacuation`), Lloyd coverage
(:mod:`~meanfield.controllers.coverage`), the static-signs baseline (:mod:`~meanfield.controllers.static_signs`)
and robots that know only what they sense (:mod:`~meanfield.controllers.local_sensing`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "AlphaSchedule": "meanfield.controllers.backstepping",
    "BacksteppingController": "meanfield.controllers.backstepping",
    "BetaGammaStrategy": "meanfield.controllers.backstepping",
    "ConstantAlpha": "meanfield.controllers.backstepping",
    "ControlState": "meanfield.controllers.backstepping",
    "CoverageController": "meanfield.controllers.coverage",
    "DVD_DT_OPTIONS": "meanfield.controllers.backstepping",
    "EvacuationController": "meanfield.controllers.evacuation",
    "ExtraInputs": "meanfield.controllers.backstepping",
    "LocalSensing": "meanfield.controllers.local_sensing",
    "MinimumNormBetaGamma": "meanfield.controllers.backstepping",
    "SaturatingAlpha": "meanfield.controllers.backstepping",
    "StaticSigns": "meanfield.controllers.static_signs",
    "UNSEEN_FLOOR": "meanfield.controllers.local_sensing",
    "UserBetaGamma": "meanfield.controllers.backstepping",
    "V_D": "meanfield.controllers.coverage",
    "WEIGHTS": "meanfield.controllers.coverage",
    "exit_distance": "meanfield.controllers.evacuation",
    "groups": "meanfield.controllers.local_sensing",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
