"""Lab campaigns written from a lab's procedure, sharing no code with the workbench (issue 40).

Nothing of ``rfsw_plan`` is imported: the robot is read from its TOML file with ``tomllib``
(modified DH lengths and angles, the controller's joint signs and offsets, the tool, the joint
stiffness) and the truth is computed here in plain numpy. The procedure is a lab's:

* **Poses** (ISO 9283 §6.2): a cube in the most used part of the workspace; the measurement
  points are its centre and points on its diagonal plane and faces, reached with the tool
  pointing down (tilted by up to 15 deg), solved by this file's own inverse kinematics.
* **Loads**: a hydraulic jack with a load cell pushes the tool along +-x, +-y, +-z of the base
  at each load level (``jack``), or a cable over a pulley pulls it (``cable``: +-x, +-y, and
  -z by hanging weights). The order of the directions is the lab's (fixed, or shuffled per
  pose), a laser tracker reads the TCP twice at zero load on arrival (the repeats that give
  the noise floor), after each direction (unless the lab skips some zero readings) and under
  each load, and the load cell logs the force with its noise.
* **Hidden effects**, one or more: ``lost_motion`` (gear play: the output sits on the flank the
  last clear load pushed it to, friction holds it there at zero load; arriving at a pose the
  output lags the motor's last motion), ``jenkin`` (a spring in series with a spring parallel
  to a Coulomb slider, the load-history hysteresis of a gearbox), ``stiffening`` (the gear
  stiffness rises with the total torque, the arm's own weight included:
  k(tau) = k0 (1 + |tau| / tau_ref)), ``harmonic`` (a transmission error
  A sin(N q + phi) of the joint), ``thermal`` (the arm warms: every DH length grows by
  alpha dT(t), dT = dT_max (1 - exp(-t / t_c)), with a ``temperature_C`` column).

The joint deflection is dq = C tau with C = diag(1 / k) of the robot file and
tau = J(q)^T F (J the positional Jacobian of the TCP in the controller's joint values, by
central differences); the measured TCP is FK(q) + J (dq + effects) plus the tracker's Gaussian
noise (small deflections). The CSV is written with the ``csv`` module in the documented
measurement format (docs/formats/measurements.md: ``q*_deg``, ``fx_N..``, ``x_mm..``,
``t_s``, ``pose_id``). The tilting compliances of the robot file add
sum_i sum_u c_u (u . (r_i x f)) (u x r_i), u the x and y axes of joint i's frame.
"""

from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
G = 9.81
#: Steel's thermal expansion [1/K].
ALPHA_STEEL = 11.7e-6


