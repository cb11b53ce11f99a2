"""Options shared by the commands that read a measurement file (validate, identify).

``--columns`` (a lab's column mapping), ``--frame`` (base or device), ``--device-to-base`` and
``--marker-mm`` (a known registration or marker offset), ``--wrench-frame`` and
``--sensor-pose`` (a wrench logged in the tool or sensor frame, converted at the reader).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.exceptions import InputError

if TYPE_CHECKING:  # the parser is built before any heavy import (a bad option answers at once)
    import numpy as np

    from rfsw_plan.elastostatics.measurement_set import MeasurementSet
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.robot.description import DeviceFrame

#: ``--frame`` and ``--wrench-frame`` choices: the readers' MEASUREMENT_FRAMES and WRENCH_FRAMES
#: (literal here so the parser needs no import; tests/test_cli_numbers.py checks they agree).
MEASUREMENT_FRAMES = ("base", "device")
WRENCH_FRAMES = ("base", "tool", "sensor")


def register(parser: argparse.ArgumentParser) -> None:
    """Add the measurement-file options to a command's parser."""
    g = parser.add_argument_group("measurement file")
    g.add_argument("--columns", metavar="FILE.toml",
                   help="map a lab's own column names and units onto the format "
                        "(docs/formats/measurements.md)")
    g.add_argument("--frame", choices=MEASUREMENT_FRAMES,
                   help="frame of the measured positions: base (default) or device (a laser "
                   "tracker's or motion-capture frame: registration and marker offset are "
                   "estimated with everything else)")
    g.add_argument("--device-to-base", metavar="FILE.toml",
                   help="a known registration ([device_frame] table as --save-robot writes "
                   "it): held, not fitted")
    g.add_argument("--marker-mm", metavar="X,Y,Z",
                   help="a known marker (SMR) offset in the tool frame [mm]: held, not fitted")
    g.add_argument("--wrench-frame", choices=WRENCH_FRAMES,
                   help="frame of the logged wrench (default base; tool = TCP frame; sensor "
                   "needs --sensor-pose)")
    g.add_argument("--sensor-pose", metavar="X,Y,Z,RX,RY,RZ",
                   help="force sensor pose in the tool frame [mm, deg; fixed-axis roll-pitch-"
                   "yaw] for --wrench-frame sensor")


def _numbers(text: str, n: int, option: str, what: str) -> np.ndarray:
    import numpy as np

    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(option, "", f"'{text}'", what) from None
    if len(vals) != n or not all(math.isfinite(v) and abs(v) < 1e7 for v in vals):
        raise InputError(option, "", f"'{text}'", what)
    return np.array(vals)


def sensor_pose(text: str | None) -> np.ndarray | None:
    """``--sensor-pose`` as a 4x4 transform [m], or None."""
    if text is None:
        return None
    import numpy as np

    from rfsw_plan.robot.description import _rpy_to_matrix

    v = _numbers(text, 6, "--sensor-pose", "six numbers X,Y,Z [mm],RX,RY,RZ [deg]")
    T = np.eye(4)
    T[:3, :3] = _rpy_to_matrix(np.radians(v[3:]))
    T[:3, 3] = v[:3] / 1000.0
    return T


def read_device_frame(path: str) -> DeviceFrame:
    """A ``--device-to-base`` file: a TOML with a ``[device_frame]`` table (or a robot file)."""
    from rfsw_plan.robot.description import read_device_frame as read_robot_device_frame

    return read_robot_device_frame(Path(path))


def load(args: argparse.Namespace, model: ElastostaticModel) -> MeasurementSet:
    """Read ``args.data`` for ``model``'s robot with the measurement-file options."""
    from rfsw_plan.io.measurements import read_measurements

    robot = model.robot
    if args.sensor_pose is not None and args.wrench_frame != "sensor":
        raise InputError("--sensor-pose", "", "given without --wrench-frame sensor",
                         "--wrench-frame sensor --sensor-pose X,Y,Z,RX,RY,RZ")

    def tool_rotation(q: np.ndarray) -> np.ndarray:
        return robot.batch_fk_jacobian(q)[0][:, :3, :3]

    data = read_measurements(
        args.data, robot.nq, prismatic=list(robot.prismatic), columns=args.columns,
        frame=args.frame, wrench_frame=args.wrench_frame,
        sensor_pose=sensor_pose(args.sensor_pose), tool_rotation=tool_rotation,
    )
    if data.frame == "base" and (args.device_to_base or args.marker_mm):
        raise InputError("--device-to-base/--marker-mm", "", "given for base-frame positions",
                         "--frame device")
    return data


def device_options(args: argparse.Namespace) -> tuple[DeviceFrame | None, np.ndarray | None]:
    """``--device-to-base`` and ``--marker-mm``: a held registration and marker offset [m]
    (None where not given; the robot file's ``[device_frame]`` is the library's default)."""
    held = read_device_frame(args.device_to_base) if args.device_to_base else None
    marker = None if args.marker_mm is None else _numbers(
        args.marker_mm, 3, "--marker-mm", "three numbers X,Y,Z [mm]") / 1000.0
    return held, marker
