"""validate's report.html and PNGs read well: engineering units, the next command, wall time,
wide plots (issue 16)."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.validation.campaign.simulation import run_campaign
from rfsw_plan.validation.report.validate import PNG_WIDTH_PX, engineering


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("rep")
    data = run_campaign("zk500", ["payload_gravity"], poses=24, loads_per_pose=4,
                        noise_mm=0.01, seed=7).data
    csv = write_measurements(tmp / "campaign.csv", data)
    plain, added = tmp / "plain", tmp / "added"
    assert main(["-q", "validate", "--robot", "zk500", "--data", str(csv), "--folds", "3",
                 "-o", str(plain)]) == 0
    assert main(["-q", "validate", "--robot", "zk500", "--data", str(csv), "--folds", "3",
                 "-o", str(added), "--add", "payload_gravity"]) == 0
    return plain, added


def _png_width(path: Path) -> int:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return int(struct.unpack(">I", head[16:20])[0])


def test_next_command_and_no_wall_time(reports: tuple[Path, Path]) -> None:
    html = (reports[0] / "report.html").read_text()
    # The verdict names payload gravity; the report gives the command that adds it.
    assert "<pre>rfsw-plan -q validate --robot zk500" in html
    # Under out/, never the repository's robots/ or the folder it runs in (issue 33, wall 5).
    assert "--add payload_gravity --save-robot out/robots/zk500+payload_gravity.toml</pre>" in html
    # no wall time in the files: the same input writes the same bytes (--json prints it)
    assert "Wall time" not in html
    assert '"seconds"' not in (reports[0] / "validate.json").read_text()


def test_stiffness_in_engineering_units_and_no_wrapping(reports: tuple[Path, Path]) -> None:
    html = (reports[1] / "report.html").read_text()
    assert "N m/rad" in html and "kN m/deg" in html
    assert "white-space:nowrap" in html
    assert "e-13 nm" not in html


def test_every_png_is_at_least_1200_px_wide(reports: tuple[Path, Path]) -> None:
    pngs = sorted(reports[1].glob("*.png"))
    assert "before_after.png" in {p.name for p in pngs}
    for p in pngs:
        assert _png_width(p) >= min(PNG_WIDTH_PX, 1200), p.name


def test_engineering_readings() -> None:
    k = 2.0e6  # N m/rad
    text = engineering(1.0 / k, "rad/(N m)")
    assert "2e+06 N m/rad" in text and f"{k * math.pi / 180 / 1e3:.4g} kN m/deg" in text
    assert engineering(0.0, "rad/(N m)") == "rigid"
    assert engineering(1e-3, "rad") == "1 mrad = 0.0573 deg"
    assert engineering(2.5e-3, "m") == "2.5 mm"
    assert engineering(150.0, "kg") == ""
    # A prismatic joint's compliance is linear (a torso lift), issue 24.
    assert engineering(1e-6, "m/N") == "k = 1e+06 N/m = 1 kN/mm"


def test_title_names_the_evaluated_model(reports: tuple[Path, Path]) -> None:
    """Issue 24: with --add the report is about the extended model, and says so."""
    assert "<h1>Model against measurement: zk500</h1>" in (reports[0] / "report.html"
                                                         ).read_text()
    added = (reports[1] / "report.html").read_text()
    assert ("<h1>Model against measurement: zk500 + payload_gravity (added and "
            "re-identified)</h1>") in added


def test_one_row_per_reason_a_candidate_was_not_fitted() -> None:
    from rfsw_plan.validation.engine.diagnosis import Skipped
    from rfsw_plan.validation.report.validate import skipped_by_reason

    why = "not identifiable from this data: does not move the measured TCP"
    rows = skipped_by_reason([Skipped("tilting_compliance:j6", why), Skipped("a", "other"),
                              Skipped("torque_dependent_stiffness:j6", why)])
    assert rows == {why: ["tilting_compliance:j6", "torque_dependent_stiffness:j6"],
                    "other": ["a"]}


def test_the_histogram_draws_what_it_names() -> None:
    """The histogram's title names the dashed +-1 sigma lines only where it draws them, and
    they are in its legend (issue 24)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from rfsw_plan.validation.report.validate import _histogram

    res = np.random.default_rng(0).normal(0, 0.01, (200, 3))
    fig = _histogram(plt, res, 0.01)
    ax = fig.axes[0]
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert len(dashed) == 2 and "dashed: +-1 sigma" in ax.get_title()
    assert "+-1 sigma noise floor" in [t.get_text() for t in ax.get_legend().get_texts()]
    plt.close(fig)
    fig = _histogram(plt, res, None)
    assert "unknown" in fig.axes[0].get_title() and "dashed" not in fig.axes[0].get_title()
    plt.close(fig)
