"""One candidate function and one candidate form for both diagnoses (issue 26): the
candidates are the library minus the model (never a set-up effect), and every bound comes
from the effect's ``param_ranges``, so a new effect gets its own bounds without any edit."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import ClassVar

import numpy as np
import pytest

from rfsw_plan.elastostatics.effects import EFFECTS, ComplianceEffect, PoseBatch, make_effect
from rfsw_plan.elastostatics.effects.base import PARAM_LIMIT, FloatArray
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.validation.engine.candidates import (
    PLAUSIBLE_FACTOR,
    addable_effects,
    candidate_form,
    candidate_labels,
    joint_form,
    parts_of,
    stiffness_labels,
)


def test_one_candidate_list_serves_both_commands(model: ElastostaticModel) -> None:
    """validate's candidates are validate-weld's minus the joint stiffnesses, and neither
    offers an effect of the measurement set-up (device registration, marker offset)."""
    campaign = candidate_labels(model)
    weld = candidate_labels(model, joint_stiffness=True)
    assert weld == stiffness_labels(model) + campaign
    assert stiffness_labels(model) == [f"joint_compliance:j{j}" for j in range(1, 7)]
    setup = {n for n, c in EFFECTS.items() if c.setup}
    assert setup == {"device_registration", "marker_offset"}
    assert not {x.partition(":")[0] for x in weld} & setup
    assert not set(addable_effects()) & (setup | {"joint_compliance"})
    extended = model.with_effect("payload_gravity")
    assert "payload_gravity" not in candidate_labels(extended, joint_stiffness=True)


def test_bounds_are_the_effects_param_ranges(model: ElastostaticModel) -> None:
    """Every candidate's bounds are its effect's declared range (the generic +-PARAM_LIMIT of
    an undeclared parameter is no bound): compliances, backlash and a payload mass >= 0."""
    for label in candidate_labels(model, joint_stiffness=True):
        form = candidate_form(model, label)
        eff = model.joint_compliance if form.refit else make_effect(model.robot, label)
        for name, lo, hi in zip(form.names, form.lower, form.upper, strict=True):
            rlo, rhi = eff.param_range(name)
            assert lo == (rlo if rlo > -PARAM_LIMIT else -np.inf), (label, name)
            assert hi == (rhi if rhi < PARAM_LIMIT else np.inf), (label, name)
    assert candidate_form(model, "tilting_compliance:j2").lower.tolist() == [0.0, 0.0]
    assert candidate_form(model, "joint_backlash:j3").lower.tolist() == [0.0]
    pg = candidate_form(model, "payload_gravity")
    assert pg.lower[pg.names.index("m")] == 0.0
    assert not pg.admissible(np.array([-1.0, 0.0, 0.0, 0.0]))
    assert pg.implausible(np.array([-1.0, 0.0, 0.0, 0.0])).startswith("outside the physical")


@pytest.fixture
def new_compliance() -> Iterator[type[ComplianceEffect]]:
    """A compliance effect defined here only, with a declared range; unregistered after."""

    class HoseSpring(ComplianceEffect):
        name = "test_hose_spring"
        description = "A test compliance: the hose pack is a spring along base x."
        param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"c_h": (0.0, 1e-4)}

        def param_names(self) -> tuple[str, ...]:
            return ("c_h",)

        def prior(self) -> FloatArray:
            return np.array([0.0])

        def plausible_params(self, batch: PoseBatch, wrench: FloatArray,
                             rng: np.random.Generator) -> dict[str, float]:
            return {"c_h": 1e-6}

        def deflection_regressor(self, batch: PoseBatch, wrench: FloatArray,
                                 theta: FloatArray) -> FloatArray:
            out = np.zeros((len(batch), 6, 1))
            out[:, 0, 0] = wrench[:, 0]
            return out

        def deflection(self, batch: PoseBatch, wrench: FloatArray,
                       theta: FloatArray) -> FloatArray:
            return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])

    yield HoseSpring
    del EFFECTS["test_hose_spring"]


def test_a_new_compliance_effect_gets_its_own_bounds(
    model: ElastostaticModel, new_compliance: type[ComplianceEffect]
) -> None:
    """Issue 26: picked by name, a new compliance effect got -inf lower bounds in
    validate-weld; now it is a candidate with the range it declares."""
    assert "test_hose_spring" in candidate_labels(model)
    form = candidate_form(model, "test_hose_spring")
    assert (form.lower.tolist(), form.upper.tolist()) == ([0.0], [1e-4])
    assert not form.admissible(np.array([-1e-7]))
    m = form.build(np.array([2e-6]))
    assert m.has("test_hose_spring") and m.effects[-1].params.tolist() == [2e-6]


def test_a_joint_stiffness_far_from_the_robot_file_is_implausible(
    model: ElastostaticModel,
) -> None:
    form = candidate_form(model, "joint_compliance:j4")
    c0 = float(form.theta0[0])
    assert form.refit and form.joint == 4
    assert form.implausible(np.array([c0 / 0.8])) == ""
    why = form.implausible(np.array([c0 / 0.056]))  # 'stiffness x0.056' (issue 24)
    assert "stiffness x0.056" in why and f"{PLAUSIBLE_FACTOR:g} x off" in why
    m = form.build(np.array([c0 * 2.0]))
    assert m.joint_compliance.params[3] == pytest.approx(2.0 * c0)
    assert model.joint_compliance.params[3] == pytest.approx(c0)  # the model is kept


def test_labels_that_are_not_candidates_are_refused(model: ElastostaticModel) -> None:
    for bad, why in (("joint_compliance", "already in the model"),
                     ("joint_compliance:j9", "no such joint"),
                     ("marker_offset", "measurement set-up")):
        with pytest.raises(InputError, match=why):
            candidate_form(model, bad)
    with pytest.raises(InputError, match="already in the model"):
        candidate_form(model.with_effect("payload_gravity"), "payload_gravity")


def test_joint_form_fits_several_candidates_in_one_vector(model: ElastostaticModel) -> None:
    forms = [candidate_form(model, "joint_compliance:j1"),
             candidate_form(model, "tilting_compliance:j2")]
    joint = joint_form(forms)
    assert joint.names == ("joint_compliance:j1.c1", "tilting_compliance:j2.c_t1",
                           "tilting_compliance:j2.c_t2")
    theta = np.array([1e-6, 2e-7, 3e-7])
    assert [p.tolist() for p in parts_of(forms, theta)] == [[1e-6], [2e-7, 3e-7]]
    m = joint.build(theta)
    assert m.joint_compliance.params[0] == 1e-6
    assert m.effects[-1].label == "tilting_compliance:j2"
    assert m.effects[-1].params.tolist() == [2e-7, 3e-7]
    with pytest.raises(InputError, match="duplicated"):
        joint_form([forms[0], forms[0]])
