"""Unwritable output paths are refused before any work, with one line and exit 2, in every
command that writes (issue 9 §4)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main


def _campaign(tmp: Path) -> Path:
    csv = tmp / "m.csv"
    assert main(["-q", "simulate-campaign", "--robot", "zk500", "--poses", "6", "-o",
                 str(csv)]) == 0
    return csv


def _commands(tmp: Path, bad: str, data: str) -> list[list[str]]:
    return [
        ["plan", "zk500_table6_seam", "-o", bad],
        ["deviation", "zk500_table6_seam", "-o", bad],
        ["compare", "zk500_table6_seam", "-o", bad],
        ["validate", "--robot", "zk500", "--data", data, "-o", bad],
        ["validate", "--robot", "zk500", "--data", data, "--no-report", "--save-robot",
         bad + "/r.toml"],
        ["identify", "--robot", "zk500", "--data", data, "-o", bad + "/r.toml"],
        ["simulate-campaign", "--robot", "zk500", "-o", bad + "/m.csv"],
    ]


@pytest.mark.parametrize("kind", ["proc", "under_file", "existing_file"])
def test_unwritable_output_is_refused_before_the_work(tmp_path, capsys, kind) -> None:
    data = str(_campaign(tmp_path))
    afile = tmp_path / "a_file"
    afile.write_text("x")
    bad = {"proc": "/proc/self", "under_file": str(afile / "sub"),
           "existing_file": str(afile)}[kind]
    capsys.readouterr()
    for argv in _commands(tmp_path, bad, data):
        if kind == "existing_file" and argv[-1].endswith((".toml", ".csv")):
            argv = [*argv[:-1], str(afile / "x" / Path(argv[-1]).name)]  # a file as a folder
        code = main(["-q", *argv])
        err = capsys.readouterr().err
        assert code == 2, (argv, err)
        assert len(err.strip().splitlines()) == 1, err
        assert "Traceback" not in err
    assert afile.read_text() == "x"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_refused(tmp_path, capsys) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["-q", "plan", "zk500_table6_seam", "-o", str(ro)]) == 2
        assert "not writable" in capsys.readouterr().err
        assert main(["-q", "simulate-campaign", "--robot", "zk500", "-o",
                     str(ro / "m.csv")]) == 2
    finally:
        ro.chmod(0o755)
