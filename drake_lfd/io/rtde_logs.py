"""Full UR RTDE recordings: the TCP-offset check of the joints against ``actual_TCP_pose``.

A full recording (UR's ``record.py`` with the whole output recipe, or ``ur_rtde``'s
``startFileRecording``) carries, next to ``actual_q_0`` .. ``actual_q_5``, the pose the
controller computed for the tool centre point: ``actual_TCP_pose_0`` .. ``_5`` (x, y, z
in metres in the robot's base frame, then a rotation vector in radians). Reading the
joints is :func:`~drake_lfd.io.demonstration_logs.read_rtde_log`'s job (any column
order, unused duplicated columns ignored, a sample rate for a log without timestamps);
this module adds the check a user asks for with ``library add --tcp-offset``: the
joints' forward kinematics (UR5e DH, :mod:`drake_lfd.robot.kinematics`) times the TCP
offset the robot was set to (tool0 to TCP: x, y, z in metres and an optional rotation
vector, as on the teach pendant) against the logged pose, sample by sample
(:func:`tcp_discrepancy`).

The report gives the largest and the median position (mm) and rotation (deg)
discrepancy. Only a gross one refuses the log (:func:`check_tcp_pose`): a median of
more than :data:`GROSS_POSITION_M` (50 mm) or :data:`GROSS_ROTATION_RAD` (10 deg).
Why that threshold: real UR5e logs agree with the nominal kinematics to 0.1-0.7 mm, and
a robot's factory calibration moves the tool by at most a few millimetres from the
nominal model; a TCP offset that is off by a centimetre shows up in the report and is
the user's to judge. Beyond 50 mm or 10 deg (median, so one glitched row does not
decide) the joint columns and the pose columns cannot describe the same motion: joint
columns mixed up, the offset in millimetres instead of metres, or the pose of another
recording.

Not for: reading the CSV (``demonstration_logs.py``), ROS bags (``rosbag_logs.py``),
choosing the reader (``log_import.py``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_lfd.core.errors import InputError
from drake_lfd.robot.kinematics import UR5eKinematics

__all__ = [
    "TCP_POSE_COLUMNS",
    "GROSS_POSITION_M",
    "GROSS_ROTATION_RAD",
    "TcpDiscrepancy",
    "tcp_offset_transform",
    "rotation_matrices_from_rotation_vectors",
    "tcp_discrepancy",
    "check_tcp_pose",
]

#: The controller's TCP pose columns: x, y, z (m), then a rotation vector (rad).
TCP_POSE_COLUMNS = tuple(f"actual_TCP_pose_{i}" for i in range(6))
#: A median position discrepancy above this refuses the log (module docstring).
GROSS_POSITION_M = 0.05
#: A median rotation discrepancy above this (10 deg) refuses the log.
GROSS_ROTATION_RAD = math.radians(10.0)


class TcpDiscrepancy(NamedTuple):
    """How far FK(q) * X_tool0_TCP is from the logged TCP pose, over ``samples`` rows."""

    samples: int
    position_max_m: float
    position_median_m: float
    rotation_max_rad: float
    rotation_median_rad: float

    def text(self):
        """One line: max and median, in mm and deg."""
        return (
            f"position max {1e3 * self.position_max_m:.3f} mm, median {1e3 * self.position_median_m:.3f} mm; "
            f"rotation max {math.degrees(self.rotation_max_rad):.3f} deg, "
            f"median {math.degrees(self.rotation_median_rad):.3f} deg (over {self.samples} samples)"
        )

    @property
    def is_gross(self):
        """Whether the median discrepancy exceeds :data:`GROSS_POSITION_M` or
        :data:`GROSS_ROTATION_RAD`."""
        return self.position_median_m > GROSS_POSITION_M or self.rotation_median_rad > GROSS_ROTATION_RAD


def rotation_matrices_from_rotation_vectors(vectors):
    """Rotation matrices of rotation vectors (axis times angle, UR's ``rx, ry, rz``).

    Parameters
    ----------
    vectors : array, shape (m, 3)

    Returns
    -------
    R : array, shape (m, 3, 3)
    """
    vectors = np.atleast_2d(np.asarray(vectors, dtype=float))
    angles = np.linalg.norm(vectors, axis=1)
    R = np.repeat(np.eye(3)[None], len(vectors), axis=0)
    for k, (vector, angle) in enumerate(zip(vectors, angles)):
        if angle > 1e-15:
            axis = vector / angle
            K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
            R[k] = np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K
    return R


def tcp_offset_transform(values, *, field="tcp offset"):
    """X_tool0_TCP from ``[x, y, z]`` (m) or ``[x, y, z, rx, ry, rz]`` (rotation vector,
    rad), as UR's TCP setting gives it.

    Raises
    ------
    InputError
        Not 3 or 6 finite numbers (naming ``field``).
    """
    values = [float(v) for v in values]
    if len(values) not in (3, 6) or not all(math.isfinite(v) for v in values):
        raise InputError(
            f"{values} is not a TCP offset: give X Y Z (m) or X Y Z RX RY RZ (m, and a rotation vector in rad)",
            field=field,
        )
    rotation = np.eye(3) if len(values) == 3 else rotation_matrices_from_rotation_vectors([values[3:]])[0]
    return RigidTransform(RotationMatrix(rotation), np.array(values[:3]))


def _rotation_angles(R_a, R_b):
    """Angle of R_a^T R_b per sample (atan2 form: accurate near zero)."""
    R = np.einsum("kji,kjl->kil", R_a, R_b)
    cos = (np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0
    skew = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    return np.arctan2(np.linalg.norm(skew, axis=1) / 2.0, cos)


def tcp_discrepancy(joint_positions, tcp_poses, X_tool0_TCP, *, kinematics=None):
    """The discrepancy between FK(q) * X_tool0_TCP and the logged TCP poses.

    Parameters
    ----------
    joint_positions : array, shape (m, 6)
    tcp_poses : array, shape (m, 6)
        ``actual_TCP_pose``: x, y, z (m) and a rotation vector (rad), in the base frame.
    X_tool0_TCP : RigidTransform
    kinematics : UR5eKinematics, optional
        With ``X_WB`` = identity (the default one is made).

    Returns
    -------
    TcpDiscrepancy
    """
    q = np.atleast_2d(np.asarray(joint_positions, dtype=float))
    poses = np.atleast_2d(np.asarray(tcp_poses, dtype=float))
    kinematics = UR5eKinematics() if kinematics is None else kinematics
    X = kinematics.X_Wtool0_batch(q) @ X_tool0_TCP.GetAsMatrix4()
    position = np.linalg.norm(X[:, :3, 3] - poses[:, :3], axis=1)
    rotation = _rotation_angles(X[:, :3, :3], rotation_matrices_from_rotation_vectors(poses[:, 3:]))
    return TcpDiscrepancy(
        samples=len(q),
        position_max_m=float(np.max(position)),
        position_median_m=float(np.median(position)),
        rotation_max_rad=float(np.max(rotation)),
        rotation_median_rad=float(np.median(rotation)),
    )


def check_tcp_pose(joint_positions, extra_columns, X_tool0_TCP, *, file):
    """The TCP check of a log read with ``extra_columns=TCP_POSE_COLUMNS``.

    Parameters
    ----------
    joint_positions : array, shape (m, 6)
    extra_columns : dict
        Column name -> array, shape (m,) (``RtdeLog.extra``).
    X_tool0_TCP : RigidTransform
    file : str or Path
        Named in the errors.

    Returns
    -------
    TcpDiscrepancy

    Raises
    ------
    InputError
        The log has no ``actual_TCP_pose_0`` .. ``_5`` columns, or the discrepancy is
        gross (:attr:`TcpDiscrepancy.is_gross`).
    """
    missing = [column for column in TCP_POSE_COLUMNS if column not in extra_columns]
    if missing:
        raise InputError(
            f"the TCP offset check needs the columns actual_TCP_pose_0 .. actual_TCP_pose_5, and the log "
            f"lacks {', '.join(missing)}; leave out the TCP offset, or record the full RTDE output",
            file=file,
            field="line 1",
        )
    poses = np.column_stack([extra_columns[column] for column in TCP_POSE_COLUMNS])
    discrepancy = tcp_discrepancy(joint_positions, poses, X_tool0_TCP)
    if discrepancy.is_gross:
        raise InputError(
            f"the joints' forward kinematics with the TCP offset disagree with actual_TCP_pose grossly "
            f"({discrepancy.text()}; more than a median {1e3 * GROSS_POSITION_M:g} mm or "
            f"{math.degrees(GROSS_ROTATION_RAD):g} deg): the joint and pose columns do not describe the same "
            "motion (joint columns mixed up, the offset not in metres, or another recording's poses)",
            file=file,
            field="actual_TCP_pose",
        )
    return discrepancy
