"""The NMPC baseline (CasADi): the ``nmpc`` controller of scenarios (docs/nmpc.md).

- :mod:`~analysis.nmpc.controller`: :class:`NMPCController`, the receding-horizon controller,
  and :func:`nmpc_controller_for`, its plugin factory (entry point ``nmpc`` of
  ``meanfield.controllers``);
- :mod:`~analysis.nmpc.options`: :class:`NMPCOptions`, the ``[controller.options.nmpc]`` table, and
  the allowed values :data:`FLUXES`, :data:`HESSIANS`, :data:`SOLVERS`;
- :mod:`~analysis.nmpc.prediction_model`: :class:`CoarseFokkerPlanck`, the coarse Fokker–Planck
  model the controller predicts with;
- :mod:`~analysis.nmpc.plan`: :class:`NMPCSolution`, one solution (``NMPCPlan`` before 0.2.0), and
  :func:`robot_state`;
- the two solvers of the one problem: :mod:`~analysis.nmpc.ipopt` (every state lifted, IPOPT:
  :func:`ipopt_function`, :func:`ipopt_arrays`) and the real-time SQP on the inputs,
  :mod:`~analysis.nmpc.sqp` (:class:`SQPSolver`, :class:`SQPResult`) with the problem condensed
  onto the inputs, :mod:`~analysis.nmpc.condensed` (:class:`CondensedProblem`,
  :func:`block_counts`), and its quadratic subproblem, :mod:`~analysis.nmpc.qp`
  (:class:`InputQP`, :class:`QPResult`).

Names are imported on first use (:mod:`meanfield._namespace`), so that ``import analysis.nmpc``
imports neither CasADi nor SciPy.  The package replaces the module ``analysis.nmpc`` of earlier
releases: its names (``analysis.nmpc.NMPCController``, ``analysis.nmpc.nmpc_controller_for``, ...)
are read here as before; the old modules ``analysis.nmpc_*`` still import, with a warning
(:mod:`analysis._moved`).
"""

from meanfield._namespace import lazy_namespace

_LAZY = {
    "CoarseFokkerPlanck": "analysis.nmpc.prediction_model",
    "CondensedProblem": "analysis.nmpc.condensed",
    "FLUXES": "analysis.nmpc.options",
    "HESSIANS": "analysis.nmpc.options",
    "InputQP": "analysis.nmpc.qp",
    "NMPCController": "analysis.nmpc.controller",
    "NMPCOptions": "analysis.nmpc.options",
    "NMPCSolution": "analysis.nmpc.plan",
    "QPResult": "analysis.nmpc.qp",
    "SOLVERS": "analysis.nmpc.options",
    "SQPResult": "analysis.nmpc.sqp",
    "SQPSolver": "analysis.nmpc.sqp",
    "block_counts": "analysis.nmpc.condensed",
    "ipopt_arrays": "analysis.nmpc.ipopt",
    "ipopt_function": "analysis.nmpc.ipopt",
    "nmpc_controller_for": "analysis.nmpc.controller",
    "robot_state": "analysis.nmpc.plan",
}

# its name before 0.2.0, read with a warning until 0.3.0
_DEPRECATED = {"NMPCPlan": ("analysis.nmpc.plan", "NMPCSolution")}

__getattr__, __dir__ = lazy_namespace(__name__, globals(), _LAZY, _DEPRECATED)

__all__ = sorted(_LAZY)
