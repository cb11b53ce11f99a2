"""The shared HTML page of the validation reports (rfsw_plan.validation.report.html_page)."""

from __future__ import annotations

import base64
from html.parser import HTMLParser
from pathlib import Path

from rfsw_plan.validation.report.html_page import CSS, PAGE_END, figure, page_head, table

_VOID = {"meta", "img", "br"}


class _Balance(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.srcs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.srcs += [v or "" for k, v in attrs if k == "src"]
        if tag not in _VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if not self.stack or self.stack.pop() != tag:
            self.errors.append(tag)


def test_page_is_balanced_self_contained_and_escaped(tmp_path: Path) -> None:
    png = tmp_path / "p.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\nfake")
    page = "\n".join([*page_head("validate: <robot> & co"),
                      table(["a<b", "c"], [["1 & 2", "<x>"]]),
                      figure(png, 'alt "q"'), PAGE_END])
    p = _Balance()
    p.feed(page.removeprefix("<!DOCTYPE html>"))
    assert p.errors == [] and p.stack == []
    assert "<title>validate: &lt;robot&gt; &amp; co</title>" in page
    assert "<th>a&lt;b</th>" in page and "<td>1 &amp; 2</td><td>&lt;x&gt;</td>" in page
    assert p.srcs == ["data:image/png;base64," + base64.b64encode(png.read_bytes()).decode()]
    assert CSS in page and "http" not in page  # no external resource


def test_both_reports_use_the_shared_page() -> None:
    """validate and validate-weld render with the same head, stylesheet and foot."""
    import inspect

    from rfsw_plan.validation.report import validate as report
    from rfsw_plan.validation.report import validate_weld as weld_report

    for mod in (report, weld_report):
        src = inspect.getsource(mod)
        assert "page_head(" in src and "PAGE_END" in src and "<style>" not in src
