"""The architecture holds: imports flow one way between subpackages, the library never
configures logging, and effects are dispatched by their own class (see ARCHITECTURE.md)."""

from __future__ import annotations

import ast
import logging
from pathlib import Path

import numpy as np

import rfsw_plan

PACKAGE = Path(rfsw_plan.__file__).parent

#: Layers, lowest first: a module may import its own layer and the layers before it, never a
#: later one (ARCHITECTURE.md draws the same order). Keys are subpackages or top-level modules
#: of ``rfsw_plan``; every folder is one floor. ``io/`` holds the readers and writers of
#: measurement and process files, right above the data types they produce (MeasurementSet,
#: ForceSeries, WeldTrack); ``planfiles/`` the plan folder, right above the planner.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("exceptions", "progress", "tomlreader", "files", "numfmt", "table"),
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
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
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
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
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
        for node in ast.walk(ast.parse(path.read_text())):
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
        for node in ast.walk(ast.parse(path.read_text())):
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
        for node in ast.walk(ast.parse(path.read_text())):
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
