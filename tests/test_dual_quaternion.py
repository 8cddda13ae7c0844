"""Dual quaternions (and their quaternions, conversions and screw motions) agree with Drake's
RigidTransform and with pytransform3d."""

import importlib
import inspect

import numpy as np
import pytest
import pytransform3d.batch_rotations as pbr
import pytransform3d.trajectories as ptr
import pytransform3d.transformations as pt
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.common.eigen_geometry import AngleAxis, Quaternion
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

import drake_lfd.core.dual_quaternion as mut
import drake_lfd.core.pose_conversions as conversions
import drake_lfd.core.quaternion as quaternions
import drake_lfd.core.screw_motion as screw_motion

TOL = 1e-12


def random_transforms(rng, n):
    return [
        RigidTransform(RotationMatrix(Quaternion(q / np.linalg.norm(q))), p)
        for q, p in zip(rng.normal(size=(n, 4)), rng.uniform(-1.0, 1.0, size=(n, 3)))
    ]


def same_pose(D1, D2, tol=TOL):
    """Equal as poses (either sign)."""
    D1, D2 = np.asarray(D1), np.asarray(D2)
    return min(np.abs(D1 - D2).max(), np.abs(D1 + D2).max()) < tol


def test_quaternion_multiply_matches_drake():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(20, 4))
    b = rng.normal(size=(20, 4))
    ab = quaternions.quaternion_multiply(a, b)
    for ai, bi, abi in zip(a, b, ab):
        expected = Quaternion(ai / np.linalg.norm(ai)).multiply(Quaternion(bi / np.linalg.norm(bi)))
        np.testing.assert_allclose(abi / np.linalg.norm(ai) / np.linalg.norm(bi), expected.wxyz(), atol=TOL)
    # Broadcasting: one quaternion against a batch.
    np.testing.assert_allclose(quaternions.quaternion_multiply(a[0], b),
                               quaternions.quaternion_multiply(np.repeat(a[:1], 20, 0), b))
    np.testing.assert_allclose(quaternions.quaternion_conjugate(a[0]), a[0] * [1, -1, -1, -1])


@pytest.mark.parametrize("shape_u, shape_v", [((3,), (3,)), ((40, 3), (40, 3)), ((3,), (7, 3)), ((2, 1, 3), (5, 3))])
def test_cross_gives_numpys_numbers_in_every_broadcast(shape_u, shape_v):
    """The kernels' cross product is ``np.cross`` to the last bit (plans stay the same)."""
    rng = np.random.default_rng(7)
    u, v = rng.normal(size=shape_u), rng.normal(size=shape_v)
    assert np.array_equal(quaternions.cross(u, v), np.cross(u, v))


def test_composition_inverse_and_conversions_match_rigid_transform():
    rng = np.random.default_rng(1)
    transforms = random_transforms(rng, 10)
    for X_AB, X_BC in zip(transforms[:-1], transforms[1:]):
        D_AB = conversions.dual_quaternion_from_rigid_transform(X_AB)
        D_BC = conversions.dual_quaternion_from_rigid_transform(X_BC)
        D_AC = mut.dual_quaternion_multiply(D_AB, D_BC)
        np.testing.assert_allclose(
            conversions.matrices_from_dual_quaternion(D_AC), (X_AB @ X_BC).GetAsMatrix4(), atol=TOL)
        np.testing.assert_allclose(
            conversions.rigid_transform_from_dual_quaternion(mut.dual_quaternion_conjugate(D_AB)).GetAsMatrix4(),
            X_AB.inverse().GetAsMatrix4(), atol=TOL)
        np.testing.assert_allclose(mut.translation_from_dual_quaternion(D_AB), X_AB.translation(), atol=TOL)
        p, q = mut.translation_rotation_from_dual_quaternion(D_AB)
        np.testing.assert_allclose(p, X_AB.translation(), atol=TOL)
        assert same_pose(np.r_[q, 0, 0, 0, 0], np.r_[X_AB.rotation().ToQuaternion().wxyz(), 0, 0, 0, 0])
        assert same_pose(conversions.dual_quaternion_from_matrices(X_AB.GetAsMatrix4()), D_AB)
        assert same_pose(mut.dual_quaternion_from_translation_rotation(p, q), D_AB)


