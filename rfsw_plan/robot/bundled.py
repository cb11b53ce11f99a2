"""Bundled data files (``robots/``, ``problems/``) referred to by stem or by path."""

from __future__ import annotations

from pathlib import Path

from rfsw_plan.exceptions import UnknownNameError


def bundled_names(folder: Path) -> list[str]:
    """Stems of the ``.toml`` files shipped in ``folder``."""
    return sorted(p.stem for p in folder.glob("*.toml"))


def resolve_bundled(kind: str, folder: Path, name_or_path: str | Path) -> Path:
    """An existing file, or the bundled ``folder/<stem>.toml`` for a bare stem.

    An existing file wins; a bare name (no folder part, no suffix other than ``.toml``) is
    looked up in ``folder``.

    Raises:
        UnknownNameError: Neither; the message lists the bundled stems of ``kind``.
    """
    p = Path(name_or_path)
    if p.is_file():
        return p
    bundled = folder / f"{p.stem}.toml"
    if p.suffix in ("", ".toml") and p.parent == Path(".") and bundled.is_file():
        return bundled
    raise UnknownNameError(kind, str(name_or_path), bundled_names(folder))
