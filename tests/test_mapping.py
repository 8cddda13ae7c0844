"""Mapping a demonstration onto a segment (Eq. 22-25) and the anchor correction."""

import numpy as np
import pytest

import drake_lfd.core.mapping as mut
from drake_lfd.core.dual_quaternion import (
    dual_quaternion_canonical,
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.quaternion import (
    axis_angle_from_quaternion,
    quaternion_from_axis_angle,
    vector_rotated_by_quaternion,
)
from drake_lfd.core.features import Feature, task_feature_from_poses
from drake_lfd.core.similarity import Allocation, Tolerances, allocate_features

TOL = 1e-12
IDENTITY_Q = [1.0, 0.0, 0.0, 0.0]


def pure_translation(p):
    return dual_quaternion_from_translation_rotation(p, IDENTITY_Q)


def same_poses(D1, D2, tol=TOL):
    np.testing.assert_allclose(dual_quaternion_canonical(D1), dual_quaternion_canonical(D2), atol=tol)


def curvy_demo():
    """A demo that moves, bends and turns about all axes (resampled, 100 poses)."""
    s = np.linspace(0.0, 1.0, 300)
    positions = np.stack([0.1 * np.sin(3 * s), 0.2 * s, 0.05 * s**2], axis=1)
    angles = np.stack([1.2 * s, 0.4 * s, -0.7 * s], axis=1)
    return Feature.from_poses(dual_quaternion_from_euler_zyx(positions, angles))


def allocation_at(indices):
    return Allocation(indices=np.asarray(indices), cost=0.0, alphas=np.zeros(len(indices)))


def path_length(D):
    return np.linalg.norm(np.diff(translation_from_dual_quaternion(D), axis=0), axis=1).sum()


@pytest.mark.parametrize("indices", [[0], [5, 30, 60], [10, 40, 70, 90]])
def test_mapping_a_demo_onto_its_own_poses_reproduces_it(indices):
    demo = curvy_demo()
    task = demo.poses[indices + [len(demo.poses) - 1]]
    segment = mut.map_segment(demo.poses, allocation_at(indices), task)
    same_poses(segment.uncorrected_poses, demo.poses[indices[0]:])
    same_poses(segment.poses, demo.poses[indices[0]:])
    assert segment.scale == pytest.approx(1.0, abs=TOL)
    np.testing.assert_array_equal(segment.anchor_indices, np.array(indices + [99]) - indices[0])


def test_rigid_copy_needs_no_correction_and_is_moved_rigidly():
    demo = curvy_demo()
    X = dual_quaternion_from_euler_zyx([0.5, -0.2, 0.3], [2.5, -0.3, 0.9])
    indices = [3, 50, 80]
    task = dual_quaternion_multiply(X, demo.poses[indices + [99]])
    allocation = allocate_features(task_feature_from_poses(task), demo, Tolerances())
    np.testing.assert_array_equal(allocation.indices, indices)
    segment = mut.map_segment(demo.poses, allocation, task)
    assert segment.max_correction_position_m < TOL
    assert segment.max_correction_rotation_rad < 1e-7  # an angle from a ~1e-16 vector part
    same_poses(segment.poses, dual_quaternion_multiply(X, demo.poses[3:]))


def test_meets_every_critical_configuration_exactly():
    demo = curvy_demo()
    rng = np.random.default_rng(0)
    indices = [8, 35, 62]
    exact = demo.poses[indices + [99]]
    # Bend the task away from the demo: 1-3 cm and ~5-10 deg at the intermediate poses.
    noise = dual_quaternion_from_euler_zyx(rng.uniform(-0.03, 0.03, (4, 3)), rng.uniform(-0.1, 0.1, (4, 3)))
    task = dual_quaternion_multiply(exact, noise)
    task[-1] = exact[-1]
    allocation = allocate_features(task_feature_from_poses(task), demo, Tolerances())
    assert allocation is not None
    segment = mut.map_segment(demo.poses, allocation, task)
    N = len(segment.poses)
    assert N == 100 - allocation.indices[0]
    assert segment.anchor_indices[0] == 0 and segment.anchor_indices[-1] == N - 1
    np.testing.assert_allclose(segment.poses[segment.anchor_indices], task, atol=TOL)
    np.testing.assert_allclose(segment.poses[-1], task[-1], atol=TOL)
    np.testing.assert_allclose(segment.uncorrected_poses[-1], task[-1], atol=TOL)
    # The uncorrected path misses the intermediate anchors; the correction is reported.
    missed = dual_quaternion_relative(segment.uncorrected_poses[segment.anchor_indices[:-1]], task[:-1])
    miss_distance = np.linalg.norm(translation_from_dual_quaternion(missed), axis=1)
    _, miss_angle = axis_angle_from_quaternion(missed[:, :4])
    # Anchors are among the samples; screw interpolation between them may bulge a little.
    assert miss_distance.max() - TOL <= segment.max_correction_position_m <= 1.2 * miss_distance.max()
    assert miss_angle.max() - TOL <= segment.max_correction_rotation_rad <= 1.2 * miss_angle.max()
    assert segment.max_correction_position_m > 0.005
    # The correction is spread along the path: no step is much longer than the demo's.
    corrected_steps = np.linalg.norm(np.diff(translation_from_dual_quaternion(segment.poses), axis=0), axis=1)
    uncorrected_steps = np.linalg.norm(
        np.diff(translation_from_dual_quaternion(segment.uncorrected_poses), axis=0), axis=1)
    shortest_interval = np.diff(segment.anchor_indices).min()
    spread = 2 * segment.max_correction_position_m / shortest_interval
    assert corrected_steps.max() < uncorrected_steps.max() + spread


def straight_demo(length, num=100):
    """Straight move of ``length`` along body z, no rotation."""
    start = dual_quaternion_from_euler_zyx([0.4, 0.0, 0.3], [0.0, 0.0, np.pi])
    s = np.linspace(0.0, 1.0, num)[:, None]
    return dual_quaternion_multiply(start, pure_translation(s * [0.0, 0.0, length]))


def test_scale_is_task_over_demo_length():
    demo = Feature.from_poses(straight_demo(0.1))
    D_j = dual_quaternion_from_euler_zyx([-0.2, 0.3, 0.5], [0.3, 0.2, 0.1])
    D_k = dual_quaternion_multiply(D_j, pure_translation([0.3, 0.0, 0.0]))
    task = np.stack([D_j, D_k])
    allocation = allocate_features(task_feature_from_poses(task), demo, Tolerances())
    assert list(allocation.indices) == [0]
    segment = mut.map_segment(demo.poses, allocation, task)
    assert segment.scale == pytest.approx(3.0, rel=1e-12)
    assert path_length(segment.uncorrected_poses) == pytest.approx(0.3, rel=1e-9)
    assert path_length(demo.poses) == pytest.approx(0.1, rel=1e-9)
    same_poses(segment.uncorrected_poses[[0, -1]], task)
    np.testing.assert_allclose(segment.poses[[0, -1]], task, atol=TOL)
    # Straight along body x of D_j: every position lies on the segment's line.
    positions = translation_from_dual_quaternion(segment.poses)
    direction = (positions[-1] - positions[0]) / 0.3
    offsets = positions - positions[0]
    np.testing.assert_allclose(offsets - (offsets @ direction)[:, None] * direction, 0.0, atol=TOL)


def test_alignment_is_the_shortest_rotation():
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, b = rng.normal(size=(2, 3))
        q = mut.alignment_from_translations(a, b)
        rotated = vector_rotated_by_quaternion(q, a)
        np.testing.assert_allclose(rotated / np.linalg.norm(rotated), b / np.linalg.norm(b), atol=TOL)
        axis, angle = axis_angle_from_quaternion(q)
        assert angle == pytest.approx(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b)), abs=1e-9)
        assert abs(axis @ a) < 1e-9 and abs(axis @ b) < 1e-9


