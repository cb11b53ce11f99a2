"""Files of the ``map`` and ``place`` commands: map CSV/JSON and the placed problem file.

Every file goes through :mod:`rfsw_plan.files` (atomic, strict JSON). The placed problem is
the original problem file's TOML with the seam moved (points and surface normals, in mm, in the
robot base frame), the seed of the planner set to the taught configuration the map found there,
and a comment block that says where it came from; everything else (process, window, planning
options) is kept, so ``rfsw-plan plan`` runs it as it is.
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.files import atomic_path, write_json
from rfsw_plan.numfmt import general
from rfsw_plan.placement.geometry import Placement, rot_z
from rfsw_plan.placement.map import PlacementMap
from rfsw_plan.tomlwriter import dumps_toml

#: Columns of map.csv, in order (file units in the names).
MAP_COLUMNS = (
    "x_mm", "y_mm", "z_mm", "yaw_deg", "dx_mm", "dy_mm", "robot_base_height_mm", "status",
    "joint_limit_margin_deg", "max_joint_step_deg", "kappa_f_max", "nu_p_max",
    "lateral_compliance_max_mm_per_kN", "lateral_compliance_mean_mm_per_kN",
    "min_lateral_stiffness_N_per_mm", "max_abs_uncompensated_lateral_mm",
    "tolerated_uncertainty_mirror", "tolerated_uncertainty_centred",
)


def _cell(v: Any) -> str:
    if isinstance(v, str):
        return v
    f = float(v)
    return "" if not np.isfinite(f) else general(f, 6)


def write_map_csv(path: str | Path, m: PlacementMap) -> Path:
    """One row per placement (:data:`MAP_COLUMNS`; empty cell: not defined, e.g. unreachable)."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(MAP_COLUMNS)
        for i in range(len(m.placements)):
            r = m.row(i)
            w.writerow([_cell(r[c]) for c in MAP_COLUMNS])
    return Path(path)


def map_summary(m: PlacementMap, requested: float, top: int = 5) -> dict[str, Any]:
    """JSON-ready summary of a map (file units).

    ``best_*`` are the figures of the placement ranked first (:meth:`PlacementMap.ranking`,
    the first row of ``top``), so the summary line and the ranked table quote one placement;
    ``highest_tolerated_uncertainty_centred`` is the largest value anywhere on the map (often
    an outlier at a soft, barely loaded placement), kept apart. No wall time (the map's
    ``seconds`` is printed, never written: the same input writes the same bytes).
    """
    g = m.grid
    rank = m.ranking(requested)
    status, counts = np.unique(m.status, return_counts=True)
    feas = m.feasible
    first = int(rank[0]) if len(rank) else None
    best_u = float("nan") if first is None else float(m.tolerated_centred[first])
    best_um = float("nan") if first is None else float(m.tolerated_mirror[first])
    highest = float(np.max(m.tolerated_centred[feas])) if np.any(feas) else float("nan")
    return {
        "problem": m.name,
        "placements": len(m.placements),
        "grid": {"x_mm": (g.x * 1e3).tolist(), "y_mm": (g.y * 1e3).tolist(),
                 "yaw_deg": np.rad2deg(g.yaw).tolist(), "z_mm": (g.z * 1e3).tolist(),
                 "shape": list(g.shape)},
        "anchor_mm": (m.anchor * 1e3).tolist(),
        "status_counts": {str(s): int(c) for s, c in zip(status, counts, strict=True)},
        "requested_uncertainty": requested,
        "given": m.given,
        "best_tolerated_uncertainty_mirror": best_um,
        "best_tolerated_uncertainty_centred": best_u,
        "highest_tolerated_uncertainty_centred": highest,
        "requested_reached_somewhere": bool(np.any(feas) and highest >= requested),
        "top": [m.row(int(i)) for i in rank[:top]],
        "evaluated_poses": m.evaluated_poses,
    }


