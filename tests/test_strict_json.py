"""Every JSON that any command writes or prints is strict JSON (no NaN or Infinity tokens),
loaded with a parser that rejects them (issue 9 §3)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main


def _reject(c: str) -> float:
    raise ValueError(f"non-strict JSON constant {c}")


def _strict(text: str) -> object:
    return json.loads(text, parse_constant=_reject)


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
def test_every_json_output_of_every_command_is_strict(tmp_path: Path, capsys) -> None:
    data = tmp_path / "m.csv"
    runs: list[list[str]] = [
        ["simulate-campaign", "--robot", "zk500", "--poses", "8", "-o", str(data), "--json"],
        ["robots", "--json"],
        ["predict", "--robot", "zk500", "--q-deg", "0,10,-10,0,20,0", "--wrench",
         "100,200,-3000", "--json"],
        ["identify", "--robot", "zk500", "--data", str(data), "--json", "-o",
         str(tmp_path / "id.toml")],
        ["validate", "--robot", "zk500", "--data", str(data), "--json", "--folds", "2", "-o",
         str(tmp_path / "val")],
        ["deviation", "zk500_table6_seam", "-o", str(tmp_path / "dev"), "--json", "--no-plot"],
        ["compare", "zk500_table6_seam", "-o", str(tmp_path / "cmp"), "--json", "--no-plot",
         "--strategies", "none", "offline"],
        ["plan", "zk500_table6_seam", "-o", str(tmp_path / "plan"), "--json"],
    ]
    for argv in runs:
        code = main(["-q", *argv])
        out, err = capsys.readouterr()
        assert code == 0, (argv, err)
        _strict(out)  # the printed JSON
    files = sorted(tmp_path.rglob("*.json"))
    assert {f.name for f in files} >= {"plan.json", "deviation.json", "compare.json",
                                       "validate.json"}
    for f in files:
        _strict(f.read_text())
    # plan.json: the branches that were rejected carry null, not NaN.
    rec = _strict((tmp_path / "plan" / "plan.json").read_text())
    assert isinstance(rec, dict) and rec["branches"]


@pytest.mark.parametrize("where", ["start-up", "run"])
def test_ctrl_c_is_one_line(monkeypatch, capsys, where) -> None:
    import rfsw_plan.cli.main as cli

    def boom(*a: object, **k: object) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser" if where == "start-up" else "_command_word",
                        boom)
    assert cli.main(["robots"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "rfsw-plan: interrupted"
