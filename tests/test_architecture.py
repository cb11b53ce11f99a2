"""The architecture holds: imports flow one way between subpackages, the library never
configures logging, effects are dispatched by their own class, one package owns the plan
folder, commands write through library jobs, and library errors name parameters, not flags
(see ARCHITECTURE.md)."""

from __future__ import annotations

import ast
import functools
import logging
import re
from pathlib import Path

import numpy as np
import pytest

import rfsw_plan

PACKAGE = Path(rfsw_plan.__file__).parent


def _tree(path: Path) -> ast.Module:
    """The syntax tree of a source file, parsed once per text for all the tests that walk it
    (the walks only read it; a file rewritten by a test's fixture is parsed again)."""
    return _parse(path.read_text(), str(path))


@functools.cache
def _parse(text: str, name: str) -> ast.Module:
    return ast.parse(text, name)

#: Layers, lowest first: a module may import its own layer and the layers before it, never a
#: later one (ARCHITECTURE.md draws the same order). Keys are subpackages or top-level modules
#: of ``rfsw_plan``; every folder is one floor. ``io/`` holds the readers and writers of
#: measurement and process files, right above the data types they produce (MeasurementSet,
#: ForceSeries, WeldTrack); ``planfiles/`` the plan folder, right above the planner.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("exceptions", "progress", "tomlreader", "tomlwriter", "files", "numfmt", "table",
     "parallel"),
    ("robot",),
    ("elastostatics",),
    ("process",),
    ("io",),
    ("timing",),
    ("planning",),
    ("planfiles",),
    ("realtime",),
    ("placement",),
    ("validation",),
    ("export",),
    ("cli",),
)

#: Backward imports that exist today and are scheduled to go. This list only shrinks: a new
#: backward import fails the test, and so does an entry here that is gone (then delete the
#: entry). Pairs of (importing module, imported module).
KNOWN_BACKWARD: frozenset[tuple[str, str]] = frozenset()


def _rank(module: str) -> int | None:
    """Layer index of a dotted ``rfsw_plan`` module (None: the package facade itself)."""
    parts = module.split(".")[1:]
    if not parts:
        return None
    for i, layer in enumerate(LAYERS):
        if parts[0] in layer:
            return i
    raise AssertionError(f"{module}: subpackage '{parts[0]}' has no layer; add it to LAYERS in "
                         "tests/test_architecture.py and to ARCHITECTURE.md")


def _module_name(path: Path, root: Path = PACKAGE) -> str:
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, root: Path = PACKAGE) -> set[str]:
    """Every ``rfsw_plan`` module a file imports, anywhere in it (module level, inside
    functions, under ``TYPE_CHECKING``): each is a dependency of the design."""
    name = _module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "rfsw_plan"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "rfsw_plan":
                continue
            out.add(mod)
            # ``from rfsw_plan.x import y`` may name a submodule y
            for a in node.names:
                sub = root.parent / (mod.replace(".", "/") + f"/{a.name}.py")
                if sub.is_file():
                    out.add(f"{mod}.{a.name}")
    return out


def backward_imports(root: Path = PACKAGE) -> set[tuple[str, str]]:
    """(importing module, imported module) pairs where the imported one is on a later layer."""
    bad: set[tuple[str, str]] = set()
    for path in sorted(root.rglob("*.py")):
        name = _module_name(path, root)
        r = _rank(name)
        if r is None:
            continue
        for mod in _imports(path, root):
            rm = _rank(mod)
            if rm is not None and rm > r:
                bad.add((name, mod))
    return bad


def test_imports_flow_one_way_between_subpackages():
    bad = backward_imports()
    new = sorted(bad - KNOWN_BACKWARD)
    assert not new, "backward imports (a lower layer imports a higher one):\n" + "\n".join(
        f"  {a} imports {b}" for a, b in new)
    gone = sorted(KNOWN_BACKWARD - bad)
    assert not gone, "no longer backward, delete from KNOWN_BACKWARD:\n" + "\n".join(
        f"  {a} -> {b}" for a, b in gone)


def folder_graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    """Top-level subpackage (or module) -> the top-level subpackages it imports, lazy imports
    included. The facade ``rfsw_plan/__init__.py`` is left out: it may import every layer."""
    graph: dict[str, set[str]] = {}
    for path in sorted(root.rglob("*.py")):
        name = _module_name(path, root)
        parts = name.split(".")
        if len(parts) < 2:
            continue
        deps = graph.setdefault(parts[1], set())
        for mod in _imports(path, root):
            top = mod.split(".")
            if len(top) > 1 and top[1] != parts[1]:
                deps.add(top[1])
    return graph


