"""The house: package layering (benchmarks → verification → analysis → meanfield, never back), the
ranks of meanfield's subpackages, no import cycle, compiled loops that import only the compiled
infrastructure, one name per public class, no plugin's name tested in the core, the old module
paths that still work, and the registry of parts (plugins)."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

from meanfield import ParameterError, plugins
from meanfield.capabilities import RECORDS, ControllerCapabilities
from meanfield.cli.app import main

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
    from importlib.metadata import EntryPoint

    broken = EntryPoint(name="broken", value="meanfield_no_such_module:register", group="meanfield.commands")
    real = plugins.entry_points

    def with_broken(group):
        return [*real(group=group), *([broken] if group == "meanfield.commands" else [])]

    monkeypatch.setattr(plugins, "entry_points", with_broken)
    assert main(["broken", "paper", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "'broken' command could not be loaded" in err and "meanfield_no_such_module" in err
    assert main(["scenario", "paper"]) == 0


# ---------------------------------------------------------------------- the import graph
PACKAGES = ("meanfield", "analysis", "verification")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def import_graph() -> dict[str, set[str]]:
    """Module → the toolkit modules it imports: lazy imports inside functions and imports for
    annotations only (``if TYPE_CHECKING:``) included, so that no arrow runs back, even for a reader.

    ``from package import name`` counts as importing ``package.name`` when that is a module, and
    the package's ``__init__`` otherwise; a module's own parent package is not an edge (importing
    a submodule runs its parent first, which is not a dependency of the submodule's code).
    """
    modules = {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        deps: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                subs = [f"{node.module}.{a.name}" for a in node.names if f"{node.module}.{a.name}" in modules]
                targets = subs if len(subs) == len(node.names) else [node.module, *subs]
            else:
                continue
            deps |= {t for t in targets if t in modules and t != name and not name.startswith(t + ".")}
        graph[name] = deps
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), i.e. the import cycles."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_import_graph_has_no_cycle():
    graph = import_graph()
    assert len(graph) > 60 and "meanfield.simulation.loop" in graph  # the graph is the real one
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle():
    """The check above can fail: a lazy import back from a low module is a cycle."""
    graph = import_graph()
    graph["meanfield.geometry.grid"] = graph["meanfield.geometry.grid"] | {"meanfield.simulation.loop"}
    cycles = _cycles(graph)
    assert any({"meanfield.geometry.grid", "meanfield.simulation.loop"} <= set(c) for c in cycles)


def test_layering_holds_in_the_module_graph():
    rank = {"meanfield": 0, "analysis": 1, "verification": 2}
    bad = [
        (a, b)
        for a, deps in import_graph().items()
        for b in deps
        if rank[b.split(".")[0]] > rank[a.split(".")[0]]
    ]
    assert bad == []


# ---------------------------------------------------------------------- meanfield's rooms
RANKS: dict[str, int] = {
    # the foundations: exceptions, namespaces, the registry, the compiled-loop infrastructure
    "errors": 0,
    "capabilities": 0,
    "_namespace": 1,
    "plugins": 2,
    "_compiled": 2,
    # what the closed loop is made of, lowest first
    "geometry": 3,
    "io": 3,
    "signs": 4,
    "fokker_planck": 5,
    "interfaces": 6,
    "crowds": 7,
    "controllers": 7,
    "scenarios": 8,
    "simulation": 9,
    "workflows": 10,
    "plotting": 11,
    "cli": 12,
    "__init__": 13,
}
"""Each room of ``meanfield`` (a subpackage, or a module at its top) and its rank: a room imports only
rooms of a lower rank (or its own).  Rooms of one rank (geometry and io; crowds and controllers) ignore
each other."""

TOP_LEVEL_MODULES = {"__init__", "errors", "capabilities", "plugins", "interfaces", "_namespace"}
"""The modules at ``meanfield``'s top (at most six); everything else lives in a subpackage."""


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def test_meanfield_keeps_at_most_six_modules_at_its_top():
    top = {p.stem for p in (ROOT / "meanfield").glob("*.py")}
    assert top == TOP_LEVEL_MODULES and len(top) <= 6
    rooms = {p.name for p in (ROOT / "meanfield").iterdir() if (p / "__init__.py").exists()}
    assert rooms | {m for m in top} == set(RANKS) | {"scenarios"}, "every room has a rank"


def test_each_room_imports_only_rooms_below_it():
    bad = sorted(
        (a, b)
        for a, deps in import_graph().items()
        if a.startswith("meanfield")
        for b in deps
        if b.startswith("meanfield.") and _room(a) != _room(b) and RANKS[_room(b)] >= RANKS[_room(a)]
    )
    assert bad == []


def test_the_rooms_have_no_cycle():
    rooms: dict[str, set[str]] = {}
    for a, deps in import_graph().items():
        if a.startswith("meanfield"):
            rooms.setdefault(_room(a), set()).update(_room(b) for b in deps if b.startswith("meanfield."))
    for room in rooms:
        rooms[room].discard(room)
    assert _cycles(rooms) == []


COMPILED_LOOP_EXCEPTIONS = {
    "meanfield.crowds._kde_loops": {"meanfield.geometry.grid"},  # its numpy twin is grid.linear_binning itself
    # the fused headway step counts by the count's own twin and reads the disk's share by the count's own helper
    # (a sibling leaf of compiled loops); it searches the cell list and shares the contacts' arithmetic, (H2)-(H5)
    "meanfield.crowds._headway_loops": {
        "meanfield.crowds._congestion_loops",
        "meanfield.crowds._cell_list",
        "meanfield.crowds._contact_loops",
    },
    "meanfield.crowds._contact_loops": {"meanfield.crowds._cell_list"},  # the contacts are searched in the cells
}


def test_compiled_loops_import_only_the_compiled_infrastructure():
    """A module of compiled loops (``_*_loops``, ``_sweeps``: it defines ``@compiled`` functions) imports
    numpy, the standard library and :mod:`meanfield._compiled`, so that it can be compiled, read and
    tested on its own."""
    loops = [
        m for m, p in _modules().items()
        if m.startswith("meanfield.") and not m.startswith("meanfield._compiled") and "@compiled(" in p.read_text()
    ]  # fmt: skip
    assert len(loops) >= 12 and all(m.rsplit(".", 1)[1].startswith("_") for m in loops), loops
    graph = import_graph()
    bad = {
        m: sorted(d for d in graph[m] if not d.startswith("meanfield._compiled"))
        for m in loops
        if {d for d in graph[m] if not d.startswith("meanfield._compiled")} - COMPILED_LOOP_EXCEPTIONS.get(m, set())
    }
    assert bad == {}
    for m in loops:  # and no third-party library but numpy
        allowed = {"__future__", "math", "numpy", "meanfield", "collections", "typing"}
        assert _imported_packages(_modules()[m]) <= allowed, m


def _public_classes() -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for name, path in _modules().items():
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                out.setdefault(node.name, []).append(name)
    return out


def test_no_two_public_classes_share_a_name():
    classes = _public_classes()
    assert "PointMassEngine" in classes and "Crowd" in classes  # the check reads the real tree
    assert {k: v for k, v in classes.items() if len(v) > 1} == {}


def _plugin_modules() -> set[str]:
    """The modules that hold a built-in part (and their private loops): a part may name itself."""
    return {ref.partition(":")[0] for names in plugins.BUILTIN.values() for ref in names.values()}


def _named_plugins() -> set[str]:
    return {
        name
        for kind in ("crowd", "controller", "guidance", "beta_gamma")
        for name in [*plugins.BUILTIN[kind], *plugins.available(kind)]
    }


def _tests_for_names(path: Path, names: set[str]) -> list[str]:
    """``x == "name"``, ``x != "name"``, ``x in ("name", ...)`` and ``NAMES = ("name", ...)`` tuples."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        consts: list[ast.AST] = []
        if isinstance(node, ast.Compare):
            consts = [node.left, *node.comparators]
            consts += [e for c in node.comparators if isinstance(c, ast.Tuple | ast.List | ast.Set) for e in c.elts]
        elif isinstance(node, ast.Assign) and isinstance(node.value, ast.Tuple | ast.List | ast.Set):
            consts = list(node.value.elts)
        found += [
            f"{path.relative_to(ROOT)}:{node.lineno} {c.value!r}"
            for c in consts
            if isinstance(c, ast.Constant) and isinstance(c.value, str) and c.value in names
        ]
    return found


def test_no_generic_module_tests_for_a_plugin_s_name():
    """The core asks a part what it needs (``accepts_sensing``, ``requires_exits``, its own options and
    stability step); it never compares a scenario's ``kind`` with a plugin's name."""
    own = _plugin_modules()
    names = _named_plugins()
    found = [
        hit
        for module, path in _modules().items()
        if module.startswith("meanfield.") and module not in own and not module.rsplit(".", 1)[1].startswith("_")
        for hit in _tests_for_names(path, names)
    ]
    assert found == []


def test_the_name_test_finds_a_test_for_a_name(tmp_path):
    """The check above can fail: a module that branches on "evacuation" is found."""
    bad = ROOT / "meanfield" / "simulation" / "_probe_for_the_layering_test.py"
    bad.write_text('def f(kind):\n    return kind == "evacuation"\n')
    try:
        assert _tests_for_names(bad, _named_plugins()) == [f"{bad.relative_to(ROOT)}:2 'evacuation'"]
    finally:
        bad.unlink()


# modules allowed above ~1,200 lines, and why (a module holds one whole concept, however long; past
# about 1,200 lines it is usually two)
LONG_MODULES: dict[str, str] = {}  # (none since the cell list and the contacts left the headway's loops)


def test_no_module_is_over_about_1200_lines_without_a_reason():
    long = {
        str(p.relative_to(ROOT)): len(p.read_text().splitlines())
        for pkg in (*PACKAGES, "benchmarks")
        for p in (ROOT / pkg).rglob("*.py")
    }
    over = {k: n for k, n in long.items() if n > 1200 and k not in LONG_MODULES}
    assert over == {}


# ---------------------------------------------------------------------- old paths, for one release
@pytest.mark.parametrize(
    "old, name, new",
    [
        ("meanfield.crowd", "Crowd", "meanfield.crowds.point_mass.PointMassEngine"),
        ("meanfield.control", "BacksteppingController", "meanfield.controllers.backstepping.BacksteppingController"),
        ("meanfield.metrics", "fit_slope", "meanfield.workflows.mean_field_limit.fit_slope"),
        ("meanfield.compiled", "CompiledKernel", "meanfield._compiled.core.CompiledLoop"),
        ("meanfield.validation", "region_from_table", "meanfield.geometry.region.region_from_table"),
    ],
)
def test_an_old_import_path_works_with_a_warning_naming_the_new_one(old, name, new):
    import importlib

    from meanfield.errors import MeanfieldDeprecationWarning

    with pytest.warns(MeanfieldDeprecationWarning, match=new.replace(".", r"\.")):
        value = getattr(importlib.import_module(old), name)
    module, _, attr = new.rpartition(".")
    assert value is getattr(importlib.import_module(module), attr)


def test_the_top_level_crowd_is_the_crowd_s_protocol_without_a_warning():
    """``meanfield.Crowd`` was a deprecated name of the point-mass engine until 0.2.0; the protocol owns it now."""
    import warnings

    import meanfield
    from meanfield.interfaces import Crowd

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert meanfield.Crowd is Crowd and meanfield.Crowd is not meanfield.PointMassEngine
    with pytest.raises(AttributeError):
        meanfield.crowd_loops_that_never_existed  # noqa: B018


def test_every_deprecation_names_the_release_that_removes_it_and_is_gone_by_then():
    """Every old module path, name, scenario field and option warns "removed in 0.3.0" (one message, from
    ``meanfield.errors``), and this fails once the package reaches that release with any of them still read."""
    import importlib
    import warnings

    import meanfield
    from analysis._moved import MOVED as ANALYSIS_MOVED
    from meanfield._namespace import MOVED
    from meanfield.cli import _DEPRECATED as CLI_NAMES
    from meanfield.controllers.coverage import DEPRECATED as COVERAGE_VALUES
    from meanfield.errors import REMOVED_IN, MeanfieldDeprecationWarning
    from meanfield.scenarios.scenario import OLD_FIELDS

    def version(v: str) -> tuple[int, ...]:
        return tuple(int(part) for part in v.split(".")[:3])

    assert version(meanfield.__version__) >= (0, 2, 0)
    old = next(iter(MOVED))
    for module in (f"meanfield.{old}", "meanfield.cli"):
        sys.modules.pop(f"meanfield.{old}", None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m = importlib.import_module(module)
            getattr(m, sorted(CLI_NAMES)[0] if module == "meanfield.cli" else sorted(dir(m))[0])
        said = [str(w.message) for w in caught if issubclass(w.category, MeanfieldDeprecationWarning)]
        assert said and all(f"removed in {REMOVED_IN}" in m for m in said), said
    from meanfield.cli.app import _build_parser

    run = next(a for a in _build_parser()._actions if a.dest == "command").choices["run"]
    old_flags = [flag for flag in ("--backend",) if flag in run._option_string_actions]
    from meanfield.controllers import backstepping

    said = rf"removed in {re.escape(REMOVED_IN)}: use law\.fused\.inputs"
    with pytest.warns(MeanfieldDeprecationWarning, match=said):
        old_fused = [backstepping.fused_robot_inputs]  # the law's compiled call before 0.2.0
    said = rf"removed in {re.escape(REMOVED_IN)}: use meanfield\.plugins\.capabilities"
    with pytest.warns(MeanfieldDeprecationWarning, match=said):
        old_question = [plugins.declared] if plugins.declared("controller", "guide", "changes_walls") else []
    from analysis.nmpc import _DEPRECATED as NMPC_NAMES
    from meanfield.crowds import _DEPRECATED as CROWDS_NAMES
    from meanfield.crowds.kde import _RENAMED as KDE_NAMES
    from meanfield.signs import kernels

    said = rf"removed in {re.escape(REMOVED_IN)}: use meanfield\.signs\.interaction\.GaussianPotential"
    with pytest.warns(MeanfieldDeprecationWarning, match=said):
        assert kernels.GaussianPotential is meanfield.signs.interaction.GaussianPotential

    left = {"meanfield's moved modules": MOVED, "analysis's moved modules": ANALYSIS_MOVED,
            "meanfield.cli's moved names": CLI_NAMES, "the old scenario fields": OLD_FIELDS,
            "coverage's deprecated values": COVERAGE_VALUES, "meanfield run's old flags": old_flags,
            "the renamed plans (BinnedPlan, NMPCPlan)": {**CROWDS_NAMES, **KDE_NAMES, **NMPC_NAMES},
            "backstepping.fused_robot_inputs": old_fused,
            "plugins.declared (the string question)": old_question,
            "the interaction potential in signs.kernels": kernels._MOVED_TO_INTERACTION}  # fmt: skip
    if version(meanfield.__version__) >= version(REMOVED_IN):
        still = [name for name, table in left.items() if table]
        assert not still, f"{meanfield.__version__} reads what its warnings said {REMOVED_IN} removes: {still}"


def test_every_old_module_path_resolves_each_of_its_names():
    """Every entry of the table of moved modules points at a module that has the name."""
    import importlib

    from meanfield._namespace import MOVED

    for old, entry in MOVED.items():
        if isinstance(entry, dict):
            for name, module in entry.items():
                assert hasattr(importlib.import_module(f"meanfield.{module}"), name), (old, name)
        else:
            module, renamed = (entry, {}) if isinstance(entry, str) else entry
            for old_name, new_name in renamed.items():
                where, _, name = new_name.rpartition(":")
                assert hasattr(importlib.import_module(f"meanfield.{where or module}"), name), (old, old_name)
            assert importlib.import_module(f"meanfield.{module}")
        assert not (ROOT / "meanfield" / f"{old}.py").exists(), old


# ---------------------------------------------------------------------- the registry
def test_every_built_in_part_is_registered_and_loads():
    for kind, names in plugins.BUILTIN.items():
        for name in names:
            assert name in plugins.available(kind)
            assert callable(plugins.load(kind, name)), (kind, name)


def test_a_name_registered_twice_is_refused_with_both_origins():
    def mine(parts):  # pragma: no cover - never built
        raise AssertionError

    record = ControllerCapabilities()
    with pytest.raises(ParameterError) as exc:
        plugins.register("controller", "backstepping", mine, capabilities=record)
    msg = str(exc.value)
    assert "meanfield.controllers.backstepping:BacksteppingController.from_parts" in msg and "test_layering" in msg
    plugins.register("controller", "test-only-controller", mine, capabilities=record)
    try:
        with pytest.raises(ParameterError) as exc:
            plugins.register(
                "controller", "test-only-controller", lambda parts: None, origin="a second module", capabilities=record
            )
        assert "a second module" in str(exc.value) and "test_layering" in str(exc.value)
        assert plugins.load("controller", "test-only-controller") is mine
    finally:
        plugins.unregister("controller", "test-only-controller")
    assert "test-only-controller" not in plugins.available("controller")


def test_every_registered_part_carries_the_capability_record_of_its_kind():
    """Each kind but the commands has one record (meanfield.capabilities.RECORDS), and every part registered now
    (built in, installed by entry point) carries a record of its kind: the core reads fields, never strings."""
    assert set(RECORDS) == set(plugins.GROUPS) - {"command"}
    for kind, record in RECORDS.items():
        for name in plugins.available(kind):
            assert type(plugins.capabilities(kind, name)) is record, (kind, name)


def _probes(path: Path) -> list[str]:
    """The ``getattr``/``hasattr`` calls of a module on anything but the object's own ``self``."""

    def root(node: ast.AST) -> ast.AST:
        while True:
            if isinstance(node, ast.Attribute):
                node = node.value
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr":
                node = node.args[0]
            else:
                return node

    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr"):
            base = root(node.args[0]) if node.args else None
            if not (isinstance(base, ast.Name) and base.id == "self"):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {ast.unparse(node)}")
    return found


def test_the_loop_and_the_scenarios_probe_no_part():
    """The loop, its observers and the scenarios use what the protocols declare (meanfield.interfaces) and what
    the records say (meanfield.capabilities): no getattr/hasattr on a part."""
    found = [hit for room in ("simulation", "scenarios") for p in sorted((ROOT / "meanfield" / room).rglob("*.py"))
             for hit in _probes(p)]  # fmt: skip
    assert found == []


def test_the_probe_check_finds_a_probe(tmp_path):
    """The check above can fail: a module that asks a crowd whether it has an attribute is found."""
    bad = ROOT / "meanfield" / "simulation" / "_probe_for_the_layering_test.py"
    bad.write_text('def f(loop, self):\n    return hasattr(loop.crowd, "reached"), getattr(self, "x")\n')
    try:
        assert _probes(bad) == [f"{bad.relative_to(ROOT)}:2 hasattr(loop.crowd, 'reached')"]
    finally:
        bad.unlink()


def test_an_entry_point_that_takes_a_built_in_name_is_refused(monkeypatch):
    from importlib.metadata import EntryPoint

    fake = EntryPoint(name="point-mass", value="somepkg.crowds:mine", group="meanfield.crowds")
    real = plugins.entry_points

    def with_fake(group):
        return [*real(group=group), *([fake] if group == "meanfield.crowds" else [])]

    monkeypatch.setattr(plugins, "entry_points", with_fake)
    with pytest.raises(ParameterError) as exc:
        plugins.available("crowd")
    msg = str(exc.value)
    assert "meanfield.crowds.agent_crowd:point_mass_crowd" in msg and "somepkg.crowds:mine" in msg
