"""Fields of earlier releases: the ``[pedestrians]`` table still works for one release, with a warning
naming the new fields (``crowd.kind``, ``[crowd.options.jupedsim]``); old and new together are refused."""

from __future__ import annotations

import pytest

from meanfield import ParameterError, paper_scenario
from meanfield.errors import MeanfieldDeprecationWarning
from meanfield.scenarios.scenario import Scenario, load_scenario, paper_unity_scenario


def test_the_old_pedestrians_table_is_read_as_the_new_fields_with_a_warning():
    new = paper_unity_scenario(seed=2).with_values({"crowd.kind": "jupedsim", "crowd.options.jupedsim.radius": 0.25})
    old = new.to_dict()
    old["pedestrians"] = {"backend": "jupedsim", **old["crowd"].pop("options")["jupedsim"]}
    del old["crowd"]["kind"]
    with pytest.warns(MeanfieldDeprecationWarning, match=r"pedestrians\.radius -> crowd\.options\.jupedsim\.radius"):
        read = Scenario.from_dict(old)
    assert read == new and read.to_toml() == new.to_toml()


def test_an_old_dotted_key_sets_the_new_field_with_a_warning():
    sc = paper_unity_scenario()
    said = "pedestrians.backend is deprecated and removed in 0.3.0: use crowd.kind"
    with pytest.warns(MeanfieldDeprecationWarning, match=said):
        got = sc.with_values({"pedestrians.backend": "jupedsim"})
    assert got.crowd.kind == "jupedsim" and got == sc.with_values({"crowd.kind": "jupedsim"})
    with pytest.warns(MeanfieldDeprecationWarning, match="crowd.options.jupedsim.time_step"):
        got = sc.with_values({"pedestrians.time_step": 0.125})
    assert got.crowd.options["jupedsim"]["time_step"] == 0.125


def test_old_and_new_field_together_are_refused_naming_both():
    with pytest.raises(ParameterError) as exc:
        paper_unity_scenario().with_values({"pedestrians.backend": "jupedsim", "crowd.kind": "point-mass"})
    assert exc.value.name == "pedestrians.backend" and "crowd.kind" in str(exc.value)
    d = paper_unity_scenario().to_dict()
    d["pedestrians"] = {"radius": 0.3}  # crowd.options.jupedsim.radius is set by paper-unity itself
    with pytest.raises(ParameterError) as exc:
        Scenario.from_dict(d)
    assert exc.value.name == "pedestrians.radius" and "crowd.options.jupedsim.radius" in str(exc.value)


def test_the_old_attribute_reads_the_new_fields_with_a_warning():
    sc = load_scenario("paper-unity").with_values({"crowd.kind": "jupedsim"})
    with pytest.warns(MeanfieldDeprecationWarning, match="Scenario.crowd.kind"):
        ped = sc.pedestrians
    assert (ped.backend, ped.radius, ped.time_step, ped.model) == ("jupedsim", 0.2, 0.05, "collision-free-speed")


def test_a_crowd_with_no_options_refuses_a_table_of_options():
    with pytest.raises(ParameterError) as exc:
        paper_scenario().with_values({"crowd.options.point-mass.radius": 1.0})
    assert exc.value.name == "crowd.options.point-mass" and "takes none" in str(exc.value)
