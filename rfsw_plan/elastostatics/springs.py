"""Linear rotational springs at the joint frames, evaluated together.

A *spring effect* (:meth:`Effect.joint_springs`, e.g. tilting compliance) is a set of k linear
rotational springs through the origin o of one chain joint frame, each about an axis a_s fixed
in that frame, with compliances c_s [rad/(N m)]. Under the TCP wrench F = [f; mu] (base frame)
spring s turns by c_s j_s^T F, with the TCP twist of a unit turn j_s = [u_s x r; u_s],
u_s = R a_s the axis in the base frame and r = p - o (seed 002 eq. 2). Summed over the springs
of a joint:

    M = r x f + mu                (moment of the wrench about o, base frame [N m])
    w = R C_l R^T M,  C_l = sum_s c_s a_s a_s^T   (rotation of the joint frame [rad])
    dX = [w x r; w]               (TCP deflection [m, rad], base frame)

so every spring effect of a model costs one 3x3 rotation sandwich per pose, vectorised over
the poses and over the effects at once (:func:`spring_deflection`). The Cartesian compliance
C = sum_s c_s j_s j_s^T is one batched product over the stacked twists
(:func:`spring_compliance`).

For one pose, :class:`SpringChain` adds one virtual revolute joint (at zero angle) per spring
to a copy of the Pinocchio chain: a single frame-Jacobian call then returns the TCP Jacobian
and every spring twist j_s, and dX = J_c C J_c^T F as for the joint compliance.

For many poses given as joint values, :func:`chain_spring_deflection` does the same on the
vectorised kinematics: the spring axes u_s are turned into the base frame inside the joint loop
of :meth:`Robot.chain_chunk` and joint and spring turns are summed in its internal layout,
without joint frames or Jacobians per pose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch, cross3
from rfsw_plan.robot.kinematics import Robot


@dataclass(frozen=True)
class JointSprings:
    """The springs of one effect at one chain joint.

    Attributes:
        joint: 0-based chain joint index.
        axes: Spring axes in that joint's frame, unit vectors, shape (k, 3).
        compliance: Spring compliances [rad/(N m)], shape (k,).
    """

    joint: int
    axes: FloatArray
    compliance: FloatArray

    def local_compliance(self) -> FloatArray:
        """C_l = sum_s c_s a_s a_s^T in the joint frame [rad/(N m)], shape (3, 3)."""
        return self.axes.T @ (self.compliance[:, None] * self.axes)


def _stack(batch: PoseBatch, springs: Sequence[JointSprings]) -> tuple[
    FloatArray, FloatArray, FloatArray
]:
    """Joint rotations R (m, E, 3, 3), TCP-minus-joint-origin r (m, E, 3) [m] and the local
    compliances C_l (E, 3, 3) of E spring effects.

    R and r depend on the poses alone: they are kept in the batch's cache
    (:attr:`PoseBatch.cache`, keyed by the springs' joints), so the many evaluations of one
    batch under different wrenches (the robust claim's force-box vertices, identification
    iterations) gather the joint frames once."""
    joints = tuple(s.joint for s in springs)
    key = f"spring_frames{joints}"
    if key not in batch.cache:
        frames = batch.frames[:, list(joints)]  # (m, E, 4, 4)
        batch.cache[key] = (frames[..., :3, :3], batch.T[:, None, :3, 3] - frames[..., :3, 3])
    R, r = batch.cache[key]
    Cl = np.stack([s.local_compliance() for s in springs])
    return R, r, Cl


def spring_deflection(
    batch: PoseBatch, springs: Sequence[JointSprings], wrench: FloatArray
) -> FloatArray:
    """Summed TCP deflection of spring effects [m, rad], base frame, shape (m, 6).

    Args:
        batch: Poses (needs the joint frames).
        springs: The spring effects (any joints, any number of axes each).
        wrench: True wrench at the TCP [N, N m], base frame, shape (m, 6).
    """
    dX = np.zeros((len(batch), 6))
    if not springs:
        return dX
    R, r, Cl = _stack(batch, springs)
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
    M = cross3(r, F[:, None, :3]) + F[:, None, 3:]  # moment about each joint origin [N m]
    local = np.matmul(M[:, :, None, :], R)  # (R^T M)^T, (m, E, 1, 3)
    w = np.matmul(R, np.matmul(local, Cl)[..., 0, :, None])[..., 0]  # R C_l R^T M [rad]
    dX[:, :3] = cross3(w, r).sum(axis=1)
    dX[:, 3:] = w.sum(axis=1)
    return dX


def chain_spring_deflection(
    robot: Robot, q: FloatArray, wrench: FloatArray, joint_compliance: FloatArray,
    springs: Sequence[JointSprings],
) -> FloatArray:
    """TCP deflection of joint compliance plus spring effects from joint values [m, rad],
    base frame, shape (m, 6).

    The same sum as :class:`~rfsw_plan.elastostatics.effects.JointCompliance` plus
    :func:`spring_deflection` (seed 000 eq. 11, seed 002 eq. 2), evaluated on the vectorised
    kinematics in their internal layout (:meth:`Robot.chain_chunk`, pose index last, the
    spring axes turned into the base frame inside its joint loop) without building a
    :class:`PoseBatch`. Every spring is a virtual revolute joint at rest (axis u_s at the
    origin o_s of its joint); with the moment of the wrench about chain joint i's origin
    M_i = (p - o_i) x f + mu, joint i turns by dq = G diag(c) G^T tau, tau_i = z_i . M_i,
    spring s by c_s u_s . M_s, and

        dX = sum over joints and springs of [w x (p - o); w],   w = turn * axis.

    Args:
        robot: The robot.
        q: Controller joint values [rad], shape (m, n).
        wrench: True wrench at the TCP [N, N m], base frame, shape (m, 6) or (6,).
        joint_compliance: Controller joint compliances c [rad/(N m)], shape (n,).
        springs: The spring effects (any joints, any number of axes each).
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    m, n = Q.shape
    W = np.broadcast_to(np.asarray(wrench, dtype=float), (m, 6))
    G = robot.coupling
    c = np.asarray(joint_compliance, dtype=float)
    identity = bool(np.array_equal(G, np.eye(n)))
    C_chain = G @ (c[:, None] * G.T)  # chain joint compliance [rad/(N m)], (n, n)
    layout = [(s.joint, s.axes) for s in springs]
    js = [s.joint for s in springs for _ in range(len(s.axes))]  # chain joint of each spring
    cs = (np.concatenate([s.compliance for s in springs]) if springs else np.zeros(0))[:, None]
    out = np.empty((m, 6))
    for lo in range(0, m, robot.BATCH_CHUNK):
        hi = min(lo + robot.BATCH_CHUNK, m)
        ch = robot.chain_chunk(Q[lo:hi], axes=layout)
        Ft = W[lo:hi].T  # (6, mc)
        r = ch.p[None] - ch.o  # TCP minus joint origins [m], (n, 3, mc)
        M = _cross_soa(r, Ft[None, :3])
        M += Ft[None, 3:]  # moments about the joint origins [N m], (n, 3, mc)
        z = ch.z
        tau = z[:, 0] * M[:, 0] + z[:, 1] * M[:, 1] + z[:, 2] * M[:, 2]  # (n, mc) [N m]
        dq = c[:, None] * tau if identity else C_chain @ tau  # chain joint turns [rad]
        w = z * dq[:, None]  # rotation vector of each joint frame [rad], (n, 3, mc)
        if js:
            u, Ms = ch.u, M[js]
            turn = cs * (u[:, 0] * Ms[:, 0] + u[:, 1] * Ms[:, 1] + u[:, 2] * Ms[:, 2])
            ws = u * turn[:, None]  # (s, 3, mc) [rad]
            for k, j in enumerate(js):
                w[j] += ws[k]
        out[lo:hi, :3] = _cross_soa(w, r).sum(axis=0).T
        out[lo:hi, 3:] = w.sum(axis=0).T
    return out


def _cross_soa(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b over axis -2 (vectors stored structure-of-arrays, pose index last)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0, :] = a[..., 1, :] * b[..., 2, :] - a[..., 2, :] * b[..., 1, :]
    out[..., 1, :] = a[..., 2, :] * b[..., 0, :] - a[..., 0, :] * b[..., 2, :]
    out[..., 2, :] = a[..., 0, :] * b[..., 1, :] - a[..., 1, :] * b[..., 0, :]
    return out


def spring_twists(batch: PoseBatch, springs: Sequence[JointSprings]) -> FloatArray:
    """TCP twists j_s = [u_s x r; u_s] of unit turns of every spring, base frame, shape
    (m, 6, s), springs in order (seed 002 eq. 2)."""
    p = batch.T[:, :3, 3]
    out = np.empty((len(batch), 6, sum(len(s.axes) for s in springs)))
    k = 0
    for s in springs:
        frame = batch.frames[:, s.joint]
        u = np.matmul(frame[:, :3, :3], s.axes.T)  # (m, 3, k) base frame
        r = p - frame[:, :3, 3]  # TCP minus joint origin [m]
        kk = k + len(s.axes)
        out[:, :3, k:kk] = cross3(u.transpose(0, 2, 1), r[:, None, :]).transpose(0, 2, 1)
        out[:, 3:, k:kk] = u
        k = kk
    return out


def spring_compliance(batch: PoseBatch, springs: Sequence[JointSprings]) -> FloatArray:
    """Summed Cartesian compliance of spring effects, base frame, shape (m, 6, 6).

    C = sum_s c_s j_s j_s^T, one batched product over all springs (:func:`spring_twists`).
    """
    if not springs:
        return np.zeros((len(batch), 6, 6))
    jt = spring_twists(batch, springs)
    c = np.concatenate([s.compliance for s in springs])
    return np.matmul(jt * c, jt.transpose(0, 2, 1))


class SpringChain:
    """The Pinocchio chain of a robot with one virtual revolute joint per spring.

    Virtual joint s sits at zero angle right after its chain joint with identity placement,
    so the kinematics are those of the robot and its Jacobian column is the spring twist j_s.

    Args:
        robot: The robot.
        layout: (chain joint, axes (k, 3) in that joint's frame) per spring effect, in the
            order their compliances are passed to :meth:`deflection`.
    """

    def __init__(self, robot: Robot, layout: Sequence[tuple[int, FloatArray]]) -> None:
        g = robot.geometry
        self.robot = robot
        model = pin.Model()
        parent = 0
        real: list[int] = []
        slots: dict[int, list[tuple[int, FloatArray]]] = {}
        offset = 0
        for joint, axes in layout:
            slots.setdefault(joint, []).append((offset, np.asarray(axes, dtype=float)))
            offset += len(axes)
        order = np.empty(offset, dtype=int)
        for i in range(robot.nq):
            M = g.placements[i]
            parent = model.addJoint(parent, pin.JointModelRevoluteUnaligned(g.axes[i]),
                                    pin.SE3(M[:3, :3], M[:3, 3]), f"joint{i + 1}")
            real.append(model.joints[parent].idx_v)
            for start, axes in slots.get(i, []):
                for s, a in enumerate(axes):
                    parent = model.addJoint(parent, pin.JointModelRevoluteUnaligned(a),
                                            pin.SE3.Identity(), f"spring{start + s}")
                    order[start + s] = model.joints[parent].idx_v
        tcp = g.tcp
        self.tcp_id = model.addFrame(
            pin.Frame("tcp", parent, pin.SE3(tcp[:3, :3], tcp[:3, 3]), pin.FrameType.OP_FRAME)
        )
        self.model = model
        self.data = model.createData()
        self.real = np.array(real)
        self.spring_v = order  # velocity index of spring s (layout order)
        self.identity = bool(np.array_equal(robot.coupling, np.eye(robot.nq)))
        self._q = np.zeros(model.nq)
        self._c = np.zeros(model.nv)

    def jacobian(self, q: FloatArray) -> FloatArray:
        """TCP Jacobian over chain and spring coordinates (6, nv), base frame [v; w], at the
        controller joint values q [rad] (n,) with every spring at rest."""
        self._q[self.real] = self.robot.chain_q(q)
        return pin.computeFrameJacobian(self.model, self.data, self._q, self.tcp_id,
                                        pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)

    def deflection(
        self, q: FloatArray, wrench: FloatArray, joint_compliance: FloatArray,
        spring_compliance: FloatArray,
    ) -> FloatArray:
        """dX = J diag(c) J^T F + sum_s c_s j_s j_s^T F [m, rad], base frame, shape (6,).

        Args:
            q: Controller joint values [rad], shape (n,).
            wrench: True wrench at the TCP [N, N m], base frame, shape (6,).
            joint_compliance: Controller joint compliances c [rad/(N m)], shape (n,).
            spring_compliance: Spring compliances in layout order [rad/(N m)], shape (s,).
        """
        Jx = self.jacobian(q)
        F = np.asarray(wrench, dtype=float).reshape(6)
        tau = F @ Jx  # joint and spring moments [N m]
        c = self._c
        c[self.spring_v] = spring_compliance
        if self.identity:
            c[self.real] = joint_compliance
            return Jx @ (c * tau)
        c[self.real] = 0.0
        G = self.robot.coupling
        Jr = Jx[:, self.real]
        return Jx @ (c * tau) + Jr @ (G @ (joint_compliance * (G.T @ tau[self.real])))
