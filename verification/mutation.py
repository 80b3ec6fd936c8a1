"""Mutation demo: which tests catch a deliberately broken controller or solver.

Each :class:`Mutation` is one textual change ``old -> new`` to one source file, chosen to
break one claim of the paper (the sign of a robot law, the β/γ condition Σβ + γ = 1, the
sign of the Step-I virtual control, ``∂_t v_d`` in ``A``, the solver's drift or mass
balance, ...).  For each mutation the packages ``meanfield/``, ``analysis/``,
``verification/`` and ``tests/`` (and ``pyproject.toml``, for pytest's configuration) are
copied into a fresh temporary directory, the mutation is applied *to the copy* (the
real files are only read), and pytest runs the chosen test files there, with the copy
first on ``sys.path`` and the current directory set to the copy.  The bootstrap checks,
in the very process that runs the tests, that ``meanfield`` and ``analysis`` are imported
from the copy (an editable install of the real tree must not shadow it).  The failing
tests are read from pytest's JUnit XML report.

A baseline run without any mutation comes first and must pass; a mutation is *caught*
when at least one test fails (or errors) under it.

Run::

    python -m verification.mutation [--out FILE.json] [--tests tests/verification/test_properties.py ...]

The hypothesis profile of the runs is ``mutation`` (``tests/conftest.py``: the
deterministic ``ci`` examples without shrinking, since only *whether* a test fails
matters here); ``--profile`` picks another.

The mutations themselves (:class:`Mutation`, :data:`MUTATIONS`, :class:`MutationError`) are
catalogued in :mod:`verification.mutation_catalogue` and re-exported here; this module
holds the sandbox, the runs and the report (``docs/verification.md``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

from verification.mutation_catalogue import MUTATIONS, Mutation, MutationError

__all__ = [
    "COPIED_PACKAGES",
    "DEFAULT_TESTS",
    "MUTATIONS",
    "Mutation",
    "MutationError",
    "RunResult",
    "apply_mutation",
    "copy_project",
    "count_occurrences",
    "main",
    "markdown_table",
    "repo_root",
    "run_demo",
    "run_tests",
]

COPIED_PACKAGES = ("meanfield", "analysis", "verification", "tests")
"""Directories copied into the sandbox (the mutated tree)."""

COPIED_FILES = ("pyproject.toml",)
"""Files copied alongside (pytest reads its configuration from ``pyproject.toml``)."""

DEFAULT_TESTS = ("tests/verification/test_properties.py", "tests/controllers/test_backstepping.py")
"""Test files run against every mutation unless ``--tests`` says otherwise."""

DEFAULT_PROFILE = "mutation"
"""Hypothesis profile of the runs (``tests/conftest.py``)."""

_IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis", ".pytest_cache")


@dataclass
class RunResult:
    """The outcome of one pytest run (the baseline or one mutation).

    Attributes
    ----------
    name, description, file, claim : str or None
        The mutation (``"baseline"`` and None for the unmutated run).
    status : str
        ``"passed"``, ``"failed"`` (some test failed or errored), ``"timeout"`` or
        ``"broken"`` (pytest produced no report).
    caught : bool or None
        Whether a test failed under the mutation (None for the baseline).
    failed_tests : list of str
        Node ids of the failing (or erroring) tests.
    counts : dict
        ``tests``, ``failures``, ``errors``, ``skipped`` from the JUnit report.
    seconds : float
        Wall time of the run.
    returncode : int or None
        pytest's exit code (None on timeout).
    imported_from : dict
        Where the run's process imported ``meanfield`` and ``analysis`` from.
    """

    name: str
    description: str
    file: str | None
    claim: str
    status: str
    caught: bool | None
    failed_tests: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    returncode: int | None = None
    imported_from: dict[str, str] = field(default_factory=dict)


# ---------------------------------------------------------------------- the sandbox
def repo_root() -> Path:
    """The repository root: the directory holding ``verification/``."""
    return Path(__file__).resolve().parents[1]


def count_occurrences(mutation: Mutation, root: Path | str) -> int:
    """How many times ``mutation.old`` occurs in its file under ``root``."""
    return (Path(root) / mutation.path).read_text(encoding="utf-8").count(mutation.old)


def apply_mutation(mutation: Mutation, root: Path | str) -> Path:
    """Apply ``mutation`` to the tree at ``root`` (a copy!) and return the changed file.

    Raises
    ------
    MutationError
        If ``mutation.old`` does not occur exactly once (the source moved on: update the
        mutation), or if ``root`` is the real repository.
    """
    root = Path(root).resolve()
    if root == repo_root():
        raise MutationError(f"refusing to mutate the real tree {root}: apply mutations to a copy")
    target = root / mutation.path
    text = target.read_text(encoding="utf-8")
    n = text.count(mutation.old)
    if n != 1:
        raise MutationError(
            f"mutation {mutation.name!r}: the text to replace occurs {n} times in {mutation.path} "
            f"(expected exactly once): {mutation.old!r}"
        )
    target.write_text(text.replace(mutation.old, mutation.new), encoding="utf-8")
    return target


def copy_project(dest: Path | str, source: Path | str | None = None) -> Path:
    """Copy the packages (:data:`COPIED_PACKAGES`) and :data:`COPIED_FILES` into ``dest``."""
    src = Path(source) if source is not None else repo_root()
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    for name in COPIED_PACKAGES:
        shutil.copytree(src / name, dest / name, ignore=_IGNORED)
    for name in COPIED_FILES:
        if (src / name).exists():
            shutil.copy2(src / name, dest / name)
    return dest


# The process that runs the tests: the copy first on sys.path, the imports checked, then pytest.
_BOOTSTRAP = """\
import importlib.util, json, os, sys
root = os.path.realpath(sys.argv[1])
sys.path.insert(0, root)
import meanfield, analysis
where = {m.__name__: os.path.realpath(m.__file__) for m in (meanfield, analysis)}
spec = importlib.util.find_spec("verification")
where["verification"] = os.path.realpath(spec.origin) if spec and spec.origin else "?"
with open(sys.argv[2], "w") as fh:
    json.dump(where, fh)
