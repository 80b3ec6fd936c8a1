"""The optional dependencies some tests need, how to tell whether each is usable, and the command that installs it.

A test that needs one says so with ``@pytest.mark.requires("jupedsim")`` (or ``"pedpy"``, ``"cfchecker"``); a
module of such tests sets ``pytestmark``. Where the dependency is missing the test skips, and the reason names the
command that installs it. Every other test runs with the optional modules hidden (``tests/conftest.py``), as on a
machine that has only what the README's test command installs: an unmarked test that reaches for one fails, naming
the marker it lacks, on this machine as on a fresh one.
"""

from __future__ import annotations

import importlib
from functools import cache
from types import ModuleType

import pytest

#: name -> (the module whose import proves it usable, the command that installs it)
OPTIONAL: dict[str, tuple[str, str]] = {
    "jupedsim": (
        "jupedsim",
        'pip install -e ".[pedestrians]" && pip install --no-deps "jupedsim==1.4.2"',
    ),
    "pedpy": ("pedpy", 'pip install -e ".[pedestrians]"'),
    # the peer of the web-app exports' tests (tests/scenarios/test_webapp.py): it runs an export in JuPedSim and reads
    # a run's export back; --no-deps for the reason JuPedSim takes it (its requirement would pull PySide6 and VTK)
    "jupedsim_scenarios": (
        "jupedsim_scenarios",
        'pip install -e ".[pedestrians]" && pip install --no-deps "jupedsim==1.4.2" "jupedsim-scenarios==0.7.4"',
    ),
    # the peer of benchmarks/hughes2d_peer.py (GPL-3.0; also in the bench extra)
    "hughes2d": ("hughes2d", 'pip install "hughes2d==1.1.8"'),
    # cfchecker itself comes with the test extra; importing its checker loads the udunits2 C library
    "cfchecker": ("cfchecker.cfchecks", "apt-get install libudunits2-0"),
}


@cache
def missing(name: str) -> str | None:
    """Why the optional dependency ``name`` cannot be used here (with its install command), or None if it can."""
    if name not in OPTIONAL:
        raise ValueError(f"requires({name!r}): expected one of {sorted(OPTIONAL)}")
    module, command = OPTIONAL[name]
    try:
        importlib.import_module(module)
    except (ImportError, OSError) as exc:  # OSError: a C library the module loads is missing
        return f"{name} is not usable here ({type(exc).__name__}: {exc}); install it with: {command}"
    return None


def load(name: str) -> ModuleType:
    """The optional module ``name`` imported, or the calling test (or module) skipped naming its install command."""
    reason = missing(name)
    if reason is not None:
        pytest.skip(reason, allow_module_level=True)
    return importlib.import_module(OPTIONAL[name][0])
