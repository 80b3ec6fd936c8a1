"""The mutation demo (verification.mutation): its mutations still match the sources, and a
mutation changes exactly one file of a copy, never the real tree.

The end-to-end run (pytest in a sandbox) is slow; it runs only with
``MEANFIELD_MUTATION_E2E=1``.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from verification.mutation import (
    COPIED_PACKAGES,
    MUTATIONS,
    Mutation,
    MutationError,
    apply_mutation,
    copy_project,
    count_occurrences,
    markdown_table,
    repo_root,
    run_demo,
)


def _digests(root: Path) -> dict[str, str]:
    out = {}
    for name in COPIED_PACKAGES:
        for p in sorted((root / name).rglob("*")):
            if p.is_file() and "__pycache__" not in p.parts:
                out[str(p.relative_to(root))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


@pytest.fixture(scope="module")
def project_copy(tmp_path_factory) -> Path:
    return copy_project(tmp_path_factory.mktemp("mutation") / "project")


def test_mutation_names_are_unique_and_changes_are_real():
    names = [m.name for m in MUTATIONS]
    assert len(names) == len(set(names))
    assert all(m.old != m.new for m in MUTATIONS)
    assert {m.path.split("/")[0] for m in MUTATIONS} <= set(COPIED_PACKAGES)


@pytest.mark.parametrize("mutation", MUTATIONS, ids=lambda m: m.name)
def test_every_mutation_matches_the_current_source_exactly_once(mutation: Mutation):
    """A stale mutation (its text edited away or duplicated) would silently test nothing."""
    assert count_occurrences(mutation, repo_root()) == 1, mutation.old


@pytest.mark.parametrize("mutation", MUTATIONS, ids=lambda m: m.name)
def test_applying_a_mutation_changes_exactly_that_file_of_the_copy(mutation: Mutation, tmp_path):
    root = copy_project(tmp_path / "project")
    before = _digests(root)
    real_before = (repo_root() / mutation.path).read_bytes()
    changed = apply_mutation(mutation, root)
    after = _digests(root)
    assert changed == root / mutation.path
    assert [k for k in before if before[k] != after[k]] == [mutation.path]
    assert before.keys() == after.keys()
    text = changed.read_text(encoding="utf-8")
    assert text == real_before.decode("utf-8").replace(mutation.old, mutation.new)
    assert (repo_root() / mutation.path).read_bytes() == real_before  # the real tree is untouched


def test_a_mutation_that_does_not_match_exactly_once_is_refused(project_copy):
    missing = Mutation("x", "", "meanfield/controllers/backstepping.py", "this text is not in the file", "y", "")
    with pytest.raises(MutationError, match="0 times"):
        apply_mutation(missing, project_copy)
    twice = Mutation("x", "", "meanfield/controllers/backstepping.py", "import", "y", "")
    with pytest.raises(MutationError, match="expected exactly once"):
        apply_mutation(twice, project_copy)


def test_the_real_tree_is_never_mutated():
    with pytest.raises(MutationError, match="refusing"):
        apply_mutation(MUTATIONS[0], repo_root())


def test_markdown_table_lists_the_baseline_and_every_run():
    run = {"status": "failed", "failed_tests": ["tests/test_a.py::test_b[1]"], "caught": True}
    report = {
        "baseline": {"status": "passed", "failed_tests": []},
        "mutations": [
            {"name": "m1", "description": "d1", "file": "meanfield/controllers/backstepping.py", **run},
            {"name": "m2", "description": "d2", "file": "meanfield/controllers/backstepping.py", "status": "passed",
             "failed_tests": [], "caught": False},
        ],
    }  # fmt: skip
    table = markdown_table(report).splitlines()
    assert len(table) == 2 + 3
    assert "baseline" in table[2] and "passed" in table[2]
    assert "`test_a::test_b[1]`" in table[3] and "| yes |" in table[3]
    assert "**NO**" in table[4] and "**none**" in table[4]


@pytest.mark.skipif(os.environ.get("MEANFIELD_MUTATION_E2E") != "1", reason="slow: set MEANFIELD_MUTATION_E2E=1")
def test_end_to_end_one_mutation_is_caught():
    """The baseline passes in the sandbox and flipping the sign of u_i fails the Theorem-3 tests."""
    u_sign = next(m for m in MUTATIONS if m.name == "u-sign")
    tests = ["tests/controllers/test_backstepping.py"]
    report = run_demo([u_sign], tests, progress=False)
    assert report["baseline"]["status"] == "passed"
    assert report["baseline"]["imported_from"]["meanfield"] != str(repo_root() / "meanfield" / "__init__.py")
    (run,) = report["mutations"]
    assert run["caught"]
    assert any("test_lyapunov_identity_semi_discrete" in t for t in run["failed_tests"])
