"""``rfsw-plan check`` against every edit a programmer makes on the pendant (issue 32): each
edit class fails with the point, its line in the program and the quantity, and the documented
touch-up workflow (editing the program inside its plan folder) is re-verified, not refused."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.export.check import check_program


@pytest.fixture
def zk500(plan_with_programs, tmp_path: Path) -> Path:
    """A copy of the zk500_table6_seam plan folder with its programs."""
    out, _ = plan_with_programs("zk500_table6_seam")
    dst = tmp_path / "plan"
    shutil.copytree(out, dst)
    return dst


def _file(folder: Path, suffix: str) -> Path:
    return next(p for p in folder.iterdir() if p.name.endswith(suffix))


def _line_of(path: Path, pattern: str) -> int:
    for n, line in enumerate(path.read_text().splitlines(), start=1):
        if re.search(pattern, line):
            return n
    raise AssertionError(pattern)


def weld_point(src: Path, k: int = 0) -> str:
    """The name of the k-th LIN point of a KRL program's constant-speed weld (the weld-start
    acceleration has points of its own, as many as its speed needs)."""
    body = src.read_text()
    weld = body[body.index("; ---- phase: weld"):body.index("; ---- phase: decelerate")]
    return re.findall(r"LIN (XP\d+)", weld)[k]


def touch_up(dat: Path, text: str, xp: str, axis: str, delta_mm: float) -> None:
    """Write ``text`` (a KRL .dat) to ``dat`` with point ``xp``'s coordinate ``axis`` (X, Y
    or Z) moved by ``delta_mm``, as a touch-up on the pendant does."""
    m = re.search(rf"(DECL E6POS {xp}=\{{[^}}]*?\b{axis} )([-0-9.]+)", text)
    assert m is not None, (xp, axis)
    dat.write_text(text[:m.start(2)] + f"{float(m.group(2)) + delta_mm:.4f}" + text[m.end(2):])


def roomy_weld_point(src: Path) -> str:
    """The constant-speed weld's point with the longest moves on both sides (a touch-up
    there changes the programmed times least)."""
    body = src.read_text()
    weld = body[body.index("; ---- phase: weld"):body.index("; ---- phase: decelerate")]
    names = re.findall(r"LIN (XP\d+)", weld)
    dat = src.with_suffix(".dat").read_text()
    xyz = np.array([[float(v) for v in re.search(
        rf"DECL E6POS {n}=\{{X ([-0-9.]+),Y ([-0-9.]+),Z ([-0-9.]+)", dat).groups()]
        for n in names])
    gap = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    room = np.minimum(gap[:-1], gap[1:])
    return names[1 + int(np.argmax(room))]


def _check(capsys: pytest.CaptureFixture[str], program: Path, *plan: str) -> tuple[int, str]:
    capsys.readouterr()  # what the plan fixture printed
    code = main(["check", str(program), *plan])
    return code, capsys.readouterr().out.strip()


def test_unedited_programs_hold_with_no_edit(zk500: Path, capsys) -> None:
    for suffix in (".src", ".ls", ".mod"):
        code, out = _check(capsys, _file(zk500, suffix))
        assert code == 0 and "holds" in out and "largest edit 0.000 mm" in out, out


def test_a_weld_segment_ten_times_faster_fails_with_its_timing(zk500: Path, capsys) -> None:
    """Was "holds" with a false "largest edit 30.7 mm"."""
    src = _file(zk500, ".src")
    text = src.read_text()
    weld = text.index("phase: weld")
    m = re.compile(r"\$VEL\.CP = ([0-9.]+)").search(text, weld)
    assert m is not None
    fast = f"{10 * float(m.group(1)):.7f}"
    src.write_text(text[:m.start(1)] + fast + text[m.end(1):])
    mv = re.compile(r"LIN (XP\d+)").search(text, m.end())
    assert mv is not None
    code, out = _check(capsys, src)
    assert code == 3, out
    assert out.startswith(f"{src.name}: {mv.group(1)} (weld")
    n = _line_of(src, rf"^\s*LIN {mv.group(1)}\b")
    assert f"line {n}" in out
    assert "timing:" in out and "-90.0 %" in out and "10.00 x the plan's" in out
    res = check_program(src)
    assert res.max_edit < 1e-5  # no false edit from a mismatched point


def test_deleted_arc_motions_fail_with_the_chord_inside(plan_with_programs, tmp_path: Path,
                                                        capsys) -> None:
    """30 deleted weld motions of the curved seam: the controller runs the chord between the
    remaining points, which leaves the window (was "holds, edit 0.000")."""
    out, _ = plan_with_programs("kr600_curved_seam")
    dst = tmp_path / "plan"
    shutil.copytree(out, dst)
    src = _file(dst, ".src")
    lines = src.read_text().splitlines()
    weld = next(k for k, x in enumerate(lines) if "phase: weld" in x)
    lin = [k for k in range(weld, len(lines)) if re.match(r"^\s*LIN XP\d+", lines[k])]
    gone = set(lin[40:70])
    kept = [x for k, x in enumerate(lines) if k not in gone]
    src.write_text("\n".join(kept) + "\n")
    code, text = _check(capsys, src)
    assert code == 3, text
    m = re.match(rf"{src.name}: (XP\d+) \(weld, s = [0-9.]+ mm, line (\d+)\) leaves the weld "
                 r"window: lateral error ([-+0-9.]+) mm", text)
    assert m is not None, text
    assert re.match(rf"^\s*LIN {m.group(1)}\b", kept[int(m.group(2)) - 1])
    assert not -1.25 <= float(m.group(3)) <= 0.7  # kr600_curved_seam's window


@pytest.mark.parametrize("edit", ["turn", "posture"])
def test_a_posture_or_turn_change_names_the_point_and_line(zk500: Path, capsys,
                                                          edit: str) -> None:
    """KUKA T bit of A6 (a turn: A6 on the other side, a whole wrist turn) or the S bit of the
    elbow: the point, its LIN line and the axis."""
    src = _file(zk500, ".src")
    dat = src.with_suffix(".dat")
    text = dat.read_text()
    xp = weld_point(src, 1)
    m = re.search(rf"DECL E6POS {xp}=\{{[^}}]*,S (\d+),T (\d+),", text)
    assert m is not None
    if edit == "turn":
        new = text[:m.start(2)] + str(int(m.group(2)) ^ 32) + text[m.end(2):]
    else:
        new = text[:m.start(1)] + str(int(m.group(1)) ^ 2) + text[m.end(1):]
    dat.write_text(new)
    code, out = _check(capsys, src)
    assert code == 3, out
    assert out.startswith(f"{src.name}: {xp} (weld"), out
    n = _line_of(src, rf"^\s*LIN {xp}\b")
    assert f"line {n}" in out
    assert re.search(r"posture changed: [AJ]6 " if edit == "turn" else "posture", out), out


def test_a_tp_turn_number_change_is_caught(zk500: Path, capsys) -> None:
    """A weld point's J6 turn number changed: named with its /MN line (the pendant's)."""
    ls = _file(zk500, ".ls")
    text = ls.read_text()
    weld = text.index("phase: weld")
    mv = re.compile(r"^\s*(\d+):L P\[(\d+)\] ", re.M)
    first = mv.search(text, weld)
    assert first is not None
    mn_line, k = mv.search(text, first.end()).groups()  # the second weld move
    m = re.search(rf"P\[{k}\]\{{\s*GP1:[^}}]*CONFIG : '([NF] [UD] [TB]), (-?\d+), (-?\d+), "
                  r"(-?\d+)'", text)
    assert m is not None
    turn = int(m.group(4))
    ls.write_text(text[:m.start(4)] + str(turn + (1 if turn <= 0 else -1)) + text[m.end(4):])
    code, out = _check(capsys, ls)
    assert code == 3, out
    assert out.startswith(f"{ls.name}: P[{k}] (weld") and "posture" in out, out
    assert f"line {mn_line})" in out, out


def test_a_program_of_another_plan_is_refused_by_its_plan_id(zk500: Path, capsys) -> None:
    mod = _file(zk500, ".mod")
    text = mod.read_text()
    m = re.search(r"plan id: ([\w.]+)-([0-9a-f]{12})", text)
    assert m is not None
    other = "0" * 12 if m.group(2) != "0" * 12 else "1" * 12
    mod.write_text(text.replace(m.group(0), f"plan id: {m.group(1)}-{other}"))
    code, out = _check(capsys, mod)
    assert code == 3
    assert f"is a program of plan {m.group(1)}-{other}, not of this plan {m.group(0)[9:]}" in out


def test_a_tp_of_another_plan_is_refused_by_its_wrapped_plan_id(zk500: Path, capsys) -> None:
    """The TP's remarks wrap the header (``! plan id: ;`` then the id on the next line):
    check reads the id there too (it once missed it and checked a TP of another plan)."""
    ls = _file(zk500, ".ls")
    text = ls.read_text()
    pid = re.search(r"(zk500_table6_seam)-([0-9a-f]{12})", text)
    assert pid is not None and not re.search(r"plan id: zk500", text)  # wrapped
    other = "0" * 12 if pid.group(2) != "0" * 12 else "1" * 12
    ls.write_text(text.replace(pid.group(0), f"{pid.group(1)}-{other}"))
    code, out = _check(capsys, ls)
    assert code == 3, out
    assert f"is a program of plan {pid.group(1)}-{other}, not of this plan {pid.group(0)}" \
        in out, out


def test_a_wait_shorter_than_the_interpolation_cycle_is_named(zk500: Path, capsys) -> None:
    """A programmer's ``WAIT SEC 0.005`` after a weld point: 5 ms moves the segment's time by
    far less than the timing tolerance, but the KUKA's 12 ms IPO cycle cannot run it as
    written: check names the point and the line, exit 3."""
    src = _file(zk500, ".src")
    xp = weld_point(src, 2)
    text = src.read_text()
    m = re.search(rf"^\s*LIN {xp}\b.*$", text, re.M)
    assert m is not None
    src.write_text(text[:m.end()] + "\n  WAIT SEC 0.005" + text[m.end():])
    code, out = _check(capsys, src)
    assert code == 3, out
    line_no = text.count("\n", 0, m.start()) + 1
    assert out.startswith(f"{src.name}: {xp} (weld") and f"line {line_no})" in out, out
    assert "the wait after it lasts 5.0 ms, below the controller's 12 ms interpolation cycle" \
        in out, out


def test_a_touch_up_inside_the_plan_folder_is_reverified(zk500: Path, capsys) -> None:
    """The documented workflow: edit the exported program where it is; check re-verifies it
    and says what changed (it used to refuse: "changed since plan.json was written")."""
    src = _file(zk500, ".src")
    dat = src.with_suffix(".dat")
    # a point in the middle of the steady weld, where the points are millimetres apart (near
    # the start of the weld they are 0.2 mm apart, and a 0.05 mm touch-up changes a segment's
    # programmed time by several per cent, which check rightly reports as timing)
    xp = roomy_weld_point(src)
    text = dat.read_text()
    touch_up(dat, text, xp, "Y", 0.05)
    code, out = _check(capsys, src)
    assert code == 0, out
    assert "largest edit 0.050 mm" in out and f"edited against the export: {dat.name}" in out
    touch_up(dat, text, xp, "Y", 2.0)
    code, out = _check(capsys, src)
    assert code == 3 and out.startswith(f"{src.name}: {xp} (weld") and "lateral error" in out


def test_every_failure_verify_samples_returns_is_reported(zk500: Path, monkeypatch) -> None:
    """A check added to verify_samples (the envelope's depth, tilt, speed rows) is reported
    by name, not filtered by a fixed list; the derivative limits stay the controller's."""
    from rfsw_plan.planning import verify

    real = verify.verify_samples
    calls = {"n": 0}

    def fake(model, task, window, samples, *a, **k):  # type: ignore[no-untyped-def]
        res = real(model, task, window, samples, *a, **k)
        calls["n"] += 1
        if calls["n"] == 1:  # the plan's own samples verify
            return res
        i = int(len(samples.t) * 0.6)
        extra = [verify.SampleFailure(i, float(samples.t[i]), str(samples.phase[i]),
                                      float(samples.s[i]), "depth", 0.9, 0.5, "mm"),
                 verify.SampleFailure(i, float(samples.t[i]), str(samples.phase[i]),
                                      float(samples.s[i]), "joint_jerk_q1", 9e3, 1e3,
                                      "deg/s^3")]
        from dataclasses import replace

        return replace(res, failures=(*res.failures, *extra))

    monkeypatch.setattr(verify, "verify_samples", fake)
    res = check_program(_file(zk500, ".src"))
    assert not res.holds and res.failure == "depth"
    assert "depth 0.900 mm beyond 0.500 mm" in res.line() and "line " in res.line()
    assert not any("joint_jerk" in f for f in res.failures)


def test_an_added_motion_fails_with_its_point_and_line(zk500: Path, capsys) -> None:
    """A motion added on the pendant (a new point 3 mm beside the seam after the weld's second
    point) is run as the controller runs it: the chords to and from it leave the window."""
    src = _file(zk500, ".src")
    dat = src.with_suffix(".dat")
    text = dat.read_text()
    xp = weld_point(src, 1)
    m = re.search(rf"DECL E6POS {xp}=\{{X ([-0-9.]+),Y ([-0-9.]+)(,[^}}]*)\}}", text)
    assert m is not None
    new = f"DECL E6POS XP900={{X {m.group(1)},Y {float(m.group(2)) + 3.0:.4f}{m.group(3)}}}"
    dat.write_text(text.replace("ENDDAT", new + "\nENDDAT"))
    s = src.read_text()
    s = re.sub(rf"(\n\s*LIN {xp}\b[^\n]*)", r"\1\n  LIN XP900", s, count=1)
    src.write_text(s)
    code, out = _check(capsys, src)
    assert code == 3, out
    n = _line_of(src, r"^\s*LIN XP900\b")
    assert out.startswith(f"{src.name}: XP900 (weld") and f"line {n}" in out, out


# --------------------------------------------------------------------------------------------
# Issue 39: the base is the plate, hooks by the pin, edits listed, TP lines as the pendant's


def _set_base(src: Path, **change: float) -> None:
    text = src.read_text()
    m = re.search(r"^(\s*\$BASE = )\{([^}]*)\}", text, re.M)
    assert m is not None
    vals = dict(item.split() for item in m.group(2).split(","))
    for k, dv in change.items():
        vals[k] = f"{float(vals[k]) + dv:.6f}"
    body = ",".join(f"{k} {v}" for k, v in vals.items())
    src.write_text(text[:m.start(2)] + body + text[m.end(2):])


def test_a_base_shifted_down_by_the_pin_depth_fails_with_depth_first(zk500: Path,
                                                                     capsys) -> None:
    """The old base sat at pin depth: a base 4.8 mm lower is what the programmer got by
    teaching the plate. Now the base is the plate, and a base 4.8 mm too low fails, the
    depth named first (was: "XP2 timing") with the pin the whole 4.8 mm too deep (was
    -0.653 mm: the shifted plunge points were matched to other plunge samples), and the
    base edit listed as what the programmer changed, not 76 moved points."""
    src = _file(zk500, ".src")
    _set_base(src, Z=-4.8)
    code, out = _check(capsys, src)
    first = out.splitlines()[0]
    assert code == 3 and ": depth " in first and "timing" not in first, out
    depth = float(re.search(r": depth ([-0-9.]+) mm", first).group(1))  # type: ignore[union-attr]
    assert -4.9 < depth < -4.6, first
    res = check_program(src).to_dict()
    assert any(e.startswith("base moved x +0.000 y +0.000 z -4.800 mm") for e in res["edited"]), \
        res["edited"]
    assert not any(" moved " in e and e.startswith("XP") for e in res["edited"]), res["edited"]


def test_a_base_retaught_on_the_surface_holds(zk500: Path, capsys) -> None:
    """The 3-point method on the plate gives back the exported base (up to the pendant's
    rounding, here 0.001 mm and 0.0001 deg): it holds as it is."""
    src = _file(zk500, ".src")
    _set_base(src, X=0.001, Y=-0.001, Z=0.001, A=0.0001)
    code, out = _check(capsys, src)
    assert code == 0 and "holds" in out, out


def test_a_spindle_stop_two_motions_earlier_fails(zk500: Path, capsys) -> None:
    """The spindle-stop hook moved up past two retract moves: the pin is not yet clear of the
    surface by the spindle clearance there, so check fails on the hook."""
    src = _file(zk500, ".src")
    lines = src.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.strip() == "; hook spindle_stop")
    j = i + 1
    while j < len(lines) and lines[j].strip().startswith(";") and "hook " not in lines[j] \
            and "phase:" not in lines[j]:
        j += 1
    block = lines[i:j]
    del lines[i:j]
    moves = [k for k, ln in enumerate(lines[:i]) if re.match(r"^\s*LIN ", ln)]
    lines[moves[-2]:moves[-2]] = block
    src.write_text("\n".join(lines) + "\n")
    code, out = _check(capsys, src)
    assert code == 3 and "hook: the spindle stops with the pin tip" in out.splitlines()[0], out


