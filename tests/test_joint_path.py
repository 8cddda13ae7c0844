"""The plan-time joint-space check: the controller's law followed kinematically, with the
UR5e's singularities, joint limits (and the 2 pi windings of the start), reach and
clearance checked along the way."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.tree import JacobianWrtVariable

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.tasks import Box
from drake_lfd.core.timing import time_plan
from drake_lfd.robot.dh_kinematics import shoulder_singularity_distance, ur5e_reach_m
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import KinematicScene

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])


def _plan_through(X_list, critical=None):
    poses = dual_quaternion_from_matrices(np.array([X.GetAsMatrix4() for X in X_list]))
    critical = [0, len(X_list) - 1] if critical is None else critical
    return time_plan(poses, critical)


def test_jacobian_determinant_vanishes_exactly_at_the_three_singularities():
    """det J = a2 a3 sin q3 sin q5 * (wrist point's distance from the shoulder axis)."""
    kinematics = UR5eKinematics()
    plant, context = kinematics.plant, kinematics.context
    frame = plant.GetFrameByName("tool0")
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-3, 3, 6)
        plant.SetPositions(context, q)
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, frame, np.zeros(3),
                                              plant.world_frame(), plant.world_frame())
        predicted = 0.425 * 0.3922 * math.sin(q[2]) * math.sin(q[4]) * shoulder_singularity_distance(q)
        assert abs(np.linalg.det(J)) == pytest.approx(abs(predicted), rel=1e-9, abs=1e-12)


def test_a_stretching_motion_is_blocked_at_the_elbow_singularity():
    kinematics = UR5eKinematics()
    X_start = kinematics.X_WE(Q_HOME)
    # Straight out along the arm's reach direction until the arm would be straight.
    direction = np.append(X_start.translation()[:2], 0.0)
    direction /= np.linalg.norm(direction)
    X_end = RigidTransform(X_start.rotation(), X_start.translation() + 0.45 * direction)
    X_list = [RigidTransform(X_start.rotation(), X_start.translation() + s * 0.45 * direction)
              for s in np.linspace(0, 1, 40)]
    checker = JointPathChecker(KinematicScene())
    path = checker.follow(_plan_through(X_list), Q_HOME)
    assert path.blocker is not None and path.blocker.reason in ("singularity", "reach")
    assert "elbow" in path.blocker.detail or "speed limit" in path.blocker.detail
    assert path.min_elbow < 0.2  # it got close before being stopped
    assert X_end is not None


def test_an_executable_motion_passes_and_reaches_its_configurations():
    kinematics = UR5eKinematics()
    q_end = Q_HOME + np.array([0.4, 0.1, -0.2, 0.1, 0.2, 0.3])
    X_list = [kinematics.X_WE(Q_HOME + s * (q_end - Q_HOME)) for s in np.linspace(0, 1, 30)]
    checker = JointPathChecker(KinematicScene())
    path = checker.follow(_plan_through(X_list, [0, 15, 29]), Q_HOME)
    assert path.executable, path.blocker
    assert len(path.critical_errors) == 3
    assert max(e[0] for e in path.critical_errors) < 5e-4
    np.testing.assert_allclose(path.q[0], Q_HOME)
    np.testing.assert_allclose(kinematics.X_WE(path.q[-1]).translation(), X_list[-1].translation(), atol=5e-4)
    assert np.all(np.diff(path.t) == pytest.approx(checker.time_step))


def test_wrist_3_winding_is_chosen_for_the_whole_plan():
    """A task twisting the tool by +4.8 rad: from wrist 3 at 1.99 rad it runs into the
    +2 pi limit; the checker then starts one turn lower, at 1.99 - 2 pi, and it runs."""
    kinematics = UR5eKinematics()
    q0 = Q_HOME.copy()
    q0[5] = 1.99
    X0 = kinematics.X_WE(q0)
    X_list = [RigidTransform(X0.rotation().multiply(RotationMatrix.MakeZRotation(a)), X0.translation())
              for a in np.linspace(0.0, 4.8, 49)]
    plan = _plan_through(X_list, [0, 24, 48])
    checker = JointPathChecker(KinematicScene())
    blocked = checker.follow(plan, q0)
    assert blocked.blocker is not None and blocked.blocker.reason == "joint_limit"
    assert "wrist_3_joint" in blocked.blocker.detail
    path = checker.follow_from_candidates(plan, [q0])
    assert path.executable, path.blocker
    assert path.q[0][5] == pytest.approx(1.99 - 2 * math.pi)
    assert path.q[-1][5] == pytest.approx(1.99 - 2 * math.pi + 4.8, abs=1e-3)


