"""``plan.json``, the commit record of a plan folder: :class:`PlanRecord`.

One type for the record every command writes and reads: ``rfsw-plan plan`` and
:func:`rfsw_plan.write_plan` build it from a :class:`~rfsw_plan.planning.result.PlanResult`
(:meth:`PlanRecord.from_result`) or from a refusal (:meth:`PlanRecord.refused`), ``export``
adds its programs to it, and :class:`~rfsw_plan.planfiles.folder.PlanFolder` reads it back
(:meth:`PlanRecord.read`, strict JSON). The keys readers rely on are typed properties, checked
by :meth:`PlanRecord.from_json`; every other key of the planner's summary is kept as written,
in its order, so a record read and written again has the same bytes.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rfsw_plan.exceptions import InfeasibleError, InputError
from rfsw_plan.files import sha256_file, write_json

if TYPE_CHECKING:
    from rfsw_plan.planning.result import PlanResult

#: Statuses of a verified plan (``plan.json`` ``status``): the NLP's (``optimal``) or the
#: verified fallback's (``verified``), ``_nominal`` when the requested force uncertainty is not
#: held (:func:`rfsw_plan.planning.api.plan_task`).
VERIFIED_STATUSES = ("optimal", "optimal_nominal", "verified", "verified_nominal")
#: Largest plan record read [bytes] (a plan of 100k samples writes about 20 MB).
MAX_RECORD_BYTES = 200_000_000
#: The keys of ``plan.json`` readers rely on, with the JSON types they must have when present.
TYPED_KEYS: dict[str, tuple[type, ...]] = {
    "status": (str,), "problem": (str,), "problem_file": (str, type(None)),
    "robot_file": (str, type(None)), "robot": (str, type(None)),
    "message": (str, type(None)), "sha256": (dict,), "files": (list,), "plots": (dict,),
    "n_start_waypoints": (int,), "waypoints": (dict,), "force_log": (dict, type(None)),
    "export": (dict,),
}
#: The unit of an :class:`InfeasibleError` margin by its constraint (file units, key suffix).
MARGIN_UNITS = {"weld_speed": (1e3, "mm_s"), "singularity": (1.0, "kappa")}


@dataclass(frozen=True)
class PlanRecord(Mapping[str, Any]):
    """The contents of ``plan.json`` (file units: mm, deg, s, N).

    A read-only mapping of the record's keys in their written order; the keys every reader
    uses are typed properties. Build a changed record with :meth:`with_keys` or
    :meth:`without`.

    Attributes:
        body: Every key of the record, in order (JSON values).
    """

    body: dict[str, Any] = field(default_factory=dict)

    # ---- mapping -------------------------------------------------------------------------
    def __getitem__(self, key: str) -> Any:
        return self.body[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.body)

    def __len__(self) -> int:
        return len(self.body)

    # ---- typed keys ----------------------------------------------------------------------
    @property
    def status(self) -> str:
        """``optimal``, ``optimal_nominal``, ``verified``, ``verified_nominal`` (a verified
        plan), ``infeasible``, ``failed`` or ``incomplete``; ``""`` if missing."""
        return str(self.body.get("status") or "")

    @property
    def verified(self) -> bool:
        """The record is a verified plan's."""
        return self.status in VERIFIED_STATUSES

    @property
    def problem(self) -> str:
        """The problem's name."""
        return str(self.body.get("problem") or "plan")

    @property
    def problem_file(self) -> str:
        """The problem file the plan was made for (``problem_file``, else ``problem``), or
        ``""``."""
        return str(self.body.get("problem_file") or self.body.get("problem") or "")

    @property
    def robot_file(self) -> str:
        """The robot file or bundled name the plan was made with (``robot_file``, else
        ``robot``), or ``""``."""
        return str(self.body.get("robot_file") or self.body.get("robot") or "")

    @property
    def sha256(self) -> dict[str, str]:
        """The files the record vouches for: name -> hex SHA-256."""
        d = self.body.get("sha256")
        return dict(d) if isinstance(d, dict) else {}

    @property
    def n_start_waypoints(self) -> int | None:
        """Number of stationary waypoints of the plan's task, or None if not recorded."""
        n = self.body.get("n_start_waypoints")
        return n if isinstance(n, int) and not isinstance(n, bool) else None

    @property
    def waypoints(self) -> dict[str, Any]:
        """The planned waypoints (``phase``, ``s_mm``, ``q_deg``...), or ``{}``."""
        wp = self.body.get("waypoints")
        return wp if isinstance(wp, dict) else {}

    @property
    def spacing(self) -> float:
        """The plan's weld waypoint spacing along the seam [m] (median step of ``s_mm``).

        Raises:
            InputError: No weld waypoints with increasing arc length.
        """
        try:
            s = np.asarray(self.waypoints.get("s_mm", []), dtype=float)
        except (TypeError, ValueError):
            raise InputError("plan.json", "waypoints.s_mm", "not numbers", "arc lengths") from None
        steps = np.diff(s)
        steps = steps[np.isfinite(steps) & (steps > 1e-9)]
        if steps.size == 0:
            raise InputError("plan.json", "waypoints.s_mm", "no weld waypoints",
                             "a plan record with waypoints")
        return float(np.median(steps)) * 1e-3

    # ---- building ------------------------------------------------------------------------
    def with_keys(self, **keys: Any) -> PlanRecord:
        """The record with ``keys`` set (an existing key keeps its place, a new one is last)."""
        return PlanRecord({**self.body, **keys})

    def without(self, *keys: str) -> PlanRecord:
        """The record without ``keys``."""
        return PlanRecord({k: v for k, v in self.body.items() if k not in keys})

    @classmethod
    def from_result(cls, result: PlanResult, **keys: Any) -> PlanRecord:
        """The record of a verified plan: its summary (:meth:`PlanResult.summary`) and the
        caller's ``keys`` (``robot_file``, ``problem_file``, ``export``...)."""
        return cls({**result.summary(), **keys})

    @classmethod
    def refused(cls, problem: str, exc: Exception, force_uncertainty: float,
                what: str = "") -> PlanRecord:
        """The record of a plan the planner refused: ``infeasible`` (with the verdict NO, the
        waypoint, the constraint and its margin with its unit in the key) for an
        :class:`InfeasibleError`, ``failed`` for any other error; ``what`` says what is
        refused when it is not the plan (:func:`~rfsw_plan.planning.verdict.no_plan`)."""
        body: dict[str, Any] = {"status": "failed", "problem": problem, "message": str(exc)}
        if isinstance(exc, InfeasibleError):
            from rfsw_plan.planning.verdict import no_plan

            verdict = no_plan(str(exc), force_uncertainty, what)
            body = {**verdict.to_dict(), **body, "status": "infeasible",
                    "waypoint": None if exc.waypoint is None else exc.waypoint + 1,
                    "constraint": exc.constraint, **margin_entry(exc)}
        return cls(body)

    @classmethod
    def incomplete(cls, problem: str) -> PlanRecord:
        """The record of a plan started into a folder and not finished."""
        return cls({"status": "incomplete", "problem": problem,
                    "message": "a plan was started into this folder and has not finished; the "
                               "files beside this record are not a verified plan"})

    # ---- JSON ----------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``plan.json`` (a copy, in the record's key order)."""
        return dict(self.body)

    @classmethod
    def from_json(cls, obj: Any, path: str | Path = "plan.json") -> PlanRecord:
        """A record from a decoded ``plan.json`` object, its typed keys checked.

        Raises:
            InputError: Not an object, or a typed key of the wrong JSON type (one line naming
                ``path`` and the key).
        """
        if not isinstance(obj, dict):
            raise InputError(path, "", f"a JSON {type(obj).__name__}, not an object",
                             "plan.json as rfsw-plan writes it")
        for key, types in TYPED_KEYS.items():
            if key in obj and (not isinstance(obj[key], types) or isinstance(obj[key], bool)):
                want = " or ".join("null" if t is type(None) else _JSON_NAMES[t] for t in types)
                raise InputError(path, key, f"a JSON {_json_name(obj[key])}", want)
        return cls(dict(obj))

    @classmethod
    def read(cls, path: str | Path) -> PlanRecord:
        """``plan.json`` as strict JSON (UTF-8 only; NaN, Infinity, duplicate keys refused).

        Raises:
            InputError: Missing, not UTF-8, not strict JSON, not an object, or a typed key of
                the wrong type.
        """
        p = Path(path)
        if not p.is_file():
            raise InputError(p, "", "missing", "a plan.json written by rfsw-plan plan")
        data = p.read_bytes()
        if len(data) > MAX_RECORD_BYTES:
            raise InputError(p, "", f"{len(data)} bytes", f"at most {MAX_RECORD_BYTES} bytes")
        if not data.strip():
            raise InputError(p, "", "empty file", "a plan.json written by rfsw-plan plan")
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError(p, f"byte {exc.start}", "not UTF-8 text",
                             "plan.json as rfsw-plan writes it (UTF-8 JSON)") from None
        try:
            rec = json.loads(text, parse_constant=_reject_constant,
                             object_pairs_hook=_no_duplicates)
        except (ValueError, RecursionError) as exc:
            where = (f"line {exc.lineno} column {exc.colno}"
                     if isinstance(exc, json.JSONDecodeError) else "")
            msg = exc.msg if isinstance(exc, json.JSONDecodeError) else str(exc)
            raise InputError(p, where, f"not strict JSON ({msg})",
                             "plan.json as rfsw-plan writes it") from None
        return cls.from_json(rec, p)

    def write(self, path: str | Path, vouches_for: list[Path] | tuple[Path, ...] = ()
              ) -> Path:
        """Write ``plan.json`` atomically as strict JSON (NaN and inf become null).

        ``plan.json`` is the commit record of a plan folder: it is written last, and
        ``sha256`` maps the name of every file it vouches for (written before it) to the
        SHA-256 of its bytes, so a reader can tell that the files beside it are this plan's
        and whole (:meth:`rfsw_plan.planfiles.folder.PlanFolder.open`).
        """
        body = self.to_json()
        if vouches_for:
            body["sha256"] = {Path(f).name: sha256_file(f) for f in vouches_for}
        return write_json(path, body)

    def check_status(self, path: str | Path) -> str:
        """The status of a verified plan.

        Raises:
            InfeasibleError: ``infeasible`` (exit 3), with the plan's reason.
            InputError: Any other unverified status (exit 2), with its reason.
        """
        status = self.body.get("status")
        if status in VERIFIED_STATUSES:
            return str(status)
        reason = str(self.body.get("message") or self.body.get("warning") or "no reason given")
        reason = " ".join(reason.split())[:300]
        if status == "infeasible":
            raise InfeasibleError(f"{path}: status 'infeasible': {reason} (expected a verified "
                                  f"plan: {', '.join(VERIFIED_STATUSES)})", None, "status", None)
        shown = "missing" if status is None else f"'{status}'"
        raise InputError(path, "status", f"{shown}: {reason}",
                         f"a verified plan ({', '.join(VERIFIED_STATUSES)})")


