"""Dual quaternions to and from the other forms of a pose: Drake's, matrices and Euler angles.

Converts unit dual quaternions (``dual_quaternion.py``, *Conventions*) to and from
pydrake ``RigidTransform`` (one pose), homogeneous 4x4 matrices (batches: the UR5e's
forward kinematics gives them) and a position with Eq. 17's Euler angles (task files'
``euler_zyx``). The batch conversions do not check their arguments;
:func:`rigid_transform_from_dual_quaternion`, an entry point, does. Conversions to Drake
types and to matrices normalise the rotation part, so rounding drift is tolerated.

Not for: the algebra of poses (``dual_quaternion.py``) or rotations alone
(``quaternion.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix

from drake_lfd.core.dual_quaternion import (
    check_unit_dual_quaternions,
    dual_quaternion_from_translation_rotation,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.quaternion import (
    quaternion_from_axis_angle,
    quaternion_from_rotation_matrices,
    quaternion_multiply,
)

__all__ = [
    "dual_quaternion_from_rigid_transform",
    "rigid_transform_from_dual_quaternion",
    "dual_quaternion_from_matrices",
    "matrices_from_dual_quaternion",
    "dual_quaternion_from_euler_zyx",
]


def dual_quaternion_from_rigid_transform(X: RigidTransform) -> NDArray[np.float64]:
    """Dual quaternion of one pydrake ``RigidTransform``.

    Parameters
    ----------
    X : RigidTransform

    Returns
    -------
    D : array, shape (8,)
    """
    return dual_quaternion_from_translation_rotation(X.translation(), X.rotation().ToQuaternion().wxyz())


def rigid_transform_from_dual_quaternion(D: ArrayLike) -> RigidTransform:
    """pydrake ``RigidTransform`` of one unit dual quaternion.

    The rotation part is normalised first, so rounding drift is tolerated.

    Parameters
    ----------
    D : array-like, shape (8,)
        A unit dual quaternion (checked).

    Returns
    -------
    X : RigidTransform

    Raises
    ------
    ValueError
        If ``D`` is not one unit dual quaternion.
    """
    D = check_unit_dual_quaternions(D)
    if D.shape != (8,):
        raise ValueError(f"D must be one dual quaternion of shape (8,), got shape {D.shape}")
    p, r = translation_rotation_from_dual_quaternion(D)
    r = r / np.linalg.norm(r)
    return RigidTransform(RotationMatrix(Quaternion(r)), p)


def dual_quaternion_from_matrices(T: ArrayLike) -> NDArray[np.float64]:
    """Dual quaternions of homogeneous transforms.

    Parameters
    ----------
    T : array-like, shape (..., 4, 4)

    Returns
    -------
    D : array, shape (..., 8)
        Rotation part with ``r_w >= 0``.
    """
    T = np.asarray(T, dtype=float)
    return dual_quaternion_from_translation_rotation(
        T[..., :3, 3], quaternion_from_rotation_matrices(T[..., :3, :3]))


def matrices_from_dual_quaternion(D: ArrayLike) -> NDArray[np.float64]:
    """Homogeneous transforms of dual quaternions.

    The rotation part is normalised first, so rounding drift is tolerated.

    Parameters
    ----------
    D : array-like, shape (..., 8)

    Returns
    -------
    T : array, shape (..., 4, 4)
    """
    p, r = translation_rotation_from_dual_quaternion(D)
    w, x, y, z = np.moveaxis(r / np.linalg.norm(r, axis=-1, keepdims=True), -1, 0)
    T = np.zeros(p.shape[:-1] + (4, 4))
    T[..., 0, :3] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1)
    T[..., 1, :3] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1)
    T[..., 2, :3] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def dual_quaternion_from_euler_zyx(p: ArrayLike, yaw_pitch_roll: ArrayLike) -> NDArray[np.float64]:
    """Pose from a position and Eq. 17's Euler angles, ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    In Drake terms ``RollPitchYaw(roll, pitch, yaw)`` (see *Conventions*).

    Parameters
    ----------
    p : array-like, shape (..., 3)
        Positions (m).
    yaw_pitch_roll : array-like, shape (..., 3)
        ``(theta1, theta2, theta3)`` = (yaw about Z, pitch about Y, roll about X), rad.

    Returns
    -------
    D : array, shape (..., 8)
    """
    angles = np.asarray(yaw_pitch_roll, dtype=float)
    yaw, pitch, roll = np.moveaxis(angles, -1, 0)
    z = quaternion_from_axis_angle(np.array([0.0, 0.0, 1.0]), yaw)
    y = quaternion_from_axis_angle(np.array([0.0, 1.0, 0.0]), pitch)
    x = quaternion_from_axis_angle(np.array([1.0, 0.0, 0.0]), roll)
    return dual_quaternion_from_translation_rotation(p, quaternion_multiply(quaternion_multiply(z, y), x))

