"""Shared helpers for the test suite: small grids and smooth positive densities."""

from __future__ import annotations

import importlib.abc
import os
import sys

import matplotlib
import numpy as np
import pytest
from hypothesis import Phase, settings

from meanfield import Domain, Grid
from tests.optional import OPTIONAL, missing

matplotlib.use("Agg")

# ---------------------------------------------------------------------- optional dependencies
# A test that needs JuPedSim, PedPy or the CF checker carries @pytest.mark.requires(name) (tests/optional.py) and
# skips, naming the install command, where that dependency is missing. Every other test runs with those modules
# hidden, as on a machine with only what the README's test command installs; one that reaches for a hidden module
# and then fails or skips is reported as a failure naming the marker it lacks. So the suite checks its own marks
# wherever it runs, with the extras installed or without.


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"requires(name): the test needs an optional dependency, one of {sorted(OPTIONAL)} (tests/optional.py)",
    )
    for name in OPTIONAL:
        missing(name)  # tried (and cached) now, before any test hides the modules


def _required(item: pytest.Item) -> set[str]:
    return {name for mark in item.iter_markers("requires") for name in mark.args}


def pytest_runtest_setup(item: pytest.Item) -> None:
    for name in sorted(_required(item)):
        reason = missing(name)
        if reason is not None:
            pytest.skip(reason)


_ASKED = pytest.StashKey[set]()


class _HiddenModules(importlib.abc.MetaPathFinder):
    """Refuses to import the hidden top-level modules and remembers which were asked for."""

    def __init__(self, names: set[str]) -> None:
        self.names = names
        self.asked: set[str] = set()

    def find_spec(self, fullname, path, target=None):  # noqa: ANN001, ANN201 (importlib's signature)
        top = fullname.partition(".")[0]
        if top in self.names:
            self.asked.add(top)
            raise ModuleNotFoundError(f"No module named {fullname!r} (hidden from tests without requires({top!r}))",
                                      name=fullname)  # fmt: skip
        return None


@pytest.fixture(autouse=True)
def _optional_dependencies_hidden(request: pytest.FixtureRequest):
    """Hide each optional module the test does not declare (``sys.modules`` and the import system alike)."""
    hidden = {OPTIONAL[name][0].partition(".")[0] for name in OPTIONAL} - {
        OPTIONAL[name][0].partition(".")[0] for name in _required(request.node)
    }
    saved = {key: sys.modules.pop(key) for key in list(sys.modules) if key.partition(".")[0] in hidden}
    finder = _HiddenModules(hidden)
    sys.meta_path.insert(0, finder)
    request.node.stash[_ASKED] = finder.asked
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        for key in [key for key in sys.modules if key.partition(".")[0] in hidden]:
            del sys.modules[key]  # half-imported leftovers of a refused import
        sys.modules.update(saved)


@pytest.fixture(autouse=True)
def _thread_settings_kept():
    """A test leaves the run's BLAS threads (``MEANFIELD_BLAS_THREADS``) and numba's thread count as it found them: a
    test that ran ``meanfield run --threads 2`` in this process once left the variable set, and every later run's
    small products ran on two BLAS threads (RiMEA 12's runs 5x slower; found 2026-12-07).  A leak is put back and
    reported as the test's error."""
    variable = "MEANFIELD_BLAS_THREADS"
    before = os.environ.get(variable)
    numba = sys.modules.get("numba")
    threads = numba.get_num_threads() if numba is not None else None
    yield
    leaks = []
    if os.environ.get(variable) != before:
        leaks.append(f"{variable}={os.environ.get(variable)!r} (was {before!r})")
        if before is None:
            del os.environ[variable]
        else:
            os.environ[variable] = before
    if threads is not None and numba.get_num_threads() != threads:
        leaks.append(f"numba's threads {numba.get_num_threads()} (was {threads})")
        numba.set_num_threads(threads)
    if leaks:
        pytest.fail(f"the test left {', '.join(leaks)}: restore it (monkeypatch, or try/finally)")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    asked = item.stash.get(_ASKED, set())
    if asked and report.when in ("setup", "call") and report.outcome in ("failed", "skipped"):
        names = sorted(name for name in OPTIONAL if OPTIONAL[name][0].partition(".")[0] in asked)
        what = report.outcome
        report.outcome = "failed"
        report.longrepr = (
            f"{item.nodeid} reached for {', '.join(names)} and {what} "
            f"without it: mark it {' '.join(f'@pytest.mark.requires({n!r})' for n in names)} (tests/optional.py), "
            f"so that it skips naming the install command where it is missing.\n\nThe test's own report:\n"
            f"{report.longrepr}"
        )