def provenance_keys(problem: Any, log: Any = None, check: Any = None) -> dict[str, Any]:
    """Entries of ``plan.json`` that say where the problem and robot came from (a bundled file
    by its name, any other by its absolute path; read back by
    :meth:`~rfsw_plan.planfiles.folder.PlanFolder.rebuild`), and, for a plan made from a force
    log (:mod:`rfsw_plan.planning.force_log`), the ``force_log`` block and the measured force
    uncertainty beside the tolerated one.

    Args:
        problem: The planned problem (its ``path`` and its robot's ``path``).
        log: The fitted force log, or None.
        check: The plan's check under the measured force box, or None.
    """
    from rfsw_plan.planning.force_log import force_log_json
    from rfsw_plan.process.problem import BUNDLED_PROBLEMS_DIR
    from rfsw_plan.robot.bundled import bundled_ref
    from rfsw_plan.robot.description import BUNDLED_ROBOTS_DIR

    robot_path = getattr(problem.robot, "path", None)
    out: dict[str, Any] = {  # a bundled file by its name: the same bytes on any machine
        "problem_file": bundled_ref(BUNDLED_PROBLEMS_DIR, problem.path) if problem.path else None,
        "robot_file": bundled_ref(BUNDLED_ROBOTS_DIR, robot_path) if robot_path else None,
    }
    if log is not None:
        out["force_log"] = force_log_json(log, check)
        if log.usable and check is not None:
            unc = log.uncertainty
            # Beside tolerated_force_uncertainty: what the trial weld says the force does.
            out["measured_force_uncertainty"] = {
                "coverage_sigma": unc.coverage, "frame": "seam (t, l, n)",
                "weld_bound_N": [float(x) for x in unc.bound.get("weld", [])],
                "weld_relative": [float(x) for x in unc.weld_relative],
                "equivalent_relative": check.u_equivalent,
                "plan_holds": check.holds,
            }
    return out


def margin_entry(exc: InfeasibleError) -> dict[str, float | None]:
    """The ``plan.json`` entry of an infeasible plan's margin, with its unit in the key:
    ``margin_mm`` (window, pose), ``margin_deg`` (joint checks), ``margin_mm_s`` (weld speed:
    the feasible speed minus the requested one), ``margin_kappa`` (singularity)."""
    c = exc.constraint or ""
    scale, unit = MARGIN_UNITS.get(c, (180.0 / 3.141592653589793, "deg") if c.startswith(
        "joint_") else (1e3, "mm"))
    return {f"margin_{unit}": None if exc.margin is None else exc.margin * scale}


_JSON_NAMES = {str: "string", dict: "object", list: "array", int: "integer", float: "number"}


def _json_name(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "boolean"
    return _JSON_NAMES.get(type(v), type(v).__name__)


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"duplicate key '{k}'")
        out[k] = v
    return out


__all__ = ["MARGIN_UNITS", "VERIFIED_STATUSES", "PlanRecord", "margin_entry", "provenance_keys"]
