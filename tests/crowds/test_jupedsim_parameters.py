"""The JuPedSim models' own parameters (``crowd.options.jupedsim.time_gap``, the repulsions): checked when the
scenario is read, each refused naming its field, and handed to JuPedSim's model or agents."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from meanfield import Domain, ParameterError
from meanfield.crowds._jupedsim_api import MODEL_PARAMETERS, MODELS
from meanfield.crowds.jupedsim_engine import JuPedSimOptions
from meanfield.scenarios.scenario import builtin_scenarios


def _bodies(values: dict):
    return builtin_scenarios()["bottleneck"](seed=0).with_values({"crowd.kind": "jupedsim", **values})


def test_the_options_name_every_parameter_a_model_may_take():
    fields = {f.name for f in dataclasses.fields(JuPedSimOptions)} - {"model", "radius", "max_speed", "time_step"}
    assert set().union(*map(set, MODEL_PARAMETERS.values())) == fields
    assert set(MODEL_PARAMETERS) == set(MODELS)


def test_unset_parameters_keep_jupedsims_defaults_and_set_ones_are_passed():
    assert JuPedSimOptions().parameters() == {}
    p = JuPedSimOptions.of(_bodies({"crowd.options.jupedsim.time_gap": 0.8}))
    assert p.parameters() == {"time_gap": 0.8, "strength_neighbor_repulsion": 5.0}  # the scenario's own, kept
    # "default" (what --set can say) unsets one: JuPedSim's default again, and another model may be chosen
    p = JuPedSimOptions.of(
        _bodies(
            {
                "crowd.options.jupedsim.model": "social-force",
                "crowd.options.jupedsim.strength_neighbor_repulsion": "default",
            }
        )
    )
    assert p.model == "social-force" and p.parameters() == {}


def test_the_defaults_are_jupedsims_bottleneck_validation():
    """JuPedSim's validation of the bottleneck (jpscore's test_13): the collision-free speed model, bodies of
    0.15 m and steps of 0.05 s; the built-in bottleneck and rimea-9 also take its neighbour repulsion, 5."""
    p = JuPedSimOptions()
    assert (p.model, p.radius, p.time_step) == ("collision-free-speed", 0.15, 0.05)
    for name in ("bottleneck", "rimea-9"):
        p = JuPedSimOptions.of(builtin_scenarios()[name](seed=0))
        assert (p.model, p.radius, p.time_step) == ("collision-free-speed", 0.15, 0.05)
        assert p.parameters() == {"strength_neighbor_repulsion": 5.0}


@pytest.mark.parametrize(
    ("values", "named"),
    [
        ({"crowd.options.jupedsim.time_gap": 0.05}, "time_gap"),  # JuPedSim accepts 0.1-10 s
        ({"crowd.options.jupedsim.range_neighbor_repulsion": 0.0}, "range_neighbor_repulsion"),
        ({"crowd.options.jupedsim.strength_geometry_repulsion": "5"}, "strength_geometry_repulsion"),
        # a parameter the model does not have
        (
            {
                "crowd.options.jupedsim.model": "anticipation-velocity",
                "crowd.options.jupedsim.range_geometry_repulsion": 0.05,
            },
            "range_geometry_repulsion",
        ),
        ({"crowd.options.jupedsim.model": "social-force", "crowd.options.jupedsim.time_gap": 1.0}, "time_gap"),
    ],
)
def test_a_bad_parameter_is_refused_naming_its_field(values, named):
    with pytest.raises(ParameterError) as info:
        _bodies(values)
    assert info.value.name == f"crowd.options.jupedsim.{named}"


# ---------------------------------------------------------------------- with JuPedSim


@pytest.mark.requires("jupedsim")
def test_the_parameters_are_jupedsims_own():
    import inspect

    import jupedsim as jps

    for model, where in MODEL_PARAMETERS.items():
        model_class, agent_class = (getattr(jps, name) for name in MODELS[model])
        for name, place in where.items():
            if place == "model":
                assert name in {f.name for f in dataclasses.fields(model_class)}, (model, name)
            else:
                assert name in inspect.signature(agent_class).parameters, (model, name)


@pytest.mark.requires("jupedsim")
def test_the_agents_get_their_time_gap():
    from meanfield.crowds._jupedsim_api import JuPedSimAdapter

    room = Domain.box(10.0, 10.0)
    for model in ("collision-free-speed", "collision-free-speed-v3", "anticipation-velocity"):
        ad = JuPedSimAdapter(room.to_shapely(), model, 0.05, parameters={"time_gap": 0.5})
        ad.add_agents(np.array([[2.0, 2.0], [5.0, 5.0]]), 0.15, 1.0)
        assert [state.time_gap for state in ad._states] == [0.5, 0.5]


@pytest.mark.requires("jupedsim")
def test_the_walls_repulsion_reaches_the_model():
    """A body walking 0.5 m beside a wall: JuPedSim's default range (0.02 m) leaves it there; a range of 1 m
    (set on the collision-free speed model's class) turns it away from the wall."""
    from meanfield.crowds._jupedsim_api import JuPedSimAdapter

    room = Domain.box(20.0, 20.0)
    heights = []
    for parameters in ({}, {"range_geometry_repulsion": 1.0}):
        ad = JuPedSimAdapter(room.to_shapely(), "collision-free-speed", 0.05, parameters=parameters)
        ad.add_agents(np.array([[1.0, 0.5]]), 0.2, 1.0)
        ad.steer(np.array([[19.0, 0.5]]), np.array([1.0]))
        ad.iterate(40)  # 2 s
        heights.append(ad.positions()[0, 1])
    assert heights[0] == pytest.approx(0.5, abs=1e-4) and heights[1] > 0.8


@pytest.mark.requires("jupedsim")
def test_a_run_records_the_parameters_it_used():
    from meanfield.simulation.loop import ClosedLoop

    sc = _bodies({"crowd.options.jupedsim.time_gap": 0.8, "t_final": 0.5, "crowd.n": 20})
    s = ClosedLoop(sc).run(progress=False).summary
    assert s["pedestrian_parameters"] == {"time_gap": 0.8, "strength_neighbor_repulsion": 5.0}
