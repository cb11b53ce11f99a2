"""The candidates of a diagnosis: what could be missing from a model, as parameters to fit.

A candidate is a label:

* ``name`` or ``name:jN``: a library effect the model lacks (never an effect of the
  measurement set-up, :attr:`~rfsw_plan.elastostatics.effects.base.Effect.setup`), added with
  its prior;
* ``<base>:jN`` (``joint_compliance:jN``): the stiffness of joint N of the model re-fitted.
  Only where the diagnosis holds the model's own parameters fixed (one weld,
  ``validate-weld``); a load campaign re-identifies every joint stiffness anyway.

:func:`candidate_labels` lists them; :func:`candidate_form` turns one into a
:class:`CandidateForm`: the parameters to fit, their prior, and their bounds. Bounds and
admissibility come from each effect's
:attr:`~rfsw_plan.elastostatics.effects.base.Effect.param_ranges` (a compliance is >= 0, a
mass too), never from the effect's name.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from rfsw_plan.elastostatics.effects import EFFECTS, JointCompliance, parse_effect_label
from rfsw_plan.elastostatics.effects.base import PARAM_LIMIT, Effect, FloatArray
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError

#: A re-fitted joint stiffness more than this factor away from the robot file's value is not
#: plausible as the same joint (catalogue and measured joint stiffnesses differ by tens of
#: percent, JointCompliance.plausible_params: x0.5-2): the residual is something else seen
#: through that joint.
PLAUSIBLE_FACTOR = 4.0


def addable_effects() -> list[str]:
    """Names of the library effects a diagnosis may add to a model: every registered effect
    except the base joint compliance (in every model) and the measurement set-up's."""
    return [n for n, cls in EFFECTS.items() if not cls.setup and cls is not JointCompliance]


def stiffness_labels(model: ElastostaticModel) -> list[str]:
    """``<base>:jN`` for every joint: the re-fitted stiffness of joint N of the model."""
    base = model.joint_compliance
    return [f"{base.name}:j{j + 1}" for j in range(model.robot.nq)]


def candidate_labels(model: ElastostaticModel, *, joint_stiffness: bool = False) -> list[str]:
    """Every candidate of a diagnosis of ``model``: each library effect (per joint where it
    applies) that the model does not contain, set-up effects excepted.

    Args:
        model: The current model.
        joint_stiffness: Also each joint's stiffness of the model, first (for a diagnosis that
            holds the model's parameters fixed).
    """
    out = stiffness_labels(model) if joint_stiffness else []
    for name in addable_effects():
        cls = EFFECTS[name]
        labels = [f"{name}:j{j + 1}" for j in range(model.robot.nq)] if cls.per_joint else [name]
        out += [x for x in labels if not model.has(x)]
    return out


@dataclass(frozen=True)
class CandidateForm:
    """One candidate as parameters to fit.

    Attributes:
        label: The candidate label.
        effect: Effect name.
        joint: 1-based joint, or None.
        names: Parameter names, in theta order.
        theta0: Prior [SI], shape (p,).
        lower: Physical lower bound of each parameter [SI] (-inf: none), shape (p,).
        upper: Physical upper bound [SI] (+inf: none), shape (p,).
        model: The model the candidate extends.
        apply: (a model, theta) -> that model with the candidate at theta (a new model).
        refit: True if the candidate re-fits a parameter the model already has (a joint
            stiffness), False if it adds an effect.
    """

    label: str
    effect: str
    joint: int | None
    names: tuple[str, ...]
    theta0: FloatArray
    lower: FloatArray
    upper: FloatArray
    model: ElastostaticModel = field(repr=False)
    apply: Callable[[ElastostaticModel, FloatArray], ElastostaticModel] = field(repr=False)
    refit: bool = False

    def build(self, theta: FloatArray) -> ElastostaticModel:
        """The model with the candidate's parameters at ``theta`` [SI], shape (p,)."""
        return self.apply(self.model, theta)

    def admissible(self, theta: FloatArray) -> bool:
        """True if every parameter is inside its physical range (the effect's
        ``param_ranges``)."""
        return bool(np.all(np.isfinite(theta)) and np.all(theta >= self.lower)
                    and np.all(theta <= self.upper))

    def implausible(self, theta: FloatArray) -> str:
        """Why the fitted values are not plausible on a real cell ('' if they are).

        A re-fitted parameter more than :data:`PLAUSIBLE_FACTOR` from the robot file's value
        is not the same part any more; an added effect is plausible when admissible.
        """
        if not self.admissible(theta):
            return "outside the physical range of " + ", ".join(
                f"{n} [{lo:g}, {hi:g}]" for n, lo, hi in zip(self.names, self.lower, self.upper,
                                                             strict=True))
        if not self.refit:
            return ""
        for n, v, v0 in zip(self.names, theta, self.theta0, strict=True):
            ratio = abs(float(v0) / float(v)) if v != 0 else float("inf")
            if v0 != 0 and not 1.0 / PLAUSIBLE_FACTOR <= ratio <= PLAUSIBLE_FACTOR:
                return (f"{n} x{1.0 / ratio:.3g} of the robot file's value (stiffness "
                        f"x{ratio:.3g}): not plausible for the same joint (more than "
                        f"{PLAUSIBLE_FACTOR:g} x off)")
        return ""

    def split(self, theta: FloatArray) -> dict[str, float]:
        """Parameters by name [SI]."""
        return dict(zip(self.names, map(float, theta), strict=True))


