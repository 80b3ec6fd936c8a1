"""The options of the NMPC (analysis.nmpc.options): bad keys and values named, defaults."""

from __future__ import annotations

import pytest

from analysis.nmpc import NMPCOptions
from meanfield import ClosedLoop, ParameterError, paper_scenario


@pytest.mark.parametrize(
    ("options", "key"),
    [
        ({"horizon_steps": 4}, "controller.options.horizon_steps"),
        ({"horizon": -1}, "controller.options.horizon"),
        ({"horizon": 2.5}, "controller.options.horizon"),
        ({"period": 0}, "controller.options.period"),
        ({"r_u": -1.0}, "controller.options.r_u"),
        ({"cells": 2}, "controller.options.cells"),
        ({"flux": "donor"}, "controller.options.flux"),
        ({"hessian": "bfgs"}, "controller.options.hessian"),
        ({"warm_start": "yes"}, "controller.options.warm_start"),
        ({"solver": "snopt"}, "controller.options.solver"),
        ({"max_iter": 0}, "controller.options.max_iter"),
        ({"blocks": [1, 2]}, "controller.options.blocks"),  # does not sum to the horizon (5)
        ({"blocks": [0, 5]}, "controller.options.blocks"),
        ({"blocks": 5}, "controller.options.blocks"),
        ({"solver": "ipopt", "blocks": [2, 3]}, "controller.options.blocks"),  # SQP only
        ({"solver": "ipopt", "hessian": "gauss-newton"}, "controller.options.hessian"),
        ({"hessian": "limited-memory"}, "controller.options.hessian"),  # IPOPT only
        ({"spread": 1}, "controller.options.spread"),
        ({"solver": "ipopt", "spread": True}, "controller.options.spread"),  # SQP only
    ],
)
def test_bad_options_name_the_key(options, key):
    with pytest.raises(ParameterError) as exc:
        NMPCOptions.from_mapping(options)
    assert exc.value.name == key


def test_bad_option_through_the_closed_loop():
    sc = paper_scenario().with_values({"controller.kind": "nmpc", "controller.options.horizon": -3})
    with pytest.raises(ParameterError) as exc:
        ClosedLoop(sc)
    assert exc.value.name == "controller.options.horizon"


def test_options_defaults_and_prediction_step():
    o = NMPCOptions.from_mapping({"cells": 12, "period": 0.1})
    assert o.cells == (12, 12) and o.prediction_step == 0.1
    assert NMPCOptions(step=0.3).prediction_step == 0.3
    assert o.solver == "sqp" and o.iteration_limit == 3 and o.spread and o.input_blocks == (1, 1, 3)
    assert NMPCOptions(horizon=3).input_blocks == (1, 1, 1) and NMPCOptions(horizon=8).input_blocks == (1, 1, 6)
    assert NMPCOptions(blocks=[1] * 5).input_blocks == (1,) * 5
    ipopt = NMPCOptions(solver="ipopt")
    assert ipopt.iteration_limit == 50 and not ipopt.spread
