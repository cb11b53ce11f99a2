"""Lost motion (backlash) of one joint: the side of the play from the torque, or from the
direction the joint last moved in when the torque is too small to know its sign."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.effects.play import MIN_SAMPLES_PER_SIDE, JointPlay

#: The torque's sign is known where |tau| exceeds this many standard deviations of its noise.
K_SIGMA = 4.0
#: Torques below this [N m] are rounding (a vertical axis under gravity), never a sign.
TAU_ROUND_NM = 1e-6
#: Most friction levels :meth:`LostMotion.profile` tries.
PROFILE_LEVELS = 256


class LostMotion(JointPlay):
    """Joint N sits on one flank of its gear play, +b/2 or -b/2 from where its encoder says.

        dq_N = (b / 2) s,   dX = J_N dq_N   (base frame [m, rad]),

        s = sign(tau_N)       where |tau_N| > tau_th = max(K_SIGMA sigma_F l_N, tau_f),
        s = sign(tau_h,N)     elsewhere, tau_h the torque of the most recent earlier load
                              at the same pose above tau_th (:attr:`PoseBatch.load_history`),
        s = -a_N              elsewhere,

    with tau_N = (J^T F + tau_g)_N the load torque on the joint [N m] (tau_g the links' own
    weight when the robot description gives link masses), l_N = |J_v,N| the lever arm from
    joint N to the TCP [m] (a force error dF moves tau_N by at most l_N |dF|), sigma_F the
    logged force's noise per axis [N] (:attr:`PoseBatch.force_noise`: given, or from the
    zero-load readings), tau_f the friction torque the output needs to leave its flank [N m]
    and a_N the joint's approach direction (+1 when it last moved up;
    :mod:`rfsw_plan.elastostatics.approach`). A load above the threshold presses the output
    against the flank it pushes towards; without one, the motor's last motion left the output
    lagging behind by half the play (a motor-side encoder reads q + b/2 when moving up), unless
    a load above the threshold at this pose pushed it to a flank since: friction holds it there
    once the load is taken off (the joint keeps the side it was last pushed to). K_SIGMA is 4,
    not 3: a jack campaign has hundreds of near-zero torques (radial and vertical loads), and
    at 3 sigma noise alone flipped the side in 2 of the 20 campaigns of
    tests/test_lost_motion_lab.py, a side that friction then held. tau_f has no regressor:
    :meth:`profile` sets it before each fit. Without force readings (sigma_F = inf: a
    motion-capture session) the side is the approach direction's everywhere; a planned path
    (no history, sigma_F = 0) takes the torque's sign.

    Linear in b. :meth:`identifiable` counts the samples on each side of each mechanism; with
    none in the approach regime it is joint_backlash's torque model and says so.
    Supersedes :class:`~rfsw_plan.elastostatics.effects.joint_backlash.JointBacklash` on
    data with history (approach directions); that one remains for torque-only loaded data.
    """

    name = "lost_motion"
    uses_approach = True
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"b": (0.0, 0.1),
                                                                  "tau_f": (0.0, 1e7)}
    param_units: ClassVar[Mapping[str, str]] = {"b": "rad", "tau_f": "N m"}
    profiled_params: ClassVar[tuple[str, ...]] = ("tau_f",)
    description = (
        "Play in the joint's gears: the output sits on the flank the load presses it to, or, "
        "under too little load, the flank its last motion left it on, so the TCP is off by "
        "half the play one way or the other."
    )
    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Lost motion of 1-4 arcmin (a worn or loosely preloaded heavy-duty gear)."""
        return {"b": float(np.radians(rng.uniform(1.0, 4.0) / 60.0)), "tau_f": 0.0}

    def param_names(self) -> tuple[str, ...]:
        return ("b", "tau_f")

    def prior(self) -> FloatArray:
        return np.zeros(2)

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        """d(dX)/d(b, tau_f), shape (m, 6, 2): tau_f moves no sample continuously (it is
        set by :meth:`profile`), its column is zero."""
        col = super().deflection_regressor(batch, wrench, theta)
        return np.concatenate([col, np.zeros_like(col)], axis=2)

    def detection_threshold(self, batch: PoseBatch) -> FloatArray:
        """K_SIGMA sigma_F l_N [N m], shape (m,): the torque whose sign the logged force
        tells (inf without force readings)."""
        assert self.joint is not None
        lever = np.linalg.norm(batch.J[:, :3, self.joint], axis=1)
        if np.isinf(batch.force_noise):
            return np.full(len(batch), np.inf)
        return np.maximum(K_SIGMA * batch.force_noise * lever, TAU_ROUND_NM)

    def threshold(self, batch: PoseBatch) -> FloatArray:
        """tau_th = max(K_SIGMA sigma_F l_N, tau_f) [N m], shape (m,) (inf without force
        readings)."""
        return np.maximum(self.detection_threshold(batch), float(self.params[1]))

    def _torques(self, batch: PoseBatch, wrench: FloatArray
                 ) -> tuple[FloatArray, FloatArray | None]:
        """(tau_N of every sample, shape (m,); tau_N of the earlier loads at the same pose,
        most recent first, shape (m, depth), or None without history) [N m]."""
        assert self.joint is not None
        tau = self.joint_torque(batch, wrench)
        if batch.load_history is None or batch.load_history.shape[1] == 0:
            return tau, None
        tau_g = self.joint_torque(batch, np.zeros(6))
        col = batch.J[:, :, self.joint]
        hist = np.einsum("ma,mha->mh", col, batch.load_history) + tau_g[:, None]
        # A slot of the history without a load (zero-padded) never decides.
        return tau, np.where(np.any(batch.load_history != 0, axis=2), hist, 0.0)

    def _sides_many(self, batch: PoseBatch, tau: FloatArray, hist: FloatArray | None,
                    th: FloatArray) -> FloatArray:
        """The side of every sample for each row of thresholds ``th`` (L, m) [N m], shape
        (L, m): sign(tau_N) where |tau_N| > th, else the sign of the most recent earlier load
        at the pose with |tau_N| > th (friction holds the flank it pushed the output to),
        else -a_N (the approach)."""
        assert self.joint is not None
        a = (np.zeros(len(batch)) if batch.approach is None
             else batch.approach[:, self.joint])
        side = np.broadcast_to(-a, th.shape)
        if hist is not None:
            clear = np.abs(hist)[None] > th[:, :, None]
            first = np.argmax(clear, axis=2)
            held = np.take_along_axis(clear, first[:, :, None], axis=2)[:, :, 0]
            side = np.where(held, np.sign(np.take_along_axis(
                np.broadcast_to(hist, clear.shape), first[:, :, None], axis=2)[:, :, 0]), side)
        out: FloatArray = np.where(np.abs(tau)[None] > th, np.sign(tau)[None], side)
        return out

    def sides(
        self, batch: PoseBatch, wrench: FloatArray
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """(side s in {-1, 0, +1}, True where the torque decides), each shape (m,)."""
        tau, hist = self._torques(batch, wrench)
        th = self.threshold(batch)
        loaded: NDArray[np.bool_] = np.abs(tau) > th
        return self._sides_many(batch, tau, hist, th[None])[0], loaded

    def profile(self, batch: PoseBatch, wrench: FloatArray, residual: FloatArray) -> None:
        """Set tau_f [N m] to the friction torque that best explains ``residual``.

        ``residual`` is the measured minus predicted TCP position without this effect [m],
        shape (m, 3), 0 where not measured. tau_f only matters where it lies between the
        sample torques, so the candidates are 0 and the distinct |tau_N| of the samples above
        the detection threshold (at most PROFILE_LEVELS of them, by quantile; an earlier
        load at a pose is an earlier sample); each is scored by the least-squares fit of
        b >= 0 alone on the residual (sum of squares ||r - b a||^2, a the regressor of b),
        the smallest tau_f of the best score kept. One discrete value chosen on all samples;
        the held-out folds then fit b.
        """
        assert self.joint is not None
        tau, hist = self._torques(batch, wrench)
        det = self.detection_threshold(batch)
        if not np.all(np.isfinite(det)):
            return
        # An earlier load at the pose is an earlier sample: its torque is among tau's.
        levels = np.unique(np.abs(tau)[np.abs(tau) > float(np.min(det))])
        if levels.size > PROFILE_LEVELS:
            levels = np.unique(np.quantile(levels, np.linspace(0, 1, PROFILE_LEVELS),
                                           method="lower"))
        r = np.asarray(residual, dtype=float)
        Jp = np.where(r != 0, batch.J[:, :3, self.joint], 0.0)
        c = 0.5 * np.einsum("ma,ma->m", Jp, r)  # a . r = s @ c
        g = 0.25 * np.einsum("ma,ma->m", Jp, Jp)  # a . a = s^2 @ g
        cand = np.concatenate([[0.0], levels])
        score = np.empty(cand.size)
        # Thresholds at a time: at most ~4e6 history entries in memory.
        step = max(1, int(4e6 // (len(batch) * (1 if hist is None else hist.shape[1] + 1))))
        for i in range(0, cand.size, step):
            s = self._sides_many(batch, tau, hist,
                                 np.maximum(det[None, :], cand[i:i + step, None]))
            ar, aa = s @ c, (s * s) @ g
            # The sum of squares less ||r||^2 at the best b >= 0 alone.
            score[i:i + step] = np.where((aa > 0) & (ar > 0),
                                         -(ar * ar) / np.where(aa > 0, aa, 1.0), 0.0)
        best_score = float(np.min(score))
        best = float(cand[np.flatnonzero(score <= best_score + 1e-12 * abs(best_score))[0]])
        self.params = np.array([self.params[0], best])

    def side(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """s = sign(tau_N) where the torque is clear, else -a_N (class docstring)."""
        return self.sides(batch, wrench)[0]

    def unknown_state(self, batch: PoseBatch, wrench: FloatArray) -> NDArray[np.bool_] | None:
        """Samples of a recording (approach directions known) whose side nothing sets: no
        clear torque, no clear earlier load at the pose and no motion of joint N before them
        in the file (s = 0), shape (m,); None for a planned path (no history). Their side is a
        state of the campaign (where the output sat when the recording began), not of the
        robot: the model predicts them anywhere within +-b/2 (:meth:`state_spread`)."""
        if batch.approach is None:
            return None
        out: NDArray[np.bool_] = self.sides(batch, wrench)[0] == 0
        return out

    def unknown_state_reason(self) -> str:
        j = self._joint_name().replace("joint ", "j")
        return (f"side of the play unknown before the first load on {j} (no motion of {j} "
                "before them in the file)")

    def unknown_state_advice(self) -> str:
        j = self._joint_name().replace("joint ", "j")
        return (f"move {j} onto the first pose from a known side (an approach move of a few "
                f"degrees), or preload {j} with a load that turns it before the first reading, "
                "so that no reading's side of the play is unknown")

    def side_counts(self, batch: PoseBatch, wrench: FloatArray) -> dict[str, int]:
        """Samples on each side of each mechanism: ``torque+``, ``torque-``, ``approach+``,
        ``approach-`` (the side, not the direction: approach+ = the joint last moved down)
        and ``unknown`` (no torque sign and no approach direction)."""
        s, loaded = self.sides(batch, wrench)
        return {"torque+": int(np.sum(loaded & (s > 0))), "torque-": int(np.sum(loaded & (s < 0))),
                "approach+": int(np.sum(~loaded & (s > 0))),
                "approach-": int(np.sum(~loaded & (s < 0))),
                "unknown": int(np.sum(s == 0))}

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        n = self.side_counts(batch, wrench)
        plus, minus = n["torque+"] + n["approach+"], n["torque-"] + n["approach-"]
        assert self.joint is not None
        if min(plus, minus) >= MIN_SAMPLES_PER_SIDE and n["approach+"] + n["approach-"] > 0:
            return None
        if min(plus, minus) >= MIN_SAMPLES_PER_SIDE:
            return (f"the torque sets joint {self.joint + 1}'s side of the play in every sample "
                    f"(none below the threshold, where the approach direction would): this is "
                    f"joint_backlash:j{self.joint + 1}'s torque-only model")
        th = self.threshold(batch)
        where = ("no force readings: the side is the approach direction's" if np.isinf(th).all()
                 else f"torque threshold {np.median(th):.3g} N m median")
        return (
            f"joint {self.joint + 1} sits on one side of its play in almost every sample "
            f"({n['torque+']} / {n['torque-']} by the torque's sign +/-, {n['approach+']} / "
            f"{n['approach-']} by the approach direction, {n['unknown']} unknown; {where}); "
            f"lost motion needs at least {MIN_SAMPLES_PER_SIDE} samples on each side"
        )

    def campaign_advice(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        """Both sides, and some of them set by the approach direction (else this is
        joint_backlash's model): what to add if not."""
        n = self.side_counts(batch, wrench)
        plus, minus = n["torque+"] + n["approach+"], n["torque-"] + n["approach-"]
        if ((min(plus, minus) >= MIN_SAMPLES_PER_SIDE and n["approach+"] + n["approach-"] > 0)
                or not self.visible(batch)):
            return None
        return self.what_to_add(batch, wrench, plus, minus)

    def what_to_add(self, batch: PoseBatch, wrench: FloatArray, plus: int, minus: int) -> str:
        n = self.side_counts(batch, wrench)
        j = self._joint_name()
        if n["approach+"] + n["approach-"] == 0:
            how = (f"unloaded samples (or loads below the torque threshold on {j}) reached "
                   f"with {j} moving up at some poses and down at others")
        else:
            side = "down (its last motion negative)" if plus < minus else "up"
            how = f"samples reached with {j} moving {side}, unloaded"
        return (f"add at least {MIN_SAMPLES_PER_SIDE} {how}, or loads that reverse {j}'s "
                f"torque (the data has {plus} samples on the + side, {minus} on the -)")
