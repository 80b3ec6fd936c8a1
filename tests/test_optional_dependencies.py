"""The suite's marks for optional dependencies (``tests/optional.py``) check themselves.

A machine with only what the README's test command installs has no JuPedSim, PedPy or udunits2. A test that needs
one carries ``@pytest.mark.requires(name)`` and skips there, naming the install command; every other test runs with
those modules hidden, so one that reaches for a hidden module and fails or skips is reported as a failure naming the
marker it lacks, wherever the suite runs. Here a small suite with that conftest is run in a subprocess, once with
each kind of test, and its outcomes are read.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from tests.optional import OPTIONAL, missing

ROOT = Path(__file__).resolve().parents[1]

CONFTEST = """
from tests.conftest import (  # noqa: F401
    _optional_dependencies_hidden,
    pytest_configure,
    pytest_runtest_makereport,
    pytest_runtest_setup,
)
"""

TESTS = '''
import pytest


def test_unmarked_import():
    import pedpy  # noqa: F401


def test_unmarked_importorskip():
    pytest.importorskip("jupedsim")


def test_unmarked_that_copes_without_it():
    try:
        import jupedsim  # noqa: F401
    except ImportError:
        pass


@pytest.mark.requires("pedpy")
def test_marked_import():
    import pedpy  # noqa: F401


@pytest.mark.requires("cfchecker")
def test_marked_checker():
    from cfchecker import cfchecks  # noqa: F401


def test_plain():
    assert 1 + 1 == 2
'''


def _outcomes(tmp_path: Path) -> tuple[dict[str, str], str]:
    (tmp_path / "conftest.py").write_text(CONFTEST)
    (tmp_path / "test_inner.py").write_text(TESTS)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-v", "-rfs", "-p", "no:cacheprovider", "test_inner.py"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    lines = re.findall(r"^test_inner\.py::(\w+) (PASSED|FAILED|SKIPPED|ERROR)", proc.stdout, flags=re.M)
    outcomes = {name: word.lower() for name, word in lines}
    return outcomes, proc.stdout


def test_unmarked_tests_that_need_an_optional_module_fail_naming_the_marker(tmp_path):
    outcomes, out = _outcomes(tmp_path)
    assert outcomes["test_unmarked_import"] == "failed", out
    assert outcomes["test_unmarked_importorskip"] == "failed", out  # a skip is not enough: it would never run
    assert "mark it @pytest.mark.requires('pedpy')" in out and "mark it @pytest.mark.requires('jupedsim')" in out
    assert outcomes["test_unmarked_that_copes_without_it"] == "passed", out
    assert outcomes["test_plain"] == "passed", out


def test_marked_tests_run_where_the_module_is_usable_and_skip_naming_the_command_where_not(tmp_path):
    outcomes, out = _outcomes(tmp_path)
    for test, name in (("test_marked_import", "pedpy"), ("test_marked_checker", "cfchecker")):
        if missing(name) is None:
            assert outcomes[test] == "passed", out
        else:
            assert outcomes[test] == "skipped", out
            assert OPTIONAL[name][1] in out  # the install command is in the skip's reason


def test_requires_refuses_an_unknown_name():
    try:
        missing("pandas")
    except ValueError as exc:
        assert "requires('pandas')" in str(exc) and "jupedsim" in str(exc)
    else:
        raise AssertionError("requires('pandas') was accepted")
