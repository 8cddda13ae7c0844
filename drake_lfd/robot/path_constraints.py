"""A task's path constraints measured on a motion: how far the tool turns from the
orientation a constraint holds.

A path constraint (:class:`~drake_lfd.core.tasks.PathConstraint`) keeps the tool's
orientation within ``tolerance_rad`` of ``euler_zyx`` from one critical configuration to
another (a cup carried upright, a part pulled straight out of a fixture). Three places
read one: the joint-path check at plan time (``joint_path.py``), refinement's check of its
motion (``planning/refinement_check.py``) and the judgement of a closed-loop run
(``diagrams/judging.py``). They share this module's measure: the angle of
``R_target^T R_WE``, from the sine and cosine of the rotation (accurate near zero, where
an arc cosine is not).

A plan is checked against the tolerance less :data:`PATH_CONSTRAINT_MARGIN_RAD` (but at
least half the tolerance): the closed loop's servos lag the commanded joints, so the
run's tool turns a little more than the command does; the margin is several times the
largest such excess seen on the paper's transferring trials. A run is judged against the
tolerance itself.

Not for: following a plan (``joint_path.py``), the refinement program's own bounds
(``planning/refinement_bounds.py``).
"""

from __future__ import annotations

import math

import numpy as np

from drake_lfd.core.tasks import PathConstraint, rigid_transform_from_euler_zyx

__all__ = [
    "PATH_CONSTRAINT_MARGIN_RAD",
    "constraint_rotation",
    "orientation_deviations",
    "constraint_window",
    "allowed_deviation",
    "describe_constraint",
    "describe_deviation",
]

# How much of a constraint's tolerance a plan leaves to the closed loop's tracking lag.
PATH_CONSTRAINT_MARGIN_RAD = math.radians(1.5)


def constraint_rotation(constraint: PathConstraint) -> np.ndarray:
    """The orientation the constraint holds, R_W (3, 3)."""
    return rigid_transform_from_euler_zyx(np.zeros(3), constraint.euler_zyx).rotation().matrix()


def orientation_deviations(R_WE: np.ndarray, R_target: np.ndarray) -> np.ndarray:
    """The angles (m,) between each rotation of ``R_WE`` (m, 3, 3) and ``R_target`` (3, 3),
    rad, in [0, pi]."""
    M = np.einsum("ji,mjk->mik", np.asarray(R_target, dtype=float), np.asarray(R_WE, dtype=float))
    cosine = 0.5 * (np.trace(M, axis1=1, axis2=2) - 1.0)
    skew = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], axis=1)
    return np.arctan2(0.5 * np.linalg.norm(skew, axis=1), cosine)


def constraint_window(constraint: PathConstraint, due_s, t: np.ndarray) -> np.ndarray:
    """Which times ``t`` (m,) the constraint covers: from the due time of its first
    critical configuration to that of its last (``due_s``: every critical
    configuration's, in order)."""
    t_from, t_to = due_s[constraint.con_from - 1], due_s[constraint.con_to - 1]
    t = np.asarray(t, dtype=float)
    return (t >= t_from - 1e-9) & (t <= t_to + 1e-9)


def allowed_deviation(constraint: PathConstraint, margin_rad: float = PATH_CONSTRAINT_MARGIN_RAD) -> float:
    """The largest angle a plan may turn from the constraint's orientation: its tolerance
    less ``margin_rad``, but at least half the tolerance."""
    return max(constraint.tolerance_rad - margin_rad, 0.5 * constraint.tolerance_rad)


def describe_constraint(constraint: PathConstraint) -> str:
    """``path constraint con_6..con_7``."""
    return f"path constraint con_{constraint.con_from}..con_{constraint.con_to}"


def describe_deviation(constraint: PathConstraint, angle_rad: float, allowed_rad: float) -> str:
    """One line: the measured angle, the constraint and what it lets a plan turn, with digits
    enough to show the excess (``the tool turns 3.1 deg from euler_zyx [0.0, -1.5708, 0.0]
    where path constraint con_6..con_7 allows a plan 1.5 deg (...)``)."""
    digits = 1
    while digits < 4 and round(math.degrees(angle_rad), digits) <= round(math.degrees(allowed_rad), digits):
        digits += 1
    return (f"the tool turns {math.degrees(angle_rad):.{digits}f} deg from euler_zyx "
            f"{np.round(constraint.euler_zyx, 4).tolist()} where {describe_constraint(constraint)} allows a plan "
            f"{math.degrees(allowed_rad):g} deg (its tolerance {math.degrees(constraint.tolerance_rad):g} deg less "
            f"{math.degrees(constraint.tolerance_rad - allowed_rad):g} deg for the closed loop's tracking)")
