"""The shipped UR5e model against Universal Robots' DH table, limits, offline loading."""

import subprocess
import sys

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

import drake_lfd.robot.kinematics as mut

# UR5e DH table, written here independently of the model file.
DH_D = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996]
DH_A = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0]
DH_ALPHA = [np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0]


def dh_forward_kinematics(q):
    """Standard DH: T = prod Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)."""
    T = np.eye(4)
    for qi, d, a, alpha in zip(q, DH_D, DH_A, DH_ALPHA):
        ct, st, ca, sa = np.cos(qi), np.sin(qi), np.cos(alpha), np.sin(alpha)
        T = T @ np.array(
            [
                [ct, -st * ca, st * sa, a * ct],
                [st, ct * ca, -ct * sa, a * st],
                [0.0, sa, ca, d],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
    return T


@pytest.fixture(scope="module")
def dut():
    return mut.UR5eKinematics()


def test_tool0_matches_dh_table(dut, rng):
    q_samples = rng.uniform(-2 * np.pi, 2 * np.pi, size=(500, 6))
    for q in q_samples:
        T_expected = dh_forward_kinematics(q)
        T = dut.X_Wtool0(q).GetAsMatrix4()
        np.testing.assert_allclose(T[:3, 3], T_expected[:3, 3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(T[:3, :3], T_expected[:3, :3], rtol=0, atol=1e-9)


def test_zero_configuration_is_the_published_one(dut):
    # At q = 0 the UR5e stretches along -x: x = a2 + a3, y = -(d4 + d6), z = d1 - d5.
    p = dut.X_Wtool0(np.zeros(6)).translation()
    np.testing.assert_allclose(p, [-0.8172, -0.2329, 0.0628], atol=1e-12)


def test_end_effector_frame_and_base_placement(rng):
    X_WB = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.4, -0.5, 0.6])
    X_tool0_E = RigidTransform(RollPitchYaw(0.0, 0.0, 0.5), [0.0, 0.0, 0.12])
    dut = mut.UR5eKinematics(X_WB=X_WB, X_tool0_E=X_tool0_E)
    q_samples = rng.uniform(-np.pi, np.pi, size=(50, 6))
    batch = dut.X_WE_batch(q_samples)
    for q, X in zip(q_samples, batch):
        expected = X_WB.GetAsMatrix4() @ dh_forward_kinematics(q) @ X_tool0_E.GetAsMatrix4()
        np.testing.assert_allclose(X, expected, atol=1e-9)


def test_limits(dut):
    lower, upper = dut.position_limits()
    np.testing.assert_allclose(upper, [2 * np.pi, 2 * np.pi, np.pi, 2 * np.pi, 2 * np.pi, 2 * np.pi])
    np.testing.assert_allclose(lower, -upper)
    np.testing.assert_allclose(dut.velocity_limits(), np.full(6, np.pi))  # 180 deg/s
    np.testing.assert_allclose(dut.effort_limits(), [150, 150, 150, 28, 28, 28])


def test_joint_names_and_actuators(dut):
    names = [joint.name() for joint in dut.joints]
    assert names == list(mut.UR5E_JOINT_NAMES)
    assert dut.plant.num_actuators() == 6
    assert dut.plant.num_positions() == 6


def test_model_loads_without_network(offline_env, tmp_path):
    script = (
        "import numpy as np\n"
        "from drake_lfd.robot.kinematics import UR5eKinematics\n"
        "k = UR5eKinematics()\n"
        "print(k.X_Wtool0(np.zeros(6)).translation()[0])\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script], env=offline_env, cwd=tmp_path,
        capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert abs(float(result.stdout.strip()) - (-0.8172)) < 1e-12
