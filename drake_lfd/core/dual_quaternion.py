"""Unit dual quaternions for rigid poses: the conventions, input checks, products and parts.

This is the numeric core every other stage builds on (features, similarity, mapping,
trajectories). Everything is plain numpy, vectorised over leading batch dimensions.
Here: the identity, the product, the inverse and relative poses, a pose from its
translation and rotation (Eq. 7) and back, the canonical sign, and the input checks.
Rotations alone are in ``quaternion.py``, conversions to and from Drake's types,
matrices and Euler angles in ``pose_conversions.py``, the logarithm, exponential and
ScLERP in ``screw_motion.py``.

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
  a pose in se(3) (``screw_motion.py``).

Input checks: the algebra and the batch conversions do not check their arguments, since
they run inside the planners' inner loops. The stage entry points (features, mapping,
timing,
:func:`~drake_lfd.core.pose_conversions.rigid_transform_from_dual_quaternion`) check
what they are handed with :func:`check_unit_dual_quaternions` (and
:func:`check_unit_quaternions`), which reject wrong shapes, non-finite values and dual
quaternions that are not unit (``|r| = 1`` and ``r . d = 0`` within
:data:`UNIT_NORM_TOLERANCE`).

Not for: Drake systems, trajectories with timing, or non-unit dual quaternions (the
formulas assume unit norm; nothing here renormalises silently except conversions to
Drake types).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drake_lfd.core.quaternion import quaternion_conjugate, quaternion_multiply

__all__ = [
    "IDENTITY_DUAL_QUATERNION",
    "UNIT_NORM_TOLERANCE",
    "check_unit_quaternions",
    "check_unit_dual_quaternions",
    "dual_quaternion_multiply",
    "dual_quaternion_conjugate",
    "dual_quaternion_relative",
    "dual_quaternion_from_translation_rotation",
    "rotation_from_dual_quaternion",
    "translation_from_dual_quaternion",
    "translation_rotation_from_dual_quaternion",
    "dual_quaternion_canonical",
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