bad = {k: v for k, v in where.items() if not v.startswith(root + os.sep)}
if bad:
    sys.stderr.write(f"imports resolve outside the copy {root}: {bad}\\n")
    sys.exit(97)
import pytest
sys.exit(pytest.main(sys.argv[3:]))
"""


def _node_id(classname: str, name: str, root: Path) -> str:
    """``tests.test_x.TestC`` + ``test_y[p]`` -> ``tests/test_x.py::TestC::test_y[p]``."""
    if not classname:
        return name
    parts = classname.split(".")
    for k in range(len(parts), 0, -1):
        path = "/".join(parts[:k]) + ".py"
        if (root / path).exists():
            return "::".join([path, *parts[k:], name])
    return f"{classname}::{name}"


def _parse_junit(report: Path, root: Path) -> tuple[list[str], dict[str, int]]:
    tree = ET.parse(report)
    failed: list[str] = []
    counts = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    suites = [tree.getroot()] if tree.getroot().tag == "testsuite" else list(tree.getroot().iter("testsuite"))
    for suite in suites:
        for key in counts:
            counts[key] += int(suite.get(key, 0))
        for case in suite.iter("testcase"):
            if case.find("failure") is not None or case.find("error") is not None:
                failed.append(_node_id(case.get("classname", ""), case.get("name", ""), root))
    return failed, counts


def run_tests(
    root: Path | str, tests: Sequence[str], profile: str = DEFAULT_PROFILE, timeout: float = 900.0
) -> tuple[str, list[str], dict[str, int], int | None, dict[str, str], float]:
    """Run pytest on ``tests`` inside the sandbox ``root``.

    Returns
    -------
    status, failed_tests, counts, returncode, imported_from, seconds
        See :class:`RunResult`.
    """
    root = Path(root).resolve()
    report = root / ".mutation-junit.xml"
    where_file = root / ".mutation-imports.json"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(root), *filter(None, [env.get("PYTHONPATH")])])
    env["HYPOTHESIS_PROFILE"] = profile
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env["MPLBACKEND"] = "Agg"
    args = ["-q", "-p", "no:cacheprovider", "-W", "ignore", f"--junitxml={report}", *tests]
    cmd = [sys.executable, "-c", _BOOTSTRAP, str(root), str(where_file), *args]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", [], {}, None, {}, time.perf_counter() - t0
    seconds = time.perf_counter() - t0
    where = json.loads(where_file.read_text()) if where_file.exists() else {}
    if proc.returncode == 97:
        raise RuntimeError(f"the sandbox does not shadow the installed packages: {proc.stderr.strip()}")
    if not report.exists():
        tail = (proc.stdout + proc.stderr)[-2000:]
        sys.stderr.write(f"pytest wrote no report (exit {proc.returncode}):\n{tail}\n")
        return "broken", [], {}, proc.returncode, where, seconds
    failed, counts = _parse_junit(report, root)
    status = "passed" if proc.returncode == 0 and not failed else "failed"
    return status, failed, counts, proc.returncode, where, seconds


def _run_one(mutation: Mutation | None, tests: Sequence[str], profile: str, timeout: float, keep: bool) -> RunResult:
    tmp = Path(tempfile.mkdtemp(prefix="mutation-"))
    try:
        root = copy_project(tmp / "project")
        if mutation is not None:
            apply_mutation(mutation, root)
        status, failed, counts, rc, where, seconds = run_tests(root, tests, profile, timeout)
    finally:
        if not keep:
            shutil.rmtree(tmp, ignore_errors=True)
    if mutation is None:
        return RunResult("baseline", "no mutation", None, "", status, None, failed, counts, seconds, rc, where)
    caught = bool(failed) or status in ("timeout", "broken") or (rc not in (0, None))
    return RunResult(
        mutation.name, mutation.description, mutation.path, mutation.claim, status, caught,
        failed, counts, seconds, rc, where,
    )  # fmt: skip


def run_demo(
    mutations: Iterable[Mutation] = MUTATIONS,
    tests: Sequence[str] = DEFAULT_TESTS,
    profile: str = DEFAULT_PROFILE,
    timeout: float = 900.0,
    keep: bool = False,
    progress: bool = True,
) -> dict:
    """The baseline run, then every mutation alone, sequentially.

    Every mutation is first checked against the current sources (raises
    :class:`MutationError` before anything runs if one is stale).

    Returns
    -------
    dict
        ``{"tests", "profile", "baseline", "mutations", "seconds", "python"}`` with the
        runs as dictionaries of :class:`RunResult` fields.
    """
    mutations = list(mutations)
    root = repo_root()
    for m in mutations:
        n = count_occurrences(m, root)
        if n != 1:
            raise MutationError(f"mutation {m.name!r}: {n} occurrences in {m.path} (expected exactly once)")
    t0 = time.perf_counter()

    def say(r: RunResult) -> None:
        if progress:
            verdict = r.status if r.caught is None else ("caught" if r.caught else "NOT caught")
            print(f"{r.name:30s} {verdict:10s} {len(r.failed_tests):3d} failing  {r.seconds:6.1f} s", flush=True)

    baseline = _run_one(None, tests, profile, timeout, keep)
    say(baseline)
    results = []
    for m in mutations:
        r = _run_one(m, tests, profile, timeout, keep)
        say(r)
        results.append(r)
    return {
        "tests": list(tests),
        "profile": profile,
        "python": sys.executable,
        "baseline": asdict(baseline),
        "mutations": [asdict(r) for r in results],
        "seconds": time.perf_counter() - t0,
    }


# ---------------------------------------------------------------------- reporting
def _short(test_id: str) -> str:
    path, _, rest = test_id.partition("::")
    return f"{Path(path).stem}::{rest}" if rest else test_id


def markdown_table(report: dict) -> str:
    """The demo's result as a markdown table (one row per run, baseline first)."""
    lines = [
        "| mutation | file | caught | failing tests |",
        "|---|---|---|---|",
    ]
    b = report["baseline"]
    lines.append(
        f"| baseline (no mutation) | - | {b['status']} | "
        + (", ".join(_short(t) for t in b["failed_tests"]) or "none")
        + " |"
    )
    for r in report["mutations"]:
        tests = ", ".join(f"`{_short(t)}`" for t in r["failed_tests"]) or "**none**"
        caught = "yes" if r["caught"] else "**NO**"
        lines.append(f"| `{r['name']}`: {r['description']} | `{r['file']}` | {caught} | {tests} |")
    return "\n".join(lines)


