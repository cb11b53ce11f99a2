"""Arm configuration (posture) of a joint vector, in the three vendors' encodings, and IK back.

A Cartesian point in a robot program needs its posture to be unambiguous. Geometric flags,
from the chain's joint frames at the controller joint values q:

* ``front``: the wrist centre (chain joint 5 origin) lies in front of the axis-1 line, i.e.
  on the side of the shoulder (joint 2 axis) offset;
* ``elbow_up``: the wrist centre is on the same side of the line through the joint 2 and
  joint 3 axes as in the reference posture (upper arm vertical, forearm horizontal: chain
  angles theta = 0), i.e. the elbow is above the shoulder-wrist line;
* ``wrist_negative``: the fifth controller axis value is negative.

Encodings (the conventions of the vendors' manuals as this module reads them; the round trip
in ``tests/test_export.py`` checks writer and reader agree on every bundled robot):

* KUKA ``S`` (Status): bit 0 = 1 if the wrist centre is overhead (behind axis 1, not
  ``front``), bit 1 = 1 if A3 is on the elbow-up side of its stretched angle (``elbow_up``),
  bit 2 = 1 if A5 < 0. ``T`` (Turn): bit i = 1 if axis i+1 < 0.
* FANUC ``CONFIG``: ``'F|N U|D T|B, t1, t4, t6'``: F (flip) if J5 > 0, N (no flip) if
  J5 < 0 (at the singular J5 = 0 either; written N); U if ``elbow_up`` else D; T (top/front)
  if ``front`` else B; turn numbers of J1, J4, J6: 0 for -180 < J <= 180 deg, +1 for
  180 < J <= 540, -1 for -540 < J <= -180. The wrist flag follows two public sources, kept
  with their origin in ``tests/data/vendor/posture_facts.csv``: RoboDK's FANUC R-30iA
  post-processor ("F means axis 5 >= 0, N means axis 5 < 0") and a ROBOGUIDE-derived
  configuration table of the CRX-10iA (J5 = -90 deg is ``N U T``, J5 = +90 deg ``F U T``).
* ABB ``confdata [cf1, cf4, cf6, cfx]``: quadrants floor(q / 90 deg) of axes 1, 4, 6 and
  cfx = 4 (not front) + 2 (not elbow_up) + (axis 5 < 0).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable, Hashable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Posture:
    """Geometric configuration flags (see the module docstring)."""

    front: bool
    elbow_up: bool
    wrist_negative: bool


def _reference_q(robot: Robot) -> FloatArray:
    """Controller values of the chain pose theta = 0 (q = G^-1 (0 - offset))."""
    conv = robot.description.convention
    return np.asarray(np.linalg.solve(robot.coupling, -conv.offset))


#: The elbow side of each robot's reference posture (:func:`_reference_side`), computed once
#: per robot: it cost two thirds of every :func:`posture` call (issue 41).
_REFERENCE_SIDE: weakref.WeakKeyDictionary[Robot, float] = weakref.WeakKeyDictionary()


def _reference_side(robot: Robot) -> float:
    """:func:`_elbow_side` of the reference posture (chain angles theta = 0)."""
    side = _REFERENCE_SIDE.get(robot)
    if side is None:
        side = _REFERENCE_SIDE[robot] = _elbow_side(robot.joint_frames(_reference_q(robot)))
    return side


def _elbow_side(F: FloatArray) -> float:
    """Side of the wrist centre from the line through the joint 2 and 3 axes, from the chain
    joint frames F (n, 4, 4) [m]: (o3 - o2) x (wc - o2) . z2 [m^2]."""
    (ax, ay, az), (bx, by, bz) = (F[2, :3, 3] - F[1, :3, 3]).tolist(), \
        (F[4, :3, 3] - F[1, :3, 3]).tolist()
    nx, ny, nz = F[1, :3, 2].tolist()
    # (o3 - o2) x (wc - o2) . z2, written out: np.cross on one 3-vector costs 30 times more
    return (ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz


def posture(robot: Robot, q: FloatArray) -> Posture:
    """Posture flags of controller joint values q [rad], shape (6,) (one forward kinematics
    of the joint frames; the reference posture's elbow side once per robot)."""
    if robot.nq != 6:
        raise InputError(robot.name, "", f"{robot.nq} joints", "a 6-axis arm for a program")
    F = robot.joint_frames(q)
    o1, z1, o2, wc = F[0, :3, 3], F[0, :3, 2], F[1, :3, 3], F[4, :3, 3]
    fwd = (o2 - o1) - z1 * ((o2 - o1) @ z1)
    if np.linalg.norm(fwd) < 1e-9:  # no shoulder offset: the joint-1 frame's x axis
        fwd = F[0, :3, 0]
    front = bool((wc - o1) @ fwd >= 0.0)
    elbow_up = bool(_elbow_side(F) * _reference_side(robot) > 0.0)
    return Posture(front, elbow_up, bool(q[4] < 0.0))


def postures(robot: Robot, Q: FloatArray) -> list[Posture]:
    """:func:`posture` of every row of Q [rad], shape (m, 6), in one pass: the chain joint
    frames of all rows from :meth:`Robot.batch_fk_jacobian_frames` (the same frames as
    :meth:`Robot.joint_frames`, to 1e-12), the same flags."""
    if robot.nq != 6:
        raise InputError(robot.name, "", f"{robot.nq} joints", "a 6-axis arm for a program")
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    if not len(Q):
        return []
    F = robot.batch_fk_jacobian_frames(Q)[2]  # (m, n, 4, 4)
    o1, z1, o2, o3, wc = (F[:, 0, :3, 3], F[:, 0, :3, 2], F[:, 1, :3, 3], F[:, 2, :3, 3],
                          F[:, 4, :3, 3])
    d = o2 - o1
    fwd = d - z1 * np.einsum("ki,ki->k", d, z1)[:, None]
    bare = np.linalg.norm(fwd, axis=1) < 1e-9  # no shoulder offset: the joint-1 frame's x
    fwd[bare] = F[bare, 0, :3, 0]
    front = np.einsum("ki,ki->k", wc - o1, fwd) >= 0.0
    side = np.einsum("ki,ki->k", np.cross(o3 - o2, wc - o2), F[:, 1, :3, 2])
    elbow_up = side * _reference_side(robot) > 0.0
    return [Posture(bool(f), bool(e), bool(q[4] < 0.0))
            for f, e, q in zip(front, elbow_up, Q, strict=True)]


# --------------------------------------------------------------------------------------------
# Vendor encodings (each of one joint vector, and of many: the writers encode every point of a
# program with one pass of the forward kinematics)


def _kuka(p: Posture, q: FloatArray) -> tuple[int, int]:
    s = (0 if p.front else 1) | (2 if p.elbow_up else 0) | (4 if p.wrist_negative else 0)
    t = sum(1 << i for i in range(6) if q[i] < 0.0)
    return s, t


def kuka_status_turn(robot: Robot, q: FloatArray) -> tuple[int, int]:
    """KUKA (S, T) of controller values q [rad]."""
    return _kuka(posture(robot, q), q)


def kuka_status_turns(robot: Robot, Q: FloatArray) -> list[tuple[int, int]]:
    """:func:`kuka_status_turn` of every row of Q [rad], (m, 6)."""
    return [_kuka(p, q) for p, q in zip(postures(robot, Q), Q, strict=True)]


def _turn(a: float) -> int:
    return math.ceil((math.degrees(a) - 180.0) / 360.0 - 1e-12)


def _fanuc(p: Posture, q: FloatArray) -> str:
    flip = bool(q[4] > 0.0)
    return (f"{'F' if flip else 'N'} {'U' if p.elbow_up else 'D'} "
            f"{'T' if p.front else 'B'}, {_turn(q[0])}, {_turn(q[3])}, {_turn(q[5])}")


def fanuc_config(robot: Robot, q: FloatArray) -> str:
    """FANUC CONFIG string of controller values q [rad], e.g. ``'N U T, 0, 0, 0'``."""
    return _fanuc(posture(robot, q), q)


def fanuc_configs(robot: Robot, Q: FloatArray) -> list[str]:
    """:func:`fanuc_config` of every row of Q [rad], (m, 6)."""
    return [_fanuc(p, q) for p, q in zip(postures(robot, Q), Q, strict=True)]


def _abb(p: Posture, q: FloatArray) -> tuple[int, int, int, int]:
    quad = [math.floor(q[j] / (math.pi / 2) + 1e-12) for j in (0, 3, 5)]
    cfx = 4 * (not p.front) + 2 * (not p.elbow_up) + int(p.wrist_negative)
    return quad[0], quad[1], quad[2], cfx


def abb_confdata(robot: Robot, q: FloatArray) -> tuple[int, int, int, int]:
    """ABB confdata (cf1, cf4, cf6, cfx) of controller values q [rad]."""
    return _abb(posture(robot, q), q)


def abb_confdatas(robot: Robot, Q: FloatArray) -> list[tuple[int, int, int, int]]:
    """:func:`abb_confdata` of every row of Q [rad], (m, 6)."""
    return [_abb(p, q) for p, q in zip(postures(robot, Q), Q, strict=True)]


def configs_near(encode: object, robot: Robot, q: FloatArray, eps: float = 1e-6) -> list[object]:
    """The encodings of q and of q with every joint that sits within ``eps`` [rad] of a
    boundary (a multiple of 90 deg, where a sign, quadrant or turn changes) nudged to either
    side: a point written at A4 = 0.0 may come back at -1e-12. The written configuration
    must be one of them."""
    assert callable(encode)
    q = np.asarray(q, dtype=float)
    step = math.pi / 2
    near = [j for j in range(len(q)) if abs(q[j] - step * round(q[j] / step)) < eps][:4]
    out = [encode(robot, q)]
    for mask in range(1, 3 ** len(near)):
        d = np.zeros_like(q)
        m = mask
        for j in near:
            d[j] = (m % 3 - 1) * 2 * eps
            m //= 3
        out.append(encode(robot, q + d))
    return out


# --------------------------------------------------------------------------------------------
# Back to joint values


def ik_on_branch(
    robot: Robot, target: FloatArray, matches: object, seed: FloatArray | None,
) -> FloatArray:
    """Joint values [rad] that reach ``target`` (TCP, base frame, (4, 4)) in a given posture.

    Args:
        robot: The robot.
        target: TCP pose in the description's base frame [m].
        matches: Callable ``q -> bool``: does q have the program's configuration (posture and
            turns)? Solutions are shifted by whole turns within the joint limits first.
        seed: The joint values to start from (the planned ones of the point, or the previous
            point's), or None (multi-start over the configuration branches).

    Raises:
        InputError: No solution with that configuration.
    """
    assert callable(matches)
    for s in _seeds(robot, seed):
        res = solve_ik(robot, target, s, tol_pos=1e-10, tol_rot=1e-10, max_iter=300)
        if not res.converged and (res.position_error > 1e-8 or res.rotation_error > 1e-8):
            continue
        for q in _turn_variants(robot, res.q, s):
            if matches(q):
                return q
    raise InputError("program", "", "a point has no joint solution in its configuration",
                     "a reachable pose with its posture and turns")


def _seeds(robot: Robot, seed: FloatArray | None) -> Iterator[FloatArray]:
    """The seed first; the configuration branches and a seeded multi-start only if it fails
    (computing the branches costs about 0.2 s, the seeded solve a millisecond)."""
    from rfsw_plan.planning.baselines import branch_seeds

    d = robot.description
    if seed is not None:
        yield np.asarray(seed, dtype=float)
    base = seed if seed is not None else 0.5 * (d.lower + d.upper)
    for _, s in branch_seeds(robot, np.asarray(base, dtype=float)):
        yield s
    if seed is None:
        rng = np.random.default_rng(0)
        yield from rng.uniform(np.maximum(d.lower, -math.pi), np.minimum(d.upper, math.pi),
                               size=(24, robot.nq))


def seeded_on_branch(
    robot: Robot, targets: FloatArray, stated: Sequence[Hashable],
    encode: Callable[[Robot, FloatArray], Sequence[Hashable]], seeds: FloatArray,
) -> list[FloatArray | None]:
    """What :func:`ik_on_branch` tries first, for many targets: the solve from each seed,
    every joint shifted by whole turns nearest the seed, where its encoding is the stated
    one (``encode``: the format's encodings of many joint vectors, one pass of the forward
    kinematics for all); None where it is not, or where the solve fails: there
    :func:`ik_on_branch` searches on (joints at a boundary, other branches).

    Args:
        robot: The robot.
        targets: TCP poses in the description's base frame [m], (m, 4, 4).
        stated: The configuration each point states, (m,).
        encode: ``(robot, Q) -> encodings`` of the rows of Q [rad], (k, n).
        seeds: The joint values to start from [rad], (m, n).
    """
    first: list[FloatArray | None] = []
    for T, s in zip(targets, seeds, strict=True):
        res = solve_ik(robot, T, s, tol_pos=1e-10, tol_rot=1e-10, max_iter=300)
        if not res.converged and (res.position_error > 1e-8 or res.rotation_error > 1e-8):
            first.append(None)
            continue
        first.append(np.array([o[0] for o in _turn_options(robot, res.q, s)]))
    solved = [k for k, q in enumerate(first) if q is not None]
    codes = encode(robot, np.array([first[k] for k in solved])) if solved else []
    for k, code in zip(solved, codes, strict=True):
        if code != stated[k]:
            first[k] = None
    return first


def _turn_options(robot: Robot, q: FloatArray, near: FloatArray) -> list[list[float]]:
    """Per joint, q's values shifted by whole turns within the limits, nearest to ``near``
    first (q's own if none is within them)."""
    d = robot.description
    options = []
    for j in range(robot.nq):
        ks = [k for k in range(-2, 3) if d.lower[j] - 1e-9 <= q[j] + 2 * math.pi * k
              <= d.upper[j] + 1e-9]
        vals = sorted((q[j] + 2 * math.pi * k for k in ks), key=lambda v: abs(v - near[j]))
        options.append(vals or [q[j]])
    return options


def _turn_variants(robot: Robot, q: FloatArray, near: FloatArray) -> list[FloatArray]:
    """q with every joint shifted by whole turns within the limits, nearest to ``near`` first."""
    options = _turn_options(robot, q, near)
    out = [np.array([o[0] for o in options])]
    for j in range(robot.nq):  # single-joint alternatives (turn numbers of one axis)
        for v in options[j][1:]:
            alt = out[0].copy()
            alt[j] = v
            out.append(alt)
    return out