def _bounds(eff: Effect, names: tuple[str, ...]) -> tuple[FloatArray, FloatArray]:
    """(lower, upper) of the parameters ``names`` from the effect's ``param_ranges``; the
    generic +-PARAM_LIMIT of an undeclared parameter counts as no bound."""
    lo, hi = np.array([eff.param_range(n) for n in names], dtype=float).reshape(-1, 2).T
    return (np.where(lo <= -PARAM_LIMIT, -np.inf, lo), np.where(hi >= PARAM_LIMIT, np.inf, hi))


def _stiffness_form(model: ElastostaticModel, label: str, j: int) -> CandidateForm:
    base = model.joint_compliance
    c0 = np.array(base.params, dtype=float)
    name = base.param_names()[j]

    def apply(m: ElastostaticModel, theta: FloatArray) -> ElastostaticModel:
        out = m.copy()
        c = np.array(out.joint_compliance.params, dtype=float)
        c[j] = theta[0]
        out.joint_compliance.params = c
        return out

    lower, upper = _bounds(base, (name,))
    return CandidateForm(label, base.name, j + 1, (name,), c0[j:j + 1], lower, upper, model,
                         apply, refit=True)


def _effect_form(model: ElastostaticModel, label: str) -> CandidateForm:
    eff = model.with_effect(label).effects[-1]
    names = tuple(eff.param_names())

    def apply(m: ElastostaticModel, theta: FloatArray) -> ElastostaticModel:
        out = m.with_effect(label)
        out.effects[-1].params = np.array(theta, dtype=float)
        return out

    lower, upper = _bounds(eff, names)
    joint = None if eff.joint is None else eff.joint + 1
    return CandidateForm(label, eff.name, joint, names, np.array(eff.params, dtype=float),
                         lower, upper, model, apply)


def joint_form(forms: Sequence[CandidateForm]) -> CandidateForm:
    """Several candidates of one model fitted together: theta is their parameters in order,
    the names are ``label.name``.

    Raises:
        InputError: A label given twice.
    """
    labels = [f.label for f in forms]
    if len(set(labels)) != len(labels):
        raise InputError("add", ", ".join(labels), "duplicated", "each effect once")

    def apply(m: ElastostaticModel, theta: FloatArray) -> ElastostaticModel:
        for f, part in zip(forms, parts_of(forms, theta), strict=True):
            m = f.apply(m, part)
        return m

    def cat(parts: Sequence[FloatArray]) -> FloatArray:
        return np.concatenate(parts) if parts else np.zeros(0)

    return CandidateForm(
        "+".join(labels), "+".join(f.effect for f in forms), None,
        tuple(f"{f.label}.{n}" for f in forms for n in f.names), cat([f.theta0 for f in forms]),
        cat([f.lower for f in forms]), cat([f.upper for f in forms]), forms[0].model, apply,
        refit=all(f.refit for f in forms))


def parts_of(forms: Sequence[CandidateForm], theta: FloatArray) -> list[FloatArray]:
    """Each candidate's slice of a :func:`joint_form` parameter vector."""
    sizes = np.cumsum([0, *(f.theta0.size for f in forms)])
    return [theta[a:b] for a, b in pairwise(sizes)]


def candidate_form(model: ElastostaticModel, label: str, option: str = "add"
                   ) -> CandidateForm:
    """The candidate ``label`` of ``model`` (module docstring).

    Raises:
        UnknownNameError: Unknown effect.
        InputError: Bad joint, a set-up effect, or an effect already in the model.
    """
    label = label.strip()
    stiff = {lab: j for j, lab in enumerate(stiffness_labels(model))}
    if label in stiff:
        return _stiffness_form(model, label, stiff[label])
    base = model.joint_compliance.name
    if label.partition(":j")[0] == base and label != base:
        raise InputError(option, label, "no such joint",
                         f"{base}:jN with N in 1..{model.robot.nq}")
    cls, _ = parse_effect_label(label, model.robot.nq)
    if model.has(label):  # the base joint compliance is in every model
        raise InputError(option, label, "already in the model",
                         f"an effect the robot file does not have, or "
                         f"{model.joint_compliance.name}:jN to re-fit joint N's stiffness")
    if cls.setup:
        raise InputError(option, label, "belongs to the measurement set-up, not the robot",
                         "one of " + ", ".join(addable_effects()))
    return _effect_form(model, label)


__all__ = ["PLAUSIBLE_FACTOR", "CandidateForm", "addable_effects", "candidate_form",
           "candidate_labels", "joint_form", "parts_of", "stiffness_labels"]