def _rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _hom(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


@dataclass
class LabRobot:
    """A robot as the lab's own script reads it from the TOML file (SI)."""

    name: str
    a: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    theta0: np.ndarray
    sign: np.ndarray
    offset: np.ndarray
    tool: np.ndarray
    k: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    tilt: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @classmethod
    def read(cls, name: str) -> LabRobot:
        """The robot ``robots/<name>.toml``."""
        doc = tomllib.loads((ROBOTS / f"{name}.toml").read_text())
        kin, ctl, tool = doc["kinematics"], doc.get("controller", {}), doc.get("tool", {})
        assert kin["convention"] == "modified_dh"
        n = len(kin["a_mm"])

        def rpy(v: list[float]) -> np.ndarray:
            r, p, y = np.radians(v)
            return _rot("z", y) @ _rot("y", p) @ _rot("x", r)

        return cls(
            name=name,
            a=np.array(kin["a_mm"]) * 1e-3, d=np.array(kin["d_mm"]) * 1e-3,
            alpha=np.radians(kin["alpha_deg"]), theta0=np.radians(kin["theta0_deg"]),
            sign=np.array(ctl.get("sign", [1] * n), dtype=float),
            offset=np.radians(ctl.get("offset_deg", [0] * n)),
            tool=_hom(rpy(tool.get("rpy_deg", [0, 0, 0])),
                      np.array(tool.get("xyz_mm", [0, 0, 0])) * 1e-3),
            k=np.array(doc["stiffness"]["k_Nm_per_rad"], dtype=float),
            lower=np.radians(doc["joints"]["lower_deg"]),
            upper=np.radians(doc["joints"]["upper_deg"]),
            tilt=np.array([[e["params"]["c_t1"], e["params"]["c_t2"]] if any(
                e["name"] == f"tilting_compliance:j{j + 1}" for e in doc.get("effects", []))
                else [0.0, 0.0] for j in range(n) for e in [next(
                    (x for x in doc.get("effects", [])
                     if x["name"] == f"tilting_compliance:j{j + 1}"), {"name": ""})]]))

    @property
    def n(self) -> int:
        return len(self.a)

    def frames(self, q: np.ndarray, scale: float = 1.0) -> list[np.ndarray]:
        """Joint frames 1..n and the TCP (the last) for controller values q [rad]; every
        length times ``scale`` (thermal growth)."""
        theta = self.sign * q + self.offset + self.theta0
        T = np.eye(4)
        out = []
        for i in range(self.n):
            T = T @ _hom(_rot("x", self.alpha[i]), np.array([self.a[i] * scale, 0, 0]))
            T = T @ _hom(_rot("z", theta[i]), np.array([0, 0, self.d[i] * scale]))
            out.append(T)
        # The tool sits on the chain's last frame (the controller's flange frame is a display
        # convention of the KRC, not part of the chain).
        tcp = T @ _hom(self.tool[:3, :3], self.tool[:3, 3] * scale)
        out.append(tcp)
        return out

    def tilting(self, q: np.ndarray, f: np.ndarray) -> np.ndarray:
        """TCP displacement [m] of the joints' bearings tilting about the x and y axes of
        their frames (rotating with the joint, origin at the frame's origin) under the moment
        of the force f at the TCP (the file's tilting compliances)."""
        if not np.any(self.tilt):
            return np.zeros(3)
        theta = self.sign * q + self.offset + self.theta0
        T = np.eye(4)
        p = self.tcp(q)[:3, 3]
        dp = np.zeros(3)
        for i in range(self.n):
            T = T @ _hom(_rot("x", self.alpha[i]), np.array([self.a[i], 0, 0]))
            Tj = T @ _hom(_rot("z", theta[i]), np.array([0, 0, self.d[i]]))
            r = p - Tj[:3, 3]
            for ax in range(2):
                u = Tj[:3, ax]
                dp += self.tilt[i, ax] * (u @ np.cross(r, f)) * np.cross(u, r)
            T = Tj
        return dp

    def tcp(self, q: np.ndarray, scale: float = 1.0) -> np.ndarray:
        return self.frames(q, scale)[-1]

    def jac(self, q: np.ndarray, point: int = -1, h: float = 1e-6) -> np.ndarray:
        """d p / d q of frame ``point``'s origin, (3, n), central differences."""
        J = np.zeros((3, self.n))
        for j in range(self.n):
            e = np.zeros(self.n)
            e[j] = h
            J[:, j] = (self.frames(q + e)[point][:3, 3]
                       - self.frames(q - e)[point][:3, 3]) / (2 * h)
        return J

    def ik(self, target: np.ndarray, q0: np.ndarray) -> np.ndarray | None:
        """Controller values reaching the TCP pose ``target`` (4x4) from the seed ``q0``:
        damped Gauss-Newton on the 6-D error (numeric Jacobian), or None."""
        q = q0.copy()
        for it in range(80):
            T = self.tcp(q)
            e = np.concatenate([target[:3, 3] - T[:3, 3], _log(target[:3, :3] @ T[:3, :3].T)])
            if np.linalg.norm(e) < 1e-10 or (it >= 40 and np.linalg.norm(e) > 1e-3):
                break
            Jn = np.zeros((6, self.n))
            for j in range(self.n):
                dq = np.zeros(self.n)
                dq[j] = 1e-7
                T2 = self.tcp(q + dq)
                Jn[:3, j] = (T2[:3, 3] - T[:3, 3]) / 1e-7
                Jn[3:, j] = _log(T2[:3, :3] @ T[:3, :3].T) / 1e-7
            step = np.linalg.solve(Jn.T @ Jn + 1e-6 * np.eye(self.n), Jn.T @ e)
            q = q + step * min(1.0, 0.3 / float(np.abs(step).max()))
        mid = (self.lower + self.upper) / 2
        q = mid + np.mod(q - mid + np.pi, 2 * np.pi) - np.pi
        ok = (np.linalg.norm(self.tcp(q)[:3, 3] - target[:3, 3]) < 1e-7
              and np.all(q > self.lower + 0.05) and np.all(q < self.upper - 0.05))
        return q if ok else None


def _log(R: np.ndarray) -> np.ndarray:
    c = np.clip((np.trace(R) - 1) / 2, -1, 1)
    th = np.arccos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return 0.5 * w if th < 1e-9 else th / (2 * np.sin(th)) * w


def iso9283_poses(robot: LabRobot, count: int, rng: np.random.Generator,
                  side: float = 0.8) -> list[np.ndarray]:
    """``count`` poses on an ISO 9283 cube of ``side`` [m] in front of the robot: its centre,
    the corners of its diagonal plane, then face and edge points, the tool pointing down
    and tilted by up to 15 deg; each solved by :meth:`LabRobot.ik` from a mid-range seed."""
    reach = float(np.sum(np.abs(robot.a)) + np.sum(np.abs(robot.d[1:])))
    c = np.array([0.55 * reach, 0.0, robot.d[0]])
    h = side / 2
    grid = [np.zeros(3)] + [np.array(v) * h for v in
                            ([1, 1, 1], [-1, -1, -1], [1, -1, 1], [-1, 1, -1], [1, 1, -1],
                             [-1, -1, 1], [1, -1, -1], [-1, 1, 1])]
    grid += [np.array(v) * h for v in ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                                       [0, 0, -1], [1, 1, 0], [-1, -1, 0], [1, -1, 0],
                                       [-1, 1, 0], [0, 1, 1], [0, -1, -1])]
    mid = (robot.lower + robot.upper) / 2
    span = (robot.upper - robot.lower) / 4
    out: list[np.ndarray] = []
    tries = 0
    while len(out) < count and tries < 40 * count:
        p = c + grid[len(out) % len(grid)] * (1.0 if len(out) < len(grid) else
                                              rng.uniform(0.3, 1.0))
        tilt = _rot("x", rng.uniform(-0.26, 0.26)) @ _rot("y", rng.uniform(-0.26, 0.26))
        q = robot.ik(_hom(tilt @ _rot("y", np.pi), p), mid + rng.uniform(-1, 1, robot.n) * span)
        tries += 1
        if q is not None:
            out.append(q)
    assert len(out) == count, f"ISO 9283 cube out of reach of {robot.name}"
    return out


