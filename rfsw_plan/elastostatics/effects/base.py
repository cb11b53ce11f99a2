"""The contract every elastostatic effect fulfils.

An *effect* is one piece of physics that moves the TCP under load or changes the wrench the
robot really feels. The base model is :class:`~rfsw_plan.elastostatics.effects.joint_compliance.
JointCompliance` (dX = J K^-1 J^T F); the others are added on top of it in an
:class:`~rfsw_plan.elastostatics.model.ElastostaticModel`.

Every effect derives from one of three abstract bases, applied in this order by the model:

:class:`WrenchEffect`
    Corrects the logged wrench into the wrench that really acts at the TCP
    (sensor misalignment, sensor bias, payload gravity): ``F_true = F_logged + dF(theta)``.
:class:`ComplianceEffect`
    Deflects the TCP under the true wrench (joint compliance, tilting, backlash,
    torque-dependent stiffness). Linear-in-wrench ones also give a Cartesian compliance, and
    rotational springs at a joint declare their axes (:meth:`ComplianceEffect.joint_springs`),
    which the model and the planner's symbolic compliance evaluate generically.
:class:`GeometricEffect`
    Load-independent pose error (kinematic offsets).

Each effect owns a parameter vector theta (SI units) with a prior, returns its contribution and
the derivative of that contribution with respect to theta (a *regressor*, exact for effects
that are linear in theta). Each base implements, once, what the model and identification ask
of every effect (:meth:`Effect.join` sorts it into the model's :class:`EffectGroups`,
:meth:`Effect.pose_regressor` is its column block of the identification Jacobian), so a new
effect is one class in one file of this folder: it registers itself by its :attr:`Effect.name`
(:data:`EFFECTS`) and implements the abstract methods of its base. Nothing outside the effect
classes asks an effect what kind it is.
"""

from __future__ import annotations

import abc
import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from difflib import get_close_matches
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.kinematics import Robot

if TYPE_CHECKING:
    from rfsw_plan.elastostatics.effects.joint_compliance import JointCompliance

FloatArray = NDArray[np.float64]


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b over the last axis (size 3), broadcast; written out because np.cross has a large
    fixed cost on the many small stacks of the batched effects and springs."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out

