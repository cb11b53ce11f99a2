"""Numeric kinematics of a robot description, through Pinocchio.

The Pinocchio model is the single source of truth for the kinematic chain: the symbolic CasADi
model (``rfsw_plan.planning.symbolic``) and the vectorised batch evaluation here are both built
from its joint placements and joint axes, and tests check they agree with it.

Conventions:
    * ``q`` are controller joint values [rad], shape (n,); the chain sees ``G q``.
    * Poses are 4x4 homogeneous transforms of the TCP in the robot base frame [m].
    * Jacobians map ``dq`` to the TCP twist ``[v; omega]`` in the base frame
      (Pinocchio ``LOCAL_WORLD_ALIGNED``: linear velocity of the TCP point, angular velocity,
      both expressed in base axes), shape (6, n). This is the J of seed 000 eq. 3.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import (
    ModifiedDH,
    RobotDescription,
    UrdfChain,
    load_robot_description,
)
from rfsw_plan.robot.urdf import axis_of, load_urdf_chain

FloatArray = NDArray[np.float64]

TCP_FRAME = "tcp"


@dataclass(frozen=True)
class ChainGeometry:
    """Constant geometry of the serial chain, read from the Pinocchio model.

    Attributes:
        placements: Joint placement of joint i in its parent joint frame, shape (n, 4, 4) [m].
        axes: Unit rotation axis of joint i in its own frame, shape (n, 3).
        tcp: TCP placement in the last joint frame, shape (4, 4) [m].
        prismatic: True for a prismatic joint (translation along its axis, q in [m]),
            False for a revolute one (rotation about it, q in [rad]), shape (n,).
    """

    placements: FloatArray
    axes: FloatArray
    tcp: FloatArray
    prismatic: NDArray[np.bool_]


@dataclass(frozen=True)
class ChainChunk:
    """Forward kinematics of a chunk of m poses, structure-of-arrays (pose index last).

    Attributes:
        R: TCP rotation in the base frame, R[a, b, k] for pose k, shape (3, 3, m).
        p: TCP position in the base frame [m], shape (3, m).
        z: Chain joint axes in the base frame (unit), shape (n, 3, m).
        o: Chain joint frame origins in the base frame [m], shape (n, 3, m).
        frames: Chain joint frame rotations in the base frame, shape (n, 3, 3, m), or None
            when not requested.
        u: Requested extra axes (fixed in joint frames) in the base frame, unit, shape
            (s, 3, m).
    """

    R: FloatArray
    p: FloatArray
    z: FloatArray
    o: FloatArray
    frames: FloatArray | None
    u: FloatArray


def _mdh_placement(alpha: float, a: float, theta0: float, d: float) -> pin.SE3:
    """Rx(alpha) Tx(a) Rz(theta0) Tz(d): the constant part of the MDH link transform."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta0), np.sin(theta0)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    rz = np.array([[ct, -st, 0], [st, ct, 0], [0, 0, 1]])
    R = rx @ rz
    p = np.array([a, 0.0, 0.0]) + R @ np.array([0.0, 0.0, d])
    return pin.SE3(R, p)


def _link_inertia(chain: ModifiedDH, i: int) -> pin.Inertia:
    """Link i of an MDH table as a point mass at its centre of mass (joint i's frame): what
    the links' weight on the joints needs (:meth:`Robot.gravity_torque`); no mass -> zero."""
    if chain.mass is None or chain.com is None:
        return pin.Inertia.Zero()
    return pin.Inertia(float(chain.mass[i]), np.asarray(chain.com[i], dtype=float),
                       np.zeros((3, 3)))


