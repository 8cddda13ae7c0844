"""The DH kernel the joint-path check steps with equals Drake's plant and trajectories."""

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis, Quaternion
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.tree import JacobianWrtVariable

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.timing import TimedPlan
from drake_lfd.robot.differential_ik_law import pose_error
from drake_lfd.robot.dh_kinematics import DHArm, rotation_error, rotation_matrices
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import KinematicScene

X_TOOL0_E = RigidTransform(RollPitchYaw(0.3, 0.1, -0.5), [0.01, 0.02, 0.15])


def test_pose_and_jacobian_equal_the_plants():
    kinematics = UR5eKinematics(X_tool0_E=X_TOOL0_E)
    arm = DHArm(X_TOOL0_E)
    for q in np.random.default_rng(0).uniform(-3.0, 3.0, (40, 6)):
        R, p, J = arm.pose_and_jacobian(q.tolist())
        X = kinematics.X_WE(q)
        J_plant = kinematics.plant.CalcJacobianSpatialVelocity(
            kinematics.context, JacobianWrtVariable.kV, kinematics.end_effector_frame, np.zeros(3),
            kinematics.world_frame, kinematics.world_frame)
        np.testing.assert_allclose(np.reshape(R, (3, 3)), X.rotation().matrix(), atol=1e-14)
        np.testing.assert_allclose(p, X.translation(), atol=1e-14)
        np.testing.assert_allclose(J, J_plant, atol=1e-14)


def test_the_batched_table_equals_the_plants_forward_kinematics():
    X_WB = RigidTransform(RollPitchYaw(0.1, -0.05, 0.7), [0.3, -0.2, 0.8])
    kinematics = UR5eKinematics(X_WB=X_WB, X_tool0_E=X_TOOL0_E)
    q = np.random.default_rng(1).uniform(-6.0, 6.0, (200, 6))
    np.testing.assert_allclose(kinematics.X_WE_table_batch(q), kinematics.X_WE_batch(q), atol=1e-14)
    np.testing.assert_allclose(kinematics.X_WE_table_batch(q[0]), kinematics.X_WE_batch(q[:1]), atol=1e-14)
    arm = DHArm(X_TOOL0_E)
    R, p, _ = arm.pose_and_jacobian(q[5].tolist())
    np.testing.assert_allclose(arm.poses_batch(q[5:6])[0, :3, :3], np.reshape(R, (3, 3)), atol=1e-15)
    np.testing.assert_allclose(arm.poses_batch(q[5:6])[0, :3, 3], p, atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-4, 0.3, 1.5])
def test_rotation_error_is_drakes_angle_axis(angle):
    R = RollPitchYaw(0.2, -0.4, 1.0).ToRotationMatrix()
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    turn = RotationMatrix(AngleAxis(angle, axis))
    R_desired = turn.multiply(R)
    expected = pose_error(RigidTransform(R_desired, [0, 0, 0]), RigidTransform(R, [0, 0, 0]))[:3]
    got = rotation_error(R_desired.matrix().ravel().tolist(), R.matrix().ravel().tolist())
    np.testing.assert_allclose(got, expected, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(got), angle, atol=1e-15)


def test_beyond_a_quarter_turn_the_caller_is_told_to_use_drakes():
    R = RollPitchYaw(0.0, 0.0, 2.0).ToRotationMatrix().matrix().ravel().tolist()
    assert rotation_error(R, np.eye(3).ravel().tolist()) is None


def test_the_checkers_plan_samples_equal_drakes_piecewise_pose():
    rng = np.random.default_rng(3)
    X = [RigidTransform(RollPitchYaw(*rng.normal(size=3)), rng.normal(size=3)) for _ in range(6)]
    times = np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.4, 5)])
    plan = TimedPlan(times, dual_quaternion_from_matrices(np.stack([x.GetAsMatrix4() for x in X])), (0, 5))
    X_WB = RigidTransform(RollPitchYaw(0.0, 0.0, 0.7), [0.2, -0.1, 0.8])
    checker = JointPathChecker(KinematicScene(X_WB=X_WB), X_WB=X_WB)
    t = np.arange(0, int(plan.duration / 0.01) + 5) * 0.01
    in_base, R_W, p_W, V_W = checker._desired_in_base(plan, t)
    in_base = np.array(in_base)
    R_B, p_B, V_B = in_base[:, :9].reshape(-1, 3, 3), in_base[:, 9:12], in_base[:, 12:]
    trajectory = plan.to_piecewise_pose()
    velocity = trajectory.MakeDerivative().vector_values(np.minimum(t, plan.duration))
    velocity[:, t >= plan.duration] = 0.0
    for i, x in enumerate(np.minimum(t, plan.duration)):
        pose = trajectory.GetPose(x)
        np.testing.assert_allclose(R_W[i], pose.rotation().matrix(), atol=1e-14)
        np.testing.assert_allclose(p_W[i], pose.translation(), atol=1e-14)
        X_B = X_WB.inverse().multiply(pose)
        np.testing.assert_allclose(R_B[i], X_B.rotation().matrix(), atol=1e-14)
        np.testing.assert_allclose(p_B[i], X_B.translation(), atol=1e-14)
    np.testing.assert_allclose(V_W, velocity.T, atol=1e-12)
    R_WB = X_WB.rotation().matrix()
    np.testing.assert_allclose(V_B, np.hstack([V_W[:, :3] @ R_WB, V_W[:, 3:] @ R_WB]), atol=1e-15)


def test_rotation_matrices_of_quaternions():
    q = np.random.default_rng(5).normal(size=(10, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    for quaternion, R in zip(q, rotation_matrices(q)):
        np.testing.assert_allclose(R, RotationMatrix(Quaternion(quaternion)).matrix(), atol=1e-15)