def test_alignment_anti_parallel_zero_length_and_twist():
    a = np.array([0.0, 0.3, 0.0])
    q = mut.alignment_from_translations(a, -2 * a)
    axis, angle = axis_angle_from_quaternion(q)
    assert angle == pytest.approx(np.pi)
    assert abs(axis @ a) < TOL
    np.testing.assert_allclose(vector_rotated_by_quaternion(q, a), -a, atol=TOL)
    # Zero-length (shorter than 1 mm) on either side: no alignment.
    np.testing.assert_array_equal(mut.alignment_from_translations([0.0005, 0, 0], [0, 1.0, 0]), IDENTITY_Q)
    np.testing.assert_array_equal(mut.alignment_from_translations([1.0, 0, 0], [0, 0, 0]), IDENTITY_Q)
    # A twist turns about the task direction after aligning.
    b = np.array([0.0, 0.0, 0.2])
    twisted = mut.alignment_from_translations([1.0, 0, 0], b, twist_rad=0.4)
    expected = quaternion_from_axis_angle([0, 0, 1.0], 0.4)
    np.testing.assert_allclose(vector_rotated_by_quaternion(twisted, [1.0, 0, 0]), [0, 0, 1.0], atol=TOL)
    np.testing.assert_allclose(
        vector_rotated_by_quaternion(twisted, [0, 1.0, 0]),
        vector_rotated_by_quaternion(expected, vector_rotated_by_quaternion(
            mut.alignment_from_translations([1.0, 0, 0], b), [0, 1.0, 0])), atol=TOL)


