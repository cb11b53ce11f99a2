"""Placement map plots and summary (issue 24): outliers do not flatten the colour scale, the
requested uncertainty is marked, candidates at one position share a mark, and the summary's
"best placement" is the ranked table's first row."""

from __future__ import annotations

import numpy as np

from rfsw_plan.placement.plots import colour_limits, grouped_marks


def test_outliers_do_not_stretch_the_tolerated_colour_scale() -> None:
    """The issue's map: most placements at 10-30 %, a few soft ones at 100-140 %."""
    rng = np.random.default_rng(0)
    Z = np.concatenate([rng.uniform(10, 30, 200), [102.3, 120.0, 140.0]])
    vmin, vmax, extend = colour_limits(Z, "tolerated_centred", requested=0.2)
    assert vmin == 0.0 and 40.0 <= vmax < 100.0 and extend == "max"
    # 10-30 % spans at least half of the scale (it was one shade of 0-140 %).
    assert (30 - 10) / (vmax - vmin) >= 0.45
    # Without outliers the scale ends at the data.
    vmin, vmax, extend = colour_limits(np.array([5.0, 12.0, 18.0]), "tolerated_mirror", 0.2)
    assert vmax == 18.0 and extend == "neither"


def test_candidates_at_one_position_share_one_mark() -> None:
    marks = grouped_marks([("1", 0.8, 0.5), ("2", 1.0, -1.0), ("3", 0.8, 0.5)])
    assert marks == [("1,3", 0.8, 0.5), ("2", 1.0, -1.0)]


def test_best_placement_is_the_first_ranked_row() -> None:
    from rfsw_plan.placement.files import map_summary
    from rfsw_plan.placement.session import MapRequest, map_problem
    from rfsw_plan.planning.api import options_from_problem
    from rfsw_plan.process.problem import load_problem

    pb = load_problem("zk500_table6_seam")
    s = map_problem(pb, MapRequest(shape=(5, 5, 4, 1), max_weld=20), options_from_problem(pb))
    d = map_summary(s.map, 0.2)
    top = d["top"][0]
    assert d["best_tolerated_uncertainty_centred"] == top["tolerated_uncertainty_centred"]
    assert d["best_tolerated_uncertainty_mirror"] == top["tolerated_uncertainty_mirror"]
    assert d["highest_tolerated_uncertainty_centred"] >= d["best_tolerated_uncertainty_centred"]
