"""The ``map`` and ``place`` jobs: screen a map of placements (:class:`PlacementMapRequest`);
plan the best candidates, choose the most robust one (:class:`PlaceRequest`); write the folder.

One library call per command (``rfsw-plan map`` and ``rfsw-plan place`` are thin layers)::

    PlacementMapRequest(load_problem("zk500_table6_seam")).run().write("out/map/zk500")

    run = PlaceRequest(load_problem("kr600_curved_seam"), MapRequest(shape=(15, 15, 8, 3)),
                       candidates=4).run()
    run.write("out/place/kr600_curved_seam")   # map.csv, map.json, map.png, map_yaw.png,
                                               # candidates.csv, place.json, <problem>_placed.toml

Errors name the request's parameters (``candidates``, ``region``, ``shape``...), never a
command-line flag; the CLI maps them to its flags (:mod:`rfsw_plan.cli.params`).
"""

from __future__ import annotations

import csv
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rfsw_plan.exceptions import InputError
from rfsw_plan.files import atomic_path, write_json
from rfsw_plan.numfmt import general
from rfsw_plan.placement.files import (
    map_summary,
    write_map_csv,
    write_map_json,
    write_placed_problem,
)
from rfsw_plan.placement.optimise import PlaceResult, place, results_table
from rfsw_plan.placement.session import MapRequest, MapSession, map_problem
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.problem import Problem, load_problem

#: Columns of ``candidates.csv``, in order (file units in the names).
CANDIDATE_COLUMNS = (
    "rank", "label", "chosen", "x_mm", "y_mm", "z_mm", "yaw_deg", "dx_mm", "dy_mm",
    "robot_base_height_mm", "status", "tolerated_uncertainty", "max_abs_lateral_mm",
    "min_lateral_stiffness_N_per_mm", "sample_window_margin_mm",
    "dominant_compliance", "screen_tolerated_uncertainty_centred", "message")
#: The files of a map folder.
MAP_FILES = ("map.csv", "map.json", "map.png", "map_yaw.png")
#: The files of a place folder besides the placed problem file.
PLACE_FILES = ("map.csv", "map.json", "map.png", "map_yaw.png", "candidates.csv", "place.json")


def _options(problem: Problem, force_uncertainty: float | None) -> PlanOptions:
    from rfsw_plan.planning.api import options_from_problem

    over = {} if force_uncertainty is None else {"force_uncertainty": force_uncertainty}
    return options_from_problem(problem, over)


def _problem(problem: Problem | str) -> Problem:
    return problem if isinstance(problem, Problem) else load_problem(problem)


@dataclass(frozen=True)
class PlacementMapRequest:
    """Where to screen placements.

    Attributes:
        problem: The problem at its given placement (or a problem file / bundled name).
        region: The region, yaw, height and grid of the map.
        force_uncertainty: The requested relative force uncertainty (None: the problem's).
    """

    problem: Problem | str
    region: MapRequest = field(default_factory=MapRequest)
    force_uncertainty: float | None = None

    def run(self) -> PlacementMapRun:
        """Compute the map (prints nothing, writes nothing).

        Raises:
            InputError: A region with no usable placement (one line).
        """
        problem = _problem(self.problem)
        opts = _options(problem, self.force_uncertainty)
        return PlacementMapRun(problem, opts, map_problem(problem, self.region, opts))