def test_anti_parallel_segment_reverses_the_demo():
    demo = Feature.from_poses(straight_demo(0.1))
    D_j = dual_quaternion_from_euler_zyx([0.1, 0.1, 0.4], [0.0, 0.0, 0.0])
    D_k = dual_quaternion_multiply(D_j, pure_translation([0.0, 0.0, -0.2]))
    segment = mut.map_segment(demo.poses, allocation_at([0]), np.stack([D_j, D_k]))
    _, angle = axis_angle_from_quaternion(segment.alignment)
    assert angle == pytest.approx(np.pi)
    assert segment.scale == pytest.approx(2.0)
    np.testing.assert_allclose(segment.poses[[0, -1]], [D_j, D_k], atol=TOL)
    np.testing.assert_allclose(path_length(segment.poses), 0.2, rtol=1e-9)


def test_demo_returning_to_its_start_keeps_scale_one():
    # Out 5 cm along body x and back: the first translation is zero.
    start = dual_quaternion_from_euler_zyx([0.3, 0.0, 0.3], [0.0, 0.0, np.pi])
    s = np.sin(np.linspace(0.0, np.pi, 101))[:, None]
    raw = dual_quaternion_multiply(start, pure_translation(s * [0.05, 0.0, 0.0]))
    demo = Feature.from_poses(raw)
    assert np.linalg.norm(demo.translations[0]) < 1e-12
    D_j = dual_quaternion_from_euler_zyx([0.0, 0.4, 0.2], [1.0, 0.0, 0.0])
    D_k = dual_quaternion_multiply(D_j, pure_translation([0.0, 0.0, 0.0005]))
    segment = mut.map_segment(demo.poses, allocation_at([0]), np.stack([D_j, D_k]))
    assert segment.scale == 1.0
    np.testing.assert_array_equal(segment.alignment, IDENTITY_Q)
    assert path_length(segment.poses) == pytest.approx(0.1, rel=0.05)
    np.testing.assert_allclose(segment.poses[[0, -1]], [D_j, D_k], atol=TOL)


def test_twist_turns_the_path_about_the_task_direction():
    demo = curvy_demo()
    task = demo.poses[[0, 99]]
    plain = mut.map_segment(demo.poses, allocation_at([0]), task)
    twisted = mut.map_segment(demo.poses, allocation_at([0]), task, twist_rad=np.pi / 2)
    np.testing.assert_allclose(twisted.poses[[0, -1]], task, atol=TOL)
    assert np.abs(translation_from_dual_quaternion(twisted.poses[50])
                  - translation_from_dual_quaternion(plain.poses[50])).max() > 0.01


@pytest.mark.parametrize("indices", [[0], [5, 30, 60], [10, 40, 70, 90]])
def test_all_twists_at_once_equal_one_mapping_per_twist_to_the_bit(indices):
    demo = curvy_demo()
    rng = np.random.default_rng(len(indices))
    task = demo.poses[indices + [99]].copy()  # the demo's own anchors, then a moved goal
    goal = dual_quaternion_from_euler_zyx(translation_from_dual_quaternion(task[-1]) + rng.normal(scale=0.05, size=3),
                                          [0.3, -0.2, 0.1])
    task[-1] = goal
    twists = np.radians(np.arange(0.0, 360.0, 30.0))
    together = mut.map_segment_twists(demo.poses, allocation_at(indices), task, twists)
    assert together.shape[0] == len(twists)
    for twist, poses in zip(twists, together):
        one = mut.map_segment(demo.poses, allocation_at(indices), task, twist_rad=float(twist))
        assert np.array_equal(one.poses, poses)


