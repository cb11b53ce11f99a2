"""Numbers on the command line (issues 24 and 25): percent where users think in percent, no
prefix matching, ``--version``, physical ranges, and a bad option answered before any heavy
import or allocation."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.cli.numbers import check_samples, percent
from rfsw_plan.exceptions import InputError

ROOT = Path(__file__).resolve().parents[1]

#: Bad arguments, each refused by the parser (exit 2, one line) with these words in the line.
BAD = [
    (["deviation", "zk500_table6_seam", "--dt", "1e-9"], ["--dt", "1e-06"]),
    (["deviation", "zk500_table6_seam", "--dt", "nan"], ["--dt", "not a finite number"]),
    (["compare", "zk500_table6_seam", "--cycle-ms", "1e-308"], ["--cycle-ms", "0.1"]),
    (["validate", "--robot", "zk500", "--data", "m.csv", "--noise-mm", "1e-308"],
     ["--noise-mm"]),
    (["simulate-campaign", "--robot", "zk500", "-o", "m.csv", "--noise-mm", "1e308"],
     ["--noise-mm"]),
    (["simulate-campaign", "--robot", "zk500", "-o", "m.csv", "--poses", "0"], ["--poses"]),
    (["predict", "--robot", "zk500", "--q-deg", "0,0,0,0,0,0", "--wrench",
      "1e308,0,0,0,0,0"], ["--wrench", "fx", "200000 N"]),
    (["plan", "zk500_table6_seam", "--force-uncertainty", "20"], ["did you mean 20 %?"]),
    (["plan", "zk500_table6_seam", "--force-uncertainty", "-5%"], ["out of range"]),
    (["plan", "zk500_table6_seam", "--spacing", "2"], ["unrecognized arguments", "--spacing"]),
    (["plan", "zk500_table6_seam", "--spacing-mm", "0"], ["--spacing-mm", "0.01"]),
    (["export", "somewhere", "--stream-cycle-ms", "0"], ["--stream-cycle-ms"]),
    (["place", "zk500_table6_seam", "--workers", "0"], ["--workers"]),
    (["validate-weld", "x", "--blocks", "1"], ["--blocks"]),
]

_CHILD = r"""
import contextlib, io, json, sys
from rfsw_plan.cli.main import main
out = []
for argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["-q", *argv])
    out.append([code, err.getvalue()])
heavy = sorted(m for m in ("numpy", "scipy", "casadi", "pinocchio", "matplotlib")
               if m in sys.modules)
print(json.dumps({"results": out, "heavy": heavy}))
"""


def test_bad_numbers_answer_before_any_heavy_import() -> None:
    """Every bad option: exit 2, one line naming it, and none of NumPy, SciPy, CasADi,
    Pinocchio or matplotlib imported (the answer takes a fraction of a second, not 3.5 s)."""
    proc = subprocess.run([sys.executable, "-c", _CHILD, json.dumps([a for a, _ in BAD])],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    for (argv, needles), (code, err) in zip(BAD, got["results"], strict=True):
        assert code == 2, (argv, err)
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, (argv, err)
        for n in needles:
            assert n in err, (argv, n, err)
    assert got["heavy"] == [], got["heavy"]


@pytest.mark.parametrize(("text", "value"), [("20%", 0.2), ("20 %", 0.2), ("0.2", 0.2),
                                             ("12.5 %", 0.125), ("0", 0.0), ("1", 1.0)])
def test_force_uncertainty_in_percent(text: str, value: float) -> None:
    assert percent()(text) == pytest.approx(value)


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    from rfsw_plan import __version__

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"rfsw-plan {__version__}"


def test_time_step_fits_the_process() -> None:
    assert check_samples("--dt", 0.5, 52.0) == 105
    with pytest.raises(InputError, match="longer than the process"):
        check_samples("--dt", 100.0, 52.6)
    with pytest.raises(InputError, match=r"at least 0\.000526"):
        check_samples("--dt", 1e-6, 52.6, max_samples=100_000)


def test_deviation_dt_longer_than_the_weld(capsys: pytest.CaptureFixture[str],
                                           tmp_path: Path) -> None:
    code = main(["-q", "deviation", "zk500_table6_seam", "--dt", "3000", "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "longer than the process" in err, err
    assert list(tmp_path.iterdir()) == []  # refused before any output


def test_measurement_frame_choices_match_the_readers() -> None:
    from rfsw_plan.cli import measurement_args
    from rfsw_plan.elastostatics.measurement_set import MEASUREMENT_FRAMES
    from rfsw_plan.io.measurements import WRENCH_FRAMES

    assert tuple(MEASUREMENT_FRAMES) == measurement_args.MEASUREMENT_FRAMES
    assert tuple(WRENCH_FRAMES) == measurement_args.WRENCH_FRAMES


def test_prismatic_joint_takes_millimetres(capsys: pytest.CaptureFixture[str]) -> None:
    """TIAGo's torso lift is prismatic: ``--q-deg`` gives it in mm, ``--q`` with its unit; an
    angle unit on it is refused (it was read as degrees and turned into radians)."""
    arm = "10,10,10,10,10,10,10"
    outs = []
    for q in (["--q-deg", f"150,{arm}"], ["--q", f"0.15m,{arm}"], ["--q", f"150mm,{arm}"]):
        assert main(["predict", "--robot", "tiago_arm", *q, "--wrench", "0,0,-50",
                     "--json"]) == 0
        outs.append(json.loads(capsys.readouterr().out))
    assert outs[0] == outs[1] == outs[2]
    assert outs[0]["q_mm"][0] == pytest.approx(150.0) and outs[0]["q_deg"][0] is None
    assert main(["predict", "--robot", "tiago_arm", "--q", f"15deg,{arm}", "--wrench",
                 "0,0,-50"]) == 2
    assert "prismatic" in capsys.readouterr().err
    assert main(["predict", "--robot", "tiago_arm", "--q-deg", f"400,{arm}", "--wrench",
                 "0,0,-50"]) == 2  # 400 mm: beyond the 350 mm stroke
    assert "mm" in capsys.readouterr().err
