"""The UR5e's inverse kinematics in closed form: every branch reaching a flange pose.

A six-joint arm with the UR's geometry (three parallel middle axes, a spherical-free
wrist offset) reaches a pose in at most eight configurations, its inverse-kinematics
branches: shoulder_pan towards or away from the target (two roots of one equation),
wrist_2 on either side (the sign of ``sin q5``) and the elbow up or down (the sign of
``sin q3``). :func:`ur5e_branches` solves for all of them from Universal Robots' DH
table, the closed form of Hawkins,
"Analytic Inverse Kinematics for the Universal Robots UR-5/UR-10 Arms" (2013), in a few
microseconds per pose instead of a nonlinear program per guess.

Where a joint is free (wrist_2 aligned, ``sin q5 = 0``: wrist_1 and wrist_3 turn
together), wrist_3 takes the value ``q6_free`` asks for. The angles come back in
(-pi, pi]; the caller checks the limits and the pose on its own model
(:func:`~drake_lfd.robot.initial_ik.initial_configuration_candidates`: the URDF's
forward kinematics equals the DH table's to 2e-16, the closed form's error is about
1e-13).

Not for: the preferred-branch ordering and the collision check (``initial_ik.py``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["UR5E_DH_D", "UR5E_DH_A", "ur5e_branches", "shoulder_pan_roots"]

# Universal Robots' UR5e DH parameters (m): link offsets d and lengths a (standard DH;
# alpha = pi/2, 0, 0, pi/2, -pi/2, 0). The URDF's forward kinematics equals the table's
# to 2e-16 (tests/test_analytic_ik.py).
UR5E_DH_D = (0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996)
UR5E_DH_A = (0.0, -0.425, -0.3922, 0.0, 0.0, 0.0)
_D1, _D4, _D5, _D6 = UR5E_DH_D[0], UR5E_DH_D[3], UR5E_DH_D[4], UR5E_DH_D[5]
_A2, _A3 = UR5E_DH_A[1], UR5E_DH_A[2]
# Below this |sin q5| wrist_1 and wrist_3 are treated as one free joint.
_ALIGNED = 1e-10


def _wrapped(angle: float) -> float:
    return math.remainder(angle, 2.0 * math.pi)


def ur5e_branches(T_B_tool0: np.ndarray, q6_free: float = 0.0) -> np.ndarray:
    """The joint configurations (k <= 8, 6) placing ``tool0`` at ``T_B_tool0`` (4, 4) in
    the base frame, by the DH table; ordered by (shoulder root, wrist side, elbow side).
    Empty (0, 6) when the pose is out of reach."""
    T = np.asarray(T_B_tool0, dtype=float)
    (T00, T01, T02, T03), (T10, T11, T12, T13), (T20, T21, T22, T23) = T[:3].tolist()
    # Shoulder pan: the wrist centre p05 (d6 back along the flange axis) is d4 off the arm's plane.
    A, B = _D6 * T12 - T13, _D6 * T02 - T03
    R = A * A + B * B
    if R < _D4 * _D4:
        return np.zeros((0, 6))
    offset = math.acos(min(_D4 / math.sqrt(R), 1.0))
    bearing = math.atan2(-B, A)
    solutions = []
    for q1 in (bearing + offset, bearing - offset):
        c1, s1 = math.cos(q1), math.sin(q1)
        cos5 = (T03 * s1 - T13 * c1 - _D4) / _D6
        if abs(cos5) > 1.0 + 1e-12:
            continue
        acos5 = math.acos(max(-1.0, min(1.0, cos5)))
        for q5 in (acos5, -acos5):
            s5, c5 = math.sin(q5), math.cos(q5)
            if abs(s5) < _ALIGNED:
                q6 = q6_free
            else:
                q6 = math.atan2(-(T01 * s1 - T11 * c1) / s5, (T00 * s1 - T10 * c1) / s5)
            c6, s6 = math.cos(q6), math.sin(q6)
            # The planar three-link arm (q2, q3, q4) in the shoulder's plane.
            x04x = -s5 * (T02 * c1 + T12 * s1) - c5 * (s6 * (T01 * c1 + T11 * s1) - c6 * (T00 * c1 + T10 * s1))
            x04y = c5 * (T20 * c6 - T21 * s6) - T22 * s5
            p13x = (_D5 * (s6 * (T00 * c1 + T10 * s1) + c6 * (T01 * c1 + T11 * s1))
                    - _D6 * (T02 * c1 + T12 * s1) + T03 * c1 + T13 * s1)
            p13y = T23 - _D1 - _D6 * T22 + _D5 * (T21 * c6 + T20 * s6)
            cos3 = (p13x * p13x + p13y * p13y - _A2 * _A2 - _A3 * _A3) / (2.0 * _A2 * _A3)
            if abs(cos3) > 1.0 + 1e-12:
                continue
            acos3 = math.acos(max(-1.0, min(1.0, cos3)))
            for q3 in (acos3, -acos3):
                s3, c3 = math.sin(q3), math.cos(q3)
                a, b = _A2 + _A3 * c3, _A3 * s3
                q2 = math.atan2(a * p13y - b * p13x, a * p13x + b * p13y)
                c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
                q4 = math.atan2(c23 * x04y - s23 * x04x, x04x * c23 + x04y * s23)
                solutions.append([_wrapped(q1), _wrapped(q2), _wrapped(q3), _wrapped(q4), _wrapped(q5),
                                  _wrapped(q6)])
    return np.array(solutions, dtype=float).reshape(-1, 6)


def shoulder_pan_roots(T_B_tool0: np.ndarray) -> np.ndarray:
    """The two shoulder_pan angles (m, 2) that place ``tool0`` at each pose of ``T_B_tool0``
    (m, 4, 4): the roots :func:`ur5e_branches` takes, ``bearing + offset`` then ``bearing -
    offset`` (each branch's q1 is one of them); NaN where the wrist centre is within
    ``d4`` of the base axis. Along a joint path that keeps off the shoulder singularity
    the root stays the same, so the pan a path must sweep follows from its poses alone."""
    T = np.asarray(T_B_tool0, dtype=float)
    A, B = _D6 * T[:, 1, 2] - T[:, 1, 3], _D6 * T[:, 0, 2] - T[:, 0, 3]
    radius = np.sqrt(A * A + B * B)
    with np.errstate(invalid="ignore", divide="ignore"):
        offset = np.where(radius >= _D4, np.arccos(np.minimum(_D4 / radius, 1.0)), np.nan)
    bearing = np.arctan2(-B, A)
    return np.stack([bearing + offset, bearing - offset], axis=1)