@dataclass(frozen=True)
class PlacementMapRun:
    """A computed placement map.

    Attributes:
        problem: The problem at its given placement.
        options: The planner options (the requested uncertainty).
        session: The map, its input and the reach of the default region.
    """

    problem: Problem
    options: PlanOptions
    session: MapSession

    def to_dict(self, folder: str | Path | None = None) -> dict[str, Any]:
        """The summary (``map.json`` without the columns), with the reach of the default
        region and (with ``folder``) the files."""
        out = map_summary(self.session.map, self.options.force_uncertainty)
        out.update(self._extra(folder))
        return out

    def _extra(self, folder: str | Path | None) -> dict[str, Any]:
        ext = self.session.extent
        extra: dict[str, Any] = {"reach": None if ext is None else ext.text()}
        if folder is not None:
            extra["files"] = [str(Path(folder) / n) for n in MAP_FILES]
        return extra

    def write(self, folder: str | Path) -> list[Path]:
        """Write the map folder (each file atomically): ``map.csv``, ``map.png``,
        ``map_yaw.png``, ``map.json``. The folder must exist.

        Returns:
            The written paths.
        """
        from rfsw_plan.placement.plots import plot_map, plot_yaw

        out = Path(folder)
        m = self.session.map
        u = self.options.force_uncertainty
        write_map_csv(out / "map.csv", m)
        plot_map(out / "map.png", m, requested=u)
        plot_yaw(out / "map_yaw.png", m)
        # the file names its files inside its folder (the same bytes in any folder)
        write_map_json(out / "map.json", m, u, {**self._extra(None), "files": list(MAP_FILES)})
        return [out / n for n in MAP_FILES]


@dataclass(frozen=True)
class PlaceRequest:
    """Where to look and how many candidates to plan.

    Attributes:
        problem: The problem at its given placement (or a problem file / bundled name).
        region: The region, yaw, height and grid of the screening map.
        candidates: Screened placements planned in full, besides the given one (>= 1).
        force_uncertainty: The requested relative force uncertainty (None: the problem's).
        executor: Where the candidate plans run (None: in this process), a process pool or
            Dask's executor.
        executor_label: How ``place.json`` names the executor.
    """

    problem: Problem | str
    region: MapRequest = field(default_factory=MapRequest)
    candidates: int = 4
    force_uncertainty: float | None = None
    executor: Executor | None = None
    executor_label: str = "in process"

    def check(self) -> None:
        """The checks that need no computation (:meth:`run` does them first).

        Raises:
            InputError: ``candidates`` < 1 or ``force_uncertainty`` < 0 (one line).
        """
        if self.candidates < 1:
            raise InputError("candidates", "", f"got {self.candidates}", ">= 1")
        if self.force_uncertainty is not None and not self.force_uncertainty >= 0:
            raise InputError("force_uncertainty", "", f"got {self.force_uncertainty}", ">= 0")

    def run(self) -> PlaceRun:
        """Map, plan the candidates and choose (prints nothing, writes nothing).

        Raises:
            InputError: ``candidates`` < 1, a bad region (one line).
        """
        self.check()
        problem = _problem(self.problem)
        opts = _options(problem, self.force_uncertainty)
        session = map_problem(problem, self.region, opts)
        res = place(problem, session.map, opts, self.candidates, self.executor)
        rows = results_table(res, session.map.anchor)
        return PlaceRun(problem, opts, session, res, rows, self.executor_label)


