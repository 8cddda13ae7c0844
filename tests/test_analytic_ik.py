"""The UR5e's closed-form inverse kinematics against forward kinematics and the IK program."""

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from drake_lfd.experiments.rederive import dh_forward_kinematics
from drake_lfd.robot.analytic_ik import ur5e_branches
from drake_lfd.robot.initial_ik import initial_configuration_candidates
from drake_lfd.robot.kinematics import UR5eKinematics


def _wrapped_distance(a, b):
    return np.abs(np.remainder(np.asarray(a) - b + np.pi, 2 * np.pi) - np.pi).max(axis=-1)


def test_every_branch_reaches_the_pose_and_the_configuration_is_among_them():
    rng = np.random.default_rng(7)
    kinematics = UR5eKinematics()
    for q in rng.uniform(-np.pi, np.pi, size=(200, 6)):
        T = kinematics.X_Wtool0(q).GetAsMatrix4()
        branches = ur5e_branches(T)
        assert 1 <= len(branches) <= 8
        np.testing.assert_allclose(dh_forward_kinematics(branches), np.broadcast_to(T, (len(branches), 4, 4)),
                                   atol=1e-11)
        assert _wrapped_distance(branches, q).min() < 1e-8
        # Distinct branches: the signs of sin q3 and sin q5 and the shoulder root differ.
        assert len({tuple(np.round(b, 6)) for b in branches}) == len(branches)


def test_out_of_reach_has_no_branch():
    T = RigidTransform([1.5, 0.0, 0.3]).GetAsMatrix4()
    assert ur5e_branches(T).shape == (0, 6)


def test_closed_form_candidates_hold_every_branch_the_program_finds():
    X_tool0_E = RigidTransform(RollPitchYaw(0.0, np.pi / 2, 0.0), [0.0, 0.0, 0.2])
    X_WB = RigidTransform([-0.2, 0.7, 0.0])
    for p, rpy in (([-0.5, 0.0, 0.3], [0.0, -np.pi / 2, 0.0]), ([0.1, 0.2, 0.25], [0.3, -np.pi / 2, 0.0]),
                   ([-0.3, 0.3, 0.45], [0.5, -1.2, 0.4])):
        X_WE = RigidTransform(RollPitchYaw(rpy[2], rpy[1], rpy[0]), p)
        program = initial_configuration_candidates(X_WE, X_WB=X_WB, X_tool0_E=X_tool0_E)
        closed = initial_configuration_candidates(X_WE, X_WB=X_WB, X_tool0_E=X_tool0_E, method="closed_form")
        assert len(closed) >= len({tuple(np.round(c.q, 3)) for c in program})
        for candidate in program:  # the program's solutions are branches, within its 1e-5 tolerances
            assert min(np.abs(candidate.q - c.q).max() for c in closed) < 1e-3
        for candidate in closed:
            assert candidate.position_error_m < 1e-9 and candidate.rotation_error_rad < 1e-8
        # The preferred branch is the program's (the same ordering rules).
        assert np.abs(program[0].q - closed[0].q).max() < 1e-3