def folder_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every cycle of the folder graph, as a path that returns to its start (Tarjan's strongly
    connected components; a component of more than one folder holds a cycle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_folders_import_each_other_without_cycles():
    """Seen folder by folder (lazy imports included), the import graph is acyclic: a reader of
    the tree sees the layers in the folders."""
    cycles = folder_cycles(folder_graph())
    assert not cycles, "folders that import each other in a cycle: " + "; ".join(
        " <-> ".join(c) for c in cycles)


def test_the_folder_cycle_check_sees_a_lazy_cycle(tmp_path):
    root = tmp_path / "rfsw_plan"
    for folder in ("robot", "planning"):
        (root / folder).mkdir(parents=True)
        (root / folder / "__init__.py").write_text("")
    (root / "planning" / "api.py").write_text("from rfsw_plan.robot import fake\n")
    (root / "robot" / "fake.py").write_text("def f():\n    from rfsw_plan.planning import api\n")
    assert folder_cycles(folder_graph(root)) == [["planning", "robot"]]


def subfolder_graphs(root: Path = PACKAGE) -> dict[str, dict[str, set[str]]]:
    """For every folder that has subfolders (``validation/engine``, ``cli/commands``...): its
    parts -> the parts they import, lazy imports included. A part is a subfolder or a module
    directly in the folder; the folder's ``__init__`` is its facade and left out. A subfolder
    is on its folder's layer (``_rank`` reads the top folder only); inside the folder the
    parts still import one way."""
    graphs: dict[str, dict[str, set[str]]] = {}
    folders = sorted(p for p in root.iterdir() if (p / "__init__.py").is_file()
                     and any((c / "__init__.py").is_file() for c in p.iterdir()))
    for folder in folders:
        graph: dict[str, set[str]] = {}
        for path in sorted(folder.rglob("*.py")):
            parts = _module_name(path, root).split(".")
            if len(parts) < 3:
                continue
            deps = graph.setdefault(parts[2], set())
            for mod in _imports(path, root):
                m = mod.split(".")
                if len(m) > 2 and m[1] == folder.name and m[2] != parts[2]:
                    deps.add(m[2])
        graphs[folder.name] = graph
    return graphs


def test_the_subfolders_of_a_folder_import_each_other_without_cycles():
    """Inside a folder split by concept (validation: engine, campaign, weld, report, and the
    command modules beside them), the subfolders and modules import each other one way."""
    graphs = subfolder_graphs()
    assert {"engine", "campaign", "weld", "report"} <= set(graphs["validation"])
    found = [f"{folder}: " + " <-> ".join(c) for folder, graph in graphs.items()
             for c in folder_cycles(graph)]
    assert not found, "parts of a folder that import each other in a cycle: " + "; ".join(found)


def test_a_subfolder_is_on_its_folders_layer(tmp_path):
    """A module in a subfolder is ranked by its top folder: importing a later layer from
    ``validation/engine/`` is backward, importing another validation subfolder is not (same
    layer); a cycle between two subfolders is seen by the subfolder check."""
    root = tmp_path / "rfsw_plan"
    for folder in ("validation", "validation/engine", "validation/weld", "export"):
        (root / folder).mkdir(parents=True)
        (root / folder / "__init__.py").write_text("")
    (root / "validation" / "engine" / "scoring.py").write_text(
        "from rfsw_plan.validation.weld import fit\n"
        "def f():\n    from rfsw_plan.export import program\n")
    (root / "validation" / "weld" / "fit.py").write_text(
        "from rfsw_plan.validation.engine.scoring import f\n")
    (root / "validation" / "commands.py").write_text("from rfsw_plan.validation.weld import fit\n")
    assert backward_imports(root) == {("rfsw_plan.validation.engine.scoring", "rfsw_plan.export")}
    graph = subfolder_graphs(root)["validation"]
    assert graph == {"engine": {"weld"}, "weld": {"engine"}, "commands": {"weld"}}
    assert folder_cycles(graph) == [["engine", "weld"]]


#: The examples; the paper reproductions among them are ``paper_checks.py`` and the modules
#: beside a paper's evidence (``examples/seed001/seed001_campaign.py``, ``seed001_evidence.py``).
EXAMPLES = PACKAGE.parent / "examples"


def paper_reproduction_imports(root: Path = PACKAGE, examples: Path = EXAMPLES) -> list[str]:
    """Package modules that import a module of ``examples/`` (by its name, anywhere in the
    file), and package modules named like a paper reproduction: the package never depends on
    a reproduction or carries one; the reproductions depend on the package."""
    names = {p.stem for p in examples.rglob("*.py")}
    papers = {p.stem for p in (*examples.glob("paper_*.py"), *examples.glob("seed*/*.py"))}
    found = []
    for path in sorted(root.rglob("*.py")):
        where = str(path.relative_to(root))
        if path.stem in papers:
            found.append(f"{where} (a paper reproduction of examples/)")
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                mods = [node.module or ""]
            else:
                continue
            found += [f"{where}:{node.lineno} imports {m}" for m in mods
                      if m.split(".")[0] in names or m.split(".")[0] == "examples"]
    return found


def test_nothing_in_the_package_imports_a_paper_reproduction():
    """The seed 001 reproductions (the cable campaign, the evidence set) live in
    ``examples/seed001/``, used by examples, tests and docs only (issue 33)."""
    assert (EXAMPLES / "seed001" / "seed001_campaign.py").is_file()
    assert not list(PACKAGE.rglob("seed001_*.py"))
    found = paper_reproduction_imports()
    assert not found, "the package imports a paper reproduction: " + ", ".join(found)


def test_the_paper_reproduction_check_sees_an_import(tmp_path):
    root, examples = tmp_path / "rfsw_plan", tmp_path / "examples"
    (root / "validation").mkdir(parents=True)
    (examples / "seed001").mkdir(parents=True)
    (examples / "seed001" / "seed001_campaign.py").write_text("")
    (root / "validation" / "a.py").write_text(
        "import numpy\ndef f():\n    from seed001_campaign import seed001_cases\n")
    (root / "validation" / "seed001_campaign.py").write_text("")
    assert paper_reproduction_imports(root, examples) == [
        "validation/a.py:3 imports seed001_campaign",
        "validation/seed001_campaign.py (a paper reproduction of examples/)"]


def test_the_layering_check_sees_backward_imports(tmp_path):
    """The walker finds a lazy function-local import and a relative import into later layers,
    and accepts imports down the layers."""
    root = tmp_path / "rfsw_plan"
    for folder in ("robot", "planning"):
        (root / folder).mkdir(parents=True)
        (root / folder / "__init__.py").write_text("")
    (root / "planning" / "api.py").write_text("from rfsw_plan.robot import fake\n")
    (root / "robot" / "fake.py").write_text(
        "from rfsw_plan.exceptions import InputError\n"
        "def f():\n    from rfsw_plan.planning import api\n    return api\n")
    (root / "robot" / "rel.py").write_text("from ..planning.api import x\n")
    assert backward_imports(root) == {
        ("rfsw_plan.robot.fake", "rfsw_plan.planning"),
        ("rfsw_plan.robot.fake", "rfsw_plan.planning.api"),
        ("rfsw_plan.robot.rel", "rfsw_plan.planning.api"),
    }


def _logging_state() -> dict[str, tuple[int, tuple[logging.Handler, ...]]]:
    loggers = [logging.getLogger(), *(logging.getLogger(n) for n in
                                      logging.Logger.manager.loggerDict)]
    return {lg.name: (lg.level, tuple(lg.handlers)) for lg in loggers}


def test_the_library_never_configures_logging():
    """Calling into the library (here the TOPPRA adapter, twice) leaves every logger's level
    and handlers as they were; only the CLI configures logging."""
    from rfsw_plan.timing.toppra_ import max_path_speed

    s = np.linspace(0.0, 0.2, 6)
    q = np.column_stack([s, -s, 0.5 * s])
    vel, acc = np.ones(3), np.full(3, 5.0)
    max_path_speed(s, q, vel, acc, n_grid=20)  # first call imports toppra
    before = _logging_state()
    max_path_speed(s, q, vel, acc, n_grid=20)
    after = _logging_state()
    assert {k: v for k, v in after.items() if k in before} == before
    # and no library module calls a logging configuration function
    calls = ("basicConfig", "setup_logging", "addHandler", "setLevel", "dictConfig",
             "fileConfig")
    found = []
    for path in PACKAGE.rglob("*.py"):
        if "cli" in path.relative_to(PACKAGE).parts:
            continue
        for node in ast.walk(_tree(path)):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr in calls):
                found.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.func.attr}")
    assert not found, found


