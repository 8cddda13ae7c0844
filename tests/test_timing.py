"""The timing law: at rest at each critical configuration, speed capped, inputs checked."""

import numpy as np
import pytest

import drake_lfd.core.timing as mut
from drake_lfd.core.dual_quaternion import translation_from_dual_quaternion
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx


def straight_plan(num=41):
    """0.4 m along x with a constant orientation; critical configurations at 0, 20, 40."""
    s = np.linspace(0.0, 1.0, num)
    positions = np.stack([0.2 + 0.4 * s, 0.1 + 0 * s, 0.3 + 0 * s], axis=1)
    return dual_quaternion_from_euler_zyx(positions, np.zeros((num, 3)) + [0.0, 0.0, np.pi]), [0, 20, 40]


def test_spans_take_the_minimum_jerk_time_at_the_speed_cap():
    poses, critical = straight_plan()
    plan = mut.time_plan(poses, critical, max_speed_m_s=0.2)
    assert plan.critical_indices == (0, 20, 40)
    assert plan.times[0] == 0.0 and np.all(np.diff(plan.times) > 0)
    # Each 0.2 m span at 0.2 m/s takes 1 s at full speed, 1.875 s with minimum jerk.
    np.testing.assert_allclose(plan.times[[20, 40]], [1.875, 3.75], rtol=1e-12)
    steps_m = np.linalg.norm(np.diff(translation_from_dual_quaternion(plan.poses), axis=0), axis=1)
    assert (steps_m / np.diff(plan.times)).max() <= 0.2 * 1.01
    assert plan.duration == pytest.approx(3.75)
    assert len(plan.X_WE_list()) == len(plan.poses)


def test_time_plan_checks_its_inputs():
    poses, critical = straight_plan()
    with pytest.raises(ValueError, match="unit dual quaternions"):
        mut.time_plan(poses * 1.01, critical)
    with pytest.raises(ValueError, match="shape"):
        mut.time_plan(poses[:, :7], critical)
    with pytest.raises(ValueError, match="shape"):
        mut.time_plan(poses[None], critical)
    for bad in ([], [0, 20], [1, 20, 40], [0, 20, 20, 40]):
        with pytest.raises(ValueError, match="critical_indices"):
            mut.time_plan(poses, bad)
    with pytest.raises(ValueError, match="must be > 0"):
        mut.time_plan(poses, critical, max_speed_m_s=0.0)
    with pytest.raises(ValueError, match="must be > 0"):
        mut.time_plan(poses, critical, max_angular_speed_rad_s=np.nan)
