"""The constraints the trajectory program writes itself, beside Drake's ready-made ones.

- :func:`add_rotation_target`: E's rotation at a target, as position boxes of two points
  1 m out on E's axes (well scaled, unlike the trace bound of an
  ``OrientationConstraint``);
- :func:`add_pass_speed_bound`: E's speed at a target, linear in the control points and
  the duration;
- :func:`add_shoulder_margin`: the wrist centre away from the shoulder axis, on the side
  both ends are on (a one-sided ``PositionConstraint`` in the shoulder link's frame);
- :func:`singularity_free_interval`: the elbow's or the wrist's interval free of its
  singularity that both ends lie in (the program narrows those joints' bounds to it).

Not for: building or solving the program (``trajectory_optimization.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pydrake.multibody.inverse_kinematics import PositionConstraint
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.trajectories import BsplineTrajectory

from drake_lfd.robot.dh_kinematics import shoulder_singularity_distance
from drake_lfd.robot.optimization_records import PoseTarget
from drake_lfd.robot.optimization_scene import OptimizationScene

__all__ = [
    "SHOULDER_FRAME_NAME",
    "WRIST_CENTRE_FRAME_NAME",
    "add_pass_speed_bound",
    "add_shoulder_margin",
    "add_rotation_target",
    "singularity_free_interval",
]


def add_pass_speed_bound(trajopt: KinematicTrajectoryOptimization, J: np.ndarray, s: float,
                          speed_m_s: float) -> None:
    """E's velocity ``J q'(s) / T`` at path fraction ``s`` within ``speed_m_s`` along each
    axis, for a fixed Jacobian ``J`` (3, n): as ``|J q'(s)| <= speed T``, linear in the
    control points and the duration ``T`` (``q'(s)`` is a fixed combination of the
    control points). Drake's ``AddVelocityConstraintAtNormalizedTime`` would take a
    general constraint on (q, v) and differentiate it through the whole spline at
    every evaluation, which makes each evaluation of the program several times dearer."""
    basis = trajopt.basis()
    count = trajopt.num_control_points()
    weights = np.array([
        BsplineTrajectory(basis, [np.array([[1.0 if k == i else 0.0]]) for k in range(count)]).MakeDerivative()
        .value(float(s))[0, 0] for i in range(count)])
    control = np.asarray(trajopt.control_points())  # (n, count) of variables
    n = control.shape[0]
    variables = [control[j, i] for i in range(count) for j in range(n)] + [trajopt.duration()]
    A = np.zeros((3, count * n + 1))
    for i in range(count):
        A[:, i * n:(i + 1) * n] = weights[i] * J
    upper, lower = A.copy(), A.copy()
    upper[:, -1], lower[:, -1] = -speed_m_s, speed_m_s
    prog = trajopt.get_mutable_prog()
    prog.AddLinearConstraint(upper, np.full(3, -np.inf), np.zeros(3), variables)
    prog.AddLinearConstraint(lower, np.zeros(3), np.full(3, np.inf), variables)


# The wrist centre's signed distance from the shoulder axis
# (``dh_kinematics.shoulder_singularity_distance``) is the x coordinate, in the shoulder
# link's frame, of the wrist-2 link's origin (tests/test_trajectory_optimization.py
# checks this on random configurations).
SHOULDER_FRAME_NAME, WRIST_CENTRE_FRAME_NAME = "shoulder_link", "wrist_2_link"


def add_shoulder_margin(trajopt: KinematicTrajectoryOptimization, scene: OptimizationScene,
                         q_ends: Sequence[np.ndarray], fractions: np.ndarray, margin_m: float) -> bool:
    """The wrist centre at least ``margin_m`` from the shoulder axis at each path
    fraction of ``fractions``, on the side the ends ``q_ends`` (two (6,) configurations)
    lie on. "Outside a cylinder" is not convex, but on a fixed side it is a half space
    in the shoulder link's frame (which turns with q1): one Drake ``PositionConstraint``
    with a one-sided bound on x, evaluated in C++ like the other path constraints. The
    margin is lowered to the ends' own distance where that is less (the ends are fixed).
    False (nothing added) when the ends lie on opposite sides or there is no fraction."""
    ends = [shoulder_singularity_distance(q) for q in q_ends]
    if ends[0] * ends[1] <= 0.0 or not len(fractions):
        return False
    margin_m = min(margin_m, abs(ends[0]), abs(ends[1]))
    lower, upper = np.full(3, -np.inf), np.full(3, np.inf)
    if ends[0] > 0:
        lower[0] = margin_m
    else:
        upper[0] = -margin_m
    plant = scene.plant
    constraint = PositionConstraint(plant, plant.GetFrameByName(SHOULDER_FRAME_NAME, scene.model), lower, upper,
                                    plant.GetFrameByName(WRIST_CENTRE_FRAME_NAME, scene.model), np.zeros(3),
                                    scene.plant_context)
    for s in fractions:
        trajopt.AddPathPositionConstraint(constraint, float(s))
    return True


# The lever of a rotation target's points (m): E's rotation is held through the positions
# of points this far along E's x and y axes.
_ROTATION_LEVER_M = 1.0


def add_rotation_target(trajopt: KinematicTrajectoryOptimization, scene: OptimizationScene,
                         target: PoseTarget) -> None:
    """E's rotation within about ``target.rotation_tolerance_rad`` of the target's at its
    path fraction, as position boxes of the points 1 m along E's x and y axes.

    An ``OrientationConstraint`` bounds ``trace(R_error)``, whose gradient vanishes as
    the error does: at 0.3 deg a violation of 4.6e-5 in it is 0.49 deg, so SNOPT
    declared filling and pouring (exact planner, seed 4) infeasible with con_4 0.49 deg
    off, and iterates at the iteration limit missed con_2 by 5 deg while nearly
    feasible in its measure. A point 1 m out moves 1 m per radian, as E's position does.
    With both points and E's origin within ``delta`` and ``epsilon`` of their targets on
    each axis, the rotation error is at most ``sqrt(6) (delta + epsilon) / lever``: the
    box half-width ``delta`` makes that the tolerance."""
    plant, world, frame_E = scene.plant, scene.plant.world_frame(), scene.frame_E
    lever = _ROTATION_LEVER_M
    delta = max(target.rotation_tolerance_rad * lever / math.sqrt(6.0) - target.position_tolerance_m,
                target.position_tolerance_m)
    X = target.X_WE
    for axis in (0, 1):
        p_EP = np.zeros(3)
        p_EP[axis] = lever
        p_WP = X.multiply(p_EP)
        trajopt.AddPathPositionConstraint(
            PositionConstraint(plant, world, p_WP - delta, p_WP + delta, frame_E, p_EP, scene.plant_context),
            target.s)


def singularity_free_interval(values: np.ndarray, margin: float) -> tuple[float, float] | None:
    """The interval ``[k pi + asin(margin), (k + 1) pi - asin(margin)]`` holding every
    value, or None when the values cross a singularity."""
    a = math.asin(margin)
    k = np.floor(np.asarray(values) / math.pi)
    if not np.all(k == k[0]):
        return None
    low, high = k[0] * math.pi + a, (k[0] + 1) * math.pi - a
    if np.min(values) < low or np.max(values) > high:
        return None
    return float(low), float(high)
