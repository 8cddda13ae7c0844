"""Poses in files: the JSON form ``{"p": [x, y, z], "q_wxyz": [w, x, y, z]}``.

Every JSON that drake-lfd writes (library manifests, ``--json`` reports) states poses in
this form (docs/cli.rst), so anyone can rebuild them with their own
tools. This module converts between it and pydrake's ``RigidTransform`` and checks what
a user's file holds: finite numbers and a quaternion of unit norm (within 1e-6, then
normalised). Problems are :class:`~drake_lfd.core.errors.InputError` naming file and field.

For messages that tell a user what to type, :func:`angle_text`, :func:`number_text` and
:func:`pose_yaml_text` write numbers, angles (``pi/2`` where the angle is an exact
multiple of pi) and poses the way task files and options read them;
:func:`tool_frame_arguments` an end-effector frame as ``library add``'s options.

Not for: task files (they write orientations as ``euler_zyx``, see ``tasks.py``) or dual
quaternions (``dual_quaternion.py``).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from drake_lfd.core.dual_quaternion import UNIT_NORM_TOLERANCE
from drake_lfd.core.errors import InputError

__all__ = [
    'UNIT_NORM_TOLERANCE',
    'POSE_KEYS',
    'pose_json_from_rigid_transform',
    'rigid_transform_from_pose_json',
    'number_text',
    'angle_text',
    'euler_zyx_from_rigid_transform',
    'pose_yaml_text',
    'tool_frame_arguments',
    'tool_frame_options',
]

# UNIT_NORM_TOLERANCE (core/dual_quaternion.py, the one bound for every entry point): a
# stored quaternion may be off unit norm by rounding in whatever wrote it; more than that
# means the numbers are not a rotation (a typo, or a different convention).

POSE_KEYS = ("p", "q_wxyz")


def pose_json_from_rigid_transform(X):
    """The JSON form of a pose.

    Parameters
    ----------
    X : RigidTransform

    Returns
    -------
    pose : dict
        ``{"p": [x, y, z], "q_wxyz": [w, x, y, z]}`` with plain floats and ``w >= 0``
        (of the two quaternions of a rotation, the one a reader expects).
    """
    q = X.rotation().ToQuaternion().wxyz()
    if q[0] < 0.0:
        q = -q
    return {
        "p": [float(v) for v in X.translation()],
        "q_wxyz": [float(v) for v in q],
    }


def _finite_numbers(value, count, *, file, field):
    """``value`` as a float array of shape (count,), or an InputError."""
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise InputError(f"expected a list of {count} numbers, got {value!r}", file=file, field=field)
    numbers = []
    for index, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, (int, float)):
            raise InputError(f"expected a number, got {item!r}", file=file, field=f"{field}[{index}]")
        if not math.isfinite(item):
            raise InputError(f"{item!r} is not a finite number", file=file, field=f"{field}[{index}]")
        numbers.append(float(item))
    return np.array(numbers)


def rigid_transform_from_pose_json(value, *, file=None, field=None):
    """A pose read from a file, checked.

    Parameters
    ----------
    value : object
        The parsed JSON value; must be a mapping with exactly the keys ``p`` (3 finite
        numbers, metres) and ``q_wxyz`` (4 finite numbers of unit norm within
        :data:`UNIT_NORM_TOLERANCE`; normalised before use).
    file : str or Path, optional
        The file it came from, for error messages.
    field : str, optional
        Where in the file it is (for example ``"X_tool0_E"``), for error messages.

    Returns
    -------
    X : RigidTransform

    Raises
    ------
    InputError
        Naming the file and the field (for example ``X_tool0_E.q_wxyz[2]``).
    """
    prefix = field or "pose"
    if not isinstance(value, dict):
        raise InputError(
            'expected a pose {"p": [x, y, z], "q_wxyz": [w, x, y, z]}, got ' + repr(value),
            file=file,
            field=field,
        )
    unknown = sorted(str(key) for key in value if key not in POSE_KEYS)
    if unknown:
        raise InputError(
            f"unknown key {unknown[0]!r} (a pose has keys p and q_wxyz)", file=file, field=prefix
        )
    missing = [key for key in POSE_KEYS if key not in value]
    if missing:
        raise InputError(f"missing key {missing[0]!r}", file=file, field=prefix)
    p = _finite_numbers(value["p"], 3, file=file, field=f"{prefix}.p")
    q = _finite_numbers(value["q_wxyz"], 4, file=file, field=f"{prefix}.q_wxyz")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > UNIT_NORM_TOLERANCE:
        raise InputError(
            f"quaternion {q.tolist()} has norm {norm:.9g}; a rotation needs norm 1 "
            f"(within {UNIT_NORM_TOLERANCE:g}), written as [w, x, y, z]",
            file=file,
            field=f"{prefix}.q_wxyz",
        )
    q = q / norm
    return RigidTransform(RotationMatrix(Quaternion(q)), p)


# An angle this close to a multiple of pi / d (d below) is written as that multiple.
_PI_MULTIPLE_TOLERANCE = 1e-10
_PI_DENOMINATORS = (1, 2, 3, 4, 6, 8, 12)


def number_text(value):
    """A number as a user would type it: fixed point, at most 12 decimals, no ``-0``
    and no exponent (so that a negative value is still read as a number by argparse)."""
    text = f"{float(value):.12f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def angle_text(value, *, non_negative=False):
    """An angle in radians as a user would type it: ``pi/2``, ``-3*pi/4``, ``0`` when it
    is a multiple of pi / d (d in 1, 2, 3, 4, 6, 8, 12) within 1e-10, else
    :func:`number_text`. ``non_negative`` writes a negative multiple of pi plus 2 pi
    (``3*pi/2`` for ``-pi/2``: the same rotation), for command-line options, where
    argparse would take ``-pi/2`` for an option."""
    value = float(value)
    for denominator in _PI_DENOMINATORS:
        k = round(value * denominator / math.pi)
        if abs(value - k * math.pi / denominator) > _PI_MULTIPLE_TOLERANCE:
            continue
        if k == 0:
            return "0"
        if non_negative and k < 0:
            k += 2 * denominator
        coefficient = {1: "", -1: "-"}.get(k, f"{k}*")
        return f"{coefficient}pi" + (f"/{denominator}" if denominator != 1 else "")
    return number_text(value)


def euler_zyx_from_rigid_transform(X):
    """``[yaw, pitch, roll]`` of a pose's rotation, ``R = Rz(yaw) Ry(pitch) Rx(roll)``
    (pitch in [-pi/2, pi/2]; at pitch +-pi/2 one of the splits of yaw and roll)."""
    rpy = RollPitchYaw(X.rotation())
    return [float(rpy.yaw_angle()), float(rpy.pitch_angle()), float(rpy.roll_angle())]


def pose_yaml_text(X):
    """A pose in the task files' form, ``{p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}``."""
    p = ", ".join(number_text(v) for v in X.translation())
    euler = ", ".join(angle_text(v) for v in euler_zyx_from_rigid_transform(X))
    return f"{{p: [{p}], euler_zyx: [{euler}]}}"


def tool_frame_arguments(X_tool0_E):
    """The ``library add`` options that choose the end-effector frame ``X_tool0_E``, as
    one would type them, tuple of str: ``("--tool0-E-p", "0", "0", "0.2",
    "--tool0-E-euler-zyx", "0", "pi/2", "0")``.

    Angles are exact multiples of pi where they are (a negative one plus 2 pi, since
    argparse takes ``-pi/2`` for an option), else radians; both read back within
    ``io.library.END_EFFECTOR_FRAME_TOLERANCE``."""
    p = tuple(number_text(v) for v in X_tool0_E.translation())
    euler = tuple(angle_text(v, non_negative=True) for v in euler_zyx_from_rigid_transform(X_tool0_E))
    return ("--tool0-E-p", *p, "--tool0-E-euler-zyx", *euler)


def tool_frame_options(X_tool0_E):
    """:func:`tool_frame_arguments` as one string:
    ``--tool0-E-p 0 0 0.2 --tool0-E-euler-zyx 0 pi/2 0``."""
    return " ".join(tool_frame_arguments(X_tool0_E))