def test_no_dispatch_on_effect_types_outside_the_effect_classes():
    """Effects are dispatched by their own methods (``Effect.join``, ``pose_regressor``...):
    no ``isinstance`` on an effect class outside ``elastostatics/effects/`` (effects have no
    ``kind`` attribute any more, so mypy catches a dispatch on it)."""
    from rfsw_plan.elastostatics import effects

    names = {c.__name__ for c in effects.EFFECTS.values()} | {
        "Effect", "ComplianceEffect", "WrenchEffect", "GeometricEffect"}
    found = []
    for path in PACKAGE.rglob("*.py"):
        if path.parent == PACKAGE / "elastostatics" / "effects":
            continue
        for node in ast.walk(_tree(path)):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id in ("isinstance", "issubclass") and len(node.args) == 2):
                classes = node.args[1].elts if isinstance(node.args[1], ast.Tuple) else [
                    node.args[1]]
                if any(isinstance(c, ast.Name) and c.id in names for c in classes):
                    found.append(f"{path.relative_to(PACKAGE)}:{node.lineno} isinstance")
    assert not found, found


def _effect_names() -> set[str]:
    from rfsw_plan.elastostatics import effects

    return set(effects.EFFECTS)


def _names_an_effect(node: ast.AST, names: set[str]) -> bool:
    """A string literal (or a tuple/list/set of them) that is an effect name or label
    (``tilting_compliance``, ``joint_compliance:j1``, ``joint_compliance:``)."""
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return any(_names_an_effect(e, names) for e in node.elts)
    return (isinstance(node, ast.Constant) and isinstance(node.value, str)
            and node.value.partition(":")[0] in names)