@pytest.mark.parametrize("seed", range(6))
def test_the_anchors_bound_the_correction_from_below_for_every_twist(seed):
    """least_anchor_correction_m, from the anchors' residuals alone, is at most the
    largest correction of the mapping with any of the twists, and equals the least of
    them when (as here) that correction is largest at an anchor: a stretch verdict it
    gives is the mapping's."""
    demo = curvy_demo()
    rng = np.random.default_rng(seed)
    indices = sorted(rng.choice(np.arange(1, 90), size=int(rng.integers(1, 4)), replace=False).tolist())
    exact = demo.poses[indices + [99]]
    noise = dual_quaternion_from_euler_zyx(rng.uniform(-0.05, 0.05, (len(exact), 3)),
                                           rng.uniform(-0.2, 0.2, (len(exact), 3)))
    task = dual_quaternion_multiply(exact, noise)
    twists = np.radians(np.arange(0.0, 360.0, 30.0))
    corrections = [mut.map_segment(demo.poses, allocation_at(indices), task, twist_rad=float(t))
                   .max_correction_position_m for t in twists]
    bound = mut.least_anchor_correction_m(demo.poses, allocation_at(indices), task, twists)
    assert bound > 0.0
    assert bound <= min(corrections) + TOL
    assert bound == pytest.approx(min(corrections), rel=0.2)
    # With one twist, the bound is that mapping's residual at its anchors.
    one = mut.map_segment(demo.poses, allocation_at(indices), task, twist_rad=float(twists[3]))
    residuals = dual_quaternion_relative(one.uncorrected_poses[one.anchor_indices[:-1]], task[:-1])
    assert mut.least_anchor_correction_m(demo.poses, allocation_at(indices), task, twists[3:4]) == pytest.approx(
        np.linalg.norm(translation_from_dual_quaternion(residuals), axis=1).max(), abs=TOL)


def test_bad_arguments():
    demo = curvy_demo()
    with pytest.raises(ValueError):
        mut.map_segment(demo.poses, allocation_at([5, 30]), demo.poses[[5, 99]])
    with pytest.raises(ValueError):
        mut.map_segment(demo.poses, allocation_at([30, 5]), demo.poses[[30, 5, 99]])
    with pytest.raises(ValueError):
        mut.map_segment(demo.poses, allocation_at([99]), demo.poses[[99, 99]])


def test_map_segment_rejects_non_unit_poses():
    demo = curvy_demo()
    task = demo.poses[[5, 30, 99]]
    allocation = allocation_at([5, 30])
    mut.map_segment(demo.poses, allocation, task)
    bad_demo = np.array(demo.poses)
    bad_demo[50, :4] *= 1.01
    with pytest.raises(ValueError, match="demo_poses must be unit dual quaternions"):
        mut.map_segment(bad_demo, allocation, task)
    bad_task = np.array(task)
    bad_task[1, 5] += 0.01  # breaks r . d = 0
    with pytest.raises(ValueError, match="task_poses must be unit dual quaternions"):
        mut.map_segment(demo.poses, allocation, bad_task)
    with pytest.raises(ValueError, match="demo_poses"):
        mut.map_segment(demo.poses[:, :7], allocation, task)
    with pytest.raises(ValueError, match="demo_poses"):
        mut.map_segment(demo.poses[None], allocation, task)
    with pytest.raises(ValueError, match="twist_rad"):
        mut.map_segment(demo.poses, allocation, task, twist_rad=np.nan)


def test_mapped_poses_from_deltas_and_alignment_check_their_inputs():
    demo = curvy_demo()
    deltas, D_final = demo.deltas, demo.poses[-1]
    np.testing.assert_allclose(mut.mapped_poses_from_deltas(deltas, D_final, IDENTITY_Q, 1.0), demo.poses,
                               atol=TOL)
    with pytest.raises(ValueError, match="alignment must be unit quaternions"):
        mut.mapped_poses_from_deltas(deltas, D_final, [1.0, 0.1, 0.0, 0.0], 1.0)
    with pytest.raises(ValueError, match="deltas"):
        mut.mapped_poses_from_deltas(1.1 * deltas, D_final, IDENTITY_Q, 1.0)
    with pytest.raises(ValueError, match="shapes"):
        mut.mapped_poses_from_deltas(deltas, demo.poses[-2:], IDENTITY_Q, 1.0)
    with pytest.raises(ValueError, match="scale"):
        mut.mapped_poses_from_deltas(deltas, D_final, IDENTITY_Q, np.inf)
    with pytest.raises(ValueError, match="shape"):
        mut.alignment_from_translations([[1.0, 0.0, 0.0]] * 2, [0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        mut.alignment_from_translations([np.nan, 0.0, 0.0], [0.0, 1.0, 0.0])


def test_returned_alignment_is_not_shared_state():
    first = mut.alignment_from_translations([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])  # identity branch
    if first.flags.writeable:
        first[:] = 0.5
    again = mut.alignment_from_translations([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(again, IDENTITY_Q)
