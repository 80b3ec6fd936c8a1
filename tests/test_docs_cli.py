"""``docs/cli.md`` says what the code does (issue 41, item 4): every command's flags are documented in its section,
every flag a section's usage line or flag table names exists, and every scenario field of the tables exists, and the
reverse.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from meanfield.cli.app import _build_parser
from meanfield.scenarios.scenario import Scenario
from meanfield.scenarios.sections import SECTIONS

DOC = (Path(__file__).resolve().parents[1] / "docs" / "cli.md").read_text(encoding="utf-8")
COMMON = {"--allow-plugins", "--plugin"}
"""Flags every command takes, documented once (the page's introduction and ``meanfield run``'s table)."""
FLAG = r"(?<![\w-])(--[a-z][a-z0-9-]*)"


def _commands() -> dict[str, set[str]]:
    parser = _build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return {
        name: {o for a in p._actions for o in a.option_strings if o.startswith("--")} - {"--help"}
        for name, p in sub.choices.items()
    }


def _sections() -> dict[str, str]:
    out = {}
    for part in re.split(r"^## ", DOC, flags=re.M)[1:]:
        m = re.match(r"`meanfield (\w+)", part)
        if m:
            out[m.group(1)] = part
    return out


def _named(section: str) -> set[str]:
    """The flags a section names as its own: in its usage block and in the first cell of its flag tables."""
    usage = re.findall(r"```text\n(.*?)```", section, flags=re.S)
    rows = re.findall(r"^\| `(--[^`]*)`", section, flags=re.M)
    return set(re.findall(FLAG, " ".join(usage + rows)))


def _table_keys(heading: str) -> set[str]:
    part = DOC.split(heading, 1)[1].split("\n### ", 1)[0].split("\n## ", 1)[0]
    keys = set()
    for cell in re.findall(r"^\| (`[^|]*`) \|", part, flags=re.M):
        keys |= {k.strip("[]") for k in re.findall(r"`([^`]*)`", cell)}
    return keys - {"Key"}


@pytest.mark.parametrize("command", sorted(_commands()))
def test_every_flag_of_a_command_is_documented_in_its_section(command):
    sections = _sections()
    assert command in sections, f"docs/cli.md has no section '## `meanfield {command}`'"
    mentioned = set(re.findall(FLAG, sections[command]))
    assert _commands()[command] - COMMON <= mentioned, sorted(_commands()[command] - COMMON - mentioned)


@pytest.mark.parametrize("command", sorted(_sections()))
def test_every_flag_a_section_names_exists(command):
    flags = _commands().get(command)
    assert flags is not None, f"docs/cli.md documents `meanfield {command}`, which is no command"
    assert _named(_sections()[command]) <= flags, sorted(_named(_sections()[command]) - flags)


def test_the_common_flags_are_documented():
    assert all(f"`{flag}" in _sections()["run"] for flag in COMMON)
    assert all(COMMON <= flags for flags in _commands().values())


def test_the_top_level_fields_are_the_scenario_s():
    fields = {f.name for f in dataclasses.fields(Scenario)} - set(SECTIONS) - {"domain"}
    assert _table_keys("### Top level") == fields


@pytest.mark.parametrize("section", sorted(SECTIONS))
def test_each_section_s_fields_are_documented_and_exist(section):
    fields = {f.name for f in dataclasses.fields(SECTIONS[section])}
    documented = _table_keys(f"### `[{section}]`")
    if f"### `[{section}.options" in DOC:  # (a section's options have a heading of their own)
        documented |= {"options"}
    assert documented == fields