def build_pinocchio_model(desc: RobotDescription) -> pin.Model:
    """Build the Pinocchio model of a description, with a ``tcp`` operational frame.

    For an MDH table, joint i is a revolute-Z joint placed at Rx(alpha_{i-1}) Tx(a_{i-1})
    Rz(theta0_i) Tz(d_i) in joint i-1 (Rz(q) commutes with Tz(d)), seed 001 eq. 1. For a URDF,
    the chain from its root to the tip link (:func:`rfsw_plan.robot.urdf.load_urdf_chain`).
    An MDH table's ``link_mass_kg``/``link_com_mm`` become point-mass link inertias.

    This is the one place where the controller offsets enter: the model's joint variable is
    ``G q`` (signed coupling times controller values) and each joint placement is turned by the
    joint's offset about its own axis, so the chain angle is ``theta = G q + offset``
    (:class:`rfsw_plan.robot.description.ControllerConvention`).
    """
    offset = desc.convention.offset
    if isinstance(desc.chain, ModifiedDH):
        model = pin.Model()
        model.name = desc.name
        parent = 0
        c = desc.chain
        for i in range(desc.n_joints):
            placement = _mdh_placement(c.alpha[i], c.a[i], c.theta0[i] + offset[i], c.d[i])
            parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
            model.appendBodyToJoint(parent, _link_inertia(c, i), pin.SE3.Identity())
        last = parent
        tip_placement = pin.SE3.Identity()
    else:
        assert isinstance(desc.chain, UrdfChain)
        chain = load_urdf_chain(desc.chain.path, desc.chain.tip_link, desc.path or "")
        model = chain.model
        for jid in range(1, model.njoints):
            turn = pin.SE3(pin.exp3(axis_of(model, jid) * offset[jid - 1]), np.zeros(3))
            model.jointPlacements[jid] = model.jointPlacements[jid] * turn
        frame = model.frames[chain.tip_frame]
        last = frame.parentJoint
        tip_placement = frame.placement
        if model.nq != desc.n_joints:
            raise InputError(desc.chain.path, desc.chain.tip_link,
                             f"the chain to the tip has {model.nq} joints",
                             f"{desc.n_joints} as in the description")
    tool = pin.SE3(desc.tool[:3, :3], desc.tool[:3, 3])
    model.addFrame(pin.Frame(TCP_FRAME, last, tip_placement * tool, pin.FrameType.OP_FRAME))
    return model


def _chain_geometry(model: pin.Model) -> ChainGeometry:
    n = model.nq
    placements = np.zeros((n, 4, 4))
    axes = np.zeros((n, 3))
    prismatic = np.zeros(n, dtype=bool)
    for i in range(n):
        jid = i + 1
        if model.parents[jid] != jid - 1:
            raise InputError(model.name, f"joint {jid}", "not a serial chain")
        placements[i] = model.jointPlacements[jid].homogeneous
        short = model.joints[jid].shortname()
        prismatic[i] = short.startswith("JointModelP")
        if short[-1] in "XYZ" and short[:-1] in ("JointModelR", "JointModelP"):
            axes[i, "XYZ".index(short[-1])] = 1.0
        elif short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
            axes[i] = np.asarray(model.joints[jid].extract().axis).ravel()
        else:
            raise InputError(model.name, f"joint {jid} ({model.names[jid]})",
                             f"joint type {short} not supported",
                             "revolute or prismatic joints (continuous joints: give limits)")
    tcp = model.frames[model.getFrameId(TCP_FRAME)].placement.homogeneous
    return ChainGeometry(placements, axes, tcp, prismatic)