def test_relative_pose_is_pose_of_b_in_a():
    rng = np.random.default_rng(2)
    X_WA, X_WB = random_transforms(rng, 2)
    D = mut.dual_quaternion_relative(
        conversions.dual_quaternion_from_rigid_transform(X_WA), conversions.dual_quaternion_from_rigid_transform(X_WB))
    R_WA = X_WA.rotation().matrix()
    np.testing.assert_allclose(
        mut.translation_from_dual_quaternion(D), R_WA.T @ (X_WB.translation() - X_WA.translation()), atol=TOL)
    r_expected = quaternions.quaternion_multiply(
        quaternions.quaternion_conjugate(conversions.dual_quaternion_from_rigid_transform(X_WA)[:4]),
        conversions.dual_quaternion_from_rigid_transform(X_WB)[:4])
    np.testing.assert_allclose(mut.rotation_from_dual_quaternion(D), r_expected, atol=TOL)
    np.testing.assert_allclose(
        conversions.matrices_from_dual_quaternion(D), (X_WA.inverse() @ X_WB).GetAsMatrix4(), atol=TOL)


def test_agrees_with_pytransform3d():
    rng = np.random.default_rng(3)
    T = np.stack([X.GetAsMatrix4() for X in random_transforms(rng, 12)])
    D = conversions.dual_quaternion_from_matrices(T)
    D_pt = ptr.dual_quaternions_from_transforms(T)  # (w, x, y, z, ...) like ours
    for ours, theirs in zip(D, D_pt):
        assert same_pose(ours, theirs)
    np.testing.assert_allclose(
        mut.dual_quaternion_multiply(D[:-1], D[1:]),
        ptr.batch_concatenate_dual_quaternions(D[:-1], D[1:]), atol=TOL)
    np.testing.assert_allclose(mut.dual_quaternion_conjugate(D), ptr.batch_dq_q_conj(D), atol=TOL)
    np.testing.assert_allclose(conversions.matrices_from_dual_quaternion(D), T, atol=TOL)
    for D0, D1, s in zip(D[:-1], D[1:], rng.uniform(0.0, 1.0, size=11)):
        np.testing.assert_allclose(
            mut.dual_quaternion_multiply(D0, D1), pt.concatenate_dual_quaternions(D0, D1), atol=TOL)
        np.testing.assert_allclose(mut.dual_quaternion_conjugate(D0), pt.dq_q_conj(D0), atol=TOL)
        # pytransform3d's ScLERP does not take the shortest screw; ours does, so compare
        # against it after putting D1 in D0's hemisphere.
        D1_near = D1 if np.dot(D0[:4], D1[:4]) >= 0 else -D1
        assert same_pose(screw_motion.dual_quaternion_sclerp(D0, D1, s), pt.dual_quaternion_sclerp(D0, D1_near, s))
    q = D[:, :4]
    axis, angle = quaternions.axis_angle_from_quaternion(q)
    axis_angle_pt = pbr.axis_angles_from_quaternions(q)
    np.testing.assert_allclose(angle, axis_angle_pt[:, 3], atol=TOL)
    np.testing.assert_allclose(axis, axis_angle_pt[:, :3], atol=TOL)


