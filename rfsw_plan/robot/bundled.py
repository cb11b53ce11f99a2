"""Bundled data files (``robots/``, ``problems/``) referred to by stem or by path."""

from __future__ import annotations

from pathlib import Path

from rfsw_plan.exceptions import InputError, UnknownNameError


def bundled_names(folder: Path) -> list[str]:
    """Stems of the ``.toml`` files shipped in ``folder``."""
    return sorted(p.stem for p in folder.glob("*.toml"))


def bundled_ref(folder: Path, path: str | Path) -> str:
    """How a record names the file at ``path``: its bare stem when it is the bundled
    ``folder/<stem>.toml`` (which :func:`resolve_bundled` reads back on any machine), else its
    absolute path."""
    p = Path(path).resolve()
    bundled = (folder / f"{p.stem}.toml").resolve()
    return p.stem if p.suffix == ".toml" and p == bundled else str(p)


def resolve_bundled(kind: str, folder: Path, name_or_path: str | Path) -> Path:
    """An existing file, or the bundled ``folder/<stem>.toml`` for a bare stem.

    An existing file wins; a bare name (no folder part, no suffix other than ``.toml``) is
    looked up in ``folder``.

    Raises:
        UnknownNameError: A bare name that is neither a file nor bundled; the message lists the
            bundled stems of ``kind``.
        InputError: A path with a folder part (``problems/nope.toml``) that does not exist,
            or that is a folder ("no such file"; a typo in a path is not an unknown name); a
            path the user may not look at (a folder without search permission).
    """
    p = Path(name_or_path)
    try:
        if p.is_file():
            return p
    except OSError as exc:  # Python 3.11's is_file raises EACCES (an unsearchable folder)
        raise InputError(p, "", f"cannot read file: {exc.strerror or exc}",
                         f"a {kind} file you may read") from None
    bundled = folder / f"{p.stem}.toml"
    if p.suffix in ("", ".toml") and p.parent == Path(".") and bundled.is_file():
        return bundled
    if p.parent != Path(".") or p.suffix not in ("", ".toml"):
        problem = "is a folder" if p.is_dir() else "no such file"
        raise InputError(p, "", problem, f"a {kind} file or a bundled {kind} name")
    raise UnknownNameError(kind, str(name_or_path), bundled_names(folder))
