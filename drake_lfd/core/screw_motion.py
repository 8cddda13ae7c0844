"""Screw motion between poses: the logarithm and exponential of unit dual quaternions, and ScLERP.

Exponential coordinates ``xi = (omega, v)``, shape ``(..., 6)``, are the logarithm of a
pose in se(3) (pytransform3d's name; screw theory calls them a twist, a word this
package keeps for the free turn about a task translation, see ``mapping.py``):
``X = exp([xi])`` with ``omega`` the rotation vector (``|omega| <= pi``) and
``p = V(omega) v``. ``D0 (x) exp(s xi)`` with ``xi = log(D0* (x) D1)`` is ScLERP, screw
linear interpolation (:func:`dual_quaternion_sclerp`). Plain numpy, vectorised over
leading batch dimensions, unchecked (``dual_quaternion.py``, *Input checks*).

Not for: the products and parts of poses (``dual_quaternion.py``) or conversions to
other forms of a pose (``pose_conversions.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.quaternion import cross, quaternion_from_rotation_vector, rotation_vector_from_quaternion

__all__ = [
    "exponential_coordinates_from_dual_quaternion",
    "dual_quaternion_from_exponential_coordinates",
    "dual_quaternion_sclerp",
]

# Below this rotation angle (rad) the coefficients of exp and log use Taylor series; the next
# neglected term is below 1e-17 there, and the closed forms lose digits to cancellation.
_SMALL_ANGLE_RAD = 1e-2


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
    wp = cross(omega, p)
    v = p - 0.5 * wp + c[..., None] * cross(omega, wp)
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
    wv = cross(omega, v)
    p = v + a[..., None] * wv + b[..., None] * cross(omega, wv)
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
