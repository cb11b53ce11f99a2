"""User-defined effects: a Python file of the user's, or a package's entry point.

An effect the library lacks is one class in a file of the user's own (``--effects FILE.py``)
or in an installed package that declares it under the entry-point group
``rfsw_plan.effects``. Loading runs the file once; its effect classes register themselves by
name like the library's (:meth:`~rfsw_plan.elastostatics.effects.base.Effect.__init_subclass__`)
and are used everywhere by that name. A saved robot file records which file or entry point
each of its effects needs, with the file's SHA-256 (:class:`~rfsw_plan.robot.description.
PluginSpec`); reading it loads them again and refuses a missing or changed file with one line.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.elastostatics.effects.base import EFFECTS, Effect
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import PluginSpec

if TYPE_CHECKING:  # importlib.metadata (and its email, socket and zipfile) is
    # imported where an entry point is looked up: a robot that names none, and every
    # command reading a plan, never pays its 17 ms (issue 41)
    from importlib import metadata

#: Entry-point group of effect plugins in installed packages.
ENTRY_POINT_GROUP = "rfsw_plan.effects"


@dataclass(frozen=True)
class LoadedPlugin:
    """A loaded effect file or entry point.

    Attributes:
        spec: Where it came from and its SHA-256 (what a saved robot file records).
        effects: The effect classes it registered, by name.
    """

    spec: PluginSpec
    effects: dict[str, type[Effect]]


#: Loaded plugins by (kind, ref); effect name -> the plugin that provides it.
_LOADED: dict[tuple[str, str], LoadedPlugin] = {}
_PROVIDER: dict[str, PluginSpec] = {}


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, hex."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _run_module(name: str, path: Path, where: str) -> dict[str, type[Effect]]:
    """Execute ``path`` as module ``name``; the effect classes it registered, by name.

    Raises:
        InputError: The file does not import (its error in one line) or defines no effect.
    """
    before = dict(EFFECTS)
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise InputError(where, "", "not a Python file", "a .py file with an effect class")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # the user's code: any error becomes one line
        sys.modules.pop(name, None)
        for k in set(EFFECTS) - set(before):
            del EFFECTS[k]
        line = str(exc).splitlines()[0] if str(exc) else ""
        raise InputError(where, "", f"could not be loaded: {type(exc).__name__}: {line}",
                         "a file that imports cleanly") from None
    new = {k: v for k, v in EFFECTS.items() if before.get(k) is not v}
    if not new:
        raise InputError(where, "", "defines no effect",
                         "a subclass of ComplianceEffect, WrenchEffect or GeometricEffect "
                         "with a 'name' (see docs/dev/writing-an-effect.md)")
    return new


def load_effect_file(path: str | Path) -> LoadedPlugin:
    """Load the effects of a user's Python file (``--effects FILE.py``), once per content.

    Raises:
        InputError: Missing file, import error, no effect in it, or an effect name that the
            library or another file already uses.
    """
    p = Path(path).expanduser().resolve()
    if not p.is_file():
        raise InputError(str(path), "", "effect file not found", "an existing .py file")
    digest = file_sha256(p)
    key = ("file", str(p))
    got = _LOADED.get(key)
    if got is not None:
        if got.spec.sha256 != digest:
            raise InputError(str(p), "", "changed since it was loaded in this process",
                             "restart to load the new version")
        EFFECTS.update(got.effects)  # registered again if a caller dropped them
        return got
    try:
        effects = _run_module(f"rfsw_plan_user_effects.{p.stem}_{digest[:12]}", p, str(p))
    except TypeError as exc:  # a name clash raised by Effect.__init_subclass__
        raise InputError(str(p), "", str(exc), "a name no other effect uses") from None
    return _remember(PluginSpec("file", str(p), digest, tuple(effects)), effects)


def _remember(spec: PluginSpec, effects: dict[str, type[Effect]]) -> LoadedPlugin:
    loaded = LoadedPlugin(spec, effects)
    _LOADED[(spec.kind, spec.ref)] = loaded
    for name in effects:
        _PROVIDER[name] = spec
    return loaded


def load_entry_point(ep: metadata.EntryPoint) -> LoadedPlugin:
    """Load one entry point of group ``rfsw_plan.effects`` (a module or an effect class).

    Raises:
        InputError: It does not import, or provides no effect.
    """
    ref = f"{ep.name} = {ep.value}"
    got = _LOADED.get(("entry_point", ref))
    if got is not None:
        return got
    before = dict(EFFECTS)
    try:
        ep.load()
    except Exception as exc:  # the package's code: one line
        raise InputError(f"entry point {ref}", "", f"could not be loaded: "
                         f"{type(exc).__name__}: {exc}", "an importable module") from None
    effects = {k: v for k, v in EFFECTS.items() if before.get(k) is not v}
    module = sys.modules.get(ep.module)
    origin = getattr(module, "__file__", None)
    if not effects:  # already imported by another entry point of the same module
        effects = {k: v for k, v in EFFECTS.items() if v.__module__ == ep.module}
    if not effects:
        raise InputError(f"entry point {ref}", "", "provides no effect",
                         "a module or class defining an effect")
    digest = file_sha256(Path(origin)) if origin else "0" * 64
    return _remember(PluginSpec("entry_point", ref, digest, tuple(effects)), effects)


def load_entry_points() -> list[LoadedPlugin]:
    """Load every installed entry point of group :data:`ENTRY_POINT_GROUP`."""
    from importlib import metadata

    return [load_entry_point(ep) for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)]


def load_plugin(spec: PluginSpec, where: str) -> LoadedPlugin:
    """Load what a robot description needs, checking that it is the same file.

    Args:
        spec: The recorded plugin.
        where: The robot file and entry, for messages (``robot.toml: effect_plugins[1]``).

    Raises:
        InputError: The file or entry point is missing, or its SHA-256 differs from the
            recorded one (never a silent fallback to other code).
    """
    if spec.kind == "file":
        p = Path(spec.ref)
        if not p.is_file():
            raise InputError(where, "file", f"effect file {p} not found",
                             f"the file that provides {', '.join(spec.effects)}")
        digest = file_sha256(p)
        if digest != spec.sha256:
            raise InputError(where, "sha256", f"{p} changed since the robot was saved "
                             f"(sha256 {digest[:12]}.., recorded {spec.sha256[:12]}..)",
                             "the file it was identified with, or identify again")
        return load_effect_file(p)
    from importlib import metadata

    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        if f"{ep.name} = {ep.value}" == spec.ref:
            loaded = load_entry_point(ep)
            if loaded.spec.sha256 != spec.sha256:
                raise InputError(where, "sha256", f"entry point {spec.ref} changed since the "
                                 f"robot was saved (sha256 {loaded.spec.sha256[:12]}.., "
                                 f"recorded {spec.sha256[:12]}..)", "the same package version")
            return loaded
    raise InputError(where, "entry_point", f"entry point {spec.ref} is not installed",
                     f"a package providing group {ENTRY_POINT_GROUP}")


def plugins_of(names: Iterable[str]) -> tuple[PluginSpec, ...]:
    """The loaded plugins that provide the effects ``names`` (library effects need none),
    each listing only the effects of ``names`` it provides, in first-use order."""
    out: dict[tuple[str, str], list[str]] = {}
    specs: dict[tuple[str, str], PluginSpec] = {}
    for name in names:
        spec = _PROVIDER.get(name)
        if spec is None:
            continue
        key = (spec.kind, spec.ref)
        specs[key] = spec
        if name not in out.setdefault(key, []):
            out[key].append(name)
    return tuple(PluginSpec(s.kind, s.ref, s.sha256, tuple(out[k])) for k, s in specs.items())
