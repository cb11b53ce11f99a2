"""The phase changes of a written plan, judged from ``waypoints.csv`` and the problem's process
numbers alone (no planner code): forces that follow the motion, a pin that stands still while
the tool stands, the dwell the problem asks for, a plunge that reaches its depth, no force with
the pin out of the plate, and the spindle running (and run up) before the pin touches.

The pin is the commanded TCP plus the predicted deflection (``x_mm + dx_mm``...); the plate
normal is the problem's ``surface_normal``; the seam's direction at its start is read from the
``seam_*`` columns of the travel rows.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rfsw_plan.process.problem import bundled_problem_names, load_problem

#: Largest lateral (and along-track) motion of the pin while the tool stands [mm].
STANDSTILL_MM = 0.05
#: The pin at the planned depth when the plunge ends [mm].
DEPTH_MM = 0.05
#: A pin this far above the plate surface is out of it [mm].
OUT_MM = 0.01
#: The problems planned in the default run (the rest are slow).
FAST = ("zk500_table6_seam",)


def _table(path: Path) -> dict[str, Any]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    out: dict[str, Any] = {}
    for j, h in enumerate(head):
        col = [r[j] for r in body]
        try:
            out[h] = np.array([float(c) if c else np.nan for c in col])
        except ValueError:
            out[h] = np.array(col)
    return out


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory, plan_folder: Any):
    """``written(problem)`` -> the columns of ``waypoints.csv`` of the session's plan folder
    (what ``rfsw-plan -q plan PROBLEM -o DIR`` writes, planned once per session)."""
    cache: dict[str, dict[str, Any]] = {}

    def get(problem: str) -> dict[str, Any]:
        if problem not in cache:
            folder = plan_folder(problem, tmp_path_factory.mktemp("phases") / problem)
            cache[problem] = _table(folder / "waypoints.csv")
        return cache[problem]

    return get


def _judge(w: dict[str, Any], problem: str) -> list[str]:
    """Every phase-change claim on one plan; the list of those that fail (empty: all hold)."""
    pr = load_problem(problem)
    proc = pr.process
    nrm = np.asarray(pr.seam.surface_normal, dtype=float).reshape(-1, 3)[0]
    nrm = nrm / np.linalg.norm(nrm)
    ph, t = w["phase"], w["t_s"]
    pin = np.stack([w[f"{a}_mm"] + w[f"d{a}_mm"] for a in "xyz"], axis=1)
    seam = np.stack([w[f"seam_{a}_mm"] for a in "xyz"], axis=1)
    F = np.stack([w["fx_N"], w["fy_N"], w["fz_N"]], axis=1)
    depth = proc.plunge_depth * 1e3
    # Pin height above the plate surface (the seam point lies at the planned depth).
    height = (pin - seam) @ nrm - depth
    travel = np.flatnonzero(np.isin(ph, ("accelerate", "weld")))
    far = travel[np.flatnonzero(w["s_mm"][travel] > 1.0)[0]]
    t_hat = seam[far] - seam[travel[0]]
    t_hat -= (t_hat @ nrm) * nrm
    t_hat /= np.linalg.norm(t_hat)
    bad: list[str] = []
    dwell = np.flatnonzero(ph == "dwell")
    plunge = np.flatnonzero(ph == "plunge")
    end = plunge[-1]
    # The dwell lasts the problem's dwell time (one sample either way).
    dur = t[dwell[-1]] - t[end]
    step = float(np.median(np.diff(t)))
    if abs(dur - proc.dwell_time) > step + 1e-6:
        bad.append(f"dwell {dur:.3f} s, the problem's {proc.dwell_time:g} s")
    # The pin stands still while the tool does: from the plunge's end through the dwell.
    stand = np.concatenate([[end], dwell])
    lat = np.ptp(w["e_lat_mm"][stand])
    along = np.ptp((pin[stand] - pin[end]) @ t_hat)
    if lat > STANDSTILL_MM or along > STANDSTILL_MM:
        bad.append(f"pin moves {lat:.3f} mm sideways, {along:.3f} mm along during the dwell")
    # No step while standing: every component of the force changes no faster than the dwell's
    # own ramp allows: the steepest slope of its exponential, the total change D over the
    # dwell T with time constant tau giving D / (tau (1 - exp(-T / tau))), times the 1.875
    # peak slope of the smoothstep between waypoints, plus a newton of round-off.
    dF = np.abs(np.diff(F[stand], axis=0))
    total = np.ptp(F[stand], axis=0)
    tau = proc.forces.dwell_tau
    slope = total / (tau * (1.0 - np.exp(-max(proc.dwell_time, step) / tau)))
    allowed = 1.875 * slope * np.diff(t[stand]).max() + 1.0
    if np.any(dF > allowed[None]):
        bad.append(f"force steps by {dF.max(axis=0).round(1)} N per sample in the dwell "
                   f"(ramp allows {allowed.round(1)})")
    # The traverse force builds with travel only: along the seam the force stays what it is
    # when the tool stands (the tilted axial force's share), and once the tool travels it
    # grows no faster than the ramp in the distance travelled, F_r (1 - exp(-s / L)).
    f_t = F @ t_hat
    if np.ptp(f_t[stand]) > 1.0:
        bad.append(f"force along the seam changes by {np.ptp(f_t[stand]):.1f} N while standing")
    acc = np.flatnonzero(ph == "accelerate")
    ramp = proc.forces.traverse * (1 - np.exp(-w["s_mm"][acc] * 1e-3 / proc.forces.ramp_length))
    grown = np.abs(f_t[acc] - f_t[dwell[-1]])
    if np.any(grown > 1.05 * ramp + 1.0):
        bad.append(f"traverse force {grown.max():.1f} N before the tool has travelled for it")
    # The end stop: after the weld's last sample the tool stands, the pin in the plate, while
    # the forces relax to the start standstill's (no traverse force, the dwell's share of the
    # lateral force); only then does the retract lift it.
    bad += _judge_end_stop(w, proc, F, pin, height, t_hat, step)
    # The plunge reaches its depth when it ends.
    if abs(height[end] + depth) > DEPTH_MM:
        bad.append(f"the plunge ends {height[end] + depth:+.3f} mm from the planned depth")
    # No force with the pin out of the plate (approach, plunge in the air, retract).
    out = height > OUT_MM
    if np.any(np.linalg.norm(F[out], axis=1) > 1.0):
        k = np.flatnonzero(out)[np.argmax(np.linalg.norm(F[out], axis=1))]
        bad.append(f"{np.linalg.norm(F[k]):.0f} N with the pin {height[k]:.3f} mm above the "
                   f"plate ({ph[k]}, t = {t[k]:.2f} s)")
    # The spindle runs, at speed, whenever the pin is in the plate, and ran up before.
    inside = height < -OUT_MM
    on = w["spindle_on"] == 1
    slow = inside & (~on | (np.abs(w["spindle_rpm"] - proc.rotation_speed_rpm) > 1e-6))
    if slow.any():
        k = int(np.flatnonzero(slow)[0])
        bad.append(f"spindle at {w['spindle_rpm'][k]:g} rpm with the pin "
                   f"{-height[k]:.3f} mm in the plate ({ph[k]}, t = {t[k]:.2f} s)")
    # It stops only with the pin as high above the plate as where it started (the spindle
    # clearance, the approach's end), where the programs' spindle-stop hook runs: not at the
    # pin's exit (a stream or cell PLC switching by the column stopped it at the surface).
    runs = np.flatnonzero(on)
    stop = runs[-1] + 1
    if stop < len(on) and height[stop] < height[runs[0]] - 1e-3:
        bad.append(f"spindle off with the pin {height[stop]:.3f} mm above the plate, it "
                   f"started {height[runs[0]]:.3f} mm above ({ph[stop]}, t = {t[stop]:.2f} s)")
    first_on = t[np.flatnonzero(on)[0]]
    touch = t[np.flatnonzero(inside)[0]]
    if touch - first_on < proc.spindle_runup - step:
        bad.append(f"spindle on {touch - first_on:.2f} s before the pin touches, run-up "
                   f"{proc.spindle_runup:g} s")
    return bad


def _judge_end_stop(w: dict[str, Any], proc: Any, F: np.ndarray, pin: np.ndarray,
                    height: np.ndarray, t_hat: np.ndarray, step: float) -> list[str]:
    """The end stop's claims: it lasts the problem's ``end_stop_s``, the pin stands (sideways
    and along the seam within STANDSTILL_MM, at its depth) from the weld's last sample to the
    stop's end, no force steps faster than the relaxation allows, the forces have relaxed
    (traverse 0, lateral the dwell's share) before the pin rises, and never grow again."""
    ph, t = w["phase"], w["t_s"]
    bad: list[str] = []
    stop = np.flatnonzero(ph == "stop")
    if proc.end_stop <= 0:
        return [] if not len(stop) else [f"{len(stop)} end-stop samples without an end stop"]
    if not len(stop):
        return ["no end stop"]
    rows = np.concatenate([stop[:1] - 1, stop])
    dur = t[stop[-1]] - t[rows[0]]
    if abs(dur - proc.end_stop) > step + 1e-6:
        bad.append(f"end stop {dur:.3f} s, the problem's {proc.end_stop:g} s")
    lat = np.ptp(w["e_lat_mm"][rows])
    along = np.ptp((pin[rows] - pin[rows[0]]) @ t_hat)
    sink = np.ptp(height[rows])
    if lat > STANDSTILL_MM or along > STANDSTILL_MM or sink > DEPTH_MM:
        bad.append(f"pin moves {lat:.3f} mm sideways, {along:.3f} mm along, {sink:.3f} mm "
                   "up or down during the end stop")
    # No step: the relaxation's steepest slope (total change D over the stop T, from rest to
    # rest: 1.875 D / T, the smoothstep's peak) per sample, plus a newton of round-off.
    fp = proc.forces
    dF = np.abs(np.diff(F[rows], axis=0))
    total = np.ptp(F[rows], axis=0)
    allowed = 1.875 * total / proc.end_stop * np.diff(t[rows]).max() + 1.0
    if np.any(dF > allowed[None]):
        bad.append(f"force steps by {dF.max(axis=0).round(1)} N per sample in the end stop "
                   f"(relaxation allows {allowed.round(1)})")
    # Relaxed before the pin rises (the pin stood at its depth through the stop, above): at
    # the stop's last sample, in the frame of the tool axis (the written orientation's z) and
    # the seam's direction at its end, no traverse force and the lateral force at the dwell's
    # share.
    k = rows[-1]
    n, t_end = _end_frame(w)
    l_end = np.cross(n, t_end)
    l_end /= np.linalg.norm(l_end)
    f_l = float(F[k] @ l_end)
    f_t = float(np.linalg.norm(F[k] - f_l * l_end - (F[k] @ n) * n))
    share = fp.dwell_lateral_fraction * fp.lateral
    # A newton, and the frame read from the written columns (the tool axis as commanded, the
    # seam's end as a chord): 0.03 deg of it moves 5 kN by 2.6 N (kr600_curved_seam: 1.6 N).
    tol = 1.0 + 5e-4 * float(np.linalg.norm(F[k]))
    if f_t > tol or abs(abs(f_l) - share) > tol:
        bad.append(f"the pin rises with {f_t:.1f} N along the seam and {abs(f_l):.1f} N "
                   f"sideways (standstill: 0 and {share:.1f} N)")
    # From the stop on the force only falls (no growth before or during the retract).
    mag = np.linalg.norm(F[rows[0]:], axis=1)
    if np.any(np.diff(mag) > 1.0):
        bad.append(f"the force grows by {np.diff(mag).max():.1f} N after the weld")
    return bad


def _end_frame(w: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The tool axis out of the plate (minus the written orientation's z) and the seam's
    direction over its last 0.1 mm (a curved seam turns over a longer chord), at the weld's
    last sample."""
    weld = np.flatnonzero(w["phase"] == "weld")
    k = weld[-1]
    qw, qx, qy, qz = (w[c][k] for c in ("qw", "qx", "qy", "qz"))
    n = -np.array([2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx), 1 - 2 * (qx * qx + qy * qy)])
    n /= np.linalg.norm(n)
    seam = np.stack([w[f"seam_{a}_mm"] for a in "xyz"], axis=1)
    j = weld[np.flatnonzero(w["s_mm"][weld] < w["s_mm"][k] - 0.1)[-1]]
    t_end = seam[k] - seam[j]
    t_end -= (t_end @ n) * n
    return n, t_end / np.linalg.norm(t_end)


@pytest.mark.parametrize("problem", FAST)
def test_phase_changes_follow_the_motion(written, problem: str) -> None:
    assert _judge(written(problem), problem) == []


@pytest.mark.slow
@pytest.mark.parametrize("problem", [p for p in bundled_problem_names() if p not in FAST])
def test_phase_changes_follow_the_motion_every_problem(written, problem: str) -> None:
    assert _judge(written(problem), problem) == []


def test_the_judge_catches_a_traverse_step_and_a_short_dwell(written) -> None:
    """The checks can fail: the old faults put back into a written plan are named."""
    w = {k: v.copy() for k, v in written("zk500_table6_seam").items()}
    dwell = np.flatnonzero(w["phase"] == "dwell")
    # -295 N of traverse force on the standing tool for the last 7 samples of the dwell
    # (what main wrote before), along the seam's direction (about +y here).
    w["fy_N"][dwell[-7:]] -= 295.0
    # And the dwell 0.5 s shorter (its last sample earlier).
    w["t_s"][dwell[-1]:] -= 0.5
    bad = _judge(w, "zk500_table6_seam")
    assert any(b.startswith("dwell ") for b in bad), bad
    assert any("while standing" in b for b in bad), bad


def test_the_judge_catches_an_end_stop_that_slides_or_lifts_loaded(written) -> None:
    """The end stop's checks can fail: the stored lateral deflection springing back while the
    tool stands, a step in the relaxation, and a retract that lifts before the forces relaxed
    (the stop's relaxation cut short: the weld's forces still on at the lift)."""
    w0 = written("zk500_table6_seam")
    stop = np.flatnonzero(w0["phase"] == "stop")
    w = {k: v.copy() for k, v in w0.items()}
    # The pin slides 0.3 mm sideways over the stop (the deflection springs back, the offsets
    # not following it).
    w["e_lat_mm"][stop] += np.linspace(0.0, 0.3, len(stop))
    # The relaxation's last 20 % at once, in its last sample.
    F = np.stack([w["fx_N"], w["fy_N"], w["fz_N"]], axis=1)
    cut = stop[-len(stop) // 5:]
    F[cut[:-1]] = F[cut[0]]
    w["fx_N"], w["fy_N"], w["fz_N"] = F.T.copy()
    bad = _judge(w, "zk500_table6_seam")
    assert any("during the end stop" in b for b in bad), bad
    assert any("in the end stop" in b for b in bad), bad
    w = {k: v.copy() for k, v in w0.items()}
    # The weld's last force held through the stop and falling only with the depth over the
    # retract: the pin rises loaded.
    F = np.stack([w["fx_N"], w["fy_N"], w["fz_N"]], axis=1)
    after = np.arange(stop[0], len(F))
    rho = np.linalg.norm(F[after], axis=1) / np.linalg.norm(F[stop[-1]])
    F[after] = np.minimum(rho, 1.0)[:, None] * F[stop[0] - 1]
    w["fx_N"], w["fy_N"], w["fz_N"] = F.T.copy()
    bad = _judge(w, "zk500_table6_seam")
    assert any(b.startswith("the pin rises with") for b in bad), bad


def test_the_judge_catches_a_spindle_stopped_at_the_pins_exit(written) -> None:
    """The spindle-stop check can fail: the spindle switched off where the pin leaves the
    plate (what ``waypoints.csv`` and the stream wrote before, while the programs' hook
    stopped it at the spindle clearance) is named with the pin's height."""
    w = {k: v.copy() for k, v in written("zk500_table6_seam").items()}
    retract = np.flatnonzero(w["phase"] == "retract")
    assert np.flatnonzero(w["spindle_on"] == 1)[-1] > retract[0]  # runs into the retract
    w["spindle_on"][retract[0] + 1:] = 0  # off as the pin starts to rise
    w["spindle_rpm"][retract[0] + 1:] = 0.0
    bad = _judge(w, "zk500_table6_seam")
    assert any(b.startswith("spindle off with the pin") for b in bad), bad