def test_sclerp_endpoints_and_known_screw_midpoint():
    # A screw about the world z axis through c = (1, 0, 0): 90 deg and 0.2 m of advance.
    c = np.array([1.0, 0.0, 0.0])
    X_start = RigidTransform(RollPitchYaw(0.3, -0.2, 0.5), [0.2, 0.1, -0.3])

    def screw(angle):
        rotation = RotationMatrix.MakeZRotation(angle)
        return RigidTransform(rotation, c - rotation.multiply(c) + [0, 0, 0.2 * angle / (np.pi / 2)])

    D0 = conversions.dual_quaternion_from_rigid_transform(X_start)
    D1 = conversions.dual_quaternion_from_rigid_transform(screw(np.pi / 2) @ X_start)
    s = np.array([0.0, 0.5, 1.0])
    D = screw_motion.dual_quaternion_sclerp(D0, D1, s)
    assert D.shape == (3, 8)
    assert same_pose(D[0], D0)
    assert same_pose(D[2], D1)
    expected_mid = conversions.dual_quaternion_from_rigid_transform(screw(np.pi / 4) @ X_start)
    assert same_pose(D[1], expected_mid)
    # Either sign of the end pose gives the same (shortest) path.
    assert same_pose(screw_motion.dual_quaternion_sclerp(D0, -D1, 0.5), expected_mid)


def test_sclerp_pure_translation_identity_and_tiny_rotation():
    D0 = conversions.dual_quaternion_from_euler_zyx([0.1, 0.2, 0.3], [0.4, 0.5, 0.6])
    step = mut.dual_quaternion_from_translation_rotation([0.3, -0.1, 0.2], [1.0, 0.0, 0.0, 0.0])
    D1 = mut.dual_quaternion_multiply(step, D0)  # world-frame translation
    s = np.linspace(0.0, 1.0, 7)
    D = screw_motion.dual_quaternion_sclerp(D0, D1, s)
    np.testing.assert_allclose(
        mut.translation_from_dual_quaternion(D), [0.1, 0.2, 0.3] + s[:, None] * [0.3, -0.1, 0.2], atol=TOL)
    np.testing.assert_allclose(D[:, :4], np.broadcast_to(D0[:4], (7, 4)), atol=TOL)
    np.testing.assert_allclose(screw_motion.dual_quaternion_sclerp(D0, D0, s), np.broadcast_to(D0, (7, 8)), atol=TOL)
    # A 1e-9 rad rotation with a translation: no 0/0 anywhere, result is the blend.
    tiny = mut.dual_quaternion_from_translation_rotation(
        [0.0, 0.0, 0.5], [np.cos(0.5e-9), 0.0, 0.0, np.sin(0.5e-9)])
    mid = screw_motion.dual_quaternion_sclerp(mut.IDENTITY_DUAL_QUATERNION, tiny, 0.5)
    assert np.all(np.isfinite(mid))
    np.testing.assert_allclose(mut.translation_from_dual_quaternion(mid), [0.0, 0.0, 0.25], atol=TOL)


def test_sclerp_batched_pairs():
    rng = np.random.default_rng(4)
    D = conversions.dual_quaternion_from_matrices(np.stack([X.GetAsMatrix4() for X in random_transforms(rng, 6)]))
    s = rng.uniform(size=5)
    batch = screw_motion.dual_quaternion_sclerp(D[:-1], D[1:], s)
    for k in range(5):
        np.testing.assert_allclose(batch[k], screw_motion.dual_quaternion_sclerp(D[k], D[k + 1], s[k]), atol=TOL)


@settings(max_examples=60, deadline=None)
@given(
    axis=st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1),
    angle=st.one_of(st.floats(0.0, np.pi - 1e-6), st.floats(0.0, 1e-6)),
    v=st.lists(st.floats(-2, 2), min_size=3, max_size=3),
)
def test_twist_log_exp_round_trip(axis, angle, v):
    axis = np.array(axis) / np.linalg.norm(axis)
    xi = np.concatenate([angle * axis, v])
    D = screw_motion.dual_quaternion_from_exponential_coordinates(xi)
    np.testing.assert_allclose(screw_motion.exponential_coordinates_from_dual_quaternion(D), xi, atol=1e-10)
    np.testing.assert_allclose(screw_motion.exponential_coordinates_from_dual_quaternion(-D), xi, atol=1e-10)


