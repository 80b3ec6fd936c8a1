"""A scenario file runs no code unless the command line asks (issue "Nothing lost", item 9).

``plugins = [...]`` in a scenario file is refused (exit 2, naming ``plugins`` and how to allow it)
before any of its modules is imported; ``--allow-plugins`` imports them; ``--plugin FILE_OR_MODULE``
imports a module the user names, and allows a scenario's entry naming that module, no other.
"""

from __future__ import annotations

import pytest

from meanfield import plugins
from meanfield.cli.app import main

TINY = """\
t_final = 0.05
dt = 0.01
record_every = 5
[crowd]
n = 40
[robots]
n = 4
[grid]
cells = [12, 12]
"""

CONTROLLER = "cli-plugin-signs"


@pytest.fixture
def plugin(tmp_path):
    """A module that registers a controller and leaves a marker file when it is imported (its code ran);
    ``(module, marker)``.  Each test's module has its own path, hence its own import."""
    module = tmp_path / "signs_plugin.py"
    module.write_text(
        "from pathlib import Path\n"
        "from meanfield import plugins\n"
        "from meanfield.controllers.static_signs import StaticSigns\n"
        "Path(__file__).with_suffix('.imported').write_text('ran')\n"
        f"plugins.register('controller', {CONTROLLER!r}, StaticSigns.from_parts)\n"
    )
    yield module, module.with_suffix(".imported")
    plugins.unregister("controller", CONTROLLER)


@pytest.fixture
def listing(tmp_path, plugin):
    """A scenario file that lists the plugin (a path relative to the file) and names its controller."""
    path = tmp_path / "shared.toml"
    path.write_text(f'plugins = ["{plugin[0].name}"]\n' + TINY + f'[controller]\nkind = "{CONTROLLER}"\n')
    return path


def _run(scenario, out, *extra):
    return main(["run", str(scenario), "--out", str(out), "--quiet", "--no-figures", *extra])


@pytest.mark.parametrize(
    "command",
    [
        ["run", "{scenario}", "--out", "{out}", "--quiet", "--no-figures"],
        ["compare", "{scenario}", "--out", "{out}", "--quiet", "--no-figures", "--n-agents", "10"],
        ["sweep", "{scenario}", "--out", "{out}", "--quiet", "--set", "robots.n=4"],
        ["study", "controllers", "{scenario}", "--out", "{out}", "--quiet", "--seeds", "1"],
        ["scenario", "{scenario}"],
    ],
    ids=lambda c: c[0],
)
def test_every_command_refuses_a_scenario_file_that_lists_plugins_and_imports_nothing(
    command, listing, plugin, tmp_path, capsys
):
    out = tmp_path / "out"
    argv = [a.format(scenario=listing, out=out) for a in command]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "invalid plugins" in err and "--allow-plugins" in err and "--plugin" in err
    assert not plugin[1].exists()  # the module's code did not run
    assert not out.exists()  # refused before anything ran


def test_allow_plugins_runs_the_scenario_with_the_part_its_module_registers(listing, plugin, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(listing, out, "--allow-plugins") == 0
    assert plugin[1].exists()
    saved = (out / "scenario.toml").read_text()
    assert str(plugin[0]) in saved and CONTROLLER in saved  # the saved scenario lists it (absolute path)
    # and the saved scenario is a shared file like any other: refused again without the flag
    assert _run(out / "scenario.toml", tmp_path / "again") == 2
    assert "invalid plugins" in capsys.readouterr().err


def test_plugin_imports_a_module_named_on_the_command_line(plugin, tmp_path):
    module, marker = plugin
    scenario = tmp_path / "plain.toml"
    scenario.write_text(TINY + f'[controller]\nkind = "{CONTROLLER}"\n')  # names the part, lists no module
    assert _run(scenario, tmp_path / "refused") == 2  # the controller is not registered without it
    assert not marker.exists()
    assert _run(scenario, tmp_path / "out", "--plugin", str(module)) == 0
    assert marker.exists()


def test_plugin_allows_the_scenario_entry_naming_that_module_and_no_other(listing, plugin, tmp_path, capsys):
    other = tmp_path / "other_plugin.py"
    other.write_text("from pathlib import Path\nPath(__file__).with_suffix('.imported').write_text('ran')\n")
    assert _run(listing, tmp_path / "wrong", "--plugin", str(other)) == 2  # another module: nothing else implied
    assert "invalid plugins" in capsys.readouterr().err and not plugin[1].exists()
    assert _run(listing, tmp_path / "out", "--plugin", str(plugin[0])) == 0
    assert plugin[1].exists()


def test_a_plugin_that_cannot_be_imported_exits_2_naming_the_flag(tmp_path, capsys):
    status = _run("paper", tmp_path / "out", "--plugin", "meanfield_no_such_plugin_module")
    assert status == 2
    err = capsys.readouterr().err
    assert "--plugin" in err and "meanfield_no_such_plugin_module" in err and not (tmp_path / "out").exists()


def test_set_plugins_on_the_command_line_needs_the_permission_too(plugin, tmp_path, capsys):
    module, marker = plugin
    assert _run("paper", tmp_path / "out", "--set", f'plugins=["{module}"]') == 2
    assert "invalid plugins" in capsys.readouterr().err and not marker.exists()
