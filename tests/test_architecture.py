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
#: of ``rfsw_plan``, or a dotted module that sits on a different floor than its folder. ``io/``
#: is at the edges of each stage: its primitives (atomic writes, the CSV table reader) are on
#: the ground floor, the readers and writers of measurement and process files sit right above
#: the data types they produce (MeasurementSet, ForceSeries, WeldTrack), and the plan files
#: right above the planner (PlanResult).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("exceptions", "progress", "tomlreader", "io.files", "io.table"),
    ("robot",),
    ("elastostatics",),
    ("process",),
    ("io",),
    ("timing",),
    ("planning",),
    ("io.waypoints",),
    ("realtime",),
    ("placement",),
    ("validation",),
    ("export",),
    ("cli",),
)

#: Backward imports that exist today and are scheduled to go (issue 10). This list only
#: shrinks: a new backward import fails the test, and so does an entry here that is gone (then
#: delete the entry). Pairs of (importing module, imported module).
KNOWN_BACKWARD: frozenset[tuple[str, str]] = frozenset({
    # PlanResult.write(dir) is the Python API's door to the one plan writer (issue 16): the
    # import is lazy, inside the method, so planning never loads the writers unless a user
    # asks a result to write itself. Writing stays in io/; nothing else in planning calls it.
    ("rfsw_plan.planning.result", "rfsw_plan.io.waypoints"),
})


def _rank(module: str) -> int | None:
    """Layer index of a dotted ``rfsw_plan`` module (None: the package facade itself)."""
    parts = module.split(".")[1:]
    if not parts:
        return None
    for key in (".".join(parts[:2]), parts[0]):
        for i, layer in enumerate(LAYERS):
            if key in layer:
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
