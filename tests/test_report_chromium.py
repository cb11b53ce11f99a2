"""The validation reports in a real browser (issue 16): ``validate``'s and ``validate-weld``'s
``report.html`` open offline in headless Chromium (Debian's ``chromium``), every image loads
with its full size, the page needs no horizontal scrolling and the screenshot is not blank.

Under ``-m slow`` (it needs the browser and a few plans); skipped, with the reason, when no
Chromium is installed.
"""

from __future__ import annotations

import json
import re
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from _browser import CHROMIUM, FLAGS, SKIP_REASON
from _helpers import softer_joint1_weld

from rfsw_plan.cli.main import main
from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.validation.campaign.simulation import run_campaign

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(CHROMIUM is None, reason=SKIP_REASON),
]

#: Browser window in CSS pixels (a laptop screen).
WIDTH, HEIGHT = 1400, 1000

#: Appended to a copy of the page: after ``load``, every image's state and the page's widths
#: as JSON in ``<pre id="check">`` (read back with ``--dump-dom``).
CHECK_SCRIPT = """<script>window.addEventListener("load", function () {
  var imgs = [];
  document.querySelectorAll("img").forEach(function (i) {
    imgs.push({alt: i.alt, complete: i.complete, w: i.naturalWidth, h: i.naturalHeight,
               shown: i.getBoundingClientRect().width, src: i.src.slice(0, 22)});
  });
  var p = document.createElement("pre");
  p.id = "check";
  p.textContent = JSON.stringify({imgs: imgs, scroll_width: document.documentElement.scrollWidth,
                                  inner_width: window.innerWidth,
                                  text_chars: document.body.innerText.length});
  document.body.appendChild(p);
});</script>"""


def _chromium(*args: str) -> subprocess.CompletedProcess[str]:
    assert CHROMIUM is not None
    # The shared flags (tests/_browser.py): headless, offline, a fresh profile.
    with tempfile.TemporaryDirectory(prefix="rfsw-chromium-") as profile:
        return subprocess.run(
            [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", f"--window-size={WIDTH},{HEIGHT}",
             "--virtual-time-budget=10000", *args],
            capture_output=True, text=True, timeout=180)


def _check_in_browser(report: Path, tmp: Path) -> dict[str, object]:
    """Render ``report`` offline; return the page's own account of its images and widths."""
    page = report.read_text(encoding="utf-8")
    # Self-contained: nothing to fetch from a network or from beside the file.
    for ref in re.findall(r'(?:src|href)\s*=\s*["\']([^"\']*)', page):
        assert ref.startswith(("data:", "#")), f"{report.name} references {ref[:60]!r}"
    assert page.count("</body>") == 1
    probe = tmp / f"probe_{report.parent.name}.html"
    probe.write_text(page.replace("</body>", CHECK_SCRIPT + "</body>"), encoding="utf-8")
    dom = _chromium("--dump-dom", probe.as_uri())
    assert dom.returncode == 0, dom.stderr[-2000:]
    m = re.search(r'<pre id="check">(.*?)</pre>', dom.stdout, re.S)
    assert m, "the page did not finish loading in Chromium"
    import html

    result = json.loads(html.unescape(m.group(1)))
    assert isinstance(result, dict)
    return result


def _assert_renders(report: Path, tmp: Path, min_images: int) -> None:
    check = _check_in_browser(report, tmp)
    imgs = check["imgs"]
    assert isinstance(imgs, list) and len(imgs) >= min_images
    for img in imgs:
        assert img["src"] == "data:image/png;base64,", img["alt"]
        assert img["complete"] and img["w"] >= 1200 and img["h"] > 100, img
        assert img["shown"] > 0.5 * min(WIDTH, 1100), img  # not squeezed to a thumbnail
    assert check["text_chars"] > 500  # type: ignore[operator]
    # No horizontal scrolling on a laptop screen (long table cells wrap, numbers do not).
    assert check["scroll_width"] <= check["inner_width"], check
    # The screenshot shows a page: mostly white paper, with text and plots on it.
    shot = tmp / f"shot_{report.parent.name}.png"
    res = _chromium(f"--screenshot={shot}", report.as_uri())
    assert res.returncode == 0 and shot.is_file(), res.stderr[-2000:]
    import matplotlib.image as mpimg

    pixels = np.asarray(mpimg.imread(shot))[..., :3]
    assert pixels.shape[1] == WIDTH
    ink = np.mean(pixels.mean(axis=2) < 0.5)  # dark pixels: text, lines
    assert 0.005 < ink < 0.5, ink
    assert pixels.std() > 0.05


def test_validate_report_in_chromium(tmp_path: Path) -> None:
    data = run_campaign("zk500", ["payload_gravity"], poses=24, loads_per_pose=4,
                        noise_mm=0.01, seed=7).data
    csv = write_measurements(tmp_path / "campaign.csv", data)
    out = tmp_path / "validate"
    assert main(["-q", "validate", "--robot", "zk500", "--data", str(csv), "--folds", "3",
                 "-o", str(out), "--add", "payload_gravity"]) == 0
    _assert_renders(out / "report.html", tmp_path, min_images=5)


def test_weld_report_in_chromium(tmp_path: Path, plan_folder: Any) -> None:
    # the real joint 1 is 20 % softer
    _, forces, track = softer_joint1_weld(tmp_path, plan_folder=plan_folder)
    out = tmp_path / "validate_weld"
    assert main(["-q", "validate-weld", str(tmp_path / "plan"), "--track", str(track),
                 "--forces", str(forces), "-o", str(out)]) == 0
    _assert_renders(out / "report.html", tmp_path, min_images=2)
