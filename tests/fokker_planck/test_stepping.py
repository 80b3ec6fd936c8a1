"""The Fokker–Planck solver's time-stepping methods (meanfield.fokker_planck.stepping), one class each.

* the registry ``STEPPERS`` names every method, in the order of ``METHODS`` and of the
  ``method`` annotation, and each class knows its own name;
* ``FokkerPlanck`` holds the stepper its ``method`` names (the default: ``"adi"`` on a box,
  ``"split"`` on a disk), composes it rather than inheriting the time stepping, and
  swapping ``method`` swaps the stepper, with the constructor's checks;
* each stepper's positivity bound and automatic bound are what the solver reports, and
  its step is the solver's step.
"""

from __future__ import annotations

import math
import typing

import numpy as np
import pytest

import meanfield.fokker_planck as fp_package
from meanfield import Domain, FokkerPlanck, Grid
from meanfield.errors import ParameterError
from meanfield.fokker_planck.solver import METHODS, Method
from meanfield.fokker_planck.stepping import (
    STEPPERS,
    AdiStepper,
    ExplicitStepper,
    ImplicitStepper,
    SplitStepper,
    Stepper,
)


def _swirl(x, y, t):
    return 0.4 * (0.5 - y) + 0.1 * np.cos(3 * t), 0.4 * (x - 0.45) + 0.2 * np.sin(2 * x)


def _still_swirl(x, y, t):  # for time_dependent=False: the coefficients are those of the first time asked
    return _swirl(x, y, 0.0)


def _box() -> Grid:
    return Grid(Domain.box(1.0, 1.0), (24, 24))


def _rho0(grid: Grid) -> np.ndarray:
    X, Y = grid.centers
    return grid.normalize(np.where(grid.active, 0.2 + np.exp(-((X - 0.3) ** 2 + (Y - 0.25) ** 2) / 0.02), 0.0))


def test_the_registry_names_every_method_in_order():
    assert tuple(STEPPERS) == METHODS == typing.get_args(Method) == ("adi", "split", "explicit", "implicit")
    classes = {"adi": AdiStepper, "split": SplitStepper, "explicit": ExplicitStepper, "implicit": ImplicitStepper}
    assert STEPPERS == classes
    for name, cls in STEPPERS.items():
        assert issubclass(cls, Stepper) and cls.name == name
    assert [name for name, cls in STEPPERS.items() if cls.accepts_courant] == ["adi"]
    for name in ("Stepper", "STEPPERS", "AdiStepper", "SplitStepper", "ExplicitStepper", "ImplicitStepper"):
        assert getattr(fp_package, name) is globals()[name]


@pytest.mark.parametrize("method", METHODS)
def test_the_solver_holds_the_stepper_its_method_names(method):
    fp = FokkerPlanck(_box(), 0.02, _swirl, method=method)
    assert type(fp.stepper) is STEPPERS[method] and fp.stepper.operator is fp
    assert fp.method == method and isinstance(fp.method, str)
    assert not any(issubclass(base, Stepper) for base in type(fp).__mro__)  # composed, not inherited


def test_the_default_method_is_adi_on_a_box_and_split_on_a_disk():
    assert type(FokkerPlanck(_box(), 0.02).stepper) is AdiStepper
    assert type(FokkerPlanck(Grid(Domain.disk(1.0), (24, 24)), 0.02).stepper) is SplitStepper


def test_setting_the_method_swaps_the_stepper_with_the_constructor_s_checks():
    g = _box()
    rho0 = _rho0(g)
    fp = FokkerPlanck(g, 0.02, _swirl, method="adi")
    fp.method = "explicit"
    assert type(fp.stepper) is ExplicitStepper and fp.method == "explicit"
    fresh = FokkerPlanck(g, 0.02, _swirl, method="explicit")
    assert np.array_equal(fp.solve(rho0, 0.05), fresh.solve(rho0, 0.05))
    with pytest.raises(ParameterError) as info:
        fp.method = "rk4"
    assert info.value.name == "method" and "'adi', 'split', 'explicit', 'implicit'" in str(info.value)
    assert fp.method == "explicit"  # unchanged
    accurate = FokkerPlanck(g, 0.02, _swirl, method="adi", courant=2.0)
    with pytest.raises(ParameterError) as info:
        accurate.method = "split"
    assert info.value.name == "courant" and accurate.method == "adi"


@pytest.mark.parametrize("method", METHODS)
def test_the_solver_reports_its_stepper_s_bounds_and_steps(method):
    g = _box()
    rho0 = _rho0(g)
    fp = FokkerPlanck(g, 0.02, _still_swirl, method=method, time_dependent=False)
    c = fp._coefficients(rho0, 0.0, None)
    bound = fp.stepper.positivity_bound(c)
    assert fp.positivity_bound(rho0) == bound
    assert fp.automatic_dt(rho0) == fp.cfl * fp.stepper.automatic_bound(c)
    explicit = c.bound(g, "xy")
    expected = {
        "explicit": explicit,
        "adi": 2.0 * min(c.bound(g, "x"), c.bound(g, "y")),
        "split": math.inf,
        "implicit": math.inf,
    }[method]
    assert bound == expected
    if not math.isfinite(bound):
        assert fp.stepper.automatic_bound(c) == 4.0 * c.bound(g, "xy", typical=True)
    dt = 0.5 * min(bound, 0.02)
    twin = FokkerPlanck(g, 0.02, _still_swirl, method=method, time_dependent=False)
    assert np.array_equal(fp.step(rho0, 0.0, dt), twin.stepper.step(rho0, 0.0, dt, None, check=True))


def test_split_alternates_its_sweeps_from_step_to_step():
    g = _box()
    rho0 = _rho0(g)
    fp = FokkerPlanck(g, 0.02, _swirl, method="split", time_dependent=False)
    first = fp.step(rho0, 0.0, 0.05)
    second = fp.step(rho0, 0.0, 0.05)  # the same step, sweeps in the other order
    third = fp.step(rho0, 0.0, 0.05)
    assert np.array_equal(first, third) and not np.array_equal(first, second)
    assert g.integrate(second) == pytest.approx(g.integrate(first), rel=1e-13)