def _write_json_atomic(path: Path, data: dict) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, indent=2, ensure_ascii=False)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m verification.mutation [--out FILE.json] [--tests ...]``.

    Returns 0 when the baseline passes (1 otherwise); with ``--strict`` also 1 when a
    mutation survives.
    """
    p = argparse.ArgumentParser(prog="python -m verification.mutation", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, help="write the results as JSON (atomically)")
    p.add_argument("--tests", nargs="+", default=list(DEFAULT_TESTS), help="test files or node ids to run")
    p.add_argument("--only", nargs="+", metavar="NAME", help="run only these mutations")
    p.add_argument("--profile", default=DEFAULT_PROFILE, help="hypothesis profile (default: %(default)s)")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per pytest run")
    p.add_argument("--keep", action="store_true", help="keep the temporary copies")
    p.add_argument("--list", action="store_true", help="list the mutations and exit")
    p.add_argument("--strict", action="store_true", help="exit 1 when a mutation is not caught")
    args = p.parse_args(argv)
    if args.list:
        for m in MUTATIONS:
            print(f"{m.name:30s} {m.path:28s} {m.description}")
        return 0
    chosen = list(MUTATIONS)
    if args.only:
        known = {m.name: m for m in MUTATIONS}
        unknown = [n for n in args.only if n not in known]
        if unknown:
            p.error(f"unknown mutation(s) {unknown}; known: {', '.join(known)}")
        chosen = [known[n] for n in args.only]
    report = run_demo(chosen, args.tests, args.profile, args.timeout, args.keep)
    print()
    print(markdown_table(report))
    print(f"\ntotal {report['seconds']:.0f} s; tests: {' '.join(report['tests'])}; profile {report['profile']}")
    if args.out:
        _write_json_atomic(args.out, report)
    if report["baseline"]["status"] != "passed":
        return 1
    if args.strict and not all(r["caught"] for r in report["mutations"]):
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