def write_map_json(path: str | Path, m: PlacementMap, requested: float,
                   extra: dict[str, Any] | None = None) -> Path:
    """Summary plus every placement's indices column-wise (strict JSON: NaN -> null)."""
    out = map_summary(m, requested)
    rows = [m.row(i) for i in range(len(m.placements))]
    out["columns"] = {c: [r[c] for r in rows] for c in MAP_COLUMNS}
    out.update(extra or {})
    return write_json(path, out)


def placed_problem_toml(problem: Any, placement: Placement, anchor: np.ndarray,
                        q_seed: np.ndarray | None, note: str, name: str | None = None,
                        force_uncertainty: float | None = None) -> str:
    """TOML text of the problem with its seam moved to ``placement``.

    Args:
        problem: The loaded problem (its ``path`` is read for the original tables).
        placement: Where the seam anchor goes (base frame) and the yaw.
        anchor: The seam anchor at the given placement [m], (3,).
        q_seed: Planner seed at the new placement [rad], (n,), or None to drop the seed.
        note: Comment lines on how the placement was found.
        name: Name of the new problem (default ``<name>_placed``).
        force_uncertainty: The force uncertainty the placement was planned for (written to
            ``[planning]`` so that ``plan`` reproduces the plan), or None to keep the file's.
    """
    src = Path(problem.path)
    data = tomllib.loads(src.read_text())
    R = rot_z(placement.yaw)
    pos = np.array([placement.x, placement.y, placement.z])
    seam = problem.seam
    pts = np.asarray(seam.points, float)
    new_pts = (pts - anchor) @ R.T + pos
    st = dict(data["seam"])
    st.pop("csv", None)
    st["points_mm"] = [[round(float(v) * 1e3, 4) for v in p] for p in new_pts]
    nrm = np.asarray(seam.surface_normal, float)
    new_n = nrm @ R.T
    st["surface_normal"] = ([round(float(v), 9) for v in new_n] if new_n.ndim == 1 else
                            [[round(float(v), 9) for v in p] for p in new_n])
    st["source"] = f"{st.get('source', '')} | moved by rfsw-plan place".strip(" |")
    data["seam"] = st
    data["name"] = name or f"{problem.name}_placed"
    data["title"] = f"{data.get('title', problem.name)} (placed)"
    robot = data.get("robot")
    if isinstance(robot, str) and robot.endswith(".toml") and not Path(robot).is_absolute():
        data["robot"] = str((src.parent / robot).resolve())
    if "csv" in data.get("seam", {}):
        del data["seam"]["csv"]
    pl = dict(data.get("planning", {}))
    if q_seed is not None:
        pl["q_seed_deg"] = [round(float(v), 4) for v in np.rad2deg(q_seed)]
    else:
        pl.pop("q_seed_deg", None)
    if force_uncertainty is not None:
        # rounded like every number of this file (0.2 + 0.01 is 0.21000000000000002 in binary)
        u = round(float(force_uncertainty), 6)
        # above 100 % only a percentage reads back (a number above 1 is a slip, refused)
        pl["force_uncertainty"] = u if u <= 1.0 else f"{u * 100:.4g} %"
    data["planning"] = pl
    header = "".join(f"# {line}\n" for line in note.splitlines())
    return header + dumps_toml(data)


def write_placed_problem(path: str | Path, problem: Any, placement: Placement,
                         anchor: np.ndarray, q_seed: np.ndarray | None, note: str,
                         name: str | None = None, force_uncertainty: float | None = None
                         ) -> Path:
    """Write :func:`placed_problem_toml` atomically; the problem reader must accept the
    temporary file (and give the moved seam) before it replaces ``path``."""
    from rfsw_plan.process.problem import load_problem

    text = placed_problem_toml(problem, placement, anchor, q_seed, note, name,
                               force_uncertainty)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
        loaded = load_problem(tmp)
        R = rot_z(placement.yaw)
        want = (np.asarray(problem.seam.points, float) - anchor) @ R.T + np.array(
            [placement.x, placement.y, placement.z])
        if not np.allclose(np.asarray(loaded.seam.points, float), want, atol=1e-6):
            raise RuntimeError("placed problem file does not reproduce the moved seam")
    return Path(path)
