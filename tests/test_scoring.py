"""The one scoring of both diagnoses: held-out F test against the F distribution, ranking by
held-out RMS, ties, and the candidate named (issue 26; issue 24: validate-weld sorted its
candidates otherwise and named an implausible joint stiffness as significant)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy import stats

from rfsw_plan.validation.engine.scoring import ALPHA, named, rank, score, ties_of


def _cand(label: str, sse: float, n_params: int = 1, **kw: Any):  # type: ignore[no-untyped-def]
    return score(label, label.partition(":")[0], None, sse_before=4.0, sse_after=sse,
                 n_obs=1000, n_free=n_params, n_params=n_params, n_tests=3, params={}, **kw)


def test_f_test_is_the_f_distribution() -> None:
    c = _cand("a", 3.0, 2)
    F = ((4.0 - 3.0) / 2) / (3.0 / 998)
    assert c.f_stat == pytest.approx(F)
    assert c.p_value == pytest.approx(stats.f.sf(F, 2, 998))
    assert c.significant == (c.p_value < ALPHA / 3)
    assert c.explained_fraction == pytest.approx(0.25)
    assert c.rms_before == pytest.approx(np.sqrt(4.0 / 1000))
    worse = _cand("b", 4.5)
    assert worse.p_value == 1.0 and not worse.significant and worse.explained_fraction < 0
    # A fit outside the effect's physical range is never significant.
    assert not _cand("c", 1.0, admissible=False).significant


def test_ranked_by_heldout_rms_and_the_simplest_tie_is_named() -> None:
    """Both reach the noise floor: the data cannot tell them apart, so the one with fewer
    parameters is named although its held-out RMS is a little higher."""
    rich = _cand("rich", 1.000, 2)
    simple = _cand("simple", 1.010, 1)
    far = _cand("far", 3.0, 1)
    ranked = rank([far, simple, rich], at_floor=lambda c: c.sse < 1.5)
    assert [c.label for c in ranked] == ["rich", "simple", "far"]
    assert [c.tied_with_best for c in ranked] == [False, True, False]
    best = named(ranked)
    assert best is not None and best.label == "simple"
    assert ties_of(ranked, best) == ["rich"]
    # Without a noise floor the F test at TIE_LEVEL decides: on 1000 observations 0.3 % more
    # SSE cannot be told from the best (F = 3.0 < 3.85), 1 % can (F = 10).
    assert rank([rich, _cand("close", 1.003, 1)])[1].tied_with_best
    assert not rank([rich, simple])[1].tied_with_best
    assert named(rank([rich, simple])) is rich


def test_an_implausible_fit_is_listed_but_never_named() -> None:
    odd = _cand("joint_compliance:j4", 0.9, 1, implausible="stiffness x0.056")
    ok = _cand("joint_compliance:j1", 1.2, 1)
    ranked = rank([odd, ok], at_floor=lambda c: True)
    assert ranked[0].label == "joint_compliance:j4" and ranked[0].significant
    assert not ranked[0].plausible
    best = named(ranked)
    assert best is not None and best.label == "joint_compliance:j1"
    assert named(rank([odd])) is None
