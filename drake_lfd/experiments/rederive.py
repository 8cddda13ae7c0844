"""Re-derive a closed-loop run's verdict from its logged joint trajectory alone.

The simulator's own judge (``closed_loop.judge_run``) uses the plant and the monitor.
This module recomputes the success criteria (docs/method.rst, Closed loop and success) from what ``simulate --json`` logs (``t``,
``q``, the critical configurations and when each was due) with independent means:

* forward kinematics from Universal Robots' DH table in numpy (not the URDF, not
  Drake; the batch kernel of :mod:`drake_lfd.robot.dh_kinematics`):
  ``X_WE = X_WB * DH(q) * X_tool0_E``;
* joint speeds by finite differences of the logged positions;
* clearances to obstacles and shells re-queried on a separate kinematics-only scene
  (``scene.KinematicScene``) at the logged configurations.

Not for: judging during simulation.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from drake_lfd.robot.analytic_ik import UR5E_DH_A, UR5E_DH_D
from drake_lfd.robot.dh_kinematics import DHArm

__all__ = [
    'DH_D',
    'DH_A',
    'DH_ALPHA',
    'POSITION_LIMITS',
    'SPEED_LIMIT',
    'dh_forward_kinematics',
    'Rederivation',
    'rederive_run',
]

# Universal Robots' UR5e DH parameters and joint limits (data sheet).
DH_D = np.array(UR5E_DH_D)
DH_A = np.array(UR5E_DH_A)
DH_ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])
POSITION_LIMITS = np.array([2 * np.pi, 2 * np.pi, np.pi, 2 * np.pi, 2 * np.pi, 2 * np.pi])
SPEED_LIMIT = np.pi  # 180 deg/s, every joint
_TOOL0 = DHArm()  # the chain to tool0 (E = tool0)


def dh_forward_kinematics(q: np.ndarray) -> np.ndarray:
    """tool0 in the base frame from the DH table, q (m, 6) -> (m, 4, 4)."""
    return _TOOL0.poses_batch(q)


def _rotation_angle(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """Angle of R_a^T R_b, (...,)."""
    trace = np.einsum("...ij,...ij->...", R_a, R_b)
    return np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))


def _R_from_euler_zyx(euler_zyx) -> np.ndarray:
    yaw, pitch, roll = euler_zyx
    return RollPitchYaw(roll, pitch, yaw).ToRotationMatrix().matrix()


@dataclasses.dataclass(frozen=True)
class Rederivation:
    success: bool
    failures: list[str]
    critical_errors: list[tuple[float, float]]  # (position m, rotation rad) per con
    min_clearance_m: float
    max_speed_fraction: float


def rederive_run(
    t,
    q,
    *,
    critical_times_s,
    critical_configurations,
    X_WB: RigidTransform,
    X_tool0_E: RigidTransform,
    path_constraints=(),
    obstacles=(),
    safety_shells=(),
    tool=None,
    position_tolerance_m: float = 0.005,
    rotation_tolerance_rad: float = np.radians(2.0),
    clearance_stride: int = 5,
) -> Rederivation:
    """The verdict of one run recomputed from its log.

    ``critical_configurations`` are ``{"p", "euler_zyx"}`` records (as in the JSON) and
    ``critical_times_s`` when each was due; path constraints are ``tasks.PathConstraint``;
    ``tool`` the task's tool shapes (None: the default of ``X_tool0_E``), checked against
    the boxes like the links.
    """
    t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
    X_E = X_WB.GetAsMatrix4() @ dh_forward_kinematics(q) @ X_tool0_E.GetAsMatrix4()
    failures, errors = [], []
    for number, (con, due) in enumerate(zip(critical_configurations, critical_times_s), start=1):
        index = int(np.argmin(np.abs(t - due)))
        position = float(np.linalg.norm(X_E[index, :3, 3] - np.asarray(con["p"])))
        rotation = float(_rotation_angle(X_E[index, :3, :3], _R_from_euler_zyx(con["euler_zyx"])))
        errors.append((position, rotation))
        if position > position_tolerance_m or rotation > rotation_tolerance_rad:
            failures.append(f"con_{number}: {position * 1e3:.1f} mm, {np.degrees(rotation):.2f} deg")
    for constraint in path_constraints:
        start = critical_times_s[constraint.con_from - 1]
        end = critical_times_s[constraint.con_to - 1]
        window = (t >= start) & (t <= end)
        deviation = _rotation_angle(X_E[window, :3, :3], _R_from_euler_zyx(constraint.euler_zyx)[None])
        worst = float(deviation.max(initial=0.0))
        if worst > constraint.tolerance_rad:
            failures.append(f"orientation con_{constraint.con_from}..con_{constraint.con_to}: "
                            f"{np.degrees(worst):.1f} deg")
    outside = np.abs(q) > POSITION_LIMITS + 1e-9
    if outside.any():
        failures.append(f"joint position limit exceeded ({int(outside.sum())} samples)")
    speed = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None] if len(t) > 1 else np.zeros((0, 6))
    max_speed_fraction = float(speed.max(initial=0.0) / SPEED_LIMIT)
    if max_speed_fraction > 1.0:
        failures.append(f"joint speed {max_speed_fraction * SPEED_LIMIT:.2f} rad/s > pi")
    min_clearance = np.inf
    if obstacles or safety_shells:
        from drake_lfd.robot.scene import KinematicScene

        scene = KinematicScene(X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles, safety_shells=safety_shells,
                               tool=tool)
        for configuration in q[::clearance_stride]:
            min_clearance = min(min_clearance, float(scene.signed_distances(configuration).min()))
        if min_clearance <= 0.0:
            failures.append(f"penetration: clearance {min_clearance * 1e3:.1f} mm")
    return Rederivation(not failures, failures, errors, min_clearance, max_speed_fraction)