def effect_name_dispatches(root: Path = PACKAGE, names: set[str] | None = None) -> list[str]:
    """Places outside ``elastostatics/effects/`` that ask which effect something is by its
    name: a comparison or ``in`` test against an effect name, or ``startswith``/``endswith``
    on one. Bounds, admissibility and behaviour come from the effect (its ``param_ranges``,
    its methods), so a new effect is handled without touching them."""
    names = _effect_names() if names is None else names
    found = []
    for path in sorted(root.rglob("*.py")):
        if path.parent == root / "elastostatics" / "effects":
            continue
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.Compare):
                hit = any(_names_an_effect(x, names) for x in (node.left, *node.comparators))
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr in ("startswith", "endswith")):
                hit = any(_names_an_effect(a, names) for a in node.args)
            else:
                continue
            if hit:
                found.append(f"{path.relative_to(root)}:{node.lineno}")  # type: ignore[attr-defined]
    return found


def test_no_dispatch_on_effect_names_outside_the_effect_classes():
    """ARCHITECTURE.md: nothing outside an effect asks what kind it is, by class or by name
    (issue 26: a bound picked by name gave a new compliance effect -inf lower bounds)."""
    found = effect_name_dispatches()
    assert not found, "dispatch on an effect's name: " + ", ".join(found)


def test_the_effect_name_check_sees_a_dispatch_in_a_fixture(tmp_path):
    """A module that picks bounds by effect name, as validation/weld.py did, fails the check;
    building an effect from a label or asking the model does not."""
    root = tmp_path / "rfsw_plan"
    (root / "validation").mkdir(parents=True)
    (root / "validation" / "bounds.py").write_text(
        "def lower(label, theta):\n"
        "    name = label.split(':')[0]\n"
        "    if name in ('joint_compliance', 'tilting_compliance'):\n"
        "        return 0.0\n"
        "    if label.startswith('joint_compliance:'):\n"
        "        return 0.0\n"
        "    if e.name == 'payload_gravity':\n"
        "        return 0.0\n"
        "    return None\n")
    (root / "validation" / "fine.py").write_text(
        "def f(model, robot):\n"
        "    eff = make_effect(robot, 'tilting_compliance:j2')\n"
        "    lo, hi = eff.param_range('c_t1')\n"
        "    return model.has('payload_gravity'), lo\n")
    names = {"joint_compliance", "tilting_compliance", "payload_gravity"}
    assert effect_name_dispatches(root, names) == [
        "validation/bounds.py:3", "validation/bounds.py:5", "validation/bounds.py:7"]


# ---- one owner per file and per job (issue 33) ------------------------------------------------

#: Names of the plan folder's own files: only ``planfiles/`` opens, reads or writes them.
PLAN_FILES = frozenset({"plan.json", "waypoints.csv"})
#: Calls that open, read, write, move or remove a file.
FILE_OPERATIONS = frozenset({
    "open", "read_text", "read_bytes", "write_text", "write_bytes", "write_json", "atomic_path",
    "read_table", "load", "loads", "reader", "DictReader", "unlink", "replace", "rename"})


def _string_constants(node: ast.AST) -> set[str]:
    return {c.value for c in ast.walk(node) if isinstance(c, ast.Constant)
            and isinstance(c.value, str)}


def _call_name(node: ast.Call) -> str:
    f = node.func
    return f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""


def plan_file_accesses(root: Path = PACKAGE) -> list[str]:
    """Places outside ``planfiles/`` that open, read or write ``plan.json`` or
    ``waypoints.csv`` themselves (a file operation whose arguments or receiver name one)."""
    found = []
    for path in sorted(root.rglob("*.py")):
        if "planfiles" in path.relative_to(root).parts:
            continue
        for node in ast.walk(_tree(path)):
            if not isinstance(node, ast.Call) or _call_name(node) not in FILE_OPERATIONS:
                continue
            named: set[str] = set()
            for arg in (*node.args, *(k.value for k in node.keywords)):
                named |= _string_constants(arg)
            if isinstance(node.func, ast.Attribute):
                named |= _string_constants(node.func.value)
            if named & PLAN_FILES:
                found.append(f"{path.relative_to(root)}:{node.lineno}")
    return sorted(set(found))


def test_one_owner_of_the_plan_folder():
    """ARCHITECTURE.md: ``planfiles/`` is the one reader and writer of a plan folder
    (``PlanRecord``, ``PlanFolder``); export, check, validate-weld and the CLI go through it."""
    found = plan_file_accesses()
    assert not found, "plan.json/waypoints.csv opened outside planfiles/: " + ", ".join(found)


def test_the_plan_folder_check_sees_a_loose_reader(tmp_path):
    root = tmp_path / "rfsw_plan"
    for folder in ("export", "planfiles"):
        (root / folder).mkdir(parents=True)
    (root / "export" / "loose.py").write_text(
        "import json\n"
        "def rec(folder):\n"
        "    return json.loads((folder / 'plan.json').read_text())\n"
        "def rows(folder):\n"
        "    with (folder / 'waypoints.csv').open() as fh:\n"
        "        return fh.read()\n"
        "def fine(folder):\n"
        "    raise ValueError('plan.json: missing')\n")
    (root / "planfiles" / "own.py").write_text(
        "def rec(folder):\n    return (folder / 'plan.json').read_text()\n")
    assert plan_file_accesses(root) == ["export/loose.py:3", "export/loose.py:5"]