#: d(deflection)/dF applied to wrench directions: (batch, F_true, dF (m, 6, p)) -> (m, 6, p).
#: The model supplies it (:meth:`ElastostaticModel.deflection_jvp`); wrench effects chain their
#: wrench regressor through it.
WrenchToPose = Callable[["PoseBatch", FloatArray, FloatArray], FloatArray]

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
        frames: Chain joint frames in the base frame [m], shape (m, n, 4, 4): joint i's
            frame after its rotation but, for a prismatic joint, before its slide (the origin
            its link placement ends at, where a link error acts). For a revolute joint this
            is Pinocchio's ``oMi``; for a prismatic one ``oMi`` is further along z by q_i.
            Gathered when first read if the batch was made without them (``_frames`` None:
            :meth:`from_q` with ``frames=False``, for a model none of whose effects reads
            them), by the same kinematics on the same joint values (a batch of
            :meth:`rows` takes its rows of its source's), so the same numbers either way.
        approach: Direction each joint last moved in before reaching the sample, shape
            (m, n): +1, -1, or 0 (unknown: the first sample, or no motion yet). None when
            the samples carry no history (a planned path): effects that need it take 0.
            See :mod:`rfsw_plan.elastostatics.approach`.
        load_change: The last change of the logged wrench at the same pose before each
            sample [N, N m], base frame, shape (m, 6), or None (no history).
        load_history: The loads logged before each sample at the same pose, most recent
            first [N, N m], base frame, shape (m, depth, 6), or None (no history).
        force_noise: 1-sigma noise of the logged force per axis [N] that the wrench of
            these samples carries: 0 for a modelled wrench (planning) or an unknown noise,
            ``inf`` for measured data without force readings (no force sensor: the load on
            a joint is not measured at all). Effects that switch on the sign of a torque use
            it for the threshold below which the sign is not known.
        cache: Wrench-independent quantities derived from the poses by effects, keyed by
            the effect's name (e.g. the complementary-stiffness basis), so that repeated
            evaluations on the same batch (identification iterations) compute them once.
            Not part of equality; the arrays above must not be modified in place.
    """

    robot: Robot
    q: FloatArray
    T: FloatArray
    J: FloatArray
    _frames: FloatArray | None
    approach: FloatArray | None = None
    force_noise: float = 0.0
    load_change: FloatArray | None = None
    load_history: FloatArray | None = None
    cache: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    #: Where the frames of a batch of :meth:`rows` without gathered frames come from: the
    #: source batch and the rows.
    _rows_of: tuple[PoseBatch, slice | NDArray[np.int_]] | None = field(
        default=None, compare=False, repr=False)

    @property
    def frames(self) -> FloatArray:
        """The chain joint frames (see the class attributes), gathered on first use."""
        if self._frames is None:
            if self._rows_of is not None:
                source, s = self._rows_of
                frames = source.frames[s]
            else:
                frames = self.robot.batch_fk_jacobian_frames(self.q)[2]
            object.__setattr__(self, "_frames", frames)
            object.__setattr__(self, "_rows_of", None)
        assert self._frames is not None
        return self._frames

    @classmethod
    def from_q(cls, robot: Robot, q: FloatArray, approach: FloatArray | None = None,
               force_noise: float = 0.0, load_change: FloatArray | None = None,
               load_history: FloatArray | None = None, frames: bool = True) -> PoseBatch:
        """Evaluate kinematics for joint values [rad], shape (m, n) or (n,), with the
        samples' history and force noise [N] (see the attributes). ``frames=False`` leaves
        the joint frames to their first use (the poses and Jacobians are the same numbers:
        the frames are a by-product of the same joint loop)."""
        Q = np.atleast_2d(np.asarray(q, dtype=float))
        if frames:
            T, J, F = robot.batch_fk_jacobian_frames(Q)
            return cls(robot, Q, T, J, F, approach, force_noise, load_change, load_history)
        T, J = robot.batch_fk_jacobian(Q)
        return cls(robot, Q, T, J, None, approach, force_noise, load_change, load_history)

    def rows(self, s: slice | NDArray[np.int_]) -> PoseBatch:
        """The samples ``s`` (a slice or indices) as a new batch (its own, empty cache)."""
        gathered = self._frames is not None
        return PoseBatch(self.robot, self.q[s], self.T[s], self.J[s],
                         self.frames[s] if gathered else None,
                         None if self.approach is None else self.approach[s],
                         self.force_noise,
                         None if self.load_change is None else self.load_change[s],
                         None if self.load_history is None else self.load_history[s],
                         _rows_of=None if gathered else (self, s))

    def __len__(self) -> int:
        return int(self.q.shape[0])


class Effect(abc.ABC):
    """One physical effect with its parameters.

    Do not subclass :class:`Effect` directly: derive from :class:`ComplianceEffect`,
    :class:`WrenchEffect` or :class:`GeometricEffect`, set the class attributes and implement
    :meth:`param_names`, :meth:`prior`, :meth:`plausible_params` and the abstract methods of that
    base. A concrete subclass with a :attr:`name` registers itself in :data:`EFFECTS`.

    Args:
        robot: The robot the effect belongs to (for joint count and priors).
        joint: 0-based joint index for per-joint effects, else None.
        params: Parameter values keyed by name [SI]; missing ones take the prior.
    """

    #: Registry name, e.g. ``"tilting_compliance"``.
    name: ClassVar[str]
    #: One-sentence physical description.
    description: ClassVar[str]
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
    #: Largest |value| of each parameter [SI] that a real robot plausibly shows, keyed like
    #: :attr:`param_ranges` (a link error of 5 mm is not a calibration, a joint 1000x softer
    #: than any gear is a stand-in for another effect). Identification keeps a parameter only
    #: where its standard error is below half this size and its estimate within it (see
    #: :func:`rfsw_plan.elastostatics.identification.implausible`); parameters not listed
    #: are not checked.
    plausible_limits: ClassVar[Mapping[str, float]] = {}
    #: True if the effect is a full parameter set of which the data identifies combinations
    #: only (a full geometric calibration): its parameters then get a Gaussian prior of
    #: mean :meth:`prior` and 1-sigma half their plausible size (a maximum a posteriori fit;
    #: FIGAROH regularises its ``full_params`` calibration the same way).
    regularised: ClassVar[bool] = False
    #: SI unit of each parameter, keyed like :attr:`param_ranges` (``"rad/(N m)"`` for a
    #: compliance); reports use it to show engineering units beside the SI value.
    param_units: ClassVar[Mapping[str, str]] = {}
    #: True if the effect distorts what the force sensor logs, not the physics (sensor
    #: misalignment, sensor bias): it applies to logged wrenches only, never to a wrench that
    #: comes from the process model (planning, deviation, the truth of a virtual weld).
    sensor_only: ClassVar[bool] = False
    #: True if the effect belongs to the measurement set-up (device registration, marker
    #: offset), not to the robot: never a diagnosis candidate, never dropped for collinearity
    #: in favour of a robot parameter, and not written into a robot's ``[[effects]]``.
    setup: ClassVar[bool] = False
    #: True if the effect moves the TCP at zero logged wrench (set by the three bases).
    load_independent: ClassVar[bool]
    #: True if the physics fixes the effect's size (complementary stiffness: gain 1 is the
    #: geometry of the loaded arm, not a parameter to be found): a simulated campaign keeps its
    #: :meth:`plausible_params` as they are instead of scaling them up until visible.
    fixed_size: ClassVar[bool] = False
    #: The effect depends on the direction its joint last moved in (a sample's approach,
    #: :attr:`PoseBatch.approach`): a campaign design then chooses each sample's approach.
    uses_approach: ClassVar[bool] = False
    #: The effect reads the chain joint frames (:attr:`PoseBatch.frames`): the model's batches
    #: then gather them with the poses (spring effects, :meth:`ComplianceEffect.joint_springs`,
    #: always do). An effect that reads them without saying so gets them all the same, on
    #: first use, at the cost of a second pass of the kinematics.
    uses_frames: ClassVar[bool] = False
    #: Seen from one side only, the effect is a constant offset of its joint: a campaign
    #: design must tell it from the joint's zero offset (a play, a hysteresis loop).
    offset_like: ClassVar[bool] = False
    #: Parameters no regressor moves continuously (a threshold): :meth:`profile` sets them
    #: from the residual before a fit, which keeps them fixed.
    profiled_params: ClassVar[tuple[str, ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if inspect.isabstract(cls) or "name" not in cls.__dict__:
            return
        known = EFFECTS.get(cls.name)
        if known is not None and known.__qualname__ != cls.__qualname__:
            raise TypeError(f"effect name '{cls.name}' is taken by {known.__qualname__}")
        EFFECTS[cls.name] = cls

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

    def plausible_limit(self, name: str) -> float | None:
        """Largest plausible |value| of parameter ``name`` [SI], or None (not checked)."""
        return self.plausible_limits.get(
            name, self.plausible_limits.get(name.rstrip("0123456789")))

    def param_unit(self, name: str) -> str:
        """SI unit of parameter ``name`` (empty if dimensionless or not declared)."""
        return self.param_units.get(name, self.param_units.get(name.rstrip("0123456789"), ""))

    def tool_load(self) -> tuple[float, FloatArray] | None:
        """The tool's mass [kg] and centre of mass in the TCP frame [m], shape (3,), where this
        effect identifies them (the spindle's weight); None for every other effect. A
        controller program's payload comes from here before the robot file's ``[payload]``."""
        return None

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

    def profile(self, batch: PoseBatch, wrench: FloatArray, residual: FloatArray) -> None:
        """Set the :attr:`profiled_params` from ``residual``, the measured minus predicted
        TCP position without this effect [m], shape (m, 3), 0 where not measured, under the
        true wrench ``wrench`` [N, N m] (none by default)."""
        return

    @abc.abstractmethod
    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Random, physically plausible parameters of this effect on a real cell [SI].

        What a simulated load campaign hides in its truth model when the user gives no values
        (:func:`rfsw_plan.validation.campaign.simulation.run_campaign`). Every name of
        :meth:`param_names` is present, every value is finite and inside :meth:`param_range`,
        and the effect is not a no-op: a hidden effect of size zero would be a campaign that
        silently hides nothing. Load-dependent effects may size themselves on the campaign.

        Args:
            batch: The campaign's poses.
            wrench: The logged wrenches [N, N m], base frame, shape (m, 6).
            rng: Random generator (the campaign's, so a seed reproduces the campaign).
        """

    def param_dict(self, theta: FloatArray | None = None) -> dict[str, float]:
        """Parameters as a name -> value mapping (current values unless theta given)."""
        th = self.params if theta is None else theta
        return {k: float(v) for k, v in zip(self.param_names(), th, strict=True)}

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        """Why this data cannot identify the effect, or None if it can (checked before fitting).

        The default says nothing, except for a sensor-only effect on data that logs no wrench
        at all (no force sensor: a motion-capture session without load); effects with an
        obvious data requirement (backlash needs both torque signs) override it.
        """
        if self.sensor_only and not np.any(np.asarray(wrench, dtype=float)):
            return "the data logs no wrench (no force sensor), so a sensor error has no effect"
        return None

    def campaign_advice(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        """What a campaign should add (poses, approach directions, load signs) so that this
        data would identify the effect, or None (nothing to say, or nothing missing). The
        diagnosis prints it for the effects it could not identify."""
        return None

    def unknown_state(self, batch: PoseBatch, wrench: FloatArray) -> NDArray[np.bool_] | None:
        """Samples whose state of this effect nothing before them in the data sets, shape
        (m,), or None when the effect has no such state (the default).

        A state of the campaign, not a parameter of the robot: the side of a joint's play
        before the first motion or load that sets it. The model's prediction there is a
        segment, the prediction at the middle state +- :meth:`state_spread`; the held-out
        score measures such a sample against that segment
        (:mod:`rfsw_plan.validation.engine.crossval`), never against a state read from the
        held-out samples themselves.

        Args:
            batch: Kinematics and history of the samples.
            wrench: True wrench at the TCP, base frame [N, N m], shape (m, 6).
        """
        return None

    def state_spread(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """Half the extent of the TCP's prediction over the unknown state [m], base frame,
        shape (m, 3) (zero by default): a sample of :meth:`unknown_state` is predicted
        anywhere on the segment centre +- this vector."""
        return np.zeros((len(batch), 3))

    def unknown_state_reason(self) -> str:
        """Why the samples of :meth:`unknown_state` have no known state, in words."""
        return "state unknown before anything in the data sets it"

    def unknown_state_advice(self) -> str:
        """How a campaign avoids samples of unknown state, in words ('' if it cannot)."""
        return ""

    # -- what the model and identification ask of every effect (implemented by the bases) ----
    @abc.abstractmethod
    def join(self, groups: EffectGroups) -> None:
        """Add this effect to the model's group that evaluates it."""

    @abc.abstractmethod
    def contribution(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        """The effect's own output for parameters theta, shape (m, 6): the deflection, the
        wrench correction or the offset (see the base)."""

    @abc.abstractmethod
    def contribution_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        """d(:meth:`contribution`)/d(theta), shape (m, 6, p)."""

    @abc.abstractmethod
    def pose_regressor(
        self, batch: PoseBatch, logged: FloatArray, true: FloatArray, through: WrenchToPose
    ) -> FloatArray:
        """d(TCP pose error)/d(theta) at the current parameters [m, rad per unit], base frame,
        shape (m, 6, p): this effect's block of the identification Jacobian.

        Args:
            batch: Poses.
            logged: Logged wrench [N, N m], base frame, (m, 6).
            true: Wrench after the model's wrench effects, (m, 6).
            through: The model's d(deflection)/dF (for wrench effects).
        """

    @abc.abstractmethod
    def pose_linear_in_params(self) -> bool:
        """True if the TCP pose is linear in this effect's theta with the other effects held
        (one least-squares step identifies it)."""


class ComplianceEffect(Effect):
    """Deflects the TCP under the true wrench (joint compliance, tilting, backlash...)."""

    load_independent = False

    @abc.abstractmethod
    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        """TCP deflection [m, rad] under the true wrench, base frame, shape (m, 6)."""

    @abc.abstractmethod
    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        """d(deflection)/d(theta), shape (m, 6, p)."""

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray | None:
        """Cartesian compliance (m, 6, 6) if the deflection is linear in the wrench, else None
        (the default: the model then evaluates :meth:`deflection` itself)."""
        return None

    def joint_springs(self) -> FloatArray | None:
        """Spring axes (k, 3) in the frame of chain joint :attr:`joint`, or None (the default).

        An effect that returns axes declares that it is k linear rotational springs through
        that joint's origin, about those axes, with compliances theta (k,) [rad/(N m)]:
        dX = sum_s theta_s j_s (j_s^T F), j_s the TCP twist of a unit turn (seed 002 eq. 2).
        The model evaluates all such effects together
        (:mod:`rfsw_plan.elastostatics.springs`) and the planner builds them symbolically;
        its :meth:`deflection` must agree.
        """
        return None

    def join(self, groups: EffectGroups) -> None:
        if self.joint is not None and self.joint_springs() is not None:
            groups.springs.append(self)
        else:
            groups.compliance.append(self)

    def contribution(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection(batch, wrench, theta)

    def contribution_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta)

    def pose_regressor(
        self, batch: PoseBatch, logged: FloatArray, true: FloatArray, through: WrenchToPose
    ) -> FloatArray:
        return self.deflection_regressor(batch, true, self.params)

    def pose_linear_in_params(self) -> bool:
        return self.linear_in_params


class WrenchEffect(Effect):
    """Corrects the logged wrench into the true one: F_true = F_logged + dF(theta)."""

    load_independent = True

    @abc.abstractmethod
    def delta_wrench(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        """Correction added to the logged wrench [N, N m], base frame, shape (m, 6)."""

    @abc.abstractmethod
    def wrench_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        """d(delta_wrench)/d(theta), shape (m, 6, p)."""

    def join(self, groups: EffectGroups) -> None:
        groups.wrench.append(self)

    def contribution(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.delta_wrench(batch, wrench, theta)

    def contribution_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        return self.wrench_regressor(batch, wrench, theta)

    def pose_regressor(
        self, batch: PoseBatch, logged: FloatArray, true: FloatArray, through: WrenchToPose
    ) -> FloatArray:
        # Chain rule through the compliance effects: dX/dF . dF/dtheta.
        return through(batch, true, self.wrench_regressor(batch, logged, self.params))

    def pose_linear_in_params(self) -> bool:
        return False  # the pose is bilinear: wrench parameters times compliances


class GeometricEffect(Effect):
    """Load-independent TCP pose error (kinematic offsets)."""

    load_independent = True

    @abc.abstractmethod
    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """Load-independent TCP pose error [m, rad], base frame, shape (m, 6)."""

    @abc.abstractmethod
    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """d(offset)/d(theta), shape (m, 6, p)."""

    def join(self, groups: EffectGroups) -> None:
        groups.geometric.append(self)

    def contribution(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.offset(batch, theta)

    def contribution_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        return self.offset_regressor(batch, theta)

    def pose_regressor(
        self, batch: PoseBatch, logged: FloatArray, true: FloatArray, through: WrenchToPose
    ) -> FloatArray:
        return self.offset_regressor(batch, self.params)

    def pose_linear_in_params(self) -> bool:
        return self.linear_in_params


@dataclass
class EffectGroups:
    """A model's effects sorted by how the model evaluates them (each effect joins its group,
    :meth:`Effect.join`), in model order within a group.

    Attributes:
        joint: The base joint compliance (the robot's joint stiffness), if given.
        springs: Compliance effects that are rotational springs at a joint
            (:meth:`ComplianceEffect.joint_springs`), evaluated together.
        compliance: The other compliance effects (the base joint compliance first).
        wrench: Wrench effects (corrections of the logged wrench).
        geometric: Load-independent pose errors.
    """

    joint: JointCompliance | None = None
    springs: list[ComplianceEffect] = field(default_factory=list)
    compliance: list[ComplianceEffect] = field(default_factory=list)
    wrench: list[WrenchEffect] = field(default_factory=list)
    geometric: list[GeometricEffect] = field(default_factory=list)

    @classmethod
    def of(cls, effects: Sequence[Effect]) -> EffectGroups:
        """The groups of ``effects``."""
        groups = cls()
        for e in effects:
            e.join(groups)
        return groups


#: Effect classes by registry name; every concrete effect class adds itself when defined.
EFFECTS: dict[str, type[Effect]] = {}
