"""The CF checker (cfchecker, the reference checker of cfconventions.org) passes on ``timeseries.nc``
(issue 33, item 10).

The checker reads the CF standard-name, area-type and region tables from cfconventions.org; offline
(as here and in CI) it is given empty tables of the same format.  ``timeseries.nc`` uses no
``standard_name``, ``area_type`` or region, so the tables' entries are never consulted: every other
rule of the conventions (units UDUNITS can read, flags, coordinates, the ``Conventions``
attribute, ...) is checked in full.  Skipped, with the reason, where ``cfchecker`` or the udunits2
C library it needs is not installed (``tests/optional.py``; ``.ci/run`` installs both).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from meanfield.cli.app import main
from tests.optional import load

pytestmark = pytest.mark.requires("cfchecker")

_TABLES = {
    "cfStandardNamesXML": (
        "standard_name_table",
        "<version_number>offline</version_number><last_modified>none</last_modified>",
    ),
    "cfAreaTypesXML": ("area_type_table", "<version_number>offline</version_number><date>none</date>"),
    "cfRegionNamesXML": ("standardized_region_list", "<version_number>offline</version_number><date>none</date>"),
}


def _checker_module() -> Any:
    return load("cfchecker")  # skips naming the install command where the checker or udunits2 is missing


def _check(path: Path, tables: Path) -> dict[str, list[str]]:
    """The checker's messages on ``path``: ``{"FATAL": [...], "ERROR": [...], "WARN": [...], "INFO": [...]}``."""
    cfchecks = _checker_module()
    tables.mkdir(exist_ok=True)
    kwargs = {}
    for key, (root, body) in _TABLES.items():
        xml = tables / f"{root}.xml"
        xml.write_text(f'<?xml version="1.0"?>\n<{root}>{body}</{root}>\n')
        kwargs[key] = str(xml)
    checker = cfchecks.CFChecker(silent=True, **kwargs)
    results = checker.checker(str(path))
    out: dict[str, list[str]] = {cat: list(results["global"][cat]) for cat in ("FATAL", "ERROR", "WARN", "INFO")}
    for name, per_var in results["variables"].items():
        for cat in out:
            out[cat] += [f"{name}: {m}" for m in per_var[cat]]
    return out


@pytest.mark.parametrize(
    "argv",
    [
        ["paper", "--set", "t_final=0.2"],  # dimensionless: units "1"
        ["l-room", "--set", "t_final=0.5"],  # SI, a plan with exits: metres, seconds, fraction_evacuated
        ["paper", "--set", "t_final=0.2", "--set", "crowd.kind=fokker-planck"],  # the density: no humans
    ],
    ids=["paper", "l-room", "fokker-planck"],
)
def test_the_cf_checker_finds_no_error_and_no_warning_in_a_saved_run(tmp_path, argv):
    _checker_module()  # skip before running anything when the checker is missing
    out = tmp_path / "run"
    assert main(["run", *argv, "--out", str(out), "--quiet", "--no-figures"]) == 0
    found = _check(out / "timeseries.nc", tmp_path / "tables")
    assert found["FATAL"] == [] and found["ERROR"] == [], found
    assert found["WARN"] == [], found
    # what it still says: V2, A and the shortfalls have no single unit (their comment says why)
    assert sorted(m.split(":")[0] for m in found["INFO"]) == ["A", "V2", "shortfall", "shortfall_applied"]


def test_the_checker_catches_what_the_writer_avoids(tmp_path):
    """The harness can fail: a unit UDUNITS cannot read, flag values of another type than the flag, a coordinate without
    units and an unknown CF version are each reported."""
    from meanfield import paper_scenario, run

    _checker_module()
    ds = run(paper_scenario(seed=0).replace(t_final=0.05), progress=False).dataset
    bad = ds.copy(deep=True)
    bad["density"].attrs["units"] = "persons per furlong"
    bad["saturated"].attrs["flag_values"] = [0.0, 1.0]  # not of the flag's type
    bad["robot"].attrs.pop("units")
    bad.attrs["Conventions"] = "CF-9.9"
    path = tmp_path / "bad.nc"
    bad.to_netcdf(path, engine="h5netcdf")
    found = _check(path, tmp_path / "tables")
    text = "\n".join(found["ERROR"] + found["WARN"])
    assert "density:" in text and "saturated:" in text and "robot:" in text
    assert "does not appear to contain CF Convention data" in text
    good = tmp_path / "good.nc"  # the same run unchanged: nothing to report
    ds.to_netcdf(good, engine="h5netcdf")
    assert _check(good, tmp_path / "tables")["ERROR"] == []