#: Low-level writers a command module must not call: every file a command writes comes from a
#: library job (``...Run.write(folder)``, ``export_plan_folder``, ``commit_plan``...).
LOW_LEVEL_WRITERS = frozenset({
    "write_json", "write_text", "write_bytes", "atomic_path", "write_figure", "savefig",
    "writer", "DictWriter"})


def cli_file_writes(root: Path = PACKAGE) -> list[str]:
    """Places in ``cli/`` that write a file themselves: a low-level writer, a plot function
    (``plot_*``) or ``open(..., "w"/"a"/"x")``."""
    found = []
    for path in sorted((root / "cli").rglob("*.py")):
        for node in ast.walk(_tree(path)):
            if not isinstance(node, ast.Call):
                continue
            name = _call_name(node)
            mode = next((a.value for a in node.args[1:2] if isinstance(a, ast.Constant)), "")
            mode = next((k.value.value for k in node.keywords if k.arg == "mode"
                         and isinstance(k.value, ast.Constant)), mode)
            writes_open = name == "open" and isinstance(mode, str) and set(mode) & set("wax")
            if name in LOW_LEVEL_WRITERS or name.startswith("plot_") or writes_open:
                found.append(f"{path.relative_to(root)}:{node.lineno} {name}")
    return found


def test_cli_commands_call_jobs_and_write_no_file_themselves():
    """ARCHITECTURE.md: a command parses, calls one library job, prints; the job writes its
    folder (``deviation``, ``place``, ``map``, ``compare``: ``Request.run()`` then
    ``write(folder)``), so Python users get the same files."""
    found = cli_file_writes()
    assert not found, "files written by the CLI itself: " + ", ".join(found)


def test_the_cli_write_check_sees_a_writer_in_a_fixture(tmp_path):
    root = tmp_path / "rfsw_plan"
    (root / "cli" / "commands").mkdir(parents=True)
    (root / "cli" / "commands" / "bad.py").write_text(
        "import csv\n"
        "from rfsw_plan.files import write_json\n"
        "def run(args, res, out):\n"
        "    write_json(out / 'x.json', {})\n"
        "    plot_deviation(res, out / 'x.png')\n"
        "    with open(out / 'x.csv', 'w') as fh:\n"
        "        csv.writer(fh)\n"
        "    with open(args.problem) as fh:\n"
        "        fh.read()\n"
        "    res.write(out)\n")
    assert cli_file_writes(root) == [
        "cli/commands/bad.py:4 write_json", "cli/commands/bad.py:5 plot_deviation",
        "cli/commands/bad.py:6 open", "cli/commands/bad.py:7 writer"]


#: A command-line flag in a string (``--noise-mm``), not a negative number or ``--``.
_FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9]*(-[a-z0-9]+)*")

#: Library modules whose strings still name command-line flags. Empty since issue 41: errors
#: name parameters and ``cli/params.py`` maps them to flags. This list only shrinks: a module
#: that names a flag and is not here fails the test, and so does an entry that no longer names
#: one.
KNOWN_FLAG_MODULES: frozenset[str] = frozenset()


def _docstring_nodes(tree: ast.AST) -> set[int]:
    out = set()
    for n in ast.walk(tree):
        if (isinstance(n, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                and n.body and isinstance(n.body[0], ast.Expr)
                and isinstance(n.body[0].value, ast.Constant)):
            out.add(id(n.body[0].value))
    return out


def _command_names(root: Path) -> set[str]:
    """The CLI's command names (``plan``, ``validate-weld``), from ``cli/commands``."""
    return {f.stem.replace("_", "-") for f in (root / "cli" / "commands").glob("*.py")
            if not f.stem.startswith("_")}


def _command_line_strings(tree: ast.AST) -> set[int]:
    """Strings of a function that writes a command line (one of its strings holds
    ``rfsw-plan ``, as ``next_command`` builds ``rfsw-plan validate ... --add E``), outside its
    ``raise`` statements: parts of the command line it prints, not errors."""
    out: set[int] = set()
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        raised = {id(n) for r in ast.walk(fn) if isinstance(r, ast.Raise) for n in ast.walk(r)}
        consts = [n for n in ast.walk(fn) if isinstance(n, ast.Constant)
                  and isinstance(n.value, str) and id(n) not in raised]
        if any("rfsw-plan " in n.value for n in consts):
            out |= {id(n) for n in consts}
    return out


def flag_names_in_library(root: Path = PACKAGE) -> dict[str, list[str]]:
    """Library module (path relative to the package) -> the flags its strings name (outside
    docstrings and comments, and outside a printed command line: a string with
    ``rfsw-plan ``, the strings of a function that writes one (not those it raises), and a
    flag right after a command's name, ``plan --forces``; an error never names a flag)."""
    commands = _command_names(root)
    after_command = re.compile(rf"(?:^|[\s(`])(?:{'|'.join(map(re.escape, sorted(commands)))}) $")
    found: dict[str, list[str]] = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] == "cli":
            continue
        tree = _tree(path)
        skip = _docstring_nodes(tree) | _command_line_strings(tree)
        raised = {id(n) for r in ast.walk(tree) if isinstance(r, ast.Raise) for n in ast.walk(r)}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                    and id(node) not in skip and "rfsw-plan " not in node.value):
                for m in _FLAG.finditer(node.value):
                    if commands and id(node) not in raised and after_command.search(
                            node.value[:m.start()]):
                        continue
                    found.setdefault(rel.as_posix(), []).append(f"{node.lineno} {m.group(0)}")
                    break
    return found