def test_euler_zyx_is_eq17_and_drake_roll_pitch_yaw():
    rng = np.random.default_rng(5)
    angles = rng.uniform(-np.pi, np.pi, size=(10, 3))
    p = rng.normal(size=(10, 3))
    D = conversions.dual_quaternion_from_euler_zyx(p, angles)
    for (yaw, pitch, roll), pi, Di in zip(angles, p, D):
        X = RigidTransform(RollPitchYaw(roll=roll, pitch=pitch, yaw=yaw), pi)
        np.testing.assert_allclose(conversions.matrices_from_dual_quaternion(Di), X.GetAsMatrix4(), atol=TOL)
        # Eq. 17 written out, theta1 = yaw, theta2 = pitch, theta3 = roll.
        c1, c2, c3 = np.cos([yaw / 2, pitch / 2, roll / 2])
        s1, s2, s3 = np.sin([yaw / 2, pitch / 2, roll / 2])
        eq17 = [c3 * c2 * c1 + s3 * s2 * s1, s3 * c2 * c1 - c3 * s2 * s1,
                c3 * s2 * c1 + s3 * c2 * s1, c3 * c2 * s1 - s3 * s2 * c1]
        np.testing.assert_allclose(Di[:4], eq17, atol=TOL)


def test_canonical_sign_and_tie_break():
    rng = np.random.default_rng(6)
    D = conversions.dual_quaternion_from_euler_zyx(rng.normal(size=(8, 3)), rng.normal(size=(8, 3)))
    flipped = D * np.where(rng.uniform(size=(8, 1)) < 0.5, -1.0, 1.0)
    canonical = mut.dual_quaternion_canonical(flipped)
    assert np.all(canonical[:, 0] >= 0)
    np.testing.assert_array_equal(canonical, mut.dual_quaternion_canonical(D))
    # Half-turn about -y: r_w == 0, so the first non-zero (r_y) becomes positive.
    half_turn = mut.dual_quaternion_from_translation_rotation([1.0, 2.0, 3.0], [0.0, 0.0, -1.0, 0.0])
    canonical = mut.dual_quaternion_canonical(half_turn)
    np.testing.assert_array_equal(canonical, -half_turn)
    assert same_pose(canonical, half_turn)


