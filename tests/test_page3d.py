"""``plan.html``, the plan in 3-D (issue 35), without a browser: written with the plan folder
and vouched for in ``plan.json``, the same bytes for the same plan and from ``rfsw-plan view``,
self-contained, and carrying the samples of ``waypoints.csv`` (the browser tests are in
``test_page3d_chromium.py``)."""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rfsw_plan.cli.main import main
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.planfiles.page3d import margin_colours
from rfsw_plan.process.problem import bundled_problem_names

ROOT = Path(__file__).resolve().parents[1]

WEB = Path(__file__).parents[1] / "rfsw_plan" / "planfiles" / "web"
PROBLEM = "zk500_table6_seam"


def page_data(page: str) -> dict[str, Any]:
    """The JSON the page draws (``<script id='plan-data'>``)."""
    m = re.search(r"<script type='application/json' id='plan-data'>(.*?)</script>", page, re.S)
    assert m, "plan.html carries no plan data"
    return dict(json.loads(m.group(1)))


def csv_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(path.open(newline="")))
    return rows[0], rows[1:]


@pytest.fixture(scope="module")
def plan_dir(tmp_path_factory: pytest.TempPathFactory, plan_folder: Any) -> Path:
    """A copy of the session's ``rfsw-plan plan PROBLEM`` folder."""
    return plan_folder(PROBLEM, tmp_path_factory.mktemp("plan3d") / "plan")


def test_vendored_three_is_the_npm_release_the_readme_names() -> None:
    readme = (WEB / "README.md").read_text()
    for name in ("three.module.min.js", "OrbitControls.js", "THREE_LICENSE"):
        m = re.search(rf"`{re.escape(name)}` \| `[^`]+` \| `([0-9a-f]{{64}})`", readme)
        assert m, name
        assert hashlib.sha256((WEB / name).read_bytes()).hexdigest() == m.group(1), name


def test_plan_html_is_committed_in_plan_json(plan_dir: Path) -> None:
    rec = json.loads((plan_dir / "plan.json").read_text())
    page = plan_dir / "plan.html"
    assert rec["sha256"]["plan.html"] == hashlib.sha256(page.read_bytes()).hexdigest()
    assert "plan.html" in rec["files"]  # named inside the folder, wherever it is
    PlanFolder.open(plan_dir)  # every vouched file, the page included, is whole
    assert page.stat().st_size < 5e6


