"""Validate the model against a measured weld (``rfsw-plan validate-weld``).

After a trial weld a welding engineer holds the plan that was run, the force log of the
spindle or wrist sensor, and a measurement of where the weld went (a laser line scan of the
bead, or seed 000's lateral offset Delta y = D1 - D2, Figs. 15-17). :func:`validate_weld`:

1. reads the plan that was run (:meth:`~rfsw_plan.planfiles.folder.PlanFolder.rebuild`) and
   puts the track on the seam (:mod:`~rfsw_plan.validation.weld.track`);
2. **predicts the executed pin path** under the logged (or planned) wrench
   (:mod:`~rfsw_plan.validation.weld.samples`);
3. **compares** it with the track: residual r = measured - predicted against s and time, RMS,
   max, the share of the measured weld inside the window;
4. **diagnoses** what the model misses with the workbench's one diagnosis engine, the weld's
   prediction as its input (:mod:`~rfsw_plan.validation.weld.diagnosis`), and says what one
   weld can identify (:mod:`~rfsw_plan.validation.weld.identifiability`);
5. optionally **re-identifies** the candidates asked for (:mod:`~rfsw_plan.validation.weld.add`).
"""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.io.force_series import ForceSeries
from rfsw_plan.io.weld_track import WeldTrack
from rfsw_plan.planfiles.rebuild import RebuiltPlan
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.validation.engine.candidates import candidate_labels
from rfsw_plan.validation.engine.scoring import Candidate
from rfsw_plan.validation.weld.add import WeldAddResult, add_and_identify
from rfsw_plan.validation.weld.diagnosis import DEFAULT_BLOCKS, WeldDiagnosis, diagnose_weld
from rfsw_plan.validation.weld.fit import rms
from rfsw_plan.validation.weld.identifiability import Identifiability
from rfsw_plan.validation.weld.samples import WeldSamples, weld_samples
from rfsw_plan.validation.weld.track import TrackOnSeam, noise_floor, track_on_seam

#: At most this many track points enter the diagnosis (evenly spread).
MAX_POINTS = 600


@dataclass(frozen=True)
class WeldValidation:
    """Outcome of :func:`validate_weld`.

    Attributes:
        plan: The plan that was run.
        model: The current robot model.
        track: The measured track on the seam.
        samples: The executed plan at the track points.
        predicted_lat / predicted_norm: Prediction at the track points [m].
        residual_lat: measured - predicted lateral [m].
        residual_norm: measured - predicted normal [m], or None.
        diagnosis: The diagnosis.
        add: The re-identification (``--add``), or None.
        predicted_after: Lateral prediction of the re-identified model [m], or None.
        forces_source: The force log file, or ``planned``.
    """

    plan: RebuiltPlan
    model: ElastostaticModel
    track: TrackOnSeam
    samples: WeldSamples
    predicted_lat: FloatArray
    predicted_norm: FloatArray
    residual_lat: FloatArray
    residual_norm: FloatArray | None
    diagnosis: WeldDiagnosis
    add: WeldAddResult | None
    predicted_after: FloatArray | None
    forces_source: str
    notes: tuple[str, ...] = field(default=())

    def inside_fraction(self, e: FloatArray) -> float:
        """Share of the measured length (gaps excluded) with e inside the window."""
        w = self.plan.problem.window
        s = self.track.s
        ds = np.gradient(s) if s.size > 1 else np.ones(1)
        ds = np.minimum(ds, 2.0 * float(np.median(ds)))
        inside = (e >= w.lower) & (e <= w.upper)
        return float(np.sum(ds * inside) / np.sum(ds))

    def to_json(self) -> dict[str, Any]:
        """``validate_weld.json`` (mm, s)."""
        w = self.plan.problem.window
        out: dict[str, Any] = {
            "plan_dir": str(self.plan.folder), "problem": self.plan.problem.name,
            "robot": self.model.robot.name, "effects": self.model.labels,
            "forces": self.forces_source,
            "window_mm": [w.lower * 1e3, w.upper * 1e3],
            "track": {"points": int(self.track.s.size), "gaps": self.track.gaps,
                      "outside_seam": self.track.dropped,
                      "overlap_mm": [self.track.overlap[0] * 1e3, self.track.overlap[1] * 1e3],
                      "seam_length_mm": self.track.seam_length * 1e3,
                      "normal_measured": self.track.e_norm is not None},
            "measured_inside_window_fraction": self.inside_fraction(self.track.e_lat),
            "predicted_inside_window_fraction": self.inside_fraction(self.predicted_lat),
            "residual_lat": _stats_mm(self.residual_lat),
            "residual_norm": None if self.residual_norm is None else _stats_mm(
                self.residual_norm),
            "diagnosis": self.diagnosis.to_json(),
            "add": None if self.add is None else self.add.to_json(),
            "notes": list(self.notes),
            "samples": {"s_mm": (self.track.s * 1e3).tolist(),
                        "t_s": self.samples.t.tolist(),
                        "measured_lat_mm": (self.track.e_lat * 1e3).tolist(),
                        "predicted_lat_mm": (self.predicted_lat * 1e3).tolist(),
                        "residual_lat_mm": (self.residual_lat * 1e3).tolist()},
        }
        if self.predicted_after is not None:
            out["samples"]["predicted_after_lat_mm"] = (self.predicted_after * 1e3).tolist()
        return out


