"""TOPP-RA with closed-form stage programs against Drake's Toppra (CLP) on the same grid."""

import math

import numpy as np
import pytest
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.trajectories import PiecewisePolynomial

from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.toppra import path_constraints, solve_parametrization

KINEMATICS = UR5eKinematics()


def _path(seed: int, knots: int = 9) -> PiecewisePolynomial:
    rng = np.random.default_rng(seed)
    q = np.cumsum(rng.normal(scale=0.35, size=(knots, 6)), axis=0) + [0.0, -1.2, 1.5, -1.9, -1.5, 0.0]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s, q.T, periodic_end_condition=False)


def _grid(path):
    grid = np.unique(np.concatenate([Toppra.CalcGridPoints(path, CalcGridPointsOptions()),
                                     np.asarray(path.get_segment_times())]))
    grid[-1] = path.end_time()
    return grid


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("tool_acceleration", [None, 2.0])
def test_closed_form_equals_drakes_toppra(seed, tool_acceleration):
    path, frame, plant = _path(seed), KINEMATICS.end_effector_frame, KINEMATICS.plant
    grid = _grid(path)
    v, a, tool_speed = np.full(6, 0.9 * math.pi), np.full(6, 7.2), 1.35
    toppra = Toppra(path, plant, grid)
    toppra.AddJointVelocityLimit(-v, v)
    toppra.AddJointAccelerationLimit(-a, a)
    toppra.AddFrameTranslationalSpeedLimit(frame, tool_speed)
    bound = None
    if tool_acceleration is not None:
        bound = np.array([np.inf] * 3 + [tool_acceleration] * 3)
        toppra.AddFrameAccelerationLimit(frame, -bound, bound)
    expected = toppra.SolvePathParameterization()
    actual = solve_parametrization(path_constraints(path, grid, plant, frame, joint_speed=v, joint_acceleration=a,
                                                    tool_speed=tool_speed, tool_acceleration=bound))
    assert expected is not None and actual is not None
    assert actual.end_time() == pytest.approx(expected.end_time(), rel=1e-9)
    t = np.linspace(0.0, expected.end_time(), 300)
    np.testing.assert_allclose(actual.vector_values(t), expected.vector_values(t), atol=1e-9)
    np.testing.assert_allclose(actual.get_segment_times(), expected.get_segment_times(), atol=1e-9)


def test_limits_hold_at_the_grid_points():
    path, frame, plant = _path(11), KINEMATICS.end_effector_frame, KINEMATICS.plant
    grid = _grid(path)
    v, a = np.full(6, 2.0), np.full(6, 5.0)
    s_of_t = solve_parametrization(path_constraints(path, grid, plant, frame, joint_speed=v, joint_acceleration=a,
                                                    tool_speed=1.0))
    breaks = np.asarray(s_of_t.get_segment_times())
    s = s_of_t.vector_values(breaks)[0]
    sd = s_of_t.derivative(1).vector_values(breaks)[0]
    np.testing.assert_allclose(s, grid, atol=1e-9)
    qdot = path.derivative(1).vector_values(s) * sd
    assert np.all(np.abs(qdot) <= v[:, None] * (1 + 1e-9))
    assert sd[0] == 0.0 and sd[-1] == pytest.approx(0.0, abs=1e-9)


def test_a_path_that_cannot_start_at_speed_has_no_parametrization():
    path, frame, plant = _path(3), KINEMATICS.end_effector_frame, KINEMATICS.plant
    constraints = path_constraints(path, _grid(path), plant, frame, joint_speed=np.full(6, 1.0),
                                   joint_acceleration=np.full(6, 1.0), tool_speed=1.0)
    assert solve_parametrization(constraints, s_dot_start=50.0) is None
