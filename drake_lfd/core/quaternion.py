"""Unit quaternions for rotations: products, rotating vectors, and the other forms of a rotation.

A quaternion is an array ``(..., 4)`` = ``(w, x, y, z)``; products are Hamilton (Eq. 3).
Everything is plain numpy, vectorised over leading batch dimensions, and unchecked (it
runs inside the planners' inner loops): the stage entry points check what they are
handed with :func:`~drake_lfd.core.dual_quaternion.check_unit_quaternions`. Here: the
Hamilton product, the conjugate, vectors rotated by a quaternion, and conversions to and
from axis-angle, rotation vectors (``omega = angle * axis``) and rotation matrices.

Not for: poses (``dual_quaternion.py``, ``pose_conversions.py``) or screw motions
(``screw_motion.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "cross",
    "quaternion_multiply",
    "quaternion_conjugate",
    "vector_rotated_by_quaternion",
    "quaternion_from_axis_angle",
    "axis_angle_from_quaternion",
    "rotation_vector_from_quaternion",
    "quaternion_from_rotation_vector",
    "quaternion_from_rotation_matrices",
]


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
    # Component views and one output array: the planner calls this on a few quaternions
    # at a time, where moving axes and stacking cost more than the products.
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    ab = np.empty(_broadcast_shape(a, b))
    ab[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    ab[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    ab[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    ab[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return ab


def _broadcast_shape(a: np.ndarray, b: np.ndarray) -> tuple[int, ...]:
    """The shape ``a`` and ``b`` broadcast to (most calls: the same shape)."""
    return a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape)


def cross(u: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
    """Cross products ``u x v`` of vectors, shape (..., 3), leading dimensions broadcast:
    ``np.cross``'s numbers (each component ``u_i v_j - u_j v_i``, rounded as it rounds it)
    without its axis moves, which cost more than the products on a few vectors."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    uv = np.empty(_broadcast_shape(u, v))
    uv[..., 0] = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    uv[..., 1] = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    uv[..., 2] = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return uv


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
    uv = cross(u, v)
    return v + 2.0 * w * uv + 2.0 * cross(u, uv)


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


def _with_w_not_negative(q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``(w, u, |u|)`` of the sign of each unit quaternion with ``w >= 0`` (``u``: its
    vector part), shapes (...), (..., 3), (...)."""
    q = np.asarray(q, dtype=float)
    sign = np.where(q[..., :1] < 0.0, -1.0, 1.0)
    w = sign[..., 0] * q[..., 0]
    u = sign * q[..., 1:]
    return w, u, np.linalg.norm(u, axis=-1)


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
    w, u, norm_u = _with_w_not_negative(q)
    angle = 2.0 * np.arctan2(norm_u, w)
    safe = norm_u > 0.0
    axis = np.where(
        safe[..., None],
        u / np.where(safe, norm_u, 1.0)[..., None],
        np.array([1.0, 0.0, 0.0]),
    )
    return axis, angle


def rotation_vector_from_quaternion(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation vectors ``omega = angle * axis`` (angle in [0, pi]) of unit quaternions,
    shape (..., 4) -> (..., 3); ``q`` and ``-q`` give the same ``omega``."""
    w, u, norm_u = _with_w_not_negative(q)
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
