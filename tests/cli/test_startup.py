"""Start-up stays light: ``import meanfield`` and ``meanfield --help`` import no heavy library (issue 16, item 8).

The times themselves are measured by ``meanfield bench --only startup`` (goal: 0.5 s each);
this test checks the mechanism, which does not depend on the machine's speed.
"""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("scipy", "xarray", "dask", "distributed", "cvxpy", "casadi", "matplotlib", "shapely", "ot", "h5netcdf")


def _modules_after(code: str) -> set[str]:
    probe = f"{code}\nimport sys\nprint(' '.join(sorted(m.split('.')[0] for m in sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_import_meanfield_and_its_packages_imports_no_heavy_library():
    loaded = _modules_after("import meanfield, analysis, verification")
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


def test_the_help_of_every_command_imports_no_heavy_library():
    code = (
        "import contextlib, io\n"
        "from meanfield.cli.app import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        "        main(['--help'])\n"
        "    except SystemExit:\n"
        "        pass"
    )
    loaded = _modules_after(code)
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


def test_a_name_of_the_namespace_is_imported_on_first_use():
    code = "import meanfield\nassert 'meanfield.simulation.loop' not in __import__('sys').modules\nrun = meanfield.run"
    loaded = _modules_after(code)
    assert "scipy" in loaded  # reading meanfield.run imported the loop and what it needs
