"""Features (Eq. 12-13, 18) and arc-length resampling."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

import drake_lfd.core.features as mut
from drake_lfd.core.dual_quaternion import (
    dual_quaternion_canonical,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx, dual_quaternion_from_rigid_transform
from drake_lfd.core.quaternion import axis_angle_from_quaternion
from drake_lfd.core.similarity import Tolerances, allocate_features

TOL = 1e-12


def motion(t):
    """A continuous demo (screw-ish move with a bend), t in [0, 1], uneven speed."""
    s = 0.5 - 0.5 * np.cos(np.pi * np.asarray(t))  # slow start and stop
    positions = np.stack([0.4 + 0.15 * s, 0.1 * np.sin(2.0 * s), 0.5 - 0.2 * s**2], axis=1)
    angles = np.stack([1.2 * s, 0.3 + 0.5 * s, np.pi - 0.8 * s], axis=1)
    return dual_quaternion_from_euler_zyx(positions, angles)


def recorded(rate_hz, duration_s=2.0):
    return motion(np.linspace(0.0, 1.0, int(round(rate_hz * duration_s)) + 1))


def test_feature_is_pose_of_last_frame_in_each_frame():
    rng = np.random.default_rng(0)
    transforms = [RigidTransform(RollPitchYaw(*rng.normal(size=3)), rng.normal(size=3)) for _ in range(6)]
    D = np.stack([dual_quaternion_from_rigid_transform(X) for X in transforms])
    deltas = mut.deltas_from_poses(D)
    assert deltas.shape == (5, 8)
    assert np.all(deltas[:, 0] >= 0)
    for X_Wi, delta in zip(transforms[:-1], deltas):
        X_im = X_Wi.inverse() @ transforms[-1]
        expected = dual_quaternion_canonical(dual_quaternion_from_rigid_transform(X_im))
        np.testing.assert_allclose(delta, expected, atol=TOL)
    feature = mut.Feature.from_deltas(deltas, D)
    np.testing.assert_allclose(feature.translations[0],
                               transforms[0].rotation().inverse().multiply(
                                   transforms[-1].translation() - transforms[0].translation()), atol=TOL)
    np.testing.assert_allclose(feature.rotations, deltas[:, :4])
    np.testing.assert_allclose(dual_quaternion_canonical(mut.poses_from_deltas(deltas, D[-1])),
                               dual_quaternion_canonical(D), atol=TOL)
    with pytest.raises(ValueError):
        feature.deltas[0, 0] = 2.0  # read-only


def test_features_invariant_to_moving_the_whole_demonstration():
    D = recorded(125.0)
    X = dual_quaternion_from_euler_zyx([0.3, -1.2, 0.7], [2.0, -0.4, 1.1])
    moved = dual_quaternion_multiply(X, D)
    np.testing.assert_allclose(mut.deltas_from_poses(moved), mut.deltas_from_poses(D), atol=TOL)
    a = mut.Feature.from_poses(D)
    b = mut.Feature.from_poses(moved)
    np.testing.assert_allclose(b.deltas, a.deltas, atol=1e-10)
    np.testing.assert_allclose(b.translations, a.translations, atol=1e-10)
    # The resampled poses moved with the demonstration.
    np.testing.assert_allclose(b.poses, dual_quaternion_multiply(X, a.poses), atol=1e-10)


def test_resampling_spaces_samples_evenly_and_keeps_endpoints():
    D = recorded(125.0)
    resampled = mut.resample_by_arc_length(D, 50)
    assert resampled.shape == (50, 8)
    np.testing.assert_array_equal(resampled[0], D[0])
    np.testing.assert_array_equal(resampled[-1], D[-1])
    steps = np.diff(mut.arc_lengths_from_poses(resampled))
    total = mut.arc_lengths_from_poses(D)[-1]
    # Even along the piecewise-screw path through the raw samples; measured screw to
    # screw between resampled neighbours it is even up to cutting corners at 125 Hz.
    np.testing.assert_allclose(steps, total / 49, rtol=2e-4)
    # The raw samples are uneven in arc length (slow start), so this is not a no-op.
    raw_steps = np.diff(mut.arc_lengths_from_poses(D))
    assert raw_steps.max() > 3 * raw_steps[1]


@pytest.mark.parametrize("kind", ["rotation", "translation"])
def test_resampling_pure_rotation_and_pure_translation(kind):
    t = np.linspace(0.0, 1.0, 40) ** 2  # uneven in time
    positions = np.zeros((40, 3)) + [0.3, 0.0, 0.4]
    angles = np.zeros((40, 3))
    if kind == "rotation":
        angles[:, 2] = 1.5 * t
    else:
        positions[:, 1] += 0.2 * t
    D = dual_quaternion_from_euler_zyx(positions, angles)
    resampled = mut.resample_by_arc_length(D, 11, rotation_length_m=0.1)
    if kind == "rotation":
        _, angle = axis_angle_from_quaternion(dual_quaternion_relative(D[0], resampled)[:, :4])
        np.testing.assert_allclose(angle, np.linspace(0.0, 1.5, 11), atol=1e-12)
        np.testing.assert_allclose(translation_from_dual_quaternion(resampled), positions[:11], atol=TOL)
    else:
        np.testing.assert_allclose(translation_from_dual_quaternion(resampled)[:, 1],
                                   np.linspace(0.0, 0.2, 11), atol=1e-12)
        np.testing.assert_allclose(np.abs(resampled[:, 0]), 1.0, atol=TOL)


def test_resampling_constant_pose_and_pauses():
    D = np.repeat(dual_quaternion_from_euler_zyx([0.1, 0.2, 0.3], [0.0, 1.0, 0.0])[None], 7, axis=0)
    np.testing.assert_array_equal(mut.resample_by_arc_length(D, 5), np.repeat(D[:1], 5, axis=0))
    feature = mut.Feature.from_poses(D, num_samples=5)
    np.testing.assert_allclose(feature.translations, 0.0, atol=TOL)
    np.testing.assert_allclose(feature.rotations, [[1.0, 0.0, 0.0, 0.0]] * 4, atol=TOL)
    # A pause (repeated samples) in the middle of a move changes nothing.
    moving = recorded(50.0)
    paused = np.concatenate([moving[:40], np.repeat(moving[40:41], 25, axis=0), moving[41:]])
    np.testing.assert_allclose(mut.resample_by_arc_length(paused, 30), mut.resample_by_arc_length(moving, 30),
                               atol=1e-12)


def test_resampling_rejects_bad_arguments():
    D = recorded(50.0)
    with pytest.raises(ValueError):
        mut.resample_by_arc_length(D, 1)
    with pytest.raises(ValueError):
        mut.resample_by_arc_length(D[:1], 10)
    with pytest.raises(ValueError):
        mut.resample_by_arc_length(D, 10, rotation_length_m=0.0)


def test_recording_rate_does_not_change_features_or_verdicts():
    slow = mut.Feature.from_poses(recorded(125.0))
    fast = mut.Feature.from_poses(recorded(500.0))
    assert len(slow) == len(fast) == mut.DEFAULT_NUM_SAMPLES - 1
    np.testing.assert_allclose(slow.rotations, fast.rotations, atol=1e-4)
    np.testing.assert_allclose(slow.translations, fast.translations, atol=1e-4)
    # Recording at 500 Hz without resampling would give 4x the deltas.
    assert len(mut.deltas_from_poses(recorded(500.0))) == 1000

    rng = np.random.default_rng(1)
    verdicts = []
    for _ in range(40):
        p = rng.integers(1, 4)
        positions = rng.uniform(-0.25, 0.25, size=(p + 1, 3))
        angles = rng.uniform(-1.0, 1.0, size=(p + 1, 3))
        task = mut.task_feature_from_poses(dual_quaternion_from_euler_zyx(positions, angles))
        a = allocate_features(task, slow, Tolerances())
        b = allocate_features(task, fast, Tolerances())
        assert (a is None) == (b is None)
        if a is not None:
            assert a.cost == pytest.approx(b.cost, abs=0.02)
        verdicts.append(a is not None)
    assert 0 < sum(verdicts) < len(verdicts)  # both outcomes were exercised


def test_task_feature_uses_eq18_and_eq17_convention():
    # Table 2: con_1..con_4 along -x, con_4 with theta = (0, 0, -pi/2), theta3 = roll.
    positions = [[-0.2, 0, 0.6], [-0.3, 0, 0.6], [-0.4, 0, 0.6], [-0.5, 0, 0.6]]
    angles = [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, -np.pi / 2]]
    feature = mut.task_feature_from_poses(dual_quaternion_from_euler_zyx(positions, angles))
    assert len(feature) == 3
    h = np.sqrt(0.5)
    np.testing.assert_allclose(feature.rotations, [[h, -h, 0, 0]] * 3, atol=TOL)
    np.testing.assert_allclose(feature.translations, [[-0.3, 0, 0], [-0.2, 0, 0], [-0.1, 0, 0]], atol=TOL)


@pytest.mark.parametrize("function", [
    mut.deltas_from_poses, mut.arc_lengths_from_poses, mut.resample_by_arc_length, mut.Feature.from_poses,
    mut.task_feature_from_poses,
])
def test_entry_points_reject_non_unit_or_misshapen_poses(function):
    D = recorded(10.0)
    function(D)
    scaled = D.copy()
    scaled[3] *= 1.001
    with pytest.raises(ValueError, match="unit dual quaternions"):
        function(scaled)
    with pytest.raises(ValueError, match="unit dual quaternions"):
        function(np.where(np.arange(len(D))[:, None] == 3, np.nan, D))
    for misshapen in (D[:, :7], D[0], D[:1], D[None]):
        with pytest.raises(ValueError, match="shape"):
            function(misshapen)


def test_poses_from_deltas_checks_its_inputs():
    D = recorded(10.0)
    deltas = mut.deltas_from_poses(D)
    with pytest.raises(ValueError, match="deltas"):
        mut.poses_from_deltas(2.0 * deltas, D[-1])
    with pytest.raises(ValueError, match="D_final"):
        mut.poses_from_deltas(deltas, 2.0 * D[-1])
    with pytest.raises(ValueError, match="shape"):
        mut.poses_from_deltas(deltas, D[-2:])


def test_feature_constructor_checks_shapes_and_units_and_stores_read_only_arrays():
    feature = mut.Feature.from_poses(recorded(10.0), num_samples=8)
    parts = dict(rotations=feature.rotations, translations=feature.translations, deltas=feature.deltas,
                 poses=feature.poses)
    # Read-only float arrays are kept as they are; anything else is copied, read-only.
    assert mut.Feature(**parts).deltas is feature.deltas
    writable = {name: np.array(value) for name, value in parts.items()}
    copied = mut.Feature(**writable)
    assert writable["deltas"].flags.writeable
    for name in parts:
        assert getattr(copied, name) is not writable[name]
        assert not getattr(copied, name).flags.writeable
    assert mut.Feature(**{**parts, "poses": None}).poses is None
    with pytest.raises(ValueError, match="needs rotations"):
        mut.Feature(**{**parts, "translations": feature.translations[:-1]})
    with pytest.raises(ValueError, match="needs rotations"):
        mut.Feature(**{**parts, "poses": feature.poses[:-1]})
    with pytest.raises(ValueError, match="deltas"):
        mut.Feature(**{**parts, "deltas": 2.0 * feature.deltas})
    with pytest.raises(ValueError, match="deltas"):
        mut.Feature.from_deltas(feature.deltas[0])
