"""Figures in the units of the field: on SI plans the density is shown in persons/m² (issue "Nothing
lost", item 11), the paper's dimensionless density as a unit-mass density."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import pytest  # noqa: E402

from meanfield import paper_scenario, run  # noqa: E402
from meanfield.plotting.figures import _people, plot_snapshots  # noqa: E402
from meanfield.scenarios.scenario import load_scenario  # noqa: E402


def test_an_si_plan_shows_persons_per_square_metre():
    result = run(load_scenario("l-room").replace(t_final=2.0), progress=False)
    n = result.scenario.crowd.n
    assert _people(result) == n  # the target: the whole crowd
    last = result.dataset.sizes["time"] - 1
    out = float(result.dataset["fraction_evacuated"].values[last])
    assert _people(result, last) == pytest.approx(n * (1 - out))  # the agents' estimate: the people inside
    fig = plot_snapshots(result)
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert any("persons/m²" in label for label in labels)


def test_the_paper_s_density_stays_a_unit_mass_density():
    result = run(paper_scenario(seed=0).replace(t_final=0.05), progress=False)
    assert _people(result) == 1.0
    fig = plot_snapshots(result)
    assert any("1/room width²" in ax.get_ylabel() for ax in fig.axes)
