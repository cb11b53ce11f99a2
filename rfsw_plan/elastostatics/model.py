"""The elastostatic model: joint compliance plus any number of physical effects.

``ElastostaticModel`` is what ``predict``, the planner, the validator and the virtual weld all
use to turn (joint values, logged wrench) into a TCP deflection. Its first effect is always
:class:`JointCompliance` (the robot's joint stiffness); the others come from the robot
description's ``[[effects]]`` or are added by the user.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from difflib import get_close_matches
from typing import Literal

import numpy as np

from rfsw_plan.elastostatics.effects import (
    ComplianceEffect,
    Effect,
    EffectGroups,
    JointCompliance,
    PoseBatch,
    make_effect,
)
from rfsw_plan.elastostatics.effects.base import FloatArray, WrenchToPose
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.plugins import load_plugin, plugins_of
from rfsw_plan.elastostatics.springs import (
    JointSprings,
    SpringChain,
    chain_spring_deflection,
    spring_compliance,
    spring_deflection,
)
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.robot.description import EffectSpec, Payload, RobotDescription, check_stiffness
from rfsw_plan.robot.kinematics import Robot

#: How a seam's points relate to the robot: taught with this robot and tool, or absolute
#: (CAD or measured) in the calibrated base frame. See
#: :meth:`ElastostaticModel.process_deflection`.
SeamReference = Literal["taught", "absolute"]


def _description_effects(robot: Robot) -> list[Effect]:
    """The effects stored in the robot description, with errors that name the file and entry.

    Raises:
        InputError: Unknown effect or parameter (with a "did you mean"), or a parameter outside
            its physical range (``effects[2].params.c_t1``).
    """
    desc = robot.description
    for i, plugin in enumerate(desc.plugins, start=1):
        load_plugin(plugin, f"{desc.path or desc.name}: effect_plugins[{i}]")
    out: list[Effect] = []
    for i, spec in enumerate(desc.effects, start=1):
        try:
            effect = make_effect(robot, spec.name, spec.params)
            effect.check_params()
            out.append(effect)
        except UnknownNameError as exc:
            close = get_close_matches(spec.name.split(":")[0], exc.known, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise InputError(desc.path or desc.name, f"effects[{i}].name",
                             f"unknown effect '{spec.name}'{hint}",
                             "" if hint else ", ".join(exc.known)) from None
        except InputError as exc:
            param = exc.where.rsplit(".", 1)[1] if "." in exc.where else ""
            where = f"effects[{i}].params.{param}" if param else f"effects[{i}].name"
            raise InputError(desc.path or desc.name, where, f"{exc.problem} ({spec.name})",
                             exc.expected) from None
    return out


class ElastostaticModel:
    """Robot plus an ordered list of effects with their current parameters.

    Args:
        robot: The robot (kinematics and joint stiffness).
        effects: Effects after the base joint compliance. None takes those stored in the
            robot description.
    """

    def __init__(self, robot: Robot, effects: Sequence[Effect] | None = None) -> None:
        self.robot = robot
        if effects is None:
            effects = _description_effects(robot)
        base = EffectGroups.of(effects).joint or JointCompliance(robot)
        self._joint_compliance = base
        self.effects: list[Effect] = [base, *(e for e in effects if e is not base)]
        self._spring_chain: tuple[tuple[tuple[int, bytes], ...], SpringChain] | None = None
        labels = self.labels
        dup = {x for x in labels if labels.count(x) > 1}
        if dup:
            raise InputError("model", ", ".join(sorted(dup)), "effect given more than once")

    def tool_payload(self) -> Payload | None:
        """The tool's load for a controller program: the mass and centre of mass an effect
        identifies (:meth:`Effect.tool_load`, e.g. ``payload_gravity``; centre of mass moved
        from the TCP frame to the flange frame, inertia from ``[payload]`` if given), else the
        robot file's ``[payload]`` table, else None."""
        desc = self.robot.description
        for e in self.effects:
            load = e.tool_load()
            if load is not None:
                m, r_tool = load
                com = desc.tool[:3, :3] @ r_tool + desc.tool[:3, 3]
                src = desc.sources.get(f"effects.{e.label}", f"the {e.label} effect")
                inertia = None if desc.payload is None else desc.payload.inertia
                return Payload(m, com, inertia, f"{e.label} effect ({src})")
        return desc.payload

    # -- composition -------------------------------------------------------------------------
    @property
    def labels(self) -> list[str]:
        """Effect labels in order, e.g. ``['joint_compliance', 'payload_gravity']``."""
        return [e.label for e in self.effects]

    def has(self, label: str) -> bool:
        """True if the model already contains the effect ``label``."""
        return label in self.labels

    def with_effect(self, label: str, params: dict[str, float] | None = None) -> ElastostaticModel:
        """A new model with one more effect (prior parameters unless given)."""
        if self.has(label):
            raise InputError("model", label, "effect is already in the model")
        return ElastostaticModel(
            self.robot, [*self.copy().effects, make_effect(self.robot, label, params)]
        )

    def copy(self) -> ElastostaticModel:
        """Deep copy of the parameters (effects are re-instantiated)."""
        effects = [type(e)(self.robot, e.joint, e.param_dict()) for e in self.effects]
        return ElastostaticModel(self.robot, effects)

    @property
    def joint_compliance(self) -> JointCompliance:
        """The base joint-compliance effect."""
        return self._joint_compliance

    @property
    def groups(self) -> EffectGroups:
        """The effects sorted by how the model evaluates them (each effect joins its group,
        :meth:`Effect.join`)."""
        return EffectGroups.of(self.effects)

    def springs(self) -> list[JointSprings]:
        """The spring effects (:meth:`ComplianceEffect.joint_springs`) with their current
        compliances, in model order."""
        out: list[JointSprings] = []
        for e in self.groups.springs:
            axes = e.joint_springs()
            assert axes is not None and e.joint is not None  # how the effect joined
            out.append(JointSprings(e.joint, axes, e.params))
        return out

    @property
    def stiffness(self) -> FloatArray:
        """Current joint stiffness [N m/rad], shape (n,)."""
        return 1.0 / self.joint_compliance.params

    # -- evaluation --------------------------------------------------------------------------
    def batch(self, q: FloatArray) -> PoseBatch:
        """Kinematics of joint values [rad], shape (m, n) or (n,). The joint frames are
        gathered with the poses only if an effect reads them (spring effects,
        :attr:`Effect.uses_frames`), else on first use (:attr:`PoseBatch.frames`)."""
        Q = np.atleast_2d(np.asarray(q, dtype=float))
        if Q.shape[0] == 1:  # one pose: Pinocchio beats the vectorised path's overhead
            T, J = self.robot.fk_jacobian(Q[0])
            return PoseBatch(self.robot, Q, T[None], J[None], self.robot.joint_frames(Q[0])[None])
        return PoseBatch.from_q(self.robot, Q, frames=self.reads_frames())

    def reads_frames(self) -> bool:
        """True if an effect reads the chain joint frames (:attr:`PoseBatch.frames`)."""
        return bool(self.groups.springs) or any(e.uses_frames for e in self.effects)

    def batch_of(self, data: MeasurementSet, force_noise: float | None = None) -> PoseBatch:
        """Kinematics of a measurement set's samples with their history: each joint's
        approach direction (:meth:`MeasurementSet.approach_directions`), the last load change
        at the same pose (:meth:`MeasurementSet.load_changes`) and the force noise
        of the logged wrench [N] (``force_noise`` if given, else from the zero-load readings;
        ``inf`` when the data logs no force at all, 0 when it cannot be estimated).
        """
        if force_noise is not None:
            fn = float(force_noise)
        elif not np.any(data.wrench[:, :3]):
            fn = math.inf
        else:
            fn = data.zero_load_force_noise() or 0.0
        b = self.batch(data.q)
        return replace(b, approach=data.approach_directions(), force_noise=fn,
                       load_change=data.load_changes(), load_history=data.load_histories())

    def true_wrench(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """Logged wrench corrected by the wrench effects [N, N m], base frame, shape (m, 6)."""
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6)).copy()
        logged = F.copy()
        for e in self.groups.wrench:
            F += e.delta_wrench(batch, logged, e.params)
        return F

    def linear_compliance(self, batch: PoseBatch) -> tuple[FloatArray, list[ComplianceEffect]]:
        """Cartesian compliance (m, 6, 6) of the wrench-linear compliance effects, and the
        compliance effects that are not linear in the wrench (no Cartesian compliance)."""
        C = spring_compliance(batch, self.springs())
        nonlinear: list[ComplianceEffect] = []
        for e in self.groups.compliance:
            Ce = e.cartesian_compliance(batch, e.params)
            if Ce is None:
                nonlinear.append(e)
            else:
                C += Ce
        return C, nonlinear

    def deflection_jvp(
        self, batch: PoseBatch, wrench: FloatArray, dF: FloatArray,
        parts: tuple[FloatArray, list[ComplianceEffect]] | None = None,
    ) -> FloatArray:
        """d(deflection)/dF applied to wrench directions: (d dX/dF) dF, shape (m, 6, p).

        Args:
            batch: Poses.
            wrench: True wrench [N, N m], base frame, (m, 6), where the derivative is taken.
            dF: Wrench directions [N, N m per unit], (m, 6, p).
            parts: :meth:`linear_compliance` of the batch, if already computed.
        """
        C, nonlinear = parts if parts is not None else self.linear_compliance(batch)
        out = np.matmul(C, dF)  # linear compliance part
        for e in nonlinear:
            # Non-linear-in-wrench compliance: directional finite difference per column.
            base = e.deflection(batch, wrench, e.params)
            for k in range(dF.shape[2]):
                h = 1e-6 * max(1.0, float(np.max(np.abs(wrench))))
                scale = np.max(np.abs(dF[:, :, k])) or 1.0
                step = dF[:, :, k] / scale * h
                moved = e.deflection(batch, wrench + step, e.params)
                out[:, :, k] += (moved - base) / h * scale
        return out

    def wrench_to_pose(self) -> WrenchToPose:
        """:meth:`deflection_jvp` that computes the linear compliance of a batch once (for
        the identification Jacobian of several wrench effects)."""
        last: list[tuple[PoseBatch, tuple[FloatArray, list[ComplianceEffect]]]] = []

        def through(batch: PoseBatch, wrench: FloatArray, dF: FloatArray) -> FloatArray:
            if not last or last[0][0] is not batch:
                last[:] = [(batch, self.linear_compliance(batch))]
            return self.deflection_jvp(batch, wrench, dF, last[0][1])

        return through

    def cartesian_compliance(self, batch: PoseBatch) -> FloatArray:
        """Cartesian compliance of the wrench-linear compliance effects, shape (m, 6, 6)."""
        return self.linear_compliance(batch)[0]

    def deflection_batch(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """TCP deflection [m, rad], base frame, shape (m, 6), for a logged wrench (m, 6).

        dX = sum_compliance dX_e(F_true) + sum_geometric offset_e, F_true = F + sum dF_e.
        The spring effects (tilting compliance) are summed in one vectorised step
        (:func:`~rfsw_plan.elastostatics.springs.spring_deflection`).
        """
        F = self.true_wrench(batch, wrench)
        groups = self.groups
        dX = spring_deflection(batch, self.springs(), F)
        for e in groups.compliance:
            dX += e.deflection(batch, F, e.params)
        for g in groups.geometric:
            dX += g.offset(batch, g.params)
        return dX

    def deflection(self, q: FloatArray, wrench: FloatArray) -> FloatArray:
        """TCP deflection [m, rad] for joint values (m, n) or (n,) and wrench (m, 6) or (6,).

        Returns shape (m, 6), or (6,) for a single pose.
        """
        single = np.ndim(q) == 1
        if self.is_linear_joint_model():
            return self._joint_deflection_fast(q, wrench, single)
        if self.is_spring_model():
            if single:
                return self._spring_deflection_single(q, wrench)
            return chain_spring_deflection(self.robot, q, wrench, self.joint_compliance.params,
                                           self.springs())
        batch = self.batch(q)
        dX = self.deflection_batch(batch, np.atleast_2d(wrench))
        return dX[0] if single else dX

    def _spring_deflection_single(self, q: FloatArray, wrench: FloatArray) -> FloatArray:
        """One pose of a joint-plus-spring model with one Pinocchio Jacobian call.

        Same equations as :class:`JointCompliance` and the spring effects; the chain with one
        virtual joint per spring (:class:`~rfsw_plan.elastostatics.springs.SpringChain`) is
        built once per effect layout.
        """
        springs = self.springs()
        key = tuple((s.joint, s.axes.tobytes()) for s in springs)
        if self._spring_chain is None or self._spring_chain[0] != key:
            layout = [(s.joint, s.axes) for s in springs]
            self._spring_chain = (key, SpringChain(self.robot, layout))
        chain = self._spring_chain[1]
        c_springs = np.concatenate([s.compliance for s in springs])
        return chain.deflection(np.asarray(q, dtype=float), wrench,
                                self.joint_compliance.params, c_springs)

    def _joint_deflection_fast(
        self, q: FloatArray, wrench: FloatArray, single: bool
    ) -> FloatArray:
        """dX = J diag(c) J^T F without building a :class:`PoseBatch` (joint compliance only).

        Same equation as :class:`JointCompliance` (seed 000 eq. 11); a single pose uses
        Pinocchio's Jacobian, many poses the vectorised batch without joint frames.
        """
        c = self.joint_compliance.params
        if single:
            _, J = self.robot.fk_jacobian(np.asarray(q, dtype=float))
            F = np.asarray(wrench, dtype=float).reshape(6)
            return J @ (c * (F @ J))
        _, J = self.robot.batch_fk_jacobian(q)
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (J.shape[0], 6))
        tau = np.matmul(F[:, None, :], J)[:, 0]  # joint torques [N m]
        return np.matmul(J, (tau * c)[:, :, None])[:, :, 0]

    def physical(self) -> ElastostaticModel:
        """This model without its sensor-only effects (see :attr:`Effect.sensor_only`).

        The model to use for a wrench that did not come from the force sensor. Returns
        ``self`` when there is nothing to drop.
        """
        keep = [e for e in self.effects if not e.sensor_only]
        return self if len(keep) == len(self.effects) else ElastostaticModel(self.robot, keep)

    def process_deflection(
        self, q: FloatArray, wrench: FloatArray, reference: SeamReference = "taught"
    ) -> FloatArray:
        """TCP deflection [m, rad], base frame, caused by a *modelled* process wrench.

        Used wherever the wrench comes from the process model rather than a sensor log
        (planning, deviation, the truth of a virtual weld):

        * sensor-only effects are dropped (:meth:`physical`): they distort a sensor's reading,
          not the robot;
        * ``reference="taught"``: the seam was taught with this robot and tool, so what the
          robot already did at zero process load (payload sag, kinematic offsets...) is in the
          taught points: dX = dX(q, F) - dX(q, 0);
        * ``reference="absolute"``: the seam is given in the calibrated base frame (from CAD or
          a measurement), so the full dX(q, F) counts.

        For joint and tilting compliance both references give J C J^T F (seed 000 eq. 11).

        Args:
            q: Joint values [rad], shape (m, n) or (n,).
            wrench: Process wrench at the TCP, base frame [N, N m], shape (m, 6) or (6,).
            reference: ``taught`` or ``absolute``.

        Returns:
            Shape (m, 6), or (6,) for a single pose.
        """
        if reference not in ("taught", "absolute"):
            raise InputError("reference", reference, "unknown seam reference", "taught or absolute")
        phys = self.physical()
        dX = phys.deflection(q, wrench)
        if reference == "taught" and phys.has_load_independent_part():
            dX = dX - phys.deflection(q, np.zeros_like(np.asarray(wrench, dtype=float)))
        return dX

    def process_deflection_batch(
        self, batch: PoseBatch, wrench: FloatArray, reference: SeamReference = "taught"
    ) -> FloatArray:
        """:meth:`process_deflection` on precomputed kinematics, shape (m, 6)."""
        if reference not in ("taught", "absolute"):
            raise InputError("reference", reference, "unknown seam reference", "taught or absolute")
        phys = self.physical()
        W = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        dX = phys.deflection_batch(batch, W)
        if reference == "taught" and phys.has_load_independent_part():
            dX = dX - phys.deflection_batch(batch, np.zeros_like(W))
        return dX

    def has_load_independent_part(self) -> bool:
        """True if the model deflects the TCP at zero logged wrench (wrench or geometric
        effects such as payload gravity or kinematic offsets)."""
        return any(e.load_independent for e in self.effects)

    def predict_position(self, q: FloatArray, wrench: FloatArray) -> FloatArray:
        """Loaded TCP position [m], base frame: FK(q) + dX_translation; shape (m, 3)."""
        batch = self.batch(q)
        return batch.T[:, :3, 3] + self.deflection_batch(batch, np.atleast_2d(wrench))[:, :3]

    def is_linear_joint_model(self) -> bool:
        """True if the model is joint compliance only and the links carry no mass (the fast
        path applies)."""
        return len(self.effects) == 1 and not self.robot.has_link_masses

    def is_spring_model(self) -> bool:
        """True if every effect after the joint compliance is a spring effect
        (:meth:`ComplianceEffect.joint_springs`, e.g. tilting compliance): linear in the
        wrench, and a single pose is one Pinocchio Jacobian call."""
        return (not self.robot.has_link_masses
                and len(self.groups.springs) == len(self.effects) - 1)

    # -- storage -----------------------------------------------------------------------------
    def to_description(self, source_note: str | None = None) -> RobotDescription:
        """The robot description with this model's stiffness and effects."""
        desc = self.robot.description
        k = self.stiffness
        check_stiffness(k, "model", "joint_compliance")
        out = desc.with_stiffness(k, source_note or desc.sources.get("stiffness", ""))
        specs = tuple(EffectSpec(e.label, e.param_dict()) for e in self.effects[1:]
                      if not e.setup)
        return replace(out, effects=specs, plugins=plugins_of(e.name for e in self.effects))


def load_model(robot: Robot | RobotDescription | str) -> ElastostaticModel:
    """Elastostatic model of a robot (bundled name, file, description or Robot)."""
    from rfsw_plan.robot.kinematics import load_robot

    return ElastostaticModel(load_robot(robot))
