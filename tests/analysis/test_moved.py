"""The modules of analysis that moved into its subpackages (analysis._moved): the old paths still import,
until 0.3.0, with a warning naming the new module; the package analysis.nmpc gives the names of the old
module analysis.nmpc without one; the subpackages' namespaces are lazy."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from analysis._moved import MOVED
from meanfield.errors import MeanfieldDeprecationWarning

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    "old, name, new",
    [
        ("analysis.nmpc_qp", "InputQP", "analysis.nmpc.qp"),
        ("analysis.nmpc_model", "CoarseFokkerPlanck", "analysis.nmpc.prediction_model"),
        ("analysis.nmpc_options", "NMPCOptions", "analysis.nmpc.options"),
        ("analysis.pedestrian_metrics", "pedestrian_metrics", "analysis.pedestrians.metrics"),
        ("analysis.pedestrian_cli", "register", "analysis.pedestrians.cli"),
    ],
)
def test_an_old_module_path_works_with_a_warning_naming_the_new_one(old, name, new):
    sys.modules.pop(old, None)  # imported afresh: the module's own warning, then the name's
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = getattr(importlib.import_module(old), name)
    assert value is getattr(importlib.import_module(new), name)
    messages = [str(w.message) for w in caught if issubclass(w.category, MeanfieldDeprecationWarning)]
    assert len(messages) == 2 and all(new in m for m in messages), messages
    said = rf"{re.escape(old)}\.{name} is deprecated and removed in 0\.3\.0: use {re.escape(new)}\.{name}$"
    assert re.search(said, messages[1])
    assert all(w.filename == __file__ for w in caught)  # attributed to the line that imports


def test_importing_an_old_module_warns_naming_the_new_one():
    code = "import analysis.nmpc_qp"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "MeanfieldDeprecationWarning" in out.stderr and "analysis.nmpc.qp" in out.stderr
    assert "<string>:1" in out.stderr  # attributed to the importing line, not to the import machinery


def test_every_old_module_path_resolves_each_of_its_names():
    for old, new in MOVED.items():
        module = importlib.import_module(f"analysis.{new}")
        assert not (ROOT / "analysis" / f"{old}.py").exists(), old
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeanfieldDeprecationWarning)
            moved = importlib.import_module(f"analysis.{old}")
            assert sorted(dir(moved)) == sorted(module.__all__)
            for name in module.__all__:
                assert getattr(moved, name) is getattr(module, name), (old, name)
            with pytest.raises(AttributeError):
                moved.a_name_that_never_existed  # noqa: B018


def test_the_old_module_analysis_nmpc_is_the_package_and_gives_its_names_without_a_warning():
    import analysis.nmpc
    from analysis.nmpc.controller import NMPCController, nmpc_controller_for
    from analysis.nmpc.options import FLUXES, HESSIANS, SOLVERS, NMPCOptions
    from analysis.nmpc.plan import NMPCSolution
    from analysis.nmpc.prediction_model import CoarseFokkerPlanck

    old_names = {
        "FLUXES": FLUXES,
        "HESSIANS": HESSIANS,
        "SOLVERS": SOLVERS,
        "NMPCOptions": NMPCOptions,
        "CoarseFokkerPlanck": CoarseFokkerPlanck,
        "NMPCSolution": NMPCSolution,
        "NMPCController": NMPCController,
        "nmpc_controller_for": nmpc_controller_for,
    }
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name, value in old_names.items():
            assert getattr(analysis.nmpc, name) is value, name
    assert set(old_names) <= set(analysis.nmpc.__all__)


@pytest.mark.parametrize("package", ["analysis.nmpc", "analysis.pedestrians"])
def test_each_name_of_a_subpackage_resolves(package):
    module = importlib.import_module(package)
    assert module.__all__ and set(module.__all__) <= set(dir(module))
    for name in module.__all__:
        assert getattr(module, name) is not None, name
    with pytest.raises(AttributeError):
        module.a_name_that_never_existed  # noqa: B018


def test_the_subpackages_import_their_names_on_first_use():
    code = (
        "import sys, analysis.nmpc, analysis.pedestrians\n"
        "assert 'casadi' not in sys.modules and 'analysis.nmpc.controller' not in sys.modules\n"
        "assert 'matplotlib' not in sys.modules and 'analysis.pedestrians.metrics' not in sys.modules\n"
        "analysis.nmpc.NMPCController\n"
        "assert 'casadi' in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize(
    "module, old, new",
    [
        ("analysis.nmpc", "NMPCPlan", "NMPCSolution"),
        ("analysis.nmpc.plan", "NMPCPlan", "NMPCSolution"),
        ("meanfield.crowds", "BinnedPlan", "BinnedLayout"),
        ("meanfield.crowds.kde", "binned_plan", "binned_layout"),
    ],
)
def test_a_name_that_said_plan_for_what_is_no_floor_plan_reads_as_its_new_name_with_a_dated_warning(module, old, new):
    """"Plan" is a floor plan; the KDE's layout and NMPC's solution were renamed in 0.2.0: the old names give the
    new objects until 0.3.0, with a warning naming the new name and that release."""
    m = importlib.import_module(module)
    with pytest.warns(MeanfieldDeprecationWarning, match=rf"{old} is deprecated and removed in 0\.3\.0: use .*{new}$"):
        value = getattr(m, old)
    assert value is getattr(m, new)
