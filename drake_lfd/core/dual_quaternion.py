"""Dual quaternions for rigid poses: products, conversions, screw interpolation.

This is the numeric core every other stage builds on (features, similarity, mapping,
trajectories). Everything is plain numpy, vectorised over leading batch dimensions.

Conventions (``docs/method.rst``, *Conventions*):

- A quaternion is an array ``(..., 4)`` = ``(w, x, y, z)``; products are Hamilton (Eq. 3).
- A dual quaternion is an array ``(..., 8)`` =
  ``(r_w, r_x, r_y, r_z, d_w, d_x, d_y, d_z)`` with ``D = r + eps * d`` and
  ``d = 0.5 * t (x) r``, ``t = (0, p)`` (Eq. 7). For a pose ``X_WE`` the rotation part
  ``r`` is ``R_WE`` and ``p`` is ``p_WE``.
- ``D*`` is the quaternion conjugate of both parts (pytransform3d's ``dq_q_conj``), the
  inverse of a unit dual quaternion, so ``D_a* (x) D_b`` is the pose of frame b
  expressed in frame a: rotation ``r_a* r_b``, translation ``R_a^T (p_b - p_a)``.
- ``D`` and ``-D`` are the same pose (double cover). Functions here accept either sign;
  :func:`dual_quaternion_canonical` picks one when a unique array is needed.
- Exponential coordinates ``xi = (omega, v)``, shape ``(..., 6)``, are the logarithm of
  a pose in se(3) (pytransform3d's name; screw theory calls them a twist, a word this
  package keeps for the free turn about a task translation, see ``mapping.py``):
  ``X = exp([xi])`` with ``omega`` the rotation vector (``|omega| <= pi``) and
  ``p = V(omega) v``. ``D0 (x) exp(s xi)`` with ``xi = log(D0* (x) D1)`` is ScLERP.

Input checks: the algebra and the batch conversions do not check their arguments, since
they run inside the planners' inner loops. The stage entry points (features, mapping,
timing, :func:`rigid_transform_from_dual_quaternion`) check what they are handed with
:func:`check_unit_dual_quaternions`, which rejects wrong shapes, non-finite values and
dual quaternions that are not unit (``|r| = 1`` and ``r . d = 0`` within
:data:`UNIT_NORM_TOLERANCE`).

Not for: Drake systems, trajectories with timing, or non-unit dual quaternions (the
formulas assume unit norm; nothing here renormalises silently except conversions to
Drake types).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix

__all__ = [
    "IDENTITY_DUAL_QUATERNION",
    "UNIT_NORM_TOLERANCE",
    "check_unit_quaternions",
    "check_unit_dual_quaternions",
    "quaternion_multiply",
    "quaternion_conjugate",
    "vector_rotated_by_quaternion",
    "quaternion_from_axis_angle",
    "axis_angle_from_quaternion",
    "rotation_vector_from_quaternion",
    "quaternion_from_rotation_vector",
    "quaternion_from_rotation_matrices",
    "dual_quaternion_multiply",
    "dual_quaternion_conjugate",
    "dual_quaternion_relative",
    "dual_quaternion_from_translation_rotation",
    "rotation_from_dual_quaternion",
    "translation_from_dual_quaternion",
    "translation_rotation_from_dual_quaternion",
    "dual_quaternion_from_rigid_transform",
    "rigid_transform_from_dual_quaternion",
    "dual_quaternion_from_matrices",
    "matrices_from_dual_quaternion",
    "dual_quaternion_from_euler_zyx",
    "dual_quaternion_canonical",
    "exponential_coordinates_from_dual_quaternion",
    "dual_quaternion_from_exponential_coordinates",
    "dual_quaternion_sclerp",
]

#: The identity pose ``1 + eps 0``, shape (8,), read-only.
IDENTITY_DUAL_QUATERNION = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
IDENTITY_DUAL_QUATERNION.flags.writeable = False

#: Largest accepted ``| |r| - 1 |`` and ``|r . d|`` (and ``| |q| - 1 |`` for quaternions)
#: at the entry points. Rounding drift after thousands of products stays near 1e-13;
#: an input beyond 1e-6 was not built as a unit (dual) quaternion.
UNIT_NORM_TOLERANCE = 1e-6
# |q| in [1 - tol, 1 + tol] as bounds on |q|^2, which needs no square root.
_UNIT_NORM_SQUARED_BOUNDS = ((1.0 - UNIT_NORM_TOLERANCE) ** 2, (1.0 + UNIT_NORM_TOLERANCE) ** 2)

# Below this rotation angle (rad) the coefficients of exp and log use Taylor series; the next
# neglected term is below 1e-17 there, and the closed forms lose digits to cancellation.
_SMALL_ANGLE_RAD = 1e-2


# ---------------------------------------------------------------------------- input checks


def _is_unit(norm_squared):
    """Whether ``|q| = 1`` within the tolerance, elementwise; False for NaN."""
    low, high = _UNIT_NORM_SQUARED_BOUNDS
    return (norm_squared >= low) & (norm_squared <= high)


def _worst_entry(error):
    """Index of the largest (or NaN) entry of ``error`` and how to name it in a message."""
    worst = np.unravel_index(np.argmax(np.where(np.isnan(error), np.inf, error)), error.shape)
    if error.ndim == 0:
        return worst, "it"
    index = tuple(int(i) for i in worst)
    return worst, f"entry {index[0] if len(index) == 1 else index}"


def check_unit_quaternions(q: ArrayLike, name: str = "q") -> NDArray[np.float64]:
    """Unit quaternions as a float array, or ValueError naming ``name``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Quaternions (w, x, y, z), each with norm 1 within :data:`UNIT_NORM_TOLERANCE`.
    name : str
        What ``q`` is, for the error message.

    Returns
    -------
    q : array, shape (..., 4)
        ``q`` as float (not copied when it already is a float array).

    Raises
    ------
    ValueError
        If the last axis is not 4 long, a value is not finite or a norm is off.
    """
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != 4:
        raise ValueError(f"{name} must be quaternions (w, x, y, z) of shape (..., 4), got shape {q.shape}")
    norm_squared = np.einsum("...i,...i->...", q, q)
    if not _is_unit(norm_squared).all():
        worst, entry = _worst_entry(np.abs(np.sqrt(norm_squared) - 1.0))
        raise ValueError(
            f"{name} must be unit quaternions (| |q| - 1 | <= {UNIT_NORM_TOLERANCE:g}); "
            f"{entry} has |q| = {np.linalg.norm(q[worst]):.9g}")
    return q


def check_unit_dual_quaternions(D: ArrayLike, name: str = "D") -> NDArray[np.float64]:
    """Unit dual quaternions as a float array, or ValueError naming ``name``.

    A unit dual quaternion ``r + eps d`` has ``|r| = 1`` and ``r . d = 0``; both are
    checked within :data:`UNIT_NORM_TOLERANCE`. Callers check the leading shape.

    Parameters
    ----------
    D : array-like, shape (..., 8)
        Dual quaternions ``(r_w, r_x, r_y, r_z, d_w, d_x, d_y, d_z)``.
    name : str
        What ``D`` is, for the error message.

    Returns
    -------
    D : array, shape (..., 8)
        ``D`` as float (not copied when it already is a float array).

    Raises
    ------
    ValueError
        If the last axis is not 8 long, a value is not finite or ``D`` is not unit.
    """
    D = np.asarray(D, dtype=float)
    if D.ndim == 0 or D.shape[-1] != 8:
        raise ValueError(f"{name} must be dual quaternions of shape (..., 8), got shape {D.shape}")
    r = D[..., :4]
    norm_squared = np.einsum("...i,...i->...", r, r)
    dot = np.einsum("...i,...i->...", r, D[..., 4:])
    # Comparisons written so that NaN fails.
    if not (_is_unit(norm_squared).all() and (np.abs(dot) <= UNIT_NORM_TOLERANCE).all()):
        worst, entry = _worst_entry(np.maximum(np.abs(np.sqrt(norm_squared) - 1.0), np.abs(dot)))
        raise ValueError(
            f"{name} must be unit dual quaternions (| |r| - 1 | and |r . d| <= {UNIT_NORM_TOLERANCE:g}); "
            f"{entry} has |r| = {np.linalg.norm(r[worst]):.9g}, r . d = {np.dot(r[worst], D[worst][4:]):.3g}")
    return D


# --------------------------------------------------------------------------- quaternions


def quaternion_multiply(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``a (x) b`` (Eq. 3).

    Parameters
    ----------
    a, b : array-like, shape (..., 4)
        Quaternions (w, x, y, z); leading dimensions broadcast.

    Returns
    -------
    ab : array, shape (..., 4)
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quaternion_conjugate(q: ArrayLike) -> NDArray[np.float64]:
    """Conjugate ``q* = (w, -x, -y, -z)`` (Eq. 2), shape (..., 4) -> (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def vector_rotated_by_quaternion(q: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
    """Rotate vectors by unit quaternions: the vector part of ``q (x) (0, v) (x) q*``.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions.
    v : array-like, shape (..., 3)
        Vectors; leading dimensions broadcast with ``q``.

    Returns
    -------
    v_rotated : array, shape (..., 3)
    """
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    w = q[..., :1]
    u = q[..., 1:]
    # Expanded sandwich product, cheaper than two Hamilton products.
    uv = np.cross(u, v)
    return v + 2.0 * w * uv + 2.0 * np.cross(u, uv)


def quaternion_from_axis_angle(axis: ArrayLike, angle: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternion of a rotation by ``angle`` about unit ``axis`` (Eq. 9).

    Parameters
    ----------
    axis : array-like, shape (..., 3)
        Unit rotation axes.
    angle : array-like, shape (...)
        Angles in radians.

    Returns
    -------
    q : array, shape (..., 4)
    """
    axis = np.asarray(axis, dtype=float)
    half = 0.5 * np.asarray(angle, dtype=float)[..., None]
    vector = np.sin(half) * axis
    return np.concatenate([np.broadcast_to(np.cos(half), vector.shape[:-1] + (1,)), vector], axis=-1)


def axis_angle_from_quaternion(q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Axis and angle of unit quaternions, the angle in [0, pi].

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions; ``q`` and ``-q`` give the same result.

    Returns
    -------
    axis : array, shape (..., 3)
        Unit axes. For a zero rotation the axis is undefined and returned as (1, 0, 0).
    angle : array, shape (...)
        Rotation angles in [0, pi].
    """
    q = np.asarray(q, dtype=float)
    sign = np.where(q[..., :1] < 0.0, -1.0, 1.0)
    w = sign[..., 0] * q[..., 0]
    u = sign * q[..., 1:]
    norm_u = np.linalg.norm(u, axis=-1)
    angle = 2.0 * np.arctan2(norm_u, w)
    safe = norm_u > 0.0
    axis = np.where(
        safe[..., None],
        u / np.where(safe, norm_u, 1.0)[..., None],
        np.array([1.0, 0.0, 0.0]),
    )
    return axis, angle


def rotation_vector_from_quaternion(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation vectors ``angle * axis`` (angle in [0, pi]) of unit quaternions.

    Parameters
    ----------
    q : array-like, shape (..., 4)
        Unit quaternions; ``q`` and ``-q`` give the same result.

    Returns
    -------
    omega : array, shape (..., 3)
    """
    q = np.asarray(q, dtype=float)
    sign = np.where(q[..., :1] < 0.0, -1.0, 1.0)
    w = sign[..., 0] * q[..., 0]
    u = sign * q[..., 1:]
    norm_u = np.linalg.norm(u, axis=-1)
    # angle / |u| -> 2 / w as |u| -> 0 (w -> 1 there since w >= 0).
    small = norm_u < 1e-8
    factor = np.where(
        small, 2.0 / np.maximum(w, 0.5), 2.0 * np.arctan2(norm_u, w) / np.where(small, 1.0, norm_u)
    )
    return factor[..., None] * u


def quaternion_from_rotation_vector(omega: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternions ``exp(omega / 2)`` of rotation vectors.

    Parameters
    ----------
    omega : array-like, shape (..., 3)
        Rotation vectors ``angle * axis`` (rad).

    Returns
    -------
    q : array, shape (..., 4)
    """
    omega = np.asarray(omega, dtype=float)
    angle = np.linalg.norm(omega, axis=-1)
    # sin(angle/2)/angle without the 0/0 at angle = 0: np.sinc(x) = sin(pi x)/(pi x).
    half_sinc = 0.5 * np.sinc(angle / (2.0 * np.pi))
    return np.concatenate([np.cos(0.5 * angle)[..., None], half_sinc[..., None] * omega], axis=-1)


def quaternion_from_rotation_matrices(R: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternions (w >= 0) of rotation matrices, vectorised Shepperd's method.

    Parameters
    ----------
    R : array-like, shape (..., 3, 3)
        Rotation matrices (the result is normalised, so rounding drift is tolerated).

    Returns
    -------
    q : array, shape (..., 4)
    """
    R = np.asarray(R, dtype=float)
    r00, r11, r22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2 (up to the common factor); pick the largest pivot for
    # accuracy, then get the other components from the off-diagonal terms.
    pivots = np.stack(
        [1 + r00 + r11 + r22, 1 + r00 - r11 - r22, 1 - r00 + r11 - r22, 1 - r00 - r11 + r22],
        axis=-1,
    )
    choice = np.argmax(pivots, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(pivots, choice[..., None], -1)[..., 0], 1e-300))
    zy = R[..., 2, 1] - R[..., 1, 2]
    xz = R[..., 0, 2] - R[..., 2, 0]
    yx = R[..., 1, 0] - R[..., 0, 1]
    xy_ = R[..., 0, 1] + R[..., 1, 0]
    xz_ = R[..., 0, 2] + R[..., 2, 0]
    yz_ = R[..., 1, 2] + R[..., 2, 1]
    candidates = np.stack(
        [
            np.stack([s * s, zy, xz, yx], axis=-1),
            np.stack([zy, s * s, xy_, xz_], axis=-1),
            np.stack([xz, xy_, s * s, yz_], axis=-1),
            np.stack([yx, xz_, yz_, s * s], axis=-1),
        ],
        axis=-2,
    ) / (2.0 * s[..., None, None])
    q = np.take_along_axis(candidates, choice[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


# ---------------------------------------------------------------------- dual quaternions


def dual_quaternion_multiply(A: ArrayLike, B: ArrayLike) -> NDArray[np.float64]:
    """Dual quaternion product ``A (x) B`` (composition of poses ``X_A X_B``).

    Parameters
    ----------
    A, B : array-like, shape (..., 8)
        Leading dimensions broadcast.

    Returns
    -------
    AB : array, shape (..., 8)
        ``r = r_A r_B``, ``d = r_A d_B + d_A r_B``.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    r = quaternion_multiply(A[..., :4], B[..., :4])
    d = quaternion_multiply(A[..., :4], B[..., 4:]) + quaternion_multiply(A[..., 4:], B[..., :4])
    return np.concatenate([r, d], axis=-1)


def dual_quaternion_conjugate(D: ArrayLike) -> NDArray[np.float64]:
    """Quaternion conjugate of both parts, ``D* = r* + eps d*`` (see *Conventions*).

    For unit dual quaternions this is the inverse pose.

    Parameters
    ----------
    D : array-like, shape (..., 8)

    Returns
    -------
    D_conjugate : array, shape (..., 8)
    """
    D = np.asarray(D, dtype=float)
    return D * np.array([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])


def dual_quaternion_relative(D_a: ArrayLike, D_b: ArrayLike) -> NDArray[np.float64]:
    """Pose of frame b in frame a: ``D_a* (x) D_b`` (Eq. 12, 18).

    Rotation ``r_a* r_b``, translation ``R_a^T (p_b - p_a)``.

    Parameters
    ----------
    D_a, D_b : array-like, shape (..., 8)

    Returns
    -------
    D_ab : array, shape (..., 8)
    """
    return dual_quaternion_multiply(dual_quaternion_conjugate(D_a), D_b)


def dual_quaternion_from_translation_rotation(p: ArrayLike, q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """Dual quaternion ``r + eps * 0.5 * (0, p) (x) r`` of positions and rotations (Eq. 7).

    The inverse of :func:`translation_rotation_from_dual_quaternion`.

    Parameters
    ----------
    p : array-like, shape (..., 3)
        Positions (m).
    q_wxyz : array-like, shape (..., 4)
        Unit quaternions (w, x, y, z). Leading dimensions broadcast with ``p``.

    Returns
    -------
    D : array, shape (..., 8)
    """
    p = np.asarray(p, dtype=float)
    r = np.asarray(q_wxyz, dtype=float)
    t = np.concatenate([np.zeros(p.shape[:-1] + (1,)), p], axis=-1)
    d = 0.5 * quaternion_multiply(t, r)
    r = np.broadcast_to(r, d.shape)
    return np.concatenate([r, d], axis=-1)


def rotation_from_dual_quaternion(D: ArrayLike) -> NDArray[np.float64]:
    """Rotation part ``r`` (a unit quaternion), as a copy.

    Parameters
    ----------
    D : array-like, shape (..., 8)

    Returns
    -------
    r : array, shape (..., 4)
    """
    return np.array(np.asarray(D, dtype=float)[..., :4])


def translation_from_dual_quaternion(D: ArrayLike) -> NDArray[np.float64]:
    """Translation ``p = 2 d (x) r*`` (vector part).

    Parameters
    ----------
    D : array-like, shape (..., 8)

    Returns
    -------
    p : array, shape (..., 3)
    """
    D = np.asarray(D, dtype=float)
    return 2.0 * quaternion_multiply(D[..., 4:], quaternion_conjugate(D[..., :4]))[..., 1:]


def translation_rotation_from_dual_quaternion(
    D: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and rotation of dual quaternions.

    The inverse of :func:`dual_quaternion_from_translation_rotation`.

    Parameters
    ----------
    D : array-like, shape (..., 8)

    Returns
    -------
    p : array, shape (..., 3)
    q_wxyz : array, shape (..., 4)
    """
    return translation_from_dual_quaternion(D), rotation_from_dual_quaternion(D)


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


def dual_quaternion_canonical(D: ArrayLike) -> NDArray[np.float64]:
    """The sign representative of each pose with ``r_w >= 0``.

    Both parts are negated together, so the pose is unchanged. Ties (``r_w == 0``
    exactly, a half-turn) are broken lexicographically: the first non-zero of
    ``(r_x, r_y, r_z)`` is made positive. Near a half-turn the result may still flip
    with rounding; compare poses with :func:`dual_quaternion_relative` when that matters.

    Parameters
    ----------
    D : array-like, shape (..., 8)

    Returns
    -------
    D_canonical : array, shape (..., 8)
    """
    D = np.asarray(D, dtype=float)
    r = D[..., :4]
    nonzero = r != 0.0
    first = np.argmax(nonzero, axis=-1)
    leading = np.take_along_axis(r, first[..., None], axis=-1)
    return np.where(leading < 0.0, -D, D)


# ------------------------------------------------------- exponential coordinates / ScLERP


def _exponential_coefficients(angle):
    """``a = (1 - cos t)/t^2``, ``b = (t - sin t)/t^3``, ``c`` of ``V^-1``, shape (...)."""
    small = angle < _SMALL_ANGLE_RAD
    t = np.where(small, 1.0, angle)  # placeholder where the series is used
    t2 = angle * angle
    a = 0.5 * np.sinc(angle / (2.0 * np.pi)) ** 2
    b = np.where(small, 1 / 6 - t2 / 120 + t2 * t2 / 5040, (t - np.sin(t)) / t**3)
    # V^-1 = I - 0.5 [w] + c [w]^2, c = (1 - (t/2) cot(t/2)) / t^2
    c = np.where(
        small,
        1 / 12 + t2 / 720 + t2 * t2 / 30240,
        (1.0 - 0.5 * t * np.sin(t) / (1.0 - np.cos(t))) / (t * t),
    )
    return a, b, c


def exponential_coordinates_from_dual_quaternion(D: ArrayLike) -> NDArray[np.float64]:
    """Logarithm of unit dual quaternions as exponential coordinates ``xi = (omega, v)``.

    Parameters
    ----------
    D : array-like, shape (..., 8)
        Either sign; the rotation with angle in [0, pi] is used.

    Returns
    -------
    xi : array, shape (..., 6)
        ``omega`` (rotation vector) and ``v`` with ``p = V(omega) v``.
    """
    p, r = translation_rotation_from_dual_quaternion(D)
    omega = rotation_vector_from_quaternion(r)
    _, _, c = _exponential_coefficients(np.linalg.norm(omega, axis=-1))
    wp = np.cross(omega, p)
    v = p - 0.5 * wp + c[..., None] * np.cross(omega, wp)
    return np.concatenate([omega, v], axis=-1)


def dual_quaternion_from_exponential_coordinates(xi: ArrayLike) -> NDArray[np.float64]:
    """Exponential of exponential coordinates ``xi = (omega, v)``.

    Parameters
    ----------
    xi : array-like, shape (..., 6)
        Rotation vector ``omega`` and ``v`` with ``p = V(omega) v``.

    Returns
    -------
    D : array, shape (..., 8)
    """
    xi = np.asarray(xi, dtype=float)
    omega, v = xi[..., :3], xi[..., 3:]
    a, b, _ = _exponential_coefficients(np.linalg.norm(omega, axis=-1))
    wv = np.cross(omega, v)
    p = v + a[..., None] * wv + b[..., None] * np.cross(omega, wv)
    return dual_quaternion_from_translation_rotation(p, quaternion_from_rotation_vector(omega))


def dual_quaternion_sclerp(D0: ArrayLike, D1: ArrayLike, s: ArrayLike) -> NDArray[np.float64]:
    """Screw linear interpolation ``D0 (x) (D0* (x) D1)^s`` (Kavan et al. 2006).

    Moves along the shortest screw (relative rotation angle <= pi). Robust for pure
    translations and identical poses (no division by the rotation angle).

    Parameters
    ----------
    D0, D1 : array-like, shape (..., 8)
        Start and end poses; leading dimensions broadcast.
    s : float or array-like, shape (...)
        Interpolation parameters (0 gives ``D0``, 1 gives ``D1`` up to sign),
        broadcast against the leading dimensions of ``D0``/``D1``: single poses with
        ``s`` of shape (n,) give (n, 8).

    Returns
    -------
    D_s : array, shape (..., 8)
    """
    D0 = np.asarray(D0, dtype=float)
    xi = exponential_coordinates_from_dual_quaternion(dual_quaternion_relative(D0, D1))
    s = np.asarray(s, dtype=float)[..., None]
    return dual_quaternion_multiply(D0, dual_quaternion_from_exponential_coordinates(s * xi))