def test_axis_angle_and_rotation_matrices():
    rng = np.random.default_rng(7)
    q = rng.normal(size=(30, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[0] = [np.cos(1.5), 0.0, np.sin(1.5), 0.0]  # 3 rad, close to a half-turn
    axis, angle = quaternions.axis_angle_from_quaternion(q)
    axis_neg, angle_neg = quaternions.axis_angle_from_quaternion(-q)
    np.testing.assert_allclose(angle, angle_neg, atol=TOL)
    np.testing.assert_allclose(axis, axis_neg, atol=TOL)
    assert np.all((angle >= 0) & (angle <= np.pi))
    for qi, ai, th in zip(q, axis, angle):
        R = RotationMatrix(Quaternion(qi))
        aa = R.ToAngleAxis()
        np.testing.assert_allclose(th, aa.angle(), atol=1e-9)
        np.testing.assert_allclose(RotationMatrix(AngleAxis(th, ai)).matrix(), R.matrix(), atol=TOL)
        np.testing.assert_allclose(quaternions.quaternion_from_rotation_matrices(R.matrix()),
                                   qi if qi[0] >= 0 else -qi, atol=TOL)
    np.testing.assert_allclose(quaternions.rotation_vector_from_quaternion(q), axis * angle[:, None], atol=TOL)
    zero_axis, zero_angle = quaternions.axis_angle_from_quaternion([1.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(zero_axis, [1.0, 0.0, 0.0])
    assert zero_angle == 0.0
    v = rng.normal(size=(30, 3))
    rotated = quaternions.vector_rotated_by_quaternion(q, v)
    for qi, vi, ri in zip(q, v, rotated):
        np.testing.assert_allclose(ri, RotationMatrix(Quaternion(qi)).multiply(vi), atol=TOL)


def test_rigid_transform_round_trip():
    X = RigidTransform(RollPitchYaw(0.1, -2.0, 3.0), [0.5, -0.4, 0.3])
    D = conversions.dual_quaternion_from_rigid_transform(X)
    assert D.shape == (8,)
    assert conversions.rigid_transform_from_dual_quaternion(D).IsNearlyEqualTo(X, TOL)
    assert conversions.rigid_transform_from_dual_quaternion(-D).IsNearlyEqualTo(X, TOL)


def unit_samples(n=5, seed=8):
    rng = np.random.default_rng(seed)
    return conversions.dual_quaternion_from_euler_zyx(rng.normal(size=(n, 3)), rng.normal(size=(n, 3)))


def test_unit_checks_accept_unit_inputs_without_copying():
    D = unit_samples()
    assert mut.check_unit_dual_quaternions(D) is D
    assert mut.check_unit_dual_quaternions(-D[0]).shape == (8,)
    # Rounding drift far above what products accumulate is still accepted.
    drifted = D * (1.0 + 0.5 * mut.UNIT_NORM_TOLERANCE)
    np.testing.assert_array_equal(mut.check_unit_dual_quaternions(drifted), drifted)
    q = D[:, :4]
    np.testing.assert_array_equal(mut.check_unit_quaternions(q), q)
    np.testing.assert_array_equal(mut.check_unit_dual_quaternions(D[None].tolist()), D[None])


@pytest.mark.parametrize("defect", ["scaled", "dual part not orthogonal", "nan", "seven columns", "scalar"])
def test_dual_quaternion_check_rejects(defect):
    D = unit_samples()
    if defect == "scaled":
        D[3] *= 1.01
    elif defect == "dual part not orthogonal":
        D[3, 4] += 1e-3  # |r| stays 1
    elif defect == "nan":
        D[3, 6] = np.nan
    elif defect == "seven columns":
        D = D[:, :7]
    else:
        D = 1.0
    with pytest.raises(ValueError, match="demo poses"):
        mut.check_unit_dual_quaternions(D, "demo poses")


def test_quaternion_check_rejects():
    with pytest.raises(ValueError, match="unit quaternions.*entry 1"):
        mut.check_unit_quaternions([[1.0, 0, 0, 0], [1.0, 1.0, 0, 0]])
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 4\)"):
        mut.check_unit_quaternions([1.0, 0, 0])


def test_rigid_transform_from_dual_quaternion_checks_its_input():
    D = unit_samples()
    with pytest.raises(ValueError, match="unit dual quaternions"):
        conversions.rigid_transform_from_dual_quaternion(2.0 * D[0])
    with pytest.raises(ValueError, match=r"shape \(8,\)"):
        conversions.rigid_transform_from_dual_quaternion(D[:2])


def test_identity_constant_is_read_only():
    with pytest.raises(ValueError):
        mut.IDENTITY_DUAL_QUATERNION[0] = 2.0
    np.testing.assert_array_equal(mut.IDENTITY_DUAL_QUATERNION, [1, 0, 0, 0, 0, 0, 0, 0])


def assert_public_api_listed(module):
    """``__all__`` names only what exists, and every public function and class defined here."""
    defined = {name for name, value in vars(module).items()
               if not name.startswith("_") and (inspect.isfunction(value) or inspect.isclass(value))
               and value.__module__ == module.__name__}
    assert defined <= set(module.__all__)
    assert len(set(module.__all__)) == len(module.__all__)
    assert all(hasattr(module, name) for name in module.__all__)


@pytest.mark.parametrize("module_name", [
    "dual_quaternion", "quaternion", "pose_conversions", "screw_motion", "features", "mapping", "timing",
    "synthetic_library", "read_only_arrays", "errors", "resources",
])
def test_core_public_api_is_listed(module_name):
    assert_public_api_listed(importlib.import_module(f"drake_lfd.core.{module_name}"))
