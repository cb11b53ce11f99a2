"""The contract every elastostatic effect fulfils.

An *effect* is one piece of physics that moves the TCP under load or changes the wrench the
robot really feels. The base model is :class:`~rfsw_plan.elastostatics.effects.joint_compliance.
JointCompliance` (dX = J K^-1 J^T F); the others are added on top of it in an
:class:`~rfsw_plan.elastostatics.model.ElastostaticModel`.

Three kinds, applied in this order by the model:

``wrench``
    Corrects the logged wrench into the wrench that really acts at the TCP
    (sensor misalignment, sensor bias, payload gravity): ``F_true = F_logged + dF(theta)``.
``compliance``
    Deflects the TCP under the true wrench (joint compliance, tilting, backlash,
    torque-dependent stiffness). Linear-in-wrench ones also expose a Cartesian compliance.
``geometric``
    Load-independent pose error (kinematic offsets).

Each effect owns a parameter vector theta (SI units) with a prior, returns its contribution and
the derivative of that contribution with respect to theta (a *regressor*, exact for effects
that are linear in theta). Identification stacks the regressors (see
``rfsw_plan.elastostatics.identification``).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from difflib import get_close_matches
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

EffectKind = Literal["compliance", "wrench", "geometric"]

#: Largest |value| of any effect parameter [SI] (each effect narrows it in param_ranges).
PARAM_LIMIT = 1e9


@dataclass(frozen=True)
class PoseBatch:
    """Kinematic quantities of a batch of samples, computed once and shared by all effects.

    Attributes:
        robot: The robot.
        q: Controller joint values [rad], shape (m, n).
        T: TCP poses in the base frame [m], shape (m, 4, 4).
        J: TCP Jacobians (base frame, wrt controller joints), shape (m, 6, n).
        frames: Chain joint frames in the base frame [m], shape (m, n, 4, 4).
        cache: Wrench-independent quantities derived from the poses by effects, keyed by
            the effect's name (e.g. the complementary-stiffness basis), so that repeated
            evaluations on the same batch (identification iterations) compute them once.
            Not part of equality; the arrays above must not be modified in place.
    """

    robot: Robot
    q: FloatArray
    T: FloatArray
    J: FloatArray
    frames: FloatArray
    cache: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_q(cls, robot: Robot, q: FloatArray) -> PoseBatch:
        """Evaluate kinematics for joint values [rad], shape (m, n) or (n,)."""
        Q = np.atleast_2d(np.asarray(q, dtype=float))
        T, J, frames = robot.batch_fk_jacobian_frames(Q)
        return cls(robot, Q, T, J, frames)

    def __len__(self) -> int:
        return int(self.q.shape[0])


class Effect(abc.ABC):
    """One physical effect with its parameters.

    Subclasses set the class attributes and implement :meth:`param_names`, :meth:`prior` and
    the method(s) of their kind.

    Args:
        robot: The robot the effect belongs to (for joint count and priors).
        joint: 0-based joint index for per-joint effects, else None.
        params: Parameter values keyed by name [SI]; missing ones take the prior.
    """

    #: Registry name, e.g. ``"tilting_compliance"``.
    name: ClassVar[str]
    #: One-sentence physical description.
    description: ClassVar[str]
    #: Kind: ``"compliance"``, ``"wrench"`` or ``"geometric"``.
    kind: ClassVar[EffectKind]
    #: True if the effect is instantiated per joint (``name:jN``).
    per_joint: ClassVar[bool] = False
    #: True if the contribution is linear in theta (one least-squares step identifies it).
    linear_in_params: ClassVar[bool] = True
    #: Physically possible range (lo, hi) of each parameter [SI], keyed by the parameter name
    #: without its trailing digits (``c_t`` for ``c_t1``, ``c_t2``). A value outside it (a
    #: negative compliance, a 1e308 mass) is rejected when a robot file is read; parameters
    #: not listed only have to be finite and within +-PARAM_LIMIT. Checked by
    #: :meth:`check_params` on effects read from a robot file.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {}
    #: True if the effect distorts what the force sensor logs, not the physics (sensor
    #: misalignment, sensor bias): it applies to logged wrenches only, never to a wrench that
    #: comes from the process model (planning, deviation, the truth of a virtual weld).
    sensor_only: ClassVar[bool] = False
    #: True if the effect belongs to the measurement set-up (device registration, marker
    #: offset), not to the robot: never a diagnosis candidate, never dropped for collinearity
    #: in favour of a robot parameter, and not written into a robot's ``[[effects]]``.
    setup: ClassVar[bool] = False

    def __init__(
        self, robot: Robot, joint: int | None = None, params: Mapping[str, float] | None = None
    ) -> None:
        if self.per_joint:
            if joint is None or not 0 <= joint < robot.nq:
                raise InputError(
                    "effect", self.name, f"joint {None if joint is None else joint + 1}",
                    f"a joint index 1..{robot.nq}",
                )
        elif joint is not None:
            raise InputError("effect", self.name, "takes no joint index")
        self.robot = robot
        self.joint = joint
        names = self.param_names()
        values = np.array(self.prior(), dtype=float)
        for k, v in (params or {}).items():
            if k not in names:
                close = get_close_matches(k, names, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise InputError("effect", f"{self.label}.{k}", f"unknown parameter{hint}",
                                 "" if hint else ", ".join(names))
            values[names.index(k)] = float(v)
        self.params = values

    def check_params(self) -> None:
        """Raise unless every parameter is finite and inside its physical range.

        Called on effects read from a file (a negative compliance there is a typo); not on
        every instance, because identification may pass through such values and reports them.

        Raises:
            InputError: The first parameter outside :meth:`param_range`.
        """
        for k, x in zip(self.param_names(), self.params, strict=True):
            lo, hi = self.param_range(k)
            if not (math.isfinite(x) and lo <= x <= hi):
                raise InputError("effect", f"{self.label}.{k}", f"got {x:g}",
                                 f"a number in [{lo:g}, {hi:g}]")

    def param_range(self, name: str) -> tuple[float, float]:
        """Physically possible range (lo, hi) of parameter ``name`` [SI]."""
        return tuple(self.param_ranges.get(name.rstrip("0123456789"),  # type: ignore[return-value]
                                           (-PARAM_LIMIT, PARAM_LIMIT)))

    @property
    def label(self) -> str:
        """Effect name with its 1-based joint, e.g. ``tilting_compliance:j2``."""
        return self.name if self.joint is None else f"{self.name}:j{self.joint + 1}"

    @abc.abstractmethod
    def param_names(self) -> tuple[str, ...]:
        """Names of the parameters, in theta order."""

    @abc.abstractmethod
    def prior(self) -> FloatArray:
        """Prior (default) parameter values [SI], shape (p,)."""

    def param_dict(self, theta: FloatArray | None = None) -> dict[str, float]:
        """Parameters as a name -> value mapping (current values unless theta given)."""
        th = self.params if theta is None else theta
        return {k: float(v) for k, v in zip(self.param_names(), th, strict=True)}

    # -- kind "compliance" -------------------------------------------------------------------
    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        """TCP deflection [m, rad] under the true wrench, base frame, shape (m, 6)."""
        raise NotImplementedError(f"{self.label} has no deflection")

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        """d(deflection)/d(theta), shape (m, 6, p)."""
        raise NotImplementedError(f"{self.label} has no deflection regressor")

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray | None:
        """Cartesian compliance (m, 6, 6) if the deflection is linear in the wrench, else None."""
        return None

    def joint_springs(self) -> FloatArray | None:
        """Spring axes (k, 3) in the frame of chain joint :attr:`joint`, or None.

        An effect that returns axes declares that it is k linear rotational springs through
        that joint's origin, about those axes, with compliances theta (k,) [rad/(N m)]:
        dX = sum_s theta_s j_s (j_s^T F), j_s the TCP twist of a unit turn (seed 002 eq. 2).
        The model then evaluates all such effects together
        (:mod:`rfsw_plan.elastostatics.springs`); its :meth:`deflection` must agree.
        """
        return None

    # -- kind "wrench" -----------------------------------------------------------------------
    def delta_wrench(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        """Correction added to the logged wrench [N, N m], base frame, shape (m, 6)."""
        raise NotImplementedError(f"{self.label} has no wrench correction")

    def wrench_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        """d(delta_wrench)/d(theta), shape (m, 6, p)."""
        raise NotImplementedError(f"{self.label} has no wrench regressor")

    # -- kind "geometric" --------------------------------------------------------------------
    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """Load-independent TCP pose error [m, rad], base frame, shape (m, 6)."""
        raise NotImplementedError(f"{self.label} has no offset")

    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """d(offset)/d(theta), shape (m, 6, p)."""
        raise NotImplementedError(f"{self.label} has no offset regressor")

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        """Why this data cannot identify the effect, or None if it can (checked before fitting).

        The default says nothing; effects with an obvious data requirement (backlash needs
        both torque signs) override it.
        """
        return None
