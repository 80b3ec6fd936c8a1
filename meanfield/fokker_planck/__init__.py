"""The finite-volume Fokker–Planck solver of the crowd's mean-field limit (paper, eq. (4)).

:mod:`~meanfield.fokker_planck.solver` holds :class:`FokkerPlanck`; :mod:`~meanfield.fokker_planck.stepping`
its time-stepping methods, one :class:`Stepper` each, chosen by name from :data:`STEPPERS`; ``_sweeps`` their
compiled tridiagonal sweeps; :mod:`~meanfield.fokker_planck.congested` the congested (LWR, Godunov) flux and the two
methods that support it (:data:`CONGESTED_STEPPERS`).

Names are imported on first use (:mod:`meanfield._namespace`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "AdiStepper": "meanfield.fokker_planck.stepping",
    "CONGESTED_STEPPERS": "meanfield.fokker_planck.congested",
    "CongestedFlux": "meanfield.fokker_planck.congested",
    "ExplicitStepper": "meanfield.fokker_planck.stepping",
    "FaceVelocity": "meanfield.fokker_planck.stepping",
    "FokkerPlanck": "meanfield.fokker_planck.solver",
    "ImplicitStepper": "meanfield.fokker_planck.stepping",
    "METHODS": "meanfield.fokker_planck.solver",
    "SplitStepper": "meanfield.fokker_planck.stepping",
    "STEPPERS": "meanfield.fokker_planck.stepping",
    "Stepper": "meanfield.fokker_planck.stepping",
    "scharfetter_gummel": "meanfield.fokker_planck.solver",
}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY)

__all__ = sorted(_LAZY)
