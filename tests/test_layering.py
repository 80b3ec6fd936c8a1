"""Package layering (benchmarks → verification → analysis → meanfield, never back) and the plugin mechanism."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from meanfield import ParameterError, plugins
from meanfield.cli import main

ROOT = Path(__file__).resolve().parents[1]
# benchmarks (the `meanfield bench` suite) sits on top: it imports the three packages, none imports it
ABOVE = {
    "meanfield": {"analysis", "verification", "benchmarks"},
    "analysis": {"verification", "benchmarks"},
    "verification": {"benchmarks"},
}


def _imported_packages(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module.split(".")[0])
    return out


@pytest.mark.parametrize("package", sorted(ABOVE))
def test_no_module_imports_a_package_above_it(package):
    files = sorted((ROOT / package).rglob("*.py"))
    assert files
    bad = {f.name: _imported_packages(f) & ABOVE[package] for f in files}
    assert not {k: v for k, v in bad.items() if v}


def test_analysis_registers_its_plugins():
    assert "bounded" in plugins.available("beta_gamma")
    assert "nmpc" in plugins.available("controller")
    assert "analyze" in plugins.available("command")


def test_unknown_plugin_and_kind_are_refused_by_name():
    with pytest.raises(ParameterError) as exc:
        plugins.load("beta_gamma", "fastest")
    assert exc.value.name == "beta_gamma" and "bounded" in str(exc.value)
    with pytest.raises(ParameterError) as exc:
        plugins.available("solver")
    assert exc.value.name == "kind"


def test_a_broken_command_plugin_does_not_break_the_other_commands(monkeypatch, tmp_path, capsys):
    real = plugins.load

    def broken(kind, name):
        if kind == "command":
            raise ImportError("No module named 'missing_dependency'")
        return real(kind, name)

    monkeypatch.setattr(plugins, "load", broken)
    assert main(["analyze", "paper", "--out", str(tmp_path)]) == 2
    assert "could not be loaded" in capsys.readouterr().err
    assert main(["scenario", "paper"]) == 0
