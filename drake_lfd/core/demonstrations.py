"""The demonstration data type: a UR5e joint-angle time series (Eq. 11), and its checks.

A kinesthetic demonstration is what the robot logs while a person guides it: the six
measured joint angles at the RTDE rate. :class:`Demonstration` holds one (read-only
arrays); :func:`check_demonstration` checks one built in code as strictly as the log
reader checks a file (at least 2 samples, finite values, strictly increasing
timestamps, angles within the UR joint range). docs/method.rst (Demonstrations and
features) says what a demonstration means to the method.

Not for: reading or writing log files (:mod:`drake_lfd.io.demonstration_logs`), forward
kinematics of a demonstration (:mod:`drake_lfd.robot.kinematics`), features
(:mod:`drake_lfd.core.features`), storing demonstrations (:mod:`drake_lfd.io.library`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.core.read_only_arrays import read_only_array

__all__ = [
    "NUM_JOINTS",
    "JOINT_COLUMNS",
    "MAX_ABS_JOINT_RAD",
    "RTDE_RATE_HZ",
    "Demonstration",
    "check_demonstration",
    "check_joint_value",
]

NUM_JOINTS = 6
# How each joint is named in messages: its column in a UR RTDE log (shoulder_pan ..
# wrist_3), so an error in a demonstration built in code reads like one in a file.
JOINT_COLUMNS = tuple(f"actual_q_{i}" for i in range(NUM_JOINTS))
# |q| above this is not a UR joint angle in radians (joint range is +-2 pi).
MAX_ABS_JOINT_RAD = 2.0 * math.pi + 0.05
# The UR e-Series RTDE interface streams at up to 500 Hz.
RTDE_RATE_HZ = 500.0


@dataclasses.dataclass(frozen=True, eq=False)
class Demonstration:
    """One kinesthetic demonstration (Eq. 11).

    Attributes
    ----------
    name : str
        Its name in a library (``[A-Za-z0-9_-]+``), or the log's file stem.
    timestamps : array, shape (m,)
        Sample times in seconds, strictly increasing (read-only).
    joint_positions : array, shape (m, 6)
        UR5e joint angles in radians, joint order shoulder_pan .. wrist_3 (read-only).
    description : str
        What was demonstrated, in words.
    """

    name: str
    timestamps: np.ndarray
    joint_positions: np.ndarray
    description: str = ""

    def __post_init__(self):
        timestamps = read_only_array(self.timestamps)
        joint_positions = read_only_array(self.joint_positions)
        if timestamps.ndim != 1:
            raise ValueError(f"timestamps must have shape (m,), got {timestamps.shape}")
        if joint_positions.shape != (timestamps.shape[0], NUM_JOINTS):
            raise ValueError(
                f"joint_positions must have shape ({timestamps.shape[0]}, {NUM_JOINTS}), "
                f"got {joint_positions.shape}"
            )
        object.__setattr__(self, "timestamps", timestamps)
        object.__setattr__(self, "joint_positions", joint_positions)

    @property
    def num_samples(self) -> int:
        """m, the number of samples."""
        return int(self.timestamps.shape[0])

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample, seconds."""
        return float(self.timestamps[-1] - self.timestamps[0]) if self.num_samples else 0.0


def check_demonstration(demonstration, *, file=None):
    """Checks a demonstration built in code, as the log reader checks a file.

    Parameters
    ----------
    demonstration : Demonstration
    file : str or Path, optional
        Named in error messages.

    Raises
    ------
    InputError
        Fewer than 2 samples, non-finite values, timestamps not strictly increasing,
        or joint angles beyond :data:`MAX_ABS_JOINT_RAD` (degrees?).
    """
    t = demonstration.timestamps
    q = demonstration.joint_positions
    if t.shape[0] < 2:
        raise InputError(
            f"has {t.shape[0]} sample(s); a demonstration needs at least 2", file=file, field="samples"
        )
    for index in range(t.shape[0]):
        if not math.isfinite(t[index]):
            raise InputError(f"{t[index]!r} is not finite", file=file, field=f"sample {index}, timestamp")
        for joint in range(NUM_JOINTS):
            check_joint_value(q[index, joint], file=file, field=f"sample {index}, {JOINT_COLUMNS[joint]}")
    steps = np.diff(t)
    if np.any(steps <= 0.0):
        index = int(np.argmax(steps <= 0.0)) + 1
        raise InputError(
            f"timestamp {t[index]!r} is not after the previous one ({t[index - 1]!r}); "
            "timestamps must strictly increase",
            file=file,
            field=f"sample {index}",
        )


def check_joint_value(value, *, file, field):
    """Raises InputError unless ``value`` is a finite joint angle within
    :data:`MAX_ABS_JOINT_RAD` (radians; a larger value suggests a log in degrees)."""
    if not math.isfinite(value):
        raise InputError(f"{value!r} is not a finite number", file=file, field=field)
    if abs(value) > MAX_ABS_JOINT_RAD:
        raise InputError(
            f"{value!r} rad is beyond the UR joint range (+-2 pi); is the log in degrees?",
            file=file,
            field=field,
        )