class Robot:
    """A robot ready for numeric kinematics: Pinocchio model plus limits and stiffness.

    Args:
        description: The robot description (or a bundled name / path, see
            :func:`load_robot`).
    """

    def __init__(self, description: RobotDescription) -> None:
        self.description = description
        self.model = build_pinocchio_model(description)
        self.data = self.model.createData()
        self.tcp_id = self.model.getFrameId(TCP_FRAME)
        self.geometry = _chain_geometry(self.model)
        self.coupling = np.asarray(description.coupling, dtype=float)

    # -- basic properties --------------------------------------------------------------------
    @property
    def name(self) -> str:
        """Robot name."""
        return self.description.name

    @property
    def nq(self) -> int:
        """Number of joints."""
        return self.description.n_joints

    @property
    def prismatic(self) -> NDArray[np.bool_]:
        """True for each prismatic joint (q in [m], stiffness in [N/m]), shape (n,)."""
        return self.geometry.prismatic

    @property
    def stiffness(self) -> FloatArray:
        """Joint stiffness on the controller side [N m/rad] ([N/m] for a prismatic joint),
        shape (n,)."""
        return self.description.stiffness

    @cached_property
    def joint_compliance(self) -> FloatArray:
        """Joint compliance matrix seen by the chain, G K^-1 G^T [rad/(N m)], shape (n, n)."""
        G = self.coupling
        return G @ np.diag(1.0 / self.stiffness) @ G.T

    def chain_q(self, q: FloatArray) -> FloatArray:
        """Chain joint angles ``G q`` [rad]; works on shape (n,) or (m, n)."""
        return np.asarray(q, dtype=float) @ self.coupling.T

    def check_q(self, q: FloatArray, source: str = "q") -> FloatArray:
        """Validate a joint vector's shape and finiteness; returns it as float array."""
        arr = np.asarray(q, dtype=float)
        if arr.shape[-1:] != (self.nq,):
            raise InputError(source, "", f"got {arr.shape[-1] if arr.ndim else 1} joint values",
                             f"{self.nq} for robot {self.name}")
        if not np.all(np.isfinite(arr)):
            raise InputError(source, "", "joint values contain NaN or infinity", "finite values")
        return arr

    @property
    def joint_names(self) -> list[str]:
        """Names of the joints in order (the URDF's, or ``joint1``.. for an MDH table)."""
        return [str(n) for n in list(self.model.names)[1: self.nq + 1]]

    @cached_property
    def has_link_masses(self) -> bool:
        """True if the description gives link masses (a URDF with inertials): the robot's own
        weight then loads its joints (:meth:`gravity_torque`)."""
        return bool(sum(float(inertia.mass) for inertia in self.model.inertias) > 0.0)

    def gravity_torque(self, Q: FloatArray) -> FloatArray:
        """Joint torques the links' own weight applies, controller side, shape (m, n).

        tau_ext = -G^T g(G q): Pinocchio's generalised gravity g is the torque that *holds*
        the links against gravity (-Z of the base frame, 9.81 m/s^2); the springs feel its
        opposite, as they feel J^T F of an external wrench. [N m] for revolute joints, [N] for
        prismatic ones; zeros when the description has no link masses.
        """
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.zeros_like(Q)
        if not self.has_link_masses:
            return out
        for k, qc in enumerate(self.chain_q(Q)):
            out[k] = -(pin.computeGeneralizedGravity(self.model, self.data, qc) @ self.coupling)
        return out

    # -- Pinocchio single-pose ---------------------------------------------------------------
    def fk(self, q: FloatArray) -> FloatArray:
        """TCP pose in the base frame, 4x4 [m]."""
        pin.framesForwardKinematics(self.model, self.data, self.chain_q(q))
        return self.data.oMf[self.tcp_id].homogeneous.copy()

    def fk_jacobian(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """TCP pose (4, 4) [m] and base-frame TCP Jacobian (6, n) wrt controller joints."""
        qc = self.chain_q(q)
        Jc = pin.computeFrameJacobian(
            self.model, self.data, qc, self.tcp_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        pin.updateFramePlacement(self.model, self.data, self.tcp_id)
        return self.data.oMf[self.tcp_id].homogeneous.copy(), Jc @ self.coupling

    def jacobian(self, q: FloatArray) -> FloatArray:
        """Base-frame TCP Jacobian wrt controller joints, shape (6, n)."""
        return self.fk_jacobian(q)[1]

    def joint_frames(self, q: FloatArray) -> FloatArray:
        """Poses of the chain joint frames in the base frame, shape (n, 4, 4) [m]."""
        pin.forwardKinematics(self.model, self.data, self.chain_q(q))
        return np.stack([self.data.oMi[i + 1].homogeneous for i in range(self.nq)])

    # -- vectorised batch --------------------------------------------------------------------
    @cached_property
    def _z_aligned_chain(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, bool]:
        """Constants of the chain rewritten with every joint rotating about its local z axis.

        A joint about unit axis a rotates by ``A Rz(q) A^T`` where A is a rotation with third
        column a; folding A into the placements gives ``P_i' = A_{i-1}^T P_i A_i`` and
        ``tcp' = A_n^T tcp``, so the batch loop only ever rotates about z.

        Returns:
            (rotations (n+1, 3, 3), translations (n+1, 3) [m], A (n, 3, 3), aligned flags
            (n,), identity coupling); index n holds the TCP placement.
        """
        g = self.geometry
        n = self.nq
        A = np.empty((n, 3, 3))
        aligned = np.empty(n, dtype=bool)
        for i in range(n):
            a = g.axes[i] / np.linalg.norm(g.axes[i])
            aligned[i] = bool(np.allclose(a, [0.0, 0.0, 1.0], rtol=0.0, atol=1e-15))
            if aligned[i]:
                A[i] = np.eye(3)
            else:
                helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
                x = helper - a * (helper @ a)
                x /= np.linalg.norm(x)
                A[i] = np.column_stack([x, np.cross(a, x), a])
        rot = np.empty((n + 1, 3, 3))
        trans = np.empty((n + 1, 3))
        prev = np.eye(3)
        for i in range(n + 1):
            M = g.placements[i] if i < n else g.tcp
            after = A[i] if i < n else np.eye(3)
            rot[i] = prev.T @ M[:3, :3] @ after
            trans[i] = prev.T @ M[:3, 3]
            prev = A[i] if i < n else prev
        identity = bool(np.array_equal(self.coupling, np.eye(n)))
        return rot, trans, A, aligned, identity

    #: Poses evaluated per chunk in :meth:`batch_fk_jacobian` (keeps the working set in cache).
    BATCH_CHUNK = 4096

    def batch_fk_jacobian(self, Q: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Vectorised TCP poses and Jacobians for many configurations.

        Same numbers as :meth:`fk_jacobian` (checked in tests to 1e-12), computed with NumPy
        over all poses at once from the Pinocchio joint placements and axes. Internally the
        poses are stored structure-of-arrays (3, 3, m) so that every constant placement is one
        BLAS product and every joint rotation (about z after :attr:`_z_aligned_chain`) is a
        few element-wise operations; poses are processed in chunks of :attr:`BATCH_CHUNK`.

        Args:
            Q: Controller joint values [rad], shape (m, n) (or (n,) for one pose).

        Returns:
            ``(T, J)``: TCP poses in the base frame, shape (m, 4, 4) [m], and base-frame TCP
            Jacobians wrt controller joints, shape (m, 6, n).
        """
        return self._batch(np.atleast_2d(np.asarray(Q, dtype=float)), None)

    def batch_fk_jacobian_frames(
        self, Q: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`batch_fk_jacobian` plus the chain joint frames.

        Args:
            Q: Controller joint values [rad], shape (m, n) (or (n,) for one pose).

        Returns:
            ``(T, J, frames)``: T shape (m, 4, 4) [m] and J shape (m, 6, n) as in
            :meth:`batch_fk_jacobian`, and the chain joint frames in the base frame, shape
            (m, n, 4, 4) [m] (same as :meth:`joint_frames` per pose).
        """
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        frames = np.zeros((*Q.shape, 4, 4))
        frames[:, :, 3, 3] = 1.0
        T, J = self._batch(Q, frames)
        return T, J, frames

    def _batch(self, Q: FloatArray, frames: FloatArray | None) -> tuple[FloatArray, FloatArray]:
        """Chunked driver of :meth:`_batch_chunk` for Q (m, n); fills ``frames`` if given."""
        m, n = Q.shape
        T = np.zeros((m, 4, 4))
        T[:, 3, 3] = 1.0
        J = np.empty((m, 6, n))
        for lo in range(0, m, self.BATCH_CHUNK):
            hi = min(lo + self.BATCH_CHUNK, m)
            self._batch_chunk(Q[lo:hi], T[lo:hi], J[lo:hi],
                              None if frames is None else frames[lo:hi])
        return T, J

    def chain_chunk(
        self, Q: FloatArray, frames: bool = False,
        axes: Sequence[tuple[int, FloatArray]] = (),
    ) -> ChainChunk:
        """Forward kinematics of up to :attr:`BATCH_CHUNK` poses in the internal layout.

        The loop over the joints that :meth:`batch_fk_jacobian` runs, returning its state
        structure-of-arrays (pose index last) so that callers can build further per-joint
        quantities (e.g. spring twists, :mod:`rfsw_plan.elastostatics.springs`) without
        copying frames out per pose.

        Args:
            Q: Controller joint values [rad], shape (m, n).
            frames: Also keep the rotation of every chain joint frame.
            axes: (chain joint i, unit axes (k, 3) fixed in joint i's frame): the axes are
                returned in the base frame, stacked in this order (:attr:`ChainChunk.u`).
        """
        rot, trans, A, aligned, identity = self._z_aligned_chain
        m, n = Q.shape
        # Extra axes in the z-aligned frame R A_i (joint frame = R A_i^T): b = A_i^T a.
        extra: dict[int, list[tuple[int, FloatArray]]] = {}
        n_extra = 0
        for joint, local in axes:
            for a in np.atleast_2d(np.asarray(local, dtype=float)):
                extra.setdefault(joint, []).append((n_extra, a @ A[joint]))
                n_extra += 1
        u = np.empty((n_extra, 3, m))
        qc = Q.T if identity else self.coupling @ Q.T  # chain angles, shape (n, m)
        slide = self.geometry.prismatic
        cq = np.cos(qc)
        sq = np.sin(qc)
        R = np.empty((3, 3, m))  # R[a, b, k]: rotation of pose k, structure-of-arrays
        R[:] = rot[0][:, :, None]
        p = np.empty((3, m))
        p[:] = trans[0][:, None]
        z = np.empty((n, 3, m))
        o = np.empty((n, 3, m))
        tmp = np.empty((3, m))
        Rf = np.empty((n, 3, 3, m)) if frames else None  # joint frame rotations
        for i in range(n):
            if i > 0:
                p += np.matmul(trans[i], R)  # p += R t_i
                R = np.matmul(rot[i].T, R)  # R <- R M_i, one BLAS product per row of R
            z[i] = R[:, 2]
            o[i] = p
            if slide[i]:  # prismatic: p <- p + q_i z_i, no rotation
                p = p + qc[i] * R[:, 2]
            else:  # R <- R Rz(q_i): only columns 0 and 1 change.
                x, y = R[:, 0], R[:, 1]
                np.multiply(x, sq[i], out=tmp)
                x *= cq[i]
                x += y * sq[i]
                y *= cq[i]
                y -= tmp
            if Rf is not None:
                Rf[i] = R if aligned[i] else np.matmul(A[i], R)
            for k, b in extra.get(i, ()):
                unit = np.flatnonzero(b)
                if len(unit) == 1 and b[unit[0]] == 1.0:  # a frame axis: copy the column
                    u[k] = R[:, unit[0]]
                else:
                    np.multiply(R[:, 0], b[0], out=u[k])
                    u[k] += R[:, 1] * b[1]
                    u[k] += R[:, 2] * b[2]
        p = p + np.matmul(trans[n], R)
        R = np.matmul(rot[n].T, R)
        return ChainChunk(R, p, z, o, Rf, u)

    def _batch_chunk(
        self, Q: FloatArray, T_out: FloatArray, J_out: FloatArray, F_out: FloatArray | None
    ) -> None:
        """Fill ``T_out`` (m, 4, 4), ``J_out`` (m, 6, n) and ``F_out`` for one chunk."""
        c = self.chain_chunk(Q, frames=F_out is not None)
        n = Q.shape[1]
        z = c.z
        T_out[:, :3, :3] = c.R.transpose(2, 0, 1)
        T_out[:, :3, 3] = c.p.T
        r = c.p[None] - c.o  # (n, 3, m) TCP minus joint origin [m]
        Jd = np.empty((6, n, Q.shape[0]))
        Jd[0] = z[:, 1] * r[:, 2] - z[:, 2] * r[:, 1]
        Jd[1] = z[:, 2] * r[:, 0] - z[:, 0] * r[:, 2]
        Jd[2] = z[:, 0] * r[:, 1] - z[:, 1] * r[:, 0]
        Jd[3:] = z.transpose(1, 0, 2)
        slide = self.geometry.prismatic
        if slide.any():  # a prismatic column is [z; 0]
            Jd[:3, slide] = z[slide].transpose(1, 0, 2)
            Jd[3:, slide] = 0.0
        if not self._z_aligned_chain[4]:
            Jd = np.matmul(self.coupling.T, Jd)  # J_ctrl = J_chain G, per row
        J_out[:] = Jd.transpose(2, 0, 1)
        if F_out is not None and c.frames is not None:
            F_out[:, :, :3, :3] = c.frames.transpose(3, 0, 1, 2)
            F_out[:, :, :3, 3] = c.o.transpose(2, 0, 1)

    def jacobian_derivatives(self, q: FloatArray) -> FloatArray:
        """Partial derivatives of the TCP Jacobian, dJ/dq_k, shape (n, 6, n).

        For revolute chain joints i and j with axis z and origin o in the base frame:
        column j is [z_j x (p - o_j); z_j]; dq_i rotates z_j and (p - o_j) about z_i when
        i < j, and only moves p when i >= j. The coupling G maps chain to controller
        derivatives. Needed for the complementary stiffness Kc (seed 000 eq. 6).
        """
        return self.batch_jacobian_derivatives(np.asarray(q, dtype=float)[None, :])[0]

    def batch_jacobian_derivatives(self, Q: FloatArray) -> FloatArray:
        """:meth:`jacobian_derivatives` for many configurations, shape (m, n, 6, n).

        Args:
            Q: Controller joint values [rad], shape (m, n).
        """
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        T, _, frames = self.batch_fk_jacobian_frames(Q)
        n = self.nq
        p = T[:, :3, 3]
        z = np.einsum("mnab,nb->mna", frames[:, :, :3, :3], self.geometry.axes)  # (m, n, 3)
        r = p[:, None, :] - frames[:, :, :3, 3]  # TCP minus joint origin, (m, n, 3) [m]
        zi = z[:, :, None, :]  # axis of the differentiated joint i
        zj = z[:, None, :, :]  # axis of the column j
        rj = r[:, None, :, :]
        upper = (np.arange(n)[:, None] < np.arange(n)[None, :])[None, :, :, None]
        slide = self.geometry.prismatic
        si = slide[None, :, None, None]  # differentiated joint i is prismatic
        sj = slide[None, None, :, None]  # column j is prismatic
        dz = np.where(si, 0.0, np.cross(zi, zj))  # (m, i, j, 3); a slide turns nothing
        v = np.where(slide[None, :, None], z, np.cross(z, r))  # TCP velocity of joint i
        # Revolute column j = [z_j x r_j; z_j]: for i < j a revolute i turns z_j and r_j,
        # a prismatic i moves p and o_j together; for i >= j joint i moves p only.
        lin_upper = np.cross(dz, rj) + np.where(si, 0.0, np.cross(zj, np.cross(zi, rj)))
        lin_lower = np.cross(zj, v[:, :, None, :])
        lin = np.where(upper, lin_upper, lin_lower)
        lin = np.where(sj, np.where(upper, dz, 0.0), lin)  # prismatic column j = [z_j; 0]
        ang = np.where(upper & ~sj, dz, 0.0)
        dJd = np.empty((Q.shape[0], n, 6, n))  # [m, i] = dJ_chain / dq_chain_i
        dJd[:, :, :3, :] = lin.transpose(0, 1, 3, 2)
        dJd[:, :, 3:, :] = ang.transpose(0, 1, 3, 2)
        G = self.coupling
        # dJ_ctrl/dq_ctrl_k = sum_i (dJ_chain/dq_chain_i) G[i, k], then times G on the right.
        if np.array_equal(G, np.eye(n)):  # no coupling: the chain joints are the controller's
            return dJd
        return np.einsum("ik,miab,bc->mkac", G, dJd, G, optimize=True)


def load_robot(name_or_path: str | object) -> Robot:
    """Load a bundled robot by name, a robot TOML file, or wrap a description.

    Raises:
        UnknownNameError: Unknown robot; the message lists the bundled ones.
        InputError: Malformed description file.
    """
    if isinstance(name_or_path, RobotDescription):
        return Robot(name_or_path)
    if isinstance(name_or_path, Robot):
        return name_or_path
    return Robot(load_robot_description(str(name_or_path)))


#: Largest joint deflection [rad] a plausible stiffness gives under the process wrench: the
#: elastostatic model is linear (small angles), and real robots turn milliradians (seed 001's
#: ZK-500: about 2.5 mrad at 4.8 kN). A thousand times that is a stiffness in kN m/rad.
MAX_PLAUSIBLE_DEFLECTION_RAD = 0.05


def check_stiffness_scale(robot: Robot, q: FloatArray, wrench: FloatArray) -> None:
    """Refuse a joint stiffness that is implausibly soft for the loads it carries, the sign of
    a unit slip (``k_Nm_per_rad`` written in kN m/rad).

    Args:
        robot: The robot.
        q: A pose near the work (the planning seed) [rad], shape (n,).
        wrench: Wrenches on the tool at the TCP, base frame [N, N m], shape (m, 6); the
            largest joint deflection over them is checked.

    Raises:
        InputError: Names the robot file's ``stiffness`` key, the joint, the deflection and the
            likely unit, if a revolute joint would turn more than
            :data:`MAX_PLAUSIBLE_DEFLECTION_RAD` (the linear model is meaningless there).
    """
    J = robot.jacobian(np.asarray(q, dtype=float))
    tau = np.abs(np.atleast_2d(wrench) @ J).max(axis=0)  # (n,) joint loads [N m] or [N]
    revolute = ~np.asarray(robot.prismatic, dtype=bool)
    turn = np.where(revolute, tau / robot.stiffness, 0.0)
    j = int(np.argmax(turn))
    if turn[j] <= MAX_PLAUSIBLE_DEFLECTION_RAD:
        return
    desc = robot.description
    raise InputError(
        desc.path or desc.name, "stiffness.k_Nm_per_rad",
        f"joint {j + 1} ({robot.stiffness[j]:.4g} N m/rad) would turn "
        f"{np.degrees(turn[j]):.3g} deg under the process loads ({tau[j]:.4g} N m): "
        "kN m/rad instead of N m/rad?",
        f"stiffness in N m/rad (x1000: {robot.stiffness[j] * 1e3:.4g}), a deflection of "
        f"at most {np.degrees(MAX_PLAUSIBLE_DEFLECTION_RAD):.2g} deg")
