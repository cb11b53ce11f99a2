"""The self-contained HTML page the validation reports share (``validate``, ``validate-weld``).

One stylesheet, one page head and foot, tables and inline PNG figures: every page opens in a
browser without network (no external resource, plots as base64 data URIs).
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

#: The reports' stylesheet (verdict classes: adequate, missing, unexplained, undetermined).
CSS = """
body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1em}
td,th{border:1px solid #bbb;padding:2px 6px;text-align:right;font-size:0.9em;white-space:nowrap}
th{white-space:normal;vertical-align:bottom}
pre{background:#f4f4f4;padding:0.6em;white-space:pre-wrap;overflow-wrap:anywhere}
td.prose{white-space:normal;text-align:left;min-width:16em}
td.list{white-space:normal;text-align:left}
th{background:#eee}td:first-child{text-align:left}
.verdict{font-size:1.2em;padding:0.6em;border-radius:4px}
.adequate{background:#dfd}.missing{background:#ffd}.unexplained{background:#fdd}.undetermined{background:#eee}
img{max-width:100%}figure{margin:0.5em 0}
"""

#: Closes the page opened by :func:`page_head`.
PAGE_END = "</body></html>"


def page_head(title: str) -> list[str]:
    """The page's opening lines up to and including ``<body>`` (``title`` is escaped)."""
    return ["<!DOCTYPE html><html><head><meta charset='utf-8'>",
            f"<title>{html.escape(title)}</title>",
            f"<style>{CSS}</style></head><body>"]


def table(header: list[str], rows: list[list[str]]) -> str:
    """An HTML table; every header and cell text is escaped.

    Numbers and short cells never wrap; a cell of prose (longer than :data:`PROSE_CHARS` with
    spaces) wraps at its spaces, and a list (``c_t1 3.9e-07, c_t2 2.0e-07``, longer than
    :data:`LIST_CHARS`) after its commas, so that the table fits the page.
    """
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(_cell(c) for c in r) + "</tr>" for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


#: Longer cells with spaces are prose and wrap; shorter ones (numbers, labels) never do.
PROSE_CHARS = 40


#: A list cell (``a 1, b 2, c 3``) longer than this, of items no longer than this, wraps after
#: its commas, never inside an item.
LIST_CHARS = 20


def _cell(text: str) -> str:
    items = text.split(", ")
    if len(text) > LIST_CHARS and len(items) > 1 and max(map(len, items)) <= LIST_CHARS:
        kept = (html.escape(t).replace(" ", "&nbsp;") for t in items)  # an item never breaks
        return f"<td class='list'>{', '.join(kept)}</td>"
    if len(text) > PROSE_CHARS and " " in text.strip():
        return f"<td class='prose'>{html.escape(text)}</td>"
    return f"<td>{html.escape(text)}</td>"


def figure(path: Path, alt: str) -> str:
    """A figure with the PNG at ``path`` inline (base64 data URI)."""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<figure><img alt="{html.escape(alt)}" src="data:image/png;base64,{data}"></figure>'


__all__ = ["CSS", "PAGE_END", "figure", "page_head", "table"]
