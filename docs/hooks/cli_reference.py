"""MkDocs hook: the command-line reference, generated from ``rfsw-plan``'s own argparse parser.

``docs/reference/cli.md`` holds a marker line ``<!-- cli-reference -->``; this hook replaces it
with one section per subcommand (its usage line, description and a table of every argument:
option strings, value, default and help), walking :func:`rfsw_plan.cli.main.build_parser` with
every command registered. Nothing in the page is written by hand, so it cannot drift from the
parser. :func:`cli_reference` is also called by ``tests/test_readme_commands.py``.
"""

from __future__ import annotations

import argparse
import html
from typing import Any

MARKER = "<!-- cli-reference -->"
PAGE = "reference/cli.md"


def _cell(text: str) -> str:
    """Text for a Markdown table cell, on one line: HTML-escaped, and the characters Markdown
    would read as a table border, a link, emphasis or code written as entities."""
    text = html.escape(" ".join(text.split()))
    return text.translate({ord(c): f"&#{ord(c)};" for c in "|[]*`_\\"})


def _value(action: argparse.Action) -> str:
    """The value an option takes (``METAVAR`` or the choices), empty for a flag."""
    if action.nargs == 0:
        return ""
    if action.metavar is not None:
        return str(action.metavar)
    if action.choices is not None:
        return "{" + ",".join(str(c) for c in action.choices) + "}"
    return action.dest.upper() if action.option_strings else action.dest


def _default(action: argparse.Action) -> str:
    """The default worth showing: none for flags, required options and suppressed values."""
    d = action.default
    if action.nargs == 0 or action.required or d is None or d is argparse.SUPPRESS:
        return ""
    if isinstance(d, list | tuple):
        return " ".join(str(x) for x in d)
    return str(d)


def _rows(parser: argparse.ArgumentParser, skip: frozenset[str] = frozenset()) -> list[str]:
    """The argument table of one parser: help actions and the options in ``skip`` (the global
    ones, listed once at the top) left out; help text expanded as ``--help`` prints it."""
    rows = ["| Argument | Value | Default | What it does |", "|---|---|---|---|"]
    formatter = parser._get_formatter()
    for a in parser._actions:  # argparse keeps no public list of its actions
        if isinstance(a, argparse._HelpAction | argparse._SubParsersAction):
            continue
        if a.help == argparse.SUPPRESS or skip.intersection(a.option_strings):
            continue
        names = ", ".join(a.option_strings) or a.dest
        value = _value(a)
        default = _default(a)
        rows.append(f"| `{names}` | {f'<code>{_cell(value)}</code>' if value else ''} "
                    f"| {f'<code>{_cell(default)}</code>' if default else ''} "
                    f"| {_cell(formatter._expand_help(a) if a.help else '')} |")
    return rows


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            return dict(a.choices)
    return {}


def _usage(parser: argparse.ArgumentParser) -> str:
    """The usage block, wrapped at 90 columns whatever the terminal (the page is the same on
    every machine)."""
    parser.formatter_class = lambda prog: argparse.HelpFormatter(prog, width=90)
    return parser.format_usage().strip()


def cli_reference() -> str:
    """The whole reference as Markdown: global options, then every subcommand in order."""
    from rfsw_plan.cli.main import build_parser

    parser, _ = build_parser()
    glob = frozenset(o for a in parser._actions for o in a.option_strings)
    out = ["## rfsw-plan", "", "```text", _usage(parser), "```", "",
           _cell(parser.description or ""), "",
           "Options of every command, accepted before or after the command word:", "",
           *_rows(parser), ""]
    for name, sub in _subparsers(parser).items():
        out += [f"## rfsw-plan {name}", "", "```text",
                _usage(sub), "```", "",
                _cell(sub.description or ""), "", *_rows(sub, glob), ""]
        # an epilog may be a function (it needs a heavy import: computed only when shown)
        epilog = sub.epilog() if callable(sub.epilog) else sub.epilog
        if epilog:
            out += ["```text", epilog.strip(), "```", ""]
    return "\n".join(out)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Expand the marker of the CLI page (MkDocs event hook)."""
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise ValueError(f"{PAGE}: the marker {MARKER} is missing")
    return markdown.replace(MARKER, cli_reference())