# -------------------------------------------------------------------------------------------
# Hidden effects


@dataclass
class Hidden:
    """The hidden physics of a campaign and its state (all joints 0-based, SI)."""

    kinds: tuple[str, ...]
    play_joint: int = 0
    play: float = np.radians(0.6 / 60)
    friction_nm: float = 300.0
    jenkin_joints: tuple[int, ...] = (0, 2)
    jenkin_share: float = 0.35
    stiff_joint: int = 2
    tau_ref: float = 2.0e4
    harmonic_joint: int = 1
    harmonic: tuple[float, float, float] = (4e-5, 37.0, 0.3)
    thermal_dT: float = 6.0
    thermal_tc: float = 3600.0
    masses: tuple[float, float, float] = (900.0, 400.0, 150.0)
    side: float = 1.0
    slip: dict[int, float] = field(default_factory=dict)

    def gravity_torque(self, robot: LabRobot, q: np.ndarray) -> np.ndarray:
        """The arm's own weight on the joints [N m]: point masses (ASSUMED, kg) at the upper
        arm's middle, the wrist centre and the TCP."""
        pts = [(1, 2, self.masses[0]), (4, 4, self.masses[1]), (robot.n, robot.n, self.masses[2])]
        tau = np.zeros(robot.n)
        for i0, i1, m in pts:
            Jm = 0.5 * (robot.jac(q, i0) + robot.jac(q, i1))
            tau += Jm.T @ np.array([0, 0, -m * G])
        return tau

    def dq(self, robot: LabRobot, q: np.ndarray, tau: np.ndarray, t: float,
           moved: np.ndarray | None) -> np.ndarray:
        """The joint error of the hidden effects at q under load torque tau at time t
        (``moved``: the last motion of each joint on arriving at a new pose, else None)."""
        out = np.zeros(robot.n)
        if "lost_motion" in self.kinds:
            j = self.play_joint
            if moved is not None and abs(moved[j]) > 1e-9:
                self.side = -float(np.sign(moved[j]))  # the output lags the motor
            if abs(tau[j]) > self.friction_nm:
                self.side = float(np.sign(tau[j]))  # pressed to the flank the load pushes to
            out[j] += 0.5 * self.play * self.side
        if "jenkin" in self.kinds:
            for j in self.jenkin_joints:
                # k_s in series with (k_p || Coulomb slider tau_f); 1/k_s + 1/k_p = 1/k.
                k = robot.k[j]
                ks, kp = k / (1 - self.jenkin_share), k / self.jenkin_share
                tf = 0.15 * self.tau_ref
                x = self.slip.get(j, 0.0)
                if tau[j] - kp * x > tf:
                    x = (tau[j] - tf) / kp
                elif tau[j] - kp * x < -tf:
                    x = (tau[j] + tf) / kp
                self.slip[j] = x
                out[j] += tau[j] / ks + x - tau[j] / k  # the linear part is dq = C tau
        if "stiffening" in self.kinds:
            j = self.stiff_joint
            tg = self.gravity_torque(robot, q)[j]
            k0 = robot.k[j]

            def delta(x: float) -> float:  # int_0^x dt / (k0 (1 + |t| / tau_ref))
                return float(np.sign(x) * self.tau_ref / k0 * np.log1p(abs(x) / self.tau_ref))

            # Stiffer than the file's k0 at the total torque: 3x k0 at rest, rising.
            out[j] += (delta(tg + tau[j]) - delta(tg)) / 3.0 - tau[j] / k0
        if "harmonic" in self.kinds:
            A, N, phi = self.harmonic
            out[self.harmonic_joint] += A * np.sin(N * q[self.harmonic_joint] + phi)
        return out

    def scale(self, t: float) -> float:
        """Length scale of the arm at time t (thermal growth)."""
        if "thermal" not in self.kinds:
            return 1.0
        return 1.0 + ALPHA_STEEL * self.temperature(t)

    def temperature(self, t: float) -> float:
        """Arm temperature rise over the start [K]."""
        return self.thermal_dT * (1 - np.exp(-t / self.thermal_tc))