def test_library_errors_name_parameters_not_flags():
    """ARCHITECTURE.md: a library error names the parameter (``dt``, ``candidates``), never the
    flag; ``cli/params.py`` is the one table from parameters to flags."""
    found = flag_names_in_library()
    new = {k: v for k, v in found.items() if k not in KNOWN_FLAG_MODULES}
    assert not new, "flag names in library modules: " + "; ".join(
        f"{k}: {', '.join(v)}" for k, v in new.items())
    gone = sorted(KNOWN_FLAG_MODULES - set(found))
    assert not gone, "no flag left, delete from KNOWN_FLAG_MODULES: " + ", ".join(gone)


def test_the_flag_check_sees_a_flag_in_a_fixture(tmp_path):
    root = tmp_path / "rfsw_plan"
    (root / "process").mkdir(parents=True)
    (root / "cli").mkdir()
    (root / "process" / "job.py").write_text(
        '"""Docs may say --dt."""\n'
        "def run(dt):\n"
        "    if dt < 0:\n"
        "        raise ValueError('--dt must be positive')\n"
        "    hint = 'rfsw-plan deviation P --dt 0.1'\n"
        "    return dt - -1, 'dt', '--'\n")
    (root / "cli" / "main.py").write_text("FLAG = '--dt'\n")
    assert flag_names_in_library(root) == {"process/job.py": ["4 --dt"]}
    # a command line a function writes, and a flag after a command's name, are not errors;
    # the same flag in what that function raises is
    (root / "cli" / "commands").mkdir()
    (root / "cli" / "commands" / "plan.py").write_text("")
    (root / "process" / "job.py").write_text(
        "def next_command(argv, labels):\n"
        "    extra = [x for lab in labels for x in ('--add', lab)]\n"
        "    if not argv:\n"
        "        raise ValueError('no command line: give --add')\n"
        "    return 'rfsw-plan ' + ' '.join([*argv, *extra])\n"
        "LEVER = 'a calibrated force model (plan --forces LOG.csv)'\n"
        "def check(x):\n"
        "    if x:\n"
        "        raise ValueError('x: run plan --forces again')\n"
        "    return 'see --forces'\n")
    assert sorted(flag_names_in_library(root)["process/job.py"]) == [
        "10 --forces", "4 --add", "9 --forces"]


#: Engines a command that reads a written plan (``export``, ``check``, ``view``) never loads: the
#: plan holds the joint values, so neither the NLP (CasADi), the timing (TOPPRA, Ruckig) nor
#: the plots (matplotlib) are on their path (issue 41: each command at its import floor).
PLAN_READER_FORBIDDEN = ("casadi", "toppra", "ruckig", "matplotlib")
#: SciPy's packages they never load either: the rotations come from SciPy's compiled backend
#: alone (``robot/rotation.py``, not the ``scipy.spatial`` package with its k-d trees, Qhull,
#: sparse matrices and linear algebra), and the penetration law's fit (``scipy.optimize``) from
#: the disk cache once fitted (``process/deviation.py``).
PLAN_READER_FORBIDDEN_SCIPY = ("scipy.spatial", "scipy.sparse", "scipy.linalg", "scipy.optimize",
                               "scipy.special", "scipy.interpolate")


