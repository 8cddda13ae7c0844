"""Timing of a plan: the UR5e's motion limits, and the geometric pass over an SE(3) plan.

:class:`TimingLimits` holds the limits a plan's timing keeps to (a task file's
``timing:`` block): the executed timing is the time-optimal parametrization of the
plan's checked joint path under them (:mod:`drake_lfd.robot.path_timing`, Drake's
``Toppra``). :func:`time_plan` below is the *geometric* pass that comes first: it lays
the SE(3) plan out in time slowly and at rest at each critical configuration, so the
plan-time joint check (:mod:`drake_lfd.robot.joint_path`) can follow it with the
controller's law and record the joint path the arm will take; without that check (a
plan made with ``joint_check`` off) it is also the executed timing.

The geometric pass:

A plan is a sequence of poses X_WE through which the critical configurations pass at
known indices. Spans between consecutive critical configurations were mapped from
different demonstrations, so the path direction may turn sharply at a join. The timing
law therefore brings the tool to rest at every critical configuration: each span follows
a minimum-jerk profile (zero velocity and acceleration at both ends), so velocity is
continuous everywhere (zero at joins) and the tool reaches each critical configuration
without overshoot. Within a span the speed is capped by a maximum TCP speed and angular
speed (defaults for collaborative work: 0.25 m/s, 1 rad/s).

See ``docs/method.rst``, *Timing*. :func:`time_plan` checks its inputs (unit dual
quaternions, critical indices, positive speed limits) and raises ValueError.

This module does not choose or map demonstrations (planning and mapping modules do).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydrake.math import RigidTransform
from pydrake.trajectories import PiecewisePose

from drake_lfd.core.dual_quaternion import (
    check_unit_dual_quaternions,
    rotation_from_dual_quaternion,
    translation_from_dual_quaternion,
)
from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion
from drake_lfd.core.quaternion import axis_angle_from_quaternion, quaternion_conjugate, quaternion_multiply

__all__ = [
    "TimingLimits",
    "DEFAULT_MAX_SPEED_M_S",
    "DEFAULT_MAX_ANGULAR_SPEED_RAD_S",
    "MIN_SPAN_DURATION_S",
    "TimedPlan",
    "time_plan",
]

DEFAULT_MAX_SPEED_M_S = 0.25
DEFAULT_MAX_ANGULAR_SPEED_RAD_S = 1.0
# Shortest span between two critical configurations (s); a span that does not move holds
# its pose this long.
MIN_SPAN_DURATION_S = 0.2
# Peak of d/dtau of the minimum-jerk profile 10 tau^3 - 15 tau^4 + 6 tau^5.
_MINIMUM_JERK_PEAK_RATE = 1.875


@dataclass(frozen=True)
class TimingLimits:
    """What a plan's timing keeps to (a task file's ``timing:`` block; docs/task_files.rst).

    Attributes
    ----------
    joint_speed_rad_s : float
        Every joint's speed limit: pi (180 deg/s), the UR5e datasheet's figure for all
        six joints.
    joint_acceleration_rad_s2 : float
        Every joint's acceleration limit: 8 rad/s^2. Universal Robots publish none (the
        joints are limited by torque); their own MoveIt configuration for the e-Series
        picks 5-10 rad/s^2 as conservative values for time parametrization. At 8 rad/s^2
        the shoulder, with the arm outstretched (about 3 kg m^2), needs about 24 N m on top
        of gravity, far below the 150 N m its joint size can give.
    tool_speed_m_s : float
        Limit on the speed of E: 1.5 m/s, UR's default safety-system tool speed limit.
    tool_acceleration_m_s2 : float or None
        Optional limit on the linear acceleration of E (a task carrying water), applied
        per world axis as ``a / sqrt(3)`` so the magnitude never exceeds it.
    limit_fraction : float
        The fraction of the joint and tool limits the plan uses (0.9); the rest is the
        controller's room to correct tracking errors without exceeding the limits.
    """

    joint_speed_rad_s: float = math.pi
    joint_acceleration_rad_s2: float = 8.0
    tool_speed_m_s: float = 1.5
    tool_acceleration_m_s2: float | None = None
    limit_fraction: float = 0.9

    def __post_init__(self):
        for name in ("joint_speed_rad_s", "joint_acceleration_rad_s2", "tool_speed_m_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        a = self.tool_acceleration_m_s2
        if a is not None and not (math.isfinite(a) and a > 0.0):
            raise ValueError(f"tool_acceleration_m_s2 must be finite and > 0, got {a}")
        if not 0.0 < self.limit_fraction <= 1.0:
            raise ValueError(f"limit_fraction must be in (0, 1], got {self.limit_fraction}")


@dataclass(frozen=True)
class TimedPlan:
    """End-effector poses with times.

    Attributes
    ----------
    times : array, shape (n,)
        Seconds, strictly increasing, starting at 0.
    poses : array, shape (n, 8)
        Unit dual quaternions of X_WE.
    critical_indices : tuple of int
        Index into ``poses`` where each con_i is met.

    Notes
    -----
    The constructor does not check these (:func:`time_plan` builds valid plans).
    """

    times: NDArray[np.float64]
    poses: NDArray[np.float64]
    critical_indices: tuple[int, ...]

    @property
    def duration(self) -> float:
        """Time of the last pose (s)."""
        return float(self.times[-1])

    def X_WE_list(self) -> list[RigidTransform]:
        """The poses as pydrake ``RigidTransform`` objects, one per sample."""
        return [RigidTransform(T) for T in matrices_from_dual_quaternion(self.poses)]

    def X_WE_critical(self) -> list[RigidTransform]:
        """The poses of the critical configurations (the samples at ``critical_indices``),
        as :meth:`X_WE_list` gives them."""
        return [RigidTransform(T) for T in matrices_from_dual_quaternion(self.poses[list(self.critical_indices)])]

    def to_piecewise_pose(self) -> PiecewisePose:
        """Linear in position, slerp in rotation between the (dense) samples."""
        return PiecewisePose.MakeLinear(list(self.times), self.X_WE_list())


def _minimum_jerk(tau: np.ndarray) -> np.ndarray:
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def _full_speed_step_durations_s(poses: np.ndarray, max_speed: float, max_angular_speed: float) -> np.ndarray:
    """Time each step would take at full speed: max(|dp| / v, dtheta / omega), shape (n-1,)."""
    p = translation_from_dual_quaternion(poses)
    r = rotation_from_dual_quaternion(poses)
    dp = np.linalg.norm(np.diff(p, axis=0), axis=1)
    relative = quaternion_multiply(quaternion_conjugate(r[:-1]), r[1:])
    _, dtheta = axis_angle_from_quaternion(relative)
    return np.maximum(dp / max_speed, dtheta / max_angular_speed)


def time_plan(
    poses: ArrayLike,
    critical_indices: Sequence[int] | ArrayLike,
    *,
    max_speed_m_s: float = DEFAULT_MAX_SPEED_M_S,
    max_angular_speed_rad_s: float = DEFAULT_MAX_ANGULAR_SPEED_RAD_S,
) -> TimedPlan:
    """Attaches times to ``poses``, at rest at each of ``critical_indices``.

    Each span between consecutive critical indices lasts
    ``max(1.875 * L, MIN_SPAN_DURATION_S)`` where L is its duration at full speed, so the
    minimum-jerk profile's peak speed equals the cap. Consecutive duplicate poses inside
    a span are dropped (they would need zero time); the returned ``critical_indices``
    refer to the returned poses.

    Parameters
    ----------
    poses : array-like, shape (n, 8)
        The plan's poses X_WE (unit dual quaternions).
    critical_indices : sequence of int, shape (k,)
        Where the critical configurations are met, increasing from 0 to n - 1.
    max_speed_m_s, max_angular_speed_rad_s : float
        Caps on the tool's speed and angular speed, > 0.

    Returns
    -------
    plan : TimedPlan
        New arrays (nothing shared with ``poses``).

    Raises
    ------
    ValueError
        If ``poses`` are not unit dual quaternions of shape (n, 8), the critical indices
        do not increase from 0 to n - 1, or a speed cap is not positive.
    """
    poses = check_unit_dual_quaternions(poses, "poses")
    if poses.ndim != 2 or len(poses) == 0:
        raise ValueError(f"poses must have shape (n >= 1, 8), got {poses.shape}")
    critical = [int(i) for i in np.asarray(critical_indices).ravel()]
    if not critical or critical[0] != 0 or critical[-1] != len(poses) - 1 or np.any(np.diff(critical) <= 0):
        raise ValueError(f"critical_indices must increase from 0 to {len(poses) - 1}: {critical}")
    if not (max_speed_m_s > 0.0 and max_angular_speed_rad_s > 0.0):
        raise ValueError(f"max_speed_m_s and max_angular_speed_rad_s must be > 0, got {max_speed_m_s} "
                         f"and {max_angular_speed_rad_s}")
    full_speed_durations = _full_speed_step_durations_s(poses, max_speed_m_s, max_angular_speed_rad_s)

    times = [0.0]
    kept = [poses[0]]
    new_critical = [0]
    t_start = 0.0
    for first, last in zip(critical[:-1], critical[1:]):
        # Time at which each sample of the span would be reached at full speed.
        elapsed = np.concatenate([[0.0], np.cumsum(full_speed_durations[first:last])])
        total = elapsed[-1]
        duration = max(_MINIMUM_JERK_PEAK_RATE * total, MIN_SPAN_DURATION_S)
        if total <= 1e-12:
            # The span does not move: hold the pose for the minimum duration.
            times.append(t_start + duration)
            kept.append(poses[last])
        else:
            # Invert the monotone profile on a fine grid: time at which each sample is due.
            tau_grid = np.linspace(0.0, 1.0, 2001)
            tau = np.interp(elapsed / total, _minimum_jerk(tau_grid), tau_grid)
            for k in range(1, len(elapsed)):
                is_last = k == len(elapsed) - 1
                if not is_last and elapsed[k] - elapsed[k - 1] <= 1e-12:
                    continue
                t = t_start + (duration if is_last else tau[k] * duration)
                if t - times[-1] <= 1e-9:
                    continue
                times.append(t)
                kept.append(poses[first + k])
        t_start = times[-1]
        new_critical.append(len(kept) - 1)
    return TimedPlan(np.array(times), np.array(kept), tuple(new_critical))