# -------------------------------------------------------------------------------------------
# The campaign


@dataclass(frozen=True)
class LabCampaign:
    """What the lab wrote: the file, its rows and poses."""

    path: Path
    rows: int
    poses: int


def lab_campaign(
    robot_name: str, out: Path, hidden: tuple[str, ...], *, poses: int = 18,
    procedure: str = "jack", loads_n: tuple[float, ...] = (2000.0, 4000.0),
    zero_between: bool = True, skip_zero: float = 0.0, shuffle: bool = False,
    repeats: int = 2, noise_mm: float = 0.01, force_noise_n: float = 5.0,
    seconds_per_reading: float = 30.0, seed: int = 0, **effect: object,
) -> LabCampaign:
    """Write a lab campaign on ``robot_name`` with the ``hidden`` effects to ``out``.

    Args:
        robot_name: A robot file in ``robots/``.
        out: CSV file to write.
        hidden: Hidden effects (module docstring): ``lost_motion``, ``jenkin``,
            ``stiffening``, ``harmonic``, ``thermal``.
        poses: ISO 9283 poses.
        procedure: ``jack`` (+-x, +-y, +-z) or ``cable`` (+-x, +-y, -z).
        loads_n: Load levels [N].
        zero_between: A zero-load reading after each direction.
        skip_zero: Share of those zero readings the lab forgets.
        shuffle: Shuffle the order of the directions at each pose.
        repeats: Zero-load readings on arrival at a pose (>= 2 gives the noise floor).
        noise_mm: Tracker noise, 1 sigma per axis [mm].
        force_noise_n: Load cell noise per axis [N].
        seconds_per_reading: Time between readings [s].
        seed: Random seed.
        effect: Overrides of :class:`Hidden`'s sizes (``play``, ``friction_nm``...).
    """
    rng = np.random.default_rng(seed)
    robot = LabRobot.read(robot_name)
    h = Hidden(tuple(hidden), **effect)  # type: ignore[arg-type]
    targets = iso9283_poses(robot, poses, rng)
    order = rng.permutation(len(targets))
    dirs = ([np.array(v, float) for v in ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
                                          [0, 0, 1], [0, 0, -1])]
            if procedure == "jack" else
            [np.array(v, float) for v in ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
                                          [0, 0, -1])])
    rows: list[list[str]] = []
    t = 0.0
    here = targets[order[0]] - 0.1
    thermal = "thermal" in hidden
    for n_pose, i in enumerate(order):
        q = targets[i]
        moved: np.ndarray | None = q - here
        here = q
        J = robot.jac(q)
        seq: list[np.ndarray] = [np.zeros(3)] * repeats
        ds = [dirs[k] for k in (rng.permutation(len(dirs)) if shuffle else range(len(dirs)))]
        for level in loads_n:
            for d in ds:
                seq.append(level * d)
                if zero_between and rng.uniform() >= skip_zero:
                    seq.append(np.zeros(3))
        if not zero_between:
            seq.append(np.zeros(3))
        for F in seq:
            tau = J.T @ F
            dq = tau / robot.k + h.dq(robot, q, tau, t, moved)
            moved = None
            # Small deflections: dp = J dq (the exact FK(q + dq) differs by ~0.2 mm on the
            # KR600 at 4 kN, a second-order term no linear compliance model has).
            p = (robot.tcp(q, h.scale(t))[:3, 3] + J @ dq + robot.tilting(q, F)
                 + rng.normal(0, noise_mm * 1e-3, 3))
            f_log = F + rng.normal(0, force_noise_n, 3)
            row = [f"{t:.1f}", f"P{n_pose + 1:02d}", *(f"{v:.6f}" for v in np.degrees(q)),
                   *(f"{v:.2f}" for v in f_log), *(f"{v:.5f}" for v in p * 1e3)]
            if thermal:
                row.append(f"{20.0 + h.temperature(t):.2f}")
            rows.append(row)
            t += seconds_per_reading
    header = ["t_s", "pose_id", *(f"q{j + 1}_deg" for j in range(robot.n)), "fx_N", "fy_N",
              "fz_N", "x_mm", "y_mm", "z_mm"] + (["temperature_C"] if thermal else [])
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return LabCampaign(out, len(rows), poses)
