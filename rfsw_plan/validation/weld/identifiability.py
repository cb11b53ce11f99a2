"""What one weld can identify: visibility and identifiability of the candidates.

One weld at one pose sees few directions of the compliance. For every candidate parameter the
track's change for a PARAM_CHANGE (20 %) change of the parameter is a column of a regressor
(of the prior; of the fit where the prior is 0). A candidate is *visible* when its columns move
the track by more than IDENT_RATIO sigma, or when its fit explains the residual significantly
(then the data sees it, whatever its size); *identifiable alone* when visible and every
parameter's standard error sigma sqrt((J^T J)^-1) is below PARAM_CHANGE / IDENT_RATIO of its
size. The singular values of the stacked columns say how many directions the track resolves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rfsw_plan.process.frames import FloatArray
from rfsw_plan.validation.engine.scoring import Candidate
from rfsw_plan.validation.weld.fit import WeldFit

#: Relative parameter change whose effect on the track defines visibility (20 %).
PARAM_CHANGE = 0.2
#: A direction (or a candidate) is identifiable when its coefficient's standard error is
#: below 1/IDENT_RATIO of a PARAM_CHANGE change: singular value >= IDENT_RATIO sigma.
IDENT_RATIO = 3.0


@dataclass(frozen=True)
class Visibility:
    """How well one weld sees one fitted candidate.

    Attributes:
        change: The track's change for a PARAM_CHANGE change of each parameter [m],
            shape (n_obs, p).
        visible: The change moves the track by at least IDENT_RATIO sigma (column norm).
        identifiable: Visible, and every relative standard error below
            PARAM_CHANGE / IDENT_RATIO.
        relative_std: Standard error / size per parameter [-], shape (p,).
    """

    change: FloatArray
    visible: bool
    identifiable: bool
    relative_std: FloatArray


def visibility(fit: WeldFit, sigma: float) -> Visibility:
    """:class:`Visibility` of a fitted candidate under the noise floor sigma [m]."""
    J, theta, theta0 = fit.jacobian, fit.theta, fit.form.theta0
    size = np.maximum(np.where(theta0 != 0, np.abs(theta0), np.abs(theta)), 1e-300)
    change = J * (PARAM_CHANGE * size)
    vis = bool(np.linalg.norm(change) >= IDENT_RATIO * sigma)
    rse = sigma * np.sqrt(np.clip(np.diag(np.linalg.pinv(J.T @ J)), 0.0, None)) / size
    return Visibility(change, vis, bool(vis and np.all(rse < PARAM_CHANGE / IDENT_RATIO)), rse)


@dataclass(frozen=True)
class Identifiability:
    """What one weld can identify.

    Attributes:
        joint_singular_values: Of the joint-stiffness regressor (column j: the track's change
            for a PARAM_CHANGE change of joint j's stiffness) [m], descending, shape (n,).
        joints_identifiable: Joints whose stiffness the weld fixes together with all others:
            the part of the joint's column orthogonal to the other joints' columns moves the
            track by at least IDENT_RATIO sigma (standard error below 1/IDENT_RATIO of a
            PARAM_CHANGE change).
        joints_not: The other joints.
        singular_values: Of the regressor of every candidate parameter [m], descending.
        n_directions: Of those, how many are >= IDENT_RATIO sigma.
        n_params: Candidate parameters stacked.
        identifiable: Candidates whose every parameter the weld fixes when fitted alone.
        combination_only: Candidates the weld sees only as a combination of parameters.
        invisible: Candidates the track does not see (a 20 % change moves it less than
            IDENT_RATIO sigma, and the fit does not explain the residual significantly).
    """

    joint_singular_values: FloatArray
    joints_identifiable: tuple[int, ...]
    joints_not: tuple[int, ...]
    singular_values: FloatArray
    n_directions: int
    n_params: int
    identifiable: tuple[str, ...]
    combination_only: tuple[str, ...]
    invisible: tuple[str, ...]

    def text(self) -> str:
        """Two lines for the summary."""
        sv = ", ".join(f"{x * 1e3:.3g}" for x in self.joint_singular_values)

        def js(j: tuple[int, ...]) -> str:
            return ", ".join(f"j{k + 1}" for k in j) or "none"

        return (f"joint stiffnesses this weld identifies together: {js(self.joints_identifiable)}"
                f"; not identifiable from it: {js(self.joints_not)} (singular values of the "
                f"joint-stiffness regressor {sv} mm for a {100 * PARAM_CHANGE:g} % change)\n"
                f"effects it sees only as a combination of their parameters: "
                f"{', '.join(self.combination_only) or 'none'}; effects it does not see: "
                f"{', '.join(self.invisible) or 'none'}")

    def to_json(self) -> dict[str, object]:
        """JSON-ready dictionary."""
        return {"joint_singular_values_mm": [float(x) * 1e3 for x in self.joint_singular_values],
                "joints_identifiable": [f"j{k + 1}" for k in self.joints_identifiable],
                "joints_not_identifiable": [f"j{k + 1}" for k in self.joints_not],
                "singular_values_mm": [float(x) * 1e3 for x in self.singular_values],
                "n_directions": self.n_directions, "n_params": self.n_params,
                "identifiable_alone": list(self.identifiable),
                "combination_only": list(self.combination_only),
                "invisible": list(self.invisible),
                "criterion": f"a parameter or direction counts when a {100 * PARAM_CHANGE:g} %"
                f" change is at least {IDENT_RATIO:g} x its standard error (noise floor)"}


def joint_identifiability(columns: FloatArray, sigma: float) -> tuple[FloatArray, list[bool]]:
    """Singular values of the joint columns (m, n) and, per joint, whether its column's part
    orthogonal to the others is >= IDENT_RATIO sigma."""
    sv: FloatArray = np.asarray(np.linalg.svd(columns, compute_uv=False), dtype=float)
    ok = []
    for j in range(columns.shape[1]):
        others = np.delete(columns, j, axis=1)
        a = columns[:, j]
        if others.shape[1]:
            coef = np.linalg.lstsq(others, a, rcond=None)[0]
            a = a - others @ coef
        ok.append(bool(np.linalg.norm(a) >= IDENT_RATIO * sigma))
    return sv, ok


def assess(candidates: Sequence[Candidate], changes: dict[str, FloatArray],
           joint_labels: Sequence[str], sigma: float) -> Identifiability:
    """What the weld identifies, from the scored candidates and their change columns.

    Args:
        candidates: Scored candidates (their ``visible`` and ``identifiable`` set).
        changes: Change columns of each fitted candidate [m], shape (n_obs, p) each.
        joint_labels: The labels of the joint-stiffness candidates, joint order.
        sigma: Noise floor [m].
    """
    cols = [c for ch in changes.values() for c in ch.T]
    sv = (np.asarray(np.linalg.svd(np.stack(cols, axis=1), compute_uv=False), dtype=float)
          if cols else np.zeros(0))
    n = len(joint_labels)
    if n and all(lab in changes for lab in joint_labels):
        jsv, jok = joint_identifiability(
            np.stack([changes[lab][:, 0] for lab in joint_labels], axis=1), sigma)
    else:
        jsv, jok = np.zeros(0), [False] * n
    return Identifiability(
        jsv, tuple(j for j, o in enumerate(jok) if o), tuple(j for j, o in enumerate(jok) if not o),
        sv, int(np.sum(sv >= IDENT_RATIO * sigma)), len(cols),
        tuple(c.label for c in candidates if c.identifiable),
        tuple(c.label for c in candidates if c.visible and not c.identifiable),
        tuple(c.label for c in candidates if not c.visible))


__all__ = ["IDENT_RATIO", "PARAM_CHANGE", "Identifiability", "Visibility", "assess",
           "joint_identifiability", "visibility"]