def _stats_mm(r: FloatArray) -> dict[str, float]:
    return {"rms_mm": rms(r) * 1e3, "max_abs_mm": float(np.max(np.abs(r))) * 1e3,
            "mean_mm": float(np.mean(r)) * 1e3}


def validate_weld(
    plan: RebuiltPlan, track: WeldTrack, series: ForceSeries | None = None,
    model: ElastostaticModel | None = None, add: Sequence[str] = (),
    blocks: int = DEFAULT_BLOCKS, smooth_s: float = 0.25,
) -> WeldValidation:
    """Predict the executed weld, compare with the track, diagnose, optionally re-identify.

    Args:
        plan: The plan that was run
            (:meth:`rfsw_plan.planfiles.folder.PlanFolder.rebuild`).
        track: The measured weld.
        series: The force log of the weld (None: the planned forces).
        model: The current robot model (default: the plan's robot).
        add: Candidates to add and fit (``joint_compliance:jN`` or effect labels).
        blocks: Blocks of s of the cross-validation.
        smooth_s: Running-mean window of the force log [s].

    Raises:
        InputError: Track off the seam or in wrong units; bad labels.
    """
    from rfsw_plan.robot.kinematics import load_robot

    problem = plan.problem
    model = model or ElastostaticModel(load_robot(problem.robot))
    on = track_on_seam(track, problem)
    notes: list[str] = []
    if series is not None:
        from rfsw_plan.planning.force_log import check_axial

        check_axial(series, problem, problem.planning.tool_rotation)
    else:
        notes.append("no force log: the prediction uses the planned forces, so force drift "
                     "along the seam shows up in the residual")
    if on.s.size > MAX_POINTS:
        idx = np.unique(np.round(np.linspace(0, on.s.size - 1, MAX_POINTS)).astype(int))
        on = TrackOnSeam(on.s[idx], on.e_lat[idx], None if on.e_norm is None else on.e_norm[idx],
                         on.overlap, on.seam_length, on.dropped, on.gaps)
        notes.append(f"diagnosis on {idx.size} of the track points (evenly spread)")
    samples = weld_samples(problem, plan.waypoints, on.s, series, smooth_s)
    ref = problem.seam_reference
    e_lat, e_norm = samples.predict(model, ref)
    res_lat = on.e_lat - e_lat
    res_norm = None if on.e_norm is None else on.e_norm - e_norm
    diag = diagnose_weld(model, samples, on, ref, blocks=blocks)
    added = None
    after = None
    if add:
        added = add_and_identify(model, samples, on, ref, list(add), blocks)
        after = samples.predict(added.model, ref)[0]
    return WeldValidation(plan, model, on, samples, e_lat, e_norm, res_lat, res_norm, diag,
                          added, after, series.source if series is not None else "planned",
                          tuple(notes))


def next_command(result: WeldValidation, plan_dir: str, track: str, forces: str | None,
                 saved: Path | None) -> str:
    """The command to run next (printed and in the report)."""
    pb = result.plan.problem
    problem = str(pb.path) if pb.path else pb.name
    f = f" --forces {forces}" if forces else ""
    if saved is not None:
        return f"rfsw-plan plan {problem}{f} --robot {saved} -o {plan_dir.rstrip('/')}_2"
    dg = result.diagnosis
    if dg.verdict == "missing" and dg.best is not None:
        from rfsw_plan.robot.description import derived_file, derived_name

        new = derived_name(result.model.robot.name, [dg.best.label])
        return (f"rfsw-plan validate-weld {plan_dir} --track {track}{f} --add "
                f"{dg.best.label} --save-robot {shlex.quote(derived_file(new))}")
    if dg.verdict == "adequate":
        return f"rfsw-plan plan {problem}{f} -o {plan_dir.rstrip('/')}_2  (the model holds)"
    return ("measure more (another weld at a different pose or direction separates the "
            "candidates), or rfsw-plan validate with a load campaign")


#: The names of the weld validation, re-exported from the modules that define them.
__all__ = ["Candidate", "Identifiability", "RebuiltPlan", "TrackOnSeam", "WeldAddResult",
           "WeldDiagnosis", "WeldSamples", "WeldValidation", "add_and_identify",
           "candidate_labels", "diagnose_weld", "next_command", "noise_floor", "track_on_seam",
           "validate_weld", "weld_samples"]