def test_a_link_passing_through_a_shell_is_a_collision_naming_both():
    kinematics = UR5eKinematics()
    q_end = Q_HOME + np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.0])
    X_list = [kinematics.X_WE(Q_HOME + s * (q_end - Q_HOME)) for s in np.linspace(0, 1, 30)]
    # A small shell where the wrist passes halfway (the arm turns about the base).
    q_mid = Q_HOME + 0.5 * (q_end - Q_HOME)
    kinematics.plant.SetPositions(kinematics.context, q_mid)
    p_wrist = kinematics.plant.GetFrameByName("wrist_1_link").CalcPoseInWorld(kinematics.context).translation()
    shell = Box(name="shell", centre=p_wrist, size=[0.06, 0.06, 0.06])
    checker = JointPathChecker(KinematicScene(safety_shells=[shell]))
    path = checker.follow(_plan_through(X_list), Q_HOME)
    assert path.blocker is not None and path.blocker.reason == "collision"
    assert "safety shell 'shell'" in path.blocker.detail and "wrist" in path.blocker.detail
    assert 0.0 < path.blocker.time_s < 0.5 * _plan_through(X_list).duration


def test_resuming_a_shared_prefix_gives_the_same_path():
    kinematics = UR5eKinematics()
    q_mid = Q_HOME + np.array([0.3, 0.1, -0.2, 0.1, 0.2, 0.3])
    q_end_a = q_mid + np.array([0.2, 0.0, 0.1, 0.0, 0.0, 0.0])
    q_end_b = q_mid + np.array([-0.2, 0.05, 0.0, 0.0, 0.1, 0.0])
    first = [kinematics.X_WE(Q_HOME + s * (q_mid - Q_HOME)) for s in np.linspace(0, 1, 20)]
    plan_a = _plan_through(first + [kinematics.X_WE(q_mid + s * (q_end_a - q_mid)) for s in np.linspace(0, 1, 20)[1:]],
                           [0, 19, 38])
    plan_b = _plan_through(first + [kinematics.X_WE(q_mid + s * (q_end_b - q_mid)) for s in np.linspace(0, 1, 20)[1:]],
                           [0, 19, 38])
    checker = JointPathChecker(KinematicScene())
    checker.follow_from_candidates(plan_a, [Q_HOME])
    resumed = checker.follow_from_candidates(plan_b, [Q_HOME])
    full = JointPathChecker(KinematicScene()).follow(plan_b, Q_HOME)
    np.testing.assert_array_equal(resumed.q, full.q)
    assert resumed.critical_errors == full.critical_errors


def test_reach_bound_covers_the_stretched_arm():
    kinematics = UR5eKinematics()
    q = np.zeros(6)  # the UR5e's zero: arm stretched horizontally
    shoulder = np.array([0.0, 0.0, 0.1625])
    assert np.linalg.norm(kinematics.X_Wtool0(q).translation() - shoulder) <= ur5e_reach_m()


def test_a_tool_entering_a_shell_is_found_at_plan_time_by_its_name():
    """Only the tool (a 25 cm rod below the flange) would enter the shell: the arm's links
    stay clear, so without the tool's geometry the same plan would pass."""
    from drake_lfd.core.tool import ToolShape

    kinematics = UR5eKinematics()
    q_end = Q_HOME + np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
    X_list = [kinematics.X_WE(Q_HOME + s * (q_end - Q_HOME)) for s in np.linspace(0, 1, 30)]
    rod = ToolShape.cylinder("rod", 0.01, 0.25, RigidTransform([0.0, 0.0, 0.125]))
    # A shell under the flange halfway: the rod's far end passes through it.
    q_mid = Q_HOME + 0.5 * (q_end - Q_HOME)
    X_mid = kinematics.X_Wtool0(q_mid)
    tip = X_mid.multiply(np.array([0.0, 0.0, 0.22]))
    shell = Box(name="shell", centre=tip, size=[0.06, 0.06, 0.06])
    plan = _plan_through(X_list)
    without_tool = JointPathChecker(KinematicScene(safety_shells=[shell], tool=())).follow(plan, Q_HOME)
    assert without_tool.executable, without_tool.blocker
    with_tool = JointPathChecker(KinematicScene(safety_shells=[shell], tool=(rod,))).follow(plan, Q_HOME)
    assert with_tool.blocker is not None and with_tool.blocker.reason == "collision"
    assert "tool/rod" in with_tool.blocker.detail and "safety shell 'shell'" in with_tool.blocker.detail


def test_a_clearance_shortfall_is_printed_with_the_digits_that_show_it():
    from drake_lfd.robot.joint_path_records import describe_clearance_shortfall, describe_shoulder_shortfall

    # 9.96 mm under a 10 mm clearance used to read "passes 10.0 mm": the reason was invisible.
    assert describe_clearance_shortfall("safety shell 'box_shell'", 0.00996, 0.01) == (
        "passes 9.96 mm from safety shell 'box_shell' (clearance 10 mm)")
    assert describe_clearance_shortfall("the table", 0.004, 0.01) == "passes 4.0 mm from the table (clearance 10 mm)"
    assert describe_clearance_shortfall("the table", -0.002, 0.01) == "enters the table by 2.0 mm"
    assert describe_shoulder_shortfall(0.04996, 0.05) == "wrist centre 49.96 mm from the shoulder axis (< 50 mm)"