def test_plan_html_same_bytes_for_the_same_plan(plan_dir: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    first = (plan_dir / "plan.html").read_bytes()
    record = (plan_dir / "plan.json").read_bytes()
    # planned again into another folder
    again = tmp_path / "again"
    assert main(["-q", "plan", PROBLEM, "-o", str(again)]) == 0
    assert (again / "plan.html").read_bytes() == first
    # rebuilt from the folder by `rfsw-plan view`: elsewhere, and in place (nothing changes)
    assert main(["view", str(plan_dir), "-o", str(tmp_path / "view.html")]) == 0
    assert (tmp_path / "view.html").read_bytes() == first
    capsys.readouterr()
    assert main(["view", str(plan_dir)]) == 0
    assert "up to date" in capsys.readouterr().out
    assert (plan_dir / "plan.html").read_bytes() == first
    assert (plan_dir / "plan.json").read_bytes() == record


def test_view_creates_the_folder_of_its_output(plan_dir: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``rfsw-plan view FOLDER -o out/view/plan.html``, as docs/guide/plan-3d.md writes it,
    failed when ``out/view`` did not exist (issue 39): the folder is created, like every
    other command's output folder; a file in its way is one line, exit 2."""
    target = tmp_path / "out" / "view" / "plan.html"
    assert main(["view", str(plan_dir), "-o", str(target)]) == 0
    assert target.read_bytes() == (plan_dir / "plan.html").read_bytes()
    (tmp_path / "file").write_text("x")
    capsys.readouterr()
    assert main(["view", str(plan_dir), "-o", str(tmp_path / "file" / "plan.html")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "-o" in err and "file" in err, err


def test_view_restores_a_lost_page_and_refuses_a_damaged_folder(
        plan_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import shutil

    folder = tmp_path / "copy"
    shutil.copytree(plan_dir, folder)
    (folder / "plan.html").unlink()
    assert main(["view", str(folder)]) == 0
    assert (folder / "plan.html").read_bytes() == (plan_dir / "plan.html").read_bytes()
    PlanFolder.open(folder)
    # a waypoints.csv that is not the one plan.json vouches for: one line, exit 2
    with (folder / "waypoints.csv").open("a") as fh:
        fh.write("\n")
    capsys.readouterr()
    assert main(["view", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "waypoints.csv" in err and "changed" in err and len(err.strip().splitlines()) == 1
    assert main(["view", str(tmp_path / "nothing")]) == 2
    # ... and into a new -o folder nothing is left behind: not the page, not the folders
    target = tmp_path / "new" / "deeper" / "plan.html"
    assert main(["view", str(folder), "-o", str(target)]) == 2
    assert not (tmp_path / "new").exists()


def test_page_is_self_contained(plan_dir: Path) -> None:
    page = (plan_dir / "plan.html").read_text(encoding="utf-8")
    # no file or URL to fetch: no src or href but inline data, the modules as data: URLs
    for ref in re.findall(r'\b(?:src|href)\s*=\s*["\']([^"\']*)', page):
        assert ref.startswith(("data:", "#")), ref[:80]
    imports = json.loads(re.search(r"<script type='importmap'>(.*?)</script>", page,
                                   re.S).group(1))["imports"]
    assert set(imports) == {"three", "three/OrbitControls"}
    assert all(v.startswith("data:text/javascript;base64,") for v in imports.values())
    assert (WEB / "THREE_LICENSE").read_text().splitlines()[2] in page  # the licence notice


def test_page_carries_the_samples_of_waypoints_csv(plan_dir: Path) -> None:
    """Every sample the page shows is a row of waypoints.csv with its values; the worst
    sample (smallest margin, found here from the file) is among them; the robot drawn from
    the page's link frames puts its TCP on the row's commanded TCP."""
    d = page_data((plan_dir / "plan.html").read_text(encoding="utf-8"))
    header, rows = csv_rows(plan_dir / "waypoints.csv")
    col = {h: i for i, h in enumerate(header)}
    margins = [(float(r[col["margin_mm"]]), k) for k, r in enumerate(rows) if r[col["margin_mm"]]]
    # a sample is numbered as the user sees it: data row N of waypoints.csv, the first sample
    # = 1 (the verdict's "sample N"); the page counted the header as row 1 (issue 39)
    worst_row = min(margins)[1] + 1
    assert d["row"][d["worst"]] == worst_row
    assert d["row"][0] == 1
    # evenly spread (900), plus the first and last sample of each phase and the worst one
    assert d["n"] == len(d["row"]) <= 900 + 2 * len(d["phases"]) + 1
    assert d["row"] == sorted(set(d["row"]))
    nj = len(d["chain_axis"]) // 3
    pos = np.array(d["link_pos"]).reshape(d["n"], nj, 3)
    quat = np.array(d["link_quat"]).reshape(d["n"], nj, 4)
    tcp_local = np.array(d["chain_tcp_pos"])
    tcp_rot = Rotation.from_quat(d["chain_tcp_quat"])
    for k, line in enumerate(d["row"]):
        r = rows[line - 1]
        assert d["phases"][d["phase"][k]] == r[col["phase"]]
        assert d["t"][k] == pytest.approx(float(r[col["t_s"]]), abs=6e-4)
        assert d["s"][k] == pytest.approx(float(r[col["s_mm"]]), abs=6e-4)
        for key, name in (("e_lat", "e_lat_mm"), ("margin", "margin_mm")):
            if r[col[name]]:
                assert d[key][k] == pytest.approx(float(r[col[name]]), abs=6e-5)
            else:
                assert d[key][k] is None
        # drawn TCP = last joint frame * tool, against the commanded TCP of the row
        tcp = pos[k, -1] + Rotation.from_quat(quat[k, -1]).apply(tcp_local)
        want = [float(r[col[c]]) for c in ("x_mm", "y_mm", "z_mm")]
        assert np.allclose(tcp, want, atol=0.2), (line, tcp, want)
        assert np.allclose((Rotation.from_quat(quat[k, -1]) * tcp_rot).as_quat(canonical=True),
                           Rotation.from_quat([float(r[col[c]]) for c in ("qx", "qy", "qz", "qw")]
                                              ).as_quat(canonical=True), atol=2e-4)
    # every phase is there, with its first and last sample
    phases = [r[col["phase"]] for r in rows]
    for p in set(phases):
        first = phases.index(p) + 1
        last = len(phases) - phases[::-1].index(p)
        assert first in d["row"] and last in d["row"], p


def test_margin_colours_are_the_plots_scale() -> None:
    from matplotlib import colormaps

    red, green = colormaps["RdYlGn"](0.0), colormaps["RdYlGn"](1.0)
    hexes = margin_colours(np.array([-0.3, 0.0, 0.975, 2.0, np.nan]), 0.975)
    as_hex = ["#" + "".join(f"{round(c * 255):02x}" for c in rgb[:3]) for rgb in (red, green)]
    assert hexes[0] == hexes[1] == as_hex[0]  # on a bound or outside: the red end
    assert hexes[2] == hexes[3] == as_hex[1]  # the window's centre: the green end
    assert hexes[4] == "#9a9a9a"  # no margin: out of the material


def test_margin_colours_are_matplotlibs_colour_map_without_matplotlib() -> None:
    """The page's lookup table is matplotlib's ``RdYlGn`` table, entry by entry, and every
    margin gets matplotlib's colour; computing them does not import matplotlib (the page is
    written on the plan's critical path, the plots in another process)."""
    from matplotlib import colormaps

    from rfsw_plan.planfiles.page3d import margin_lut

    cmap = colormaps["RdYlGn"]
    assert len(margin_lut()) == cmap.N
    assert np.array_equal(np.asarray(cmap(np.arange(cmap.N)))[:, :3], margin_lut())
    m = np.concatenate([np.random.default_rng(0).uniform(-0.5, 1.5, 20000),
                        np.linspace(0.0, 1.0, 2049), [np.nan]]) * 0.975
    x = np.clip(np.nan_to_num(m / 0.975, nan=0.0), 0.0, 1.0)
    ref = np.rint(np.asarray(cmap(x))[:, :3] * 255).astype(int)
    assert margin_colours(m, 0.975)[:-1] == ["#{:02x}{:02x}{:02x}".format(*c) for c in ref[:-1]]
    code = ("import sys, numpy as np; from rfsw_plan.planfiles.page3d import margin_colours; "
            "margin_colours(np.linspace(0, 1, 9), 1.0); "
            "assert 'matplotlib' not in sys.modules, 'matplotlib imported'")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT,
                   env={**os.environ, "PYTHONPATH": str(ROOT)})


@pytest.mark.slow
@pytest.mark.parametrize("problem", bundled_problem_names())
def test_page_under_5_mb_for_every_bundled_problem(problem: str, planned_result: Any,
                                                   tmp_path: Path) -> None:
    from rfsw_plan.planfiles.waypoints import write_plan_data
    from rfsw_plan.process.problem import load_problem

    written = write_plan_data(tmp_path, planned_result(problem), load_problem(problem).seam)
    page = next(p for p in written if p.name == "plan.html")
    assert page.stat().st_size < 5e6
    d = page_data(page.read_text(encoding="utf-8"))
    assert d["n"] >= 100


def test_a_name_cannot_close_the_pages_script(plan_dir: Path) -> None:
    from rfsw_plan.planfiles.page3d import plan_page
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.robot.kinematics import load_robot

    pb = load_problem(PROBLEM)
    evil = "x</script><script>alert(1)</script>"
    page = plan_page(plan_dir / "waypoints.csv", load_robot(pb.robot), pb.seam.frames_at,
                     (-1.25, 0.7), evil, evil)
    normal = plan_page(plan_dir / "waypoints.csv", load_robot(pb.robot), pb.seam.frames_at,
                       (-1.25, 0.7), "x", "x")
    assert page.count("</script>") == normal.count("</script>")
    d = page_data(page)
    assert d["title"] == d["verdict"] == evil


def test_margin_rgba_are_the_numbers_matplotlib_reads_from_the_hex_colours() -> None:
    """The margin panel of ``lateral_error_time.png`` colours its samples with
    :func:`margin_rgba`: each the RGBA matplotlib makes of that sample's
    :func:`margin_colours` text, bit for bit (so the image is the one the texts drew)."""
    from matplotlib.colors import to_rgba_array

    from rfsw_plan.planfiles.page3d import margin_rgba

    m = np.concatenate([np.random.default_rng(1).uniform(-0.5, 1.5, 3000),
                        np.linspace(0.0, 1.0, 257), [np.nan, 0.0, np.nan]]) * 0.975
    got = margin_rgba(m, 0.975)
    want = to_rgba_array(margin_colours(m, 0.975))
    assert got.shape == (len(m), 4) and got.dtype == np.float64
    assert np.array_equal(got, want)  # exact: the same divisions by 255
    assert np.array_equal(got[-1], to_rgba_array(["#9a9a9a"])[0])  # no margin: the grey


def test_the_page_reads_the_cells_csv_rows_reads(tmp_path: Path) -> None:
    """``read_table`` splits only the lines whose cells the page reads: every column, of every
    row or of chosen rows, is the cells :func:`~rfsw_plan.planfiles.folder.csv_rows` gives
    (first, middle and last columns, empty cells, a CSV with quotes read by the csv module),
    and a row with another number of cells is refused as before."""
    from rfsw_plan.exceptions import InputError
    from rfsw_plan.planfiles.folder import csv_rows as rows_of
    from rfsw_plan.planfiles.page3d import read_table

    header = ["t_s", "s_mm", "phase", "a", "b", "margin_mm", "c", "spindle_on"]
    rng = np.random.default_rng(2)
    lines = [",".join(header)]
    for k in range(40):
        cells = [f"{k * 0.01:.2f}", f"{rng.uniform(0, 9):.6f}", ("dwell", "weld")[k % 2],
                 "" if k % 3 else f"{rng.normal():.3f}", f"{rng.normal():.6f}",
                 "" if k % 5 == 0 else f"{rng.uniform(0.1, 1):.6f}", "", str(k % 2)]
        lines.append(",".join(cells))
    quoted = lines[:1] + [line.replace("dwell", '"dwell"') for line in lines[1:]]
    for text in ("\r\n".join(lines) + "\r\n", "\r\n".join(quoted) + "\r\n"):
        path = tmp_path / "waypoints.csv"
        path.write_bytes(text.encode())
        rows = rows_of(text)
        tab = read_table(path)
        assert tab.header == rows[0]
        at = np.array([39, 0, 17, 17, 5])
        for j, name in enumerate(header):
            assert tab._cells(name, None) == [r[j] for r in rows[1:]], name
            assert tab._cells(name, at) == [rows[1 + k][j] for k in at], name
        assert np.array_equal(tab.col("margin_mm"), np.array(
            [float(r[5]) if r[5] else np.nan for r in rows[1:]]), equal_nan=True)
    for bad in (lines[:1] + lines[1:5] + [lines[5] + ",x"], lines[:1] + lines[1:5] + [""],
                lines[:2]):
        path.write_bytes(("\r\n".join(bad) + "\r\n").encode())
        with pytest.raises(InputError, match="not a table of at least two samples"):
            read_table(path)
