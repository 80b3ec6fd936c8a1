"""The options of the NMPC (analysis.nmpc.options): bad keys and values named, defaults."""

from __future__ import annotations

import pytest

from analysis.nmpc import NMPCOptions
from meanfield import ParameterError, paper_scenario


@pytest.mark.parametrize(
    ("options", "key"),
    [
        ({"horizon_steps": 4}, "controller.options.nmpc.horizon_steps"),
        ({"horizon": -1}, "controller.options.nmpc.horizon"),
        ({"horizon": 2.5}, "controller.options.nmpc.horizon"),
        ({"period": 0}, "controller.options.nmpc.period"),
        ({"r_u": -1.0}, "controller.options.nmpc.r_u"),
        ({"cells": 2}, "controller.options.nmpc.cells"),
        ({"flux": "donor"}, "controller.options.nmpc.flux"),
        ({"hessian": "bfgs"}, "controller.options.nmpc.hessian"),
        ({"warm_start": "yes"}, "controller.options.nmpc.warm_start"),
        ({"solver": "snopt"}, "controller.options.nmpc.solver"),
        ({"max_iter": 0}, "controller.options.nmpc.max_iter"),
        ({"blocks": [1, 2]}, "controller.options.nmpc.blocks"),  # does not sum to the horizon (5)
        ({"blocks": [0, 5]}, "controller.options.nmpc.blocks"),
        ({"blocks": 5}, "controller.options.nmpc.blocks"),
        ({"solver": "ipopt", "blocks": [2, 3]}, "controller.options.nmpc.blocks"),  # SQP only
        ({"solver": "ipopt", "hessian": "gauss-newton"}, "controller.options.nmpc.hessian"),
        ({"hessian": "limited-memory"}, "controller.options.nmpc.hessian"),  # IPOPT only
        ({"spread": 1}, "controller.options.nmpc.spread"),
        ({"solver": "ipopt", "spread": True}, "controller.options.nmpc.spread"),  # SQP only
    ],
)
def test_bad_options_name_the_key(options, key):
    with pytest.raises(ParameterError) as exc:
        NMPCOptions.from_mapping(options)
    assert exc.value.name == key


def test_bad_option_through_the_closed_loop():
    with pytest.raises(ParameterError) as exc:  # refused as the scenario is read
        paper_scenario().with_values({"controller.kind": "nmpc", "controller.options.nmpc.horizon": -3})
    assert exc.value.name == "controller.options.nmpc.horizon"


def test_options_defaults_and_prediction_step():
    o = NMPCOptions.from_mapping({"cells": 12, "period": 0.1})
    assert o.cells == (12, 12) and o.prediction_step == 0.1
    assert NMPCOptions(step=0.3).prediction_step == 0.3
    assert o.solver == "sqp" and o.iteration_limit == 3 and o.spread and o.input_blocks == (1, 1, 3)
    assert NMPCOptions(horizon=3).input_blocks == (1, 1, 1) and NMPCOptions(horizon=8).input_blocks == (1, 1, 6)
    assert NMPCOptions(blocks=[1] * 5).input_blocks == (1,) * 5
    ipopt = NMPCOptions(solver="ipopt")
    assert ipopt.iteration_limit == 50 and not ipopt.spread
