"""Griffe extension for the API page: Sphinx cross-reference roles in docstrings as code.

The docstrings are Google style but name other objects with Sphinx roles
(``:func:`~rfsw_plan.plan```, ``:meth:`Effect.join```), which mkdocstrings does not read: it
would print the role as text. This extension rewrites each role to inline code of the name
(the last dotted part for a ``~`` reference, as Sphinx shows it) before rendering.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|meth|class|attr|mod|data|obj|exc|const):`(~?)([^`]+)`")


def plain(text: str) -> str:
    """``text`` with every Sphinx role replaced by inline code of its target."""
    def code(m: re.Match[str]) -> str:
        target = m[2].strip()
        return f"`{target.rsplit('.', 1)[-1] if m[1] else target}`"

    return ROLE.sub(code, text)


class SphinxRoles(griffe.Extension):
    """Rewrites the roles of every docstring griffe loads."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain(obj.docstring.value)