@dataclass(frozen=True)
class PlaceRun:
    """A placement search.

    Attributes:
        problem: The problem at its given placement.
        options: The planner options the candidates were judged by.
        session: The screening map and its input.
        result: The planned candidates and the choice.
        rows: One row per candidate, best first (``candidates.csv``).
        executor_label: Where the candidate plans ran.
    """

    problem: Problem
    options: PlanOptions
    session: MapSession
    result: PlaceResult
    rows: list[dict[str, Any]]
    executor_label: str = "in process"

    @property
    def chosen(self) -> Any:
        """The chosen candidate's result, or None if no candidate could be planned."""
        return self.result.chosen

    def placed_file(self, folder: str | Path) -> Path:
        """The placed problem file in ``folder``."""
        return Path(folder) / f"{self.problem.name}_placed.toml"

    def files(self, folder: str | Path) -> list[Path]:
        """The files :meth:`write` writes into ``folder`` (the placed problem first)."""
        out = Path(folder)
        placed = [self.placed_file(out)] if self.chosen is not None else []
        return [*placed, *(out / n for n in PLACE_FILES)]

    def to_dict(self, folder: str | Path | None = None) -> dict[str, Any]:
        """``place.json``: the verdict, the given and chosen placements, every candidate, the
        map's summary, and (with ``folder``) the files."""
        u = self.options.force_uncertainty
        out = _summary(self.problem, self.result, self.rows, self.session.map, u,
                       self.executor_label)
        out["map"] = {k: v for k, v in map_summary(self.session.map, u).items()
                      if k not in ("grid",)}
        if folder is not None:
            out["files"] = [str(f) for f in self.files(folder)]
        return out

    def write(self, folder: str | Path) -> list[Path]:
        """Write the place folder (each file atomically; ``place.json`` last): the map
        (``map.csv``, ``map.json``, ``map.png``, ``map_yaw.png``), ``candidates.csv`` and,
        when a candidate was planned, the placed problem file. The folder must exist (the
        CLI prepares and locks it).

        Returns:
            The written paths.
        """
        from rfsw_plan.placement.plots import plot_map, plot_yaw

        out = Path(folder)
        m = self.session.map
        res = self.result
        u = self.options.force_uncertainty
        write_map_csv(out / "map.csv", m)
        marks = [(c.label, c.placement.x, c.placement.y) for c in res.candidates
                 if c.label != "given"]
        plot_map(out / "map.png", m, marks, requested=u)
        plot_yaw(out / "map_yaw.png", m)
        write_map_json(out / "map.json", m, u)
        write_candidates_csv(out / "candidates.csv", self.rows)
        summary = self.to_dict()  # the file names its files inside its folder
        summary["files"] = [f.name for f in self.files(out)]
        chosen = self.chosen
        if chosen is not None:
            note = (f"Placed by rfsw-plan place from {self.problem.name}: seam anchor moved to "
                    f"x {chosen.placement.x * 1e3:.1f}, y {chosen.placement.y * 1e3:.1f}, "
                    f"z {chosen.placement.z * 1e3:.1f} mm, yaw "
                    f"{summary['chosen']['yaw_deg']:+.1f} deg.\nPlanned tolerated force "
                    f"uncertainty {chosen.tolerated_uncertainty * 100:.1f} % (given placement:"
                    f" {summary['given']['tolerated_uncertainty'] * 100:.1f} %), planned "
                    f"for {res.planned_for * 100:.3g} % (requested {u * 100:.3g} % plus headroom "
                    f"for the planner's fine projection).")
            write_placed_problem(self.placed_file(out), self.problem, chosen.placement,
                                 m.anchor, chosen.q_start, note,
                                 force_uncertainty=res.planned_for)
        write_json(out / "place.json", summary)
        return self.files(out)


def write_candidates_csv(path: Path, rows: list[dict[str, Any]]) -> Path:
    """``candidates.csv``: one row per planned candidate, best first, atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CANDIDATE_COLUMNS)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in CANDIDATE_COLUMNS])
    return path


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "" if v != v or v in (float("inf"), float("-inf")) else general(v, 6)
    return str(v)


def _summary(problem: Any, res: Any, rows: list[dict[str, Any]], m: Any, requested: float,
             where: str) -> dict[str, Any]:
    given = next(r for r in rows if r["label"] == "given")
    chosen = next((r for r in rows if r["chosen"]), None)
    best_u = chosen["tolerated_uncertainty"] if chosen else float("nan")
    reached = bool(chosen is not None and best_u >= requested)
    if chosen is None:
        verdict = "no candidate could be planned: " + "; ".join(
            f"{r['label']}: {r['message']}" for r in rows)
    elif reached:
        verdict = (f"+-{requested * 100:.3g} % holds at the chosen placement (tolerated "
                   f"{best_u * 100:.1f} %); the stiffest such placement was chosen")
    else:
        verdict = (f"+-{requested * 100:.3g} % is reached by no planned candidate in this region; "
                   f"the largest is {best_u * 100:.1f} % (given placement "
                   f"{given['tolerated_uncertainty'] * 100:.1f} %); the worst-case spread there "
                   f"comes mostly from the compliance of {chosen['dominant_compliance']}")
    return {
        "problem": problem.name,
        "requested_uncertainty": requested,
        "planned_for_uncertainty": res.planned_for,
        "requested_reached": reached,
        "verdict": verdict,
        "given": given,
        "chosen": chosen,
        "candidates": rows,
        "executor": where,
    }


__all__ = ["CANDIDATE_COLUMNS", "MAP_FILES", "PLACE_FILES", "PlaceRequest", "PlaceRun",
           "PlacementMapRequest", "PlacementMapRun", "write_candidates_csv"]