def test_deleted_weld_points_hold_and_are_listed(zk500: Path, capsys) -> None:
    """Five weld points of a straight stretch deleted: the path is the same line, so it holds,
    and --json lists the edit under "edited"."""
    import json

    src = _file(zk500, ".src")
    lines = src.read_text().splitlines()
    weld = next(k for k, ln in enumerate(lines) if "phase: weld" in ln)
    moves = [k for k, ln in enumerate(lines) if k > weld and re.match(r"^\s*LIN ", ln)]
    gone = set(moves[25:30])
    src.write_text("\n".join(ln for k, ln in enumerate(lines) if k not in gone) + "\n")
    capsys.readouterr()
    assert main(["check", str(src), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["holds"] and any("5 points deleted" in e for e in rec["edited"]), rec["edited"]


def test_tp_lines_are_the_pendants(zk500: Path, capsys) -> None:
    """A TP point moved 2 mm is reported at its /MN line number (what the pendant shows), not
    the file's line."""
    ls = _file(zk500, ".ls")
    text = ls.read_text()
    mn = text.split("/MN", 1)[1]
    m = re.search(r"^\s*(\d+):L P\[(\d+)\]", mn.split("phase: weld", 1)[1], re.M)
    assert m is not None
    k = int(m.group(2))
    moved = re.sub(rf"(P\[{k}\]\{{[^}}]*?Y =\s*)(-?[\d.]+)",
                   lambda x: x.group(1) + f"{float(x.group(2)) + 2.0:.4f}", text, flags=re.S)
    ls.write_text(moved)
    file_line = _line_of(ls, rf"^\s*{m.group(1)}:L P\[{k}\]")
    assert file_line != int(m.group(1))
    code, out = _check(capsys, ls)
    assert code == 3 and f"P[{k}]" in out and f"line {m.group(1)})" in out, out


def test_the_force_uncertainty_held_as_run_is_reported_against_the_claim(
        zk500: Path, capsys) -> None:
    """``check`` computes the robust claim on the samples the controller runs and sets it
    beside the plan's: a weld point touched up 0.2 mm deeper (along the plate normal, where
    the moves are millimetres long, so the programmed times hold) keeps the pin inside the
    depth window (the nominal envelope holds), but it eats the depth's share of the force
    uncertainty: the program then holds less than the plan claims, and check fails (exit 3)
    saying so, the depth first: the controller would not run what was verified."""
    import json

    claimed = 100 * json.loads((zk500 / "plan.json").read_text())["tolerated_force_uncertainty"]
    src = _file(zk500, ".src")
    dat = src.with_suffix(".dat")
    capsys.readouterr()
    assert main(["check", str(src), "--json"]) == 0
    before = json.loads(capsys.readouterr().out)
    assert before["claimed_pct"] == pytest.approx(claimed)
    assert before["held_pct"] >= claimed * 0.99 and before["held_limited_by"]
    assert not before["below_claim"]
    touch_up(dat, dat.read_text(), roomy_weld_point(src), "Z", -0.2)
    code, out = _check(capsys, src)
    assert code == 3 and "holds the weld envelope nominally, but as run" in out, out
    assert main(["check", str(src), "--json"]) == 3
    after = json.loads(capsys.readouterr().out)
    assert after["held_pct"] < before["held_pct"] - 0.5, (before["held_pct"], after)
    assert after["below_claim"] and after["held_limited_by"] == "depth"
    assert after["failure"] == "claim" and after["quantity"] == "depth"
    assert f"below the plan's +-{claimed:.2f} %" in out, out


def test_a_tp_header_cut_inside_the_plan_id_is_read_whole(tmp_path: Path) -> None:
    """A long problem name puts the plan id over two TP remarks, cut inside the word
    (``! kr600_forming_contour-b68bd740 ;`` then ``! 712c ;``): check read the first part
    only and refused the program as one of another plan; the remarks are joined again."""
    from rfsw_plan.export.check import _stated
    from rfsw_plan.export.fanuc_tp import FanucTpFormat, remarks

    pid = "kr600_forming_contour-b68bd740712c"
    lines = [*remarks(f"plan id: {pid}"), *remarks("robot: kuka_kr600_r2830"),
             *remarks("verified tolerated force uncertainty: +-23.7 %")]
    assert len(lines) >= 4 and pid not in " ".join(lines)  # the id is cut
    ls = tmp_path / "RFSW_X.ls"
    ls.write_text("/PROG RFSW_X\n/MN\n" + "".join(f"{k + 1:4d}:  {r} ;\n"
                                                for k, r in enumerate(lines)))
    assert pid in FanucTpFormat().header_text(ls)
    assert _stated(ls) == {"plan id": pid, "verified tolerated force uncertainty": "+-23.7"}


def test_the_sample_index_answers_as_the_full_search() -> None:
    """check's nearest-sample queries (the IK seed of every Cartesian point, the in-order
    match with its ties at rest) prune by a slab along the samples' longest axis: the
    answers are the full search's, ties and repeated positions included."""
    from rfsw_plan.export.check import _SampleIndex

    rng = np.random.default_rng(0)
    for _ in range(20):
        n = int(rng.integers(50, 2000))
        p = np.cumsum(rng.normal(size=(n, 3)) * rng.choice([0.0, 1e-3, 1e-2], size=(n, 1)),
                      axis=0)
        p[rng.integers(0, n, n // 5)] = p[0]  # the tool at rest: samples at one place
        index = _SampleIndex(p)
        for _ in range(100):
            q = p[rng.integers(0, n)] + rng.normal(size=3) * rng.choice([0.0, 1e-7, 1e-3, 1.0])
            guess, start = (int(v) for v in rng.integers(0, n, 2))
            assert index.nearest(q, guess) == int(np.argmin(np.linalg.norm(p - q, axis=1)))
            d = np.linalg.norm(p[start:] - q, axis=1)
            assert np.array_equal(index.within_tie(q, start, 3e-6),
                                  start + np.flatnonzero(d <= d.min() + 3e-6))
