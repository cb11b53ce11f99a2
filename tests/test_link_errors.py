"""Full geometric calibration (issue 27): the link-error regressor against Pinocchio, the
plausibility rule of identification, and a simulated calibration brought to its floor."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from rfsw_plan.elastostatics.effects import PoseBatch, make_effect
from rfsw_plan.elastostatics.identification import Plausibility, implausible
from rfsw_plan.elastostatics.model import load_model
from rfsw_plan.validation import run_campaign, validate


@pytest.mark.parametrize("robot_name", ["zk500", "tiago_arm"])
def test_regressor_is_the_derivative_of_perturbed_link_placements(robot_name: str) -> None:
    """Perturb each link placement of the Pinocchio model (a small twist in the frame of the
    joint before it) and compare the TCP's motion with the regressor column; the TIAGo's
    prismatic torso checks the frame after the joint's travel."""
    robot = load_model(robot_name).robot
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.description.lower, robot.description.upper)
    eff = make_effect(robot, "link_errors")
    A = eff.offset_regressor(PoseBatch.from_q(robot, q[None]), eff.params)[0]
    T0 = robot.fk(q)
    h = 1e-7
    for j in range(robot.nq):
        for k in range(6):
            twist = np.zeros(6)
            twist[k] = h  # pinocchio: linear first, then angular, like (d, r)
            model = robot.model.copy()
            small = pin.exp6(pin.Motion(twist))
            if j + 1 < robot.nq:
                model.jointPlacements[j + 2] = small * model.jointPlacements[j + 2]
            else:
                frame = model.frames[robot.tcp_id]
                frame.placement = small * frame.placement
            data = model.createData()
            pin.framesForwardKinematics(model, data, robot.chain_q(q))
            moved = (data.oMf[robot.tcp_id].translation - T0[:3, 3]) / h
            np.testing.assert_allclose(A[:3, 6 * j + k], moved, atol=2e-6,
                                       err_msg=f"{robot_name} link {j + 1} param {k}")


def test_implausible_values_and_unidentified_parameters_keep_their_prior() -> None:
    bounds = Plausibility(limit=np.array([5e-3, 5e-3, 5e-3, np.inf]),
                          lo=np.full(4, -1.0), hi=np.full(4, 1.0),
                          regularised=np.array([False, False, True, False]))
    free = np.ones(4, dtype=bool)
    # A 6 mm value beyond the 5 mm plausible size: not a calibration.
    k, note = implausible(np.array([6e-3, 1e-3, 0, 0]), np.full(4, 1e-4), free, bounds) or (
        -1, "")
    assert k == 0 and "stand-in" in note
    # A standard error above half the plausible size: the data cannot tell it from zero.
    k, note = implausible(np.array([1e-3, 1e-3, 0, 0]), np.array([1e-4, 3e-3, 1, 1]), free,
                          bounds) or (-1, "")
    assert k == 1 and "cannot tell it from zero" in note
    # A regularised parameter's error is bounded by its prior: only its value is checked;
    # a parameter without a plausible size is never checked; outside the physical range goes.
    assert implausible(np.array([1e-3, 1e-3, 1e-3, 0.5]), np.array([1e-4, 1e-4, 1.0, 9.0]),
                       free, bounds) is None
    k, note = implausible(np.array([1e-3, 1e-3, 1e-3, 2.0]), np.full(4, 1e-4), free,
                          bounds) or (-1, "")
    assert k == 3 and "physically possible" in note


def test_hidden_link_errors_are_calibrated_to_the_floor() -> None:
    """A ZK-500 whose links are off by their plausible size (0.1 mm, 0.2 mrad): the diagnosis
    names link_errors, the calibrated model reaches the floor, and what the data cannot see
    (the rotation about each joint axis is its zero offset...) is named, not fitted."""
    camp = run_campaign("zk500", ["link_errors"], poses=40, loads_per_pose=3,
                        noise_mm=0.005, seed=5)
    model = load_model("zk500")
    res = validate(model, camp.data, add=["kinematic_offsets", "link_errors"])
    dg = res.diagnosis
    assert dg.noise.sigma is not None
    assert dg.heldout_rms <= 1.5 * dg.noise.sigma, dg.message
    est = [e for e in res.identification.estimates if e.effect == "link_errors"]
    named = [e for e in est if not e.identified]
    reasons = ("collinear", "absorb", "does not move the measured TCP")
    assert named and all(any(r in e.note for r in reasons) for e in named), [
        e.note for e in named]
    for e in est:
        limit = 5e-3 if e.name.startswith("d") else np.radians(3.0)
        assert abs(e.value) <= limit
