"""Symbolic CasADi kinematics and compliance, built from the Pinocchio model.

The ``pin`` wheel ships no ``pinocchio.casadi``, so the chain is rebuilt here from the
Pinocchio model's joint placements and joint axes (``Robot.geometry``). Tests check these
expressions against Pinocchio to 1e-9.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.robot.kinematics import Robot


def _rot(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rodrigues rotation about a constant unit axis by a symbolic angle."""
    K = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return ca.DM.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


@dataclass(frozen=True)
class SymbolicChain:
    """Symbolic chain quantities as functions of the controller joint values q [rad].

    Attributes:
        q: The symbol, shape (n, 1).
        p: TCP position, base frame [m], shape (3, 1).
        R: TCP orientation, shape (3, 3).
        J: TCP Jacobian ([v; omega], base frame), shape (6, n).
        joint_R: Chain joint frame orientations, list of (3, 3).
        joint_o: Chain joint frame origins [m], list of (3, 1).
    """

    q: ca.SX
    p: ca.SX
    R: ca.SX
    J: ca.SX
    joint_R: list[ca.SX]
    joint_o: list[ca.SX]


def symbolic_chain(robot: Robot, q: ca.SX | None = None) -> SymbolicChain:
    """Forward kinematics and Jacobian of ``robot`` as CasADi SX expressions.

    Args:
        robot: Robot whose Pinocchio geometry is used.
        q: Symbol to use (shape (n, 1)); a fresh ``q`` is created if None.
    """
    n = robot.nq
    if q is None:
        q = ca.SX.sym("q", n)
    g = robot.geometry
    qc = ca.DM(robot.coupling) @ q
    R = ca.SX.eye(3)
    p = ca.SX.zeros(3, 1)
    zs, os_, joint_R, joint_o = [], [], [], []
    for i in range(n):
        M = g.placements[i]
        p = p + R @ ca.DM(M[:3, 3])
        R = R @ ca.DM(M[:3, :3])
        zs.append(R @ ca.DM(g.axes[i]))
        os_.append(p)
        R = R @ _rot(g.axes[i], qc[i])
        joint_R.append(R)
        joint_o.append(p)
    p_tcp = p + R @ ca.DM(g.tcp[:3, 3])
    R_tcp = R @ ca.DM(g.tcp[:3, :3])
    cols = [ca.vertcat(ca.cross(zs[i], p_tcp - os_[i]), zs[i]) for i in range(n)]
    J = ca.horzcat(*cols) @ ca.DM(robot.coupling)
    return SymbolicChain(q, p_tcp, R_tcp, J, joint_R, joint_o)


def symbolic_cartesian_compliance(
    model: ElastostaticModel, chain: SymbolicChain
) -> tuple[ca.SX, list[str]]:
    """Cartesian compliance C_X(q) of the model's wrench-linear effects, shape (6, 6).

    The joint compliance J diag(c) J^T (seed 000 eq. 11) plus every spring effect the model
    declares (:meth:`ElastostaticModel.springs`): spring s at chain joint i about the axis
    a_s of that joint's frame adds c_s j_s j_s^T, j_s = [u_s x (p - o_i); u_s],
    u_s = R_i a_s (seed 002 eq. 2). Returns the expression and the labels of the effects it
    does *not* include (not springs: non-linear compliance, wrench and geometric effects),
    which the planner treats by an outer correction loop.
    """
    C = chain.J @ ca.diag(ca.DM(model.joint_compliance.params)) @ chain.J.T
    for s in model.springs():
        for axis, c in zip(s.axes, s.compliance, strict=True):
            u = chain.joint_R[s.joint] @ ca.DM(axis)
            jt = ca.vertcat(ca.cross(u, chain.p - chain.joint_o[s.joint]), u)
            C += float(c) * (jt @ jt.T)
    included = {id(model.joint_compliance), *(id(e) for e in model.groups.springs)}
    return C, [e.label for e in model.effects if id(e) not in included]


def kinematics_function(robot: Robot) -> ca.Function:
    """CasADi function ``q -> (p [m], R, J)``; handy for tests and numeric checks."""
    ch = symbolic_chain(robot)
    return ca.Function("fk", [ch.q], [ch.p, ch.R, ch.J], ["q"], ["p", "R", "J"])