# ---------------------------------------------------------------------- hypothesis profiles
# Select with HYPOTHESIS_PROFILE (default "ci"); a decorator's own settings (e.g. an explicit
# max_examples) still take precedence over the profile.
#   ci       deterministic (derandomize, no example database); tests/verification/test_properties.py
#            takes ~15 s on 2 cores
#   dev      more examples, random seeds; the local example database replays failures
#   release  10x ci, random seeds: the broad search before a release (a few minutes)
#   mutation ci without shrinking: verification.mutation only asks *whether* a test fails
settings.register_profile("ci", max_examples=200, derandomize=True, database=None, deadline=None, print_blob=True)
settings.register_profile("dev", max_examples=500, deadline=None, print_blob=True)
settings.register_profile("release", max_examples=2000, deadline=None, print_blob=True)
settings.register_profile(
    "mutation", parent=settings.get_profile("ci"), phases=(Phase.explicit, Phase.reuse, Phase.generate)
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# A convex pentagon used wherever a polygon domain is needed (counter-clockwise).
PENTAGON = [(0.0, 0.0), (1.0, -0.1), (1.3, 0.6), (0.6, 1.1), (-0.2, 0.7)]


def smooth_density(grid: Grid, floor: float = 0.05) -> np.ndarray:
    """A smooth, strictly positive density of unit mass: two Gaussian bumps plus a floor."""
    X, Y = grid.centers
    x0, x1, y0, y1 = grid.domain.bounds
    w, h = x1 - x0, y1 - y0
    f = (
        floor
        + np.exp(-((X - x0 - 0.3 * w) ** 2 + (Y - y0 - 0.35 * h) ** 2) / (2 * (0.15 * w) ** 2))
        + 0.6 * np.exp(-((X - x0 - 0.7 * w) ** 2 + (Y - y0 - 0.6 * h) ** 2) / (2 * (0.2 * w) ** 2))
    )
    return f / grid.integrate(f)


def lyapunov_v2(ctrl, kernel, rho, positions, headings) -> float:
    """``V₂ = ½‖ρ − ρ_*‖² + ½‖v_r − v_d‖²`` on ``ctrl``'s grid (complex arguments allowed, for complex steps)."""
    from meanfield import NavigationField

    g = ctrl.grid
    v_r = NavigationField(kernel, g, positions, headings).velocity()
    v_d = ctrl.virtual_velocity(rho)
    vt = (v_r[0] - v_d[0], v_r[1] - v_d[1])
    rt = rho - ctrl.target
    return 0.5 * g.inner(rt, rt) + 0.5 * g.face_inner(vt, vt)


def all_domains() -> list[Domain]:
    """One domain of each shape: an offset box, a disk and a convex pentagon."""
    return [
        Domain.box(1.1, 0.9, origin=(-0.3, 0.7)),
        Domain.disk(0.8, center=(0.2, -0.1)),
        Domain.polygon(PENTAGON),
    ]


@pytest.fixture(params=["box", "disk", "polygon"])
def domain(request) -> Domain:
    """Each domain shape in turn."""
    return dict(zip(["box", "disk", "polygon"], all_domains(), strict=True))[request.param]


@pytest.fixture
def rng() -> np.random.Generator:
    """A fixed-seed generator (tests are deterministic)."""
    return np.random.default_rng(20240611)
