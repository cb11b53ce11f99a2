"""MkDocs hook: the Python API page, generated from the package's public names.

``docs/reference/api.md`` holds a marker line ``<!-- api-reference -->``; this hook replaces it
with one mkdocstrings directive (``::: module.Name``) per name of ``rfsw_plan.__all__``, taken
from the module that defines it (``rfsw_plan._EXPORTS``). mkdocstrings then renders each from
its docstring, so the page lists exactly the public API and nothing is copied by hand.
"""

from __future__ import annotations

from typing import Any

MARKER = "<!-- api-reference -->"
PAGE = "reference/api.md"


def api_reference() -> str:
    """One ``:::`` directive per public name, classes first, each group alphabetical."""
    import rfsw_plan

    exports: dict[str, str] = rfsw_plan._EXPORTS
    names = sorted(rfsw_plan.__all__, key=lambda n: (not n[:1].isupper(), n.lower()))
    missing = [n for n in names if n not in exports]
    if missing:
        raise ValueError(f"rfsw_plan.__all__ names without a module in _EXPORTS: {missing}")
    return "\n\n".join(f"::: {exports[n]}.{n}" for n in names)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Expand the marker of the API page (MkDocs event hook)."""
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise ValueError(f"{PAGE}: the marker {MARKER} is missing")
    return markdown.replace(MARKER, api_reference())