def modules_loaded_by(imports: list[str], then: str = "") -> set[str]:
    """Top-level packages in ``sys.modules`` after a fresh interpreter imports ``imports`` and
    runs the statement ``then``."""
    import subprocess
    import sys

    code = ("import sys\n" + "".join(f"import {m}\n" for m in imports) + then + "\n"
            + "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=PACKAGE.parent, timeout=120)
    return set(out.stdout.split())


def test_export_and_check_never_import_the_planner():
    """``export`` and ``check`` read the plan folder and the formats: importing their command
    modules, the export package with every format, the check and the plan folder reader loads
    none of :data:`PLAN_READER_FORBIDDEN` (``casadi`` costs the import, the planner its
    modules; ``planning/__init__`` and ``planning/rows.py`` import them on first use)."""
    loaded = modules_loaded_by([
        "rfsw_plan.cli.commands.export", "rfsw_plan.cli.commands.check", "rfsw_plan.export",
        "rfsw_plan.export.check", "rfsw_plan.planfiles", "rfsw_plan.planfiles.rebuild",
        "rfsw_plan.planning.result", "rfsw_plan.planning.verify"],
        "rfsw_plan.export.format.formats()")
    assert "rfsw_plan" in loaded
    assert not loaded & set(PLAN_READER_FORBIDDEN), sorted(loaded & set(PLAN_READER_FORBIDDEN))


def test_check_and_export_commands_run_without_the_planner(plan_with_programs, tmp_path):
    """Not only their imports: ``check`` of the zk500 ``.src`` and ``export`` of its plan, run
    as the CLI runs them (the task rebuilt, the penetration law read from the disk cache, the
    programs written and checked), load none of :data:`PLAN_READER_FORBIDDEN` and none of
    :data:`PLAN_READER_FORBIDDEN_SCIPY` (issue 41)."""
    import subprocess
    import sys

    from rfsw_plan.planfiles.folder import PlanFolder

    folder, _ = plan_with_programs("zk500_table6_seam")
    PlanFolder.open(folder).rebuild().task()  # the penetration law fitted once, or on disk
    src = folder / "rfsw_zk500_table6_seam.src"
    for argv in (["check", str(src), "--plan", str(folder)],
                 ["export", str(folder), "-q", "-o", str(tmp_path / "p"), "--format",
                  "krl,fanuc_tp,rapid,stream"]):
        code = ("import sys\nfrom rfsw_plan.cli.main import main\n"
                f"assert main({argv!r}) == 0\n"
                "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))\n"
                f"print(' '.join(m for m in {PLAN_READER_FORBIDDEN_SCIPY!r} if m in sys.modules))")
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True, cwd=PACKAGE.parent, timeout=300).stdout
        loaded = set(out.splitlines()[-2].split())
        assert "rfsw_plan" in loaded and "pinocchio" in loaded and "scipy" in loaded, argv[0]
        assert not loaded & set(PLAN_READER_FORBIDDEN), (argv[0], sorted(
            loaded & set(PLAN_READER_FORBIDDEN)))
        assert out.splitlines()[-1] == "", (argv[0], out.splitlines()[-1])


def test_plan_readers_never_import_the_timing_or_scipy_interpolate():
    """``export`` and ``check`` need SciPy's rotations, not its splines: the timing
    (``rfsw_plan.timing``, TOPPRA's and Ruckig's adapters, ``scipy.interpolate``) and SciPy's
    optimisation stay out of their imports (issue 41; a spline seam imports
    ``scipy.interpolate`` when it is built)."""
    import subprocess
    import sys

    code = ("import sys\n"
            "import rfsw_plan.cli.commands.export, rfsw_plan.cli.commands.check\n"
            "import rfsw_plan.export, rfsw_plan.export.check, rfsw_plan.planfiles\n"
            "import rfsw_plan.process, rfsw_plan.process.problem, rfsw_plan.planning.result\n"
            "print(' '.join(sorted(m for m in sys.modules if m.startswith(('rfsw_plan.timing',"
            " 'scipy.interpolate', 'scipy.optimize')))))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=PACKAGE.parent, timeout=120).stdout.split()
    assert out == [], out


def test_the_import_check_sees_casadi():
    """The same check on the planner's NLP module finds CasADi (the check can fail)."""
    assert "casadi" in modules_loaded_by(["rfsw_plan.planning.nlp"])


def test_timing_and_the_plan_plots_never_import_pyplot():
    """TOPPRA imports ``matplotlib.pyplot`` at module level (about a second of a start): the
    adapter keeps it out, and the plan's plots draw with the object API (issue 41). After the
    timing and a plot, ``matplotlib.pyplot`` is not loaded; toppra's ``plt`` still reaches the
    real pyplot on use, and an import of it afterwards is the real module."""
    code = (
        "import sys, tempfile, numpy as np\n"
        "from pathlib import Path\n"
        "from matplotlib.figure import Figure\n"
        "from rfsw_plan.files import write_figure\n"
        "from rfsw_plan.timing.toppra_ import max_path_speed\n"
        "s = np.linspace(0.0, 0.2, 6)\n"
        "max_path_speed(s, np.column_stack([s, -s]), np.ones(2), np.full(2, 5.0), n_grid=20)\n"
        "fig = Figure(); fig.subplots().plot([0, 1])\n"
        "write_figure(Path(tempfile.mkdtemp()) / 'a.png', fig)\n"
        "print('pyplot' if 'matplotlib.pyplot' in sys.modules else 'none')\n"
        "import toppra.algorithm.algorithm as a, matplotlib.pyplot as plt\n"
        "print(a.plt.plot is plt.plot, type(plt).__name__)\n")
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=PACKAGE.parent, timeout=120).stdout.split()
    assert out == ["none", "True", "module"]
    # the plan's plot modules name no pyplot
    for rel in ("planfiles/waypoints.py", "planfiles/tradeoff_plot.py"):
        assert "pyplot" not in (PACKAGE / rel).read_text(), rel


#: The plan folder's write transaction and the planner itself: a command reaches them through
#: a library job (``PlanRequest.run()``, ``PlanRun.write(folder)``), never by itself.
TRANSACTION_NAMES = frozenset({
    "mark_outputs_stale", "commit_plan", "write_plan_data", "discard_incomplete_record",
    "write_plan_plots", "plan_with_force_log", "plan_task"})


def cli_transaction_calls(root: Path = PACKAGE) -> list[str]:
    """Places in ``cli/`` that import a name of :data:`TRANSACTION_NAMES` or the planner's
    ``planning.api.plan``."""
    found = []
    for path in sorted((root / "cli").rglob("*.py")):
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.ImportFrom) and node.module:
                for alias in node.names:
                    if alias.name in TRANSACTION_NAMES or (
                            node.module == "rfsw_plan.planning.api" and alias.name == "plan"):
                        found.append(f"{path.relative_to(root)}:{node.lineno} {alias.name}")
    return found


def test_plan_is_a_library_job():
    """ARCHITECTURE.md: ``plan`` is one library job like the others; the CLI parses, calls
    ``PlanRequest`` and prints, and runs neither the planner nor the write transaction."""
    assert not cli_transaction_calls()


def test_the_job_check_sees_a_transaction_in_a_fixture(tmp_path):
    root = tmp_path / "rfsw_plan"
    (root / "cli" / "commands").mkdir(parents=True)
    (root / "cli" / "commands" / "plan.py").write_text(
        "def run(args):\n"
        "    from rfsw_plan.planning.api import plan, options_from_problem\n"
        "    from rfsw_plan.planfiles.waypoints import commit_plan\n")
    assert cli_transaction_calls(root) == [
        "cli/commands/plan.py:2 plan", "cli/commands/plan.py:3 commit_plan"]


#: Largest cyclomatic complexity of a function (radon; issue 41: no function above 20).
MAX_COMPLEXITY = 20

#: Functions above :data:`MAX_COMPLEXITY` in modules being edited in parallel (issues 38-40),
#: scheduled to be split. This list only shrinks: a new one fails the test, and so does an
#: entry that is no longer above the limit.
KNOWN_COMPLEX: frozenset[str] = frozenset({
    "planfiles/page3d.py:rebuild_plan_page",
    "validation/campaign/design.py:_pool", "validation/engine/diagnosis.py:_verdict"})


def complex_functions(root: Path = PACKAGE, limit: int = MAX_COMPLEXITY) -> dict[str, int]:
    """``module:function`` -> cyclomatic complexity (radon) of every function above ``limit``."""
    cc = pytest.importorskip("radon.complexity")  # in the dev extras
    found = {}
    for path in sorted(root.rglob("*.py")):
        for block in cc.cc_visit(path.read_text()):
            if block.complexity > limit:
                found[f"{path.relative_to(root).as_posix()}:{block.name}"] = block.complexity
    return found


def test_no_function_is_above_the_complexity_limit():
    found = complex_functions()
    new = {k: v for k, v in found.items() if k not in KNOWN_COMPLEX}
    assert not new, f"above complexity {MAX_COMPLEXITY}: {new}"
    gone = sorted(KNOWN_COMPLEX - set(found))
    assert not gone, "within the limit now, delete from KNOWN_COMPLEX: " + ", ".join(gone)


def test_the_complexity_check_sees_a_branchy_function(tmp_path):
    body = "".join(f"    if x == {k}:\n        return {k}\n" for k in range(25))
    (tmp_path / "m.py").write_text(f"def branchy(x):\n{body}    return -1\n")
    assert complex_functions(tmp_path) == {"m.py:branchy": 26}


def option_definitions(root: Path = PACKAGE) -> list[str]:
    """Modules that define planner options (``PlanOptions``, ``OPTION_KEYS``,
    ``options_from_table``, ``check_well_posed``) or import them from anywhere but
    ``process/plan_options.py``."""
    names = {"PlanOptions", "OPTION_KEYS", "options_from_table", "check_well_posed"}
    found = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        for node in ast.walk(_tree(path)):
            defined = ((isinstance(node, (ast.ClassDef, ast.FunctionDef)) and node.name in names)
                       or (isinstance(node, ast.Assign) and any(
                           isinstance(t, ast.Name) and t.id in names for t in node.targets)))
            imported = (isinstance(node, ast.ImportFrom) and node.module
                        and node.module != "rfsw_plan.process.plan_options"
                        and node.module.startswith("rfsw_plan")
                        and any(a.name in names for a in node.names))
            if (defined and rel != "process/plan_options.py") or imported:
                found.append(f"{rel}:{node.lineno}")
    return found


def test_the_planner_options_live_in_one_module():
    """Issue 41: the planner's options, their keys, their reader and their check are one
    module, ``process/plan_options.py``; everything imports them from there."""
    assert not option_definitions()


def test_the_options_check_sees_a_second_module(tmp_path):
    (tmp_path / "planning").mkdir()
    (tmp_path / "planning" / "options.py").write_text(
        "from rfsw_plan.process.plan_options import PlanOptions\n"
        "def check_well_posed(o):\n    return o\n")
    (tmp_path / "planning" / "api.py").write_text(
        "from rfsw_plan.planning.options import PlanOptions\n")
    assert option_definitions(tmp_path) == ["planning/api.py:1", "planning/options.py:2"]
