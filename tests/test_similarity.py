"""The similarity kernel (Eq. 19-21): alpha, beta, pair costs, the allocation DP, the case study.

The planners' legal-action table runs this same kernel batched; its meaning tests
through the planner's own code are in ``test_composition.py``.
"""

import itertools

import numpy as np
import pytest

import drake_lfd.core.similarity as mut
from drake_lfd.core.synthetic_library import PAPER5, synthetic_features
from drake_lfd.core.dual_quaternion import dual_quaternion_from_translation_rotation, dual_quaternion_multiply
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.quaternion import quaternion_from_axis_angle, quaternion_multiply
from drake_lfd.core.features import task_feature_from_poses

X_AXIS, Y_AXIS, Z_AXIS = np.eye(3)


def random_unit_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_alpha_is_two_sin_quarter_angle_and_sign_free():
    rng = np.random.default_rng(0)
    q1 = random_unit_quaternions(rng, 50)
    axes = random_unit_quaternions(rng, 50)[:, 1:]
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(0.0, np.pi, 50)
    q2 = quaternion_multiply(q1, quaternion_from_axis_angle(axes, angles))
    alpha = mut.rotation_distance(q1, q2)
    np.testing.assert_allclose(alpha, 2.0 * np.sin(angles / 4.0), atol=1e-12)
    np.testing.assert_allclose(mut.rotation_distance(-q1, q2), alpha, atol=1e-12)
    assert mut.rotation_distance(q1[0], q2).shape == (50,)  # broadcasting
    # alpha 0.5 is about 58 deg (docs/method.rst, Conventions).
    assert np.degrees(4 * np.arcsin(0.25)) == pytest.approx(57.9, abs=0.1)


def test_translation_cosine_and_short_translations():
    assert mut.translation_cosine([1.0, 0, 0], [0, 2.0, 0]) == pytest.approx(0.0)
    assert mut.translation_cosine([1.0, 0, 0], [-3.0, 0, 0]) == pytest.approx(-1.0)
    assert mut.translation_cosine([1.0, 1.0, 0], [1.0, 0, 0]) == pytest.approx(np.sqrt(0.5))
    # Both shorter than 1 mm: similar; exactly one shorter: not.
    assert mut.translation_cosine([0.0005, 0, 0], [0, -0.0002, 0]) == 1.0
    assert mut.translation_cosine([0.0, 0, 0], [0, 0, 0]) == 1.0
    assert mut.translation_cosine([0.0005, 0, 0], [0.5, 0, 0]) == -1.0
    assert mut.translation_cosine([0.5, 0, 0], [0.0, 0, 0]) == -1.0
    assert mut.translation_cosine([0.0005, 0, 0], [0.5, 0, 0], min_length_m=1e-4) == pytest.approx(1.0)
    long_and_short = np.array([[1.0, 0, 0], [0, 0, 0]])
    beta = mut.translation_cosine(long_and_short[:, None], long_and_short[::-1] * 2)
    np.testing.assert_allclose(beta, [[-1.0, 1.0], [1.0, -1.0]])


def independent_alpha(q1, q2):
    """2 sin(theta / 4), theta = 2 arccos |q1 . q2| the relative rotation angle."""
    theta = 2.0 * np.arccos(np.clip(abs(np.dot(q1, q2)), 0.0, 1.0))
    return 2.0 * np.sin(theta / 4.0)


def independent_beta(t1, t2, min_length_m=1e-3):
    short1, short2 = np.linalg.norm(t1) < min_length_m, np.linalg.norm(t2) < min_length_m
    if short1 or short2:
        return 1.0 if short1 and short2 else -1.0
    return float(np.dot(t1, t2) / (np.linalg.norm(t1) * np.linalg.norm(t2)))


def test_kernel_matrices_against_independent_formulas():
    rng = np.random.default_rng(1)
    tr, dr = random_unit_quaternions(rng, 3), random_unit_quaternions(rng, 7)
    tt, dt = rng.normal(size=(3, 3)), rng.normal(size=(7, 3))
    dt[2] *= 1e-4  # a short demo translation
    tt[1] *= 1e-4  # a short task translation
    alpha, beta = mut.alpha_beta_matrices(tr, tt, dr, dt)
    assert alpha.shape == beta.shape == (3, 7)
    for l, i in itertools.product(range(3), range(7)):
        assert alpha[l, i] == pytest.approx(independent_alpha(tr[l], dr[i]), abs=1e-7)
        assert beta[l, i] == pytest.approx(independent_beta(tt[l], dt[i]), abs=1e-12)
    np.testing.assert_allclose(beta, mut.translation_cosine(tt[:, None], dt[None]), atol=1e-12)
    cost = mut.pair_costs(tr, tt, dr, dt, mut.Tolerances(d_alpha=1.0, d_beta=0.0))
    similar = (alpha <= 1.0) & (beta >= 0.0)
    np.testing.assert_array_equal(cost, np.where(similar, alpha, np.inf))


def test_kernel_broadcasts_over_leading_dimensions():
    rng = np.random.default_rng(3)
    tr, tt = random_unit_quaternions(rng, 2 * 3).reshape(2, 1, 3, 4), rng.normal(size=(2, 1, 3, 3))
    dr, dt = random_unit_quaternions(rng, 4 * 5).reshape(4, 5, 4), rng.normal(size=(4, 5, 3))
    tolerances = mut.Tolerances(d_alpha=1.2, d_beta=-0.5)
    cost = mut.pair_costs(tr, tt, dr, dt, tolerances)
    assert cost.shape == (2, 4, 3, 5)
    for a, b in itertools.product(range(2), range(4)):
        np.testing.assert_array_equal(cost[a, b], mut.pair_costs(tr[a, 0], tt[a, 0], dr[b], dt[b], tolerances))
    table = mut.allocation_table(cost)
    for a, b in itertools.product(range(2), range(4)):
        np.testing.assert_array_equal(table[a, b], mut.allocation_table(cost[a, b]))
    step = mut.allocation_step(table[:, :, 0, :], cost[:1, :1, 1, :])  # (2, 4, 5) with (1, 1, 5)
    np.testing.assert_array_equal(step[1, 2], mut.allocation_step(table[1, 2, 0], cost[0, 0, 1]))


def test_allocation_step_is_strictly_ordered():
    # Delta 2 may follow delta 1 only at a later demo index.
    previous = np.array([0.1, np.inf, np.inf, 0.3])
    row = np.array([0.0, np.inf, 0.2, 0.0])
    np.testing.assert_allclose(mut.allocation_step(previous, row), [np.inf, np.inf, 0.1 + 0.2, 0.1])
    # Two deltas that match only demo index 0: no allocation.
    assert not np.isfinite(mut.allocation_step([0.1, np.inf], [0.1, np.inf])).any()
    table = mut.allocation_table([[0.1, np.inf], [0.1, np.inf]])
    assert mut.allocation_backtrack(table) is None


def brute_force(tr, tt, dr, dt, tolerances):
    p, n = len(tr), len(dr)
    best = None
    for indices in itertools.combinations(range(n), p):
        alphas = [independent_alpha(tr[l], dr[i]) for l, i in enumerate(indices)]
        betas = [independent_beta(tt[l], dt[i]) for l, i in enumerate(indices)]
        if all(a <= tolerances.d_alpha for a in alphas) and all(b >= tolerances.d_beta for b in betas):
            if best is None or sum(alphas) < best:
                best = sum(alphas)
    return best


def test_allocation_is_valid_and_minimal_against_brute_force():
    rng = np.random.default_rng(2)
    tolerances = mut.Tolerances(d_alpha=0.9, d_beta=-0.2)
    found = 0
    for _ in range(200):
        p, n = rng.integers(1, 4), rng.integers(1, 9)
        # Rotations clustered so that some pairs are within tolerance.
        tr = random_unit_quaternions(rng, p) * 0.3 + [1, 0, 0, 0]
        dr = random_unit_quaternions(rng, n) * 0.3 + [1, 0, 0, 0]
        tr /= np.linalg.norm(tr, axis=1, keepdims=True)
        dr /= np.linalg.norm(dr, axis=1, keepdims=True)
        tt, dt = rng.normal(size=(p, 3)), rng.normal(size=(n, 3))
        allocation = mut.allocate(tr, tt, dr, dt, tolerances)
        expected = brute_force(tr, tt, dr, dt, tolerances)
        if expected is None:
            assert allocation is None
            continue
        found += 1
        assert allocation is not None
        indices = allocation.indices
        assert indices.shape == (p,) and np.all(np.diff(indices) > 0)
        for l, i in enumerate(indices):
            assert independent_alpha(tr[l], dr[i]) <= tolerances.d_alpha + 1e-9
            assert independent_beta(tt[l], dt[i]) >= tolerances.d_beta - 1e-9
        assert allocation.cost == pytest.approx(expected, abs=1e-7)
        np.testing.assert_allclose(allocation.alphas, mut.rotation_distance(tr, dr[indices]), atol=1e-15)
    assert 40 < found < 190  # both outcomes exercised


def test_allocation_tolerances_are_inclusive():
    turn = quaternion_from_axis_angle(Z_AXIS, 0.8)
    x = [[0.25, 0, 0]]
    alpha, _ = mut.alpha_beta_matrices([[1.0, 0, 0, 0]], x, [turn], x)
    d_alpha = float(alpha[0, 0])
    assert mut.allocate([[1.0, 0, 0, 0]], x, [turn], x, mut.Tolerances(d_alpha=d_alpha)) is not None
    assert mut.allocate([[1.0, 0, 0, 0]], x, [turn], x,
                        mut.Tolerances(d_alpha=np.nextafter(d_alpha, 0.0))) is None
    back = [[-0.1, 0.03, 0]]
    _, beta = mut.alpha_beta_matrices([[1.0, 0, 0, 0]], x, [[1.0, 0, 0, 0]], back)
    d_beta = float(beta[0, 0])
    assert mut.allocate([[1.0, 0, 0, 0]], x, [[1.0, 0, 0, 0]], back, mut.Tolerances(d_beta=d_beta)) is not None
    assert mut.allocate([[1.0, 0, 0, 0]], x, [[1.0, 0, 0, 0]], back,
                        mut.Tolerances(d_beta=np.nextafter(d_beta, 1.0))) is None


def test_allocation_prefers_order_and_least_alpha():
    identity = [1.0, 0, 0, 0]
    turn = quaternion_from_axis_angle(Z_AXIS, 0.6)
    small_turn = quaternion_from_axis_angle(Z_AXIS, 0.1)
    x = [1.0, 0, 0]
    demo_r = np.array([turn, small_turn, identity, turn])
    demo_t = np.array([x] * 4)
    # One delta: the exact match (index 2) wins over the near one.
    a = mut.allocate(np.array([identity]), np.array([x]), demo_r, demo_t)
    assert list(a.indices) == [2] and a.cost == pytest.approx(0.0, abs=1e-15)
    # Two deltas (turn, identity): order forces the turn before the identity.
    a = mut.allocate(np.array([turn, identity]), np.array([x, x]), demo_r, demo_t)
    assert list(a.indices) == [0, 2]
    # (identity, turn) must use index 3 for the turn.
    a = mut.allocate(np.array([identity, turn]), np.array([x, x]), demo_r, demo_t)
    assert list(a.indices) == [2, 3]
    # Too many task deltas, or a direction nothing matches.
    assert mut.allocate(np.array([identity] * 5), np.array([x] * 5), demo_r, demo_t) is None
    assert mut.allocate(np.array([identity]), np.array([[-1.0, 0, 0]]), demo_r, demo_t) is None
    assert mut.allocate(np.array([identity]), np.array([[-1.0, 0, 0]]), demo_r, demo_t,
                        mut.Tolerances(d_beta=-1.0)) is not None


def test_allocation_applies_the_short_translation_rule():
    identity = [1.0, 0, 0, 0]
    demo_r = np.array([identity] * 3)
    demo_t = np.array([[0.1, 0, 0], [0.0005, 0, 0], [0.2, 0, 0]])
    # A task delta without translation only matches the demo delta without one.
    a = mut.allocate(np.array([identity]), np.array([[0.0, 0.0, 0.0]]), demo_r, demo_t)
    assert list(a.indices) == [1]
    long_only = [0, 2]
    assert mut.allocate(np.array([identity]), np.zeros((1, 3)), demo_r[long_only], demo_t[long_only]) is None
    # A long task translation never matches the short demo delta, whatever its direction.
    a = mut.allocate(np.array([identity] * 2), np.array([[0.0, 0.3, 0.0]] * 2), demo_r, demo_t)
    assert list(a.indices) == [0, 2]


# ---- the paper's case study (Section 6; docs/method.rst, Similarity) ----------------

@pytest.fixture(scope="module")
def library():
    return synthetic_features(PAPER5)


def segment(body_axis, angle, body_translation):
    """Task poses of a one-step segment starting somewhere else in the workspace."""
    D_j = dual_quaternion_from_euler_zyx([-0.3, 0.2, 0.4], [0.7, 0.2, -2.5])
    step = dual_quaternion_from_translation_rotation(
        body_translation, quaternion_from_axis_angle(body_axis, angle))
    D_k = dual_quaternion_multiply(D_j, step)
    return task_feature_from_poses(np.stack([D_j, D_k]))


def matches(library, task):
    result = {name: mut.allocate_features(task, feature, mut.Tolerances(0.5, -0.9))
              for name, feature in library.items()}
    return {name: a for name, a in result.items() if a is not None}


def test_library_first_deltas_match_table5_rotations(library):
    h = np.sqrt(0.5)
    table5 = {"screw_cw": [h, 0, 0, -h], "screw_ccw": [h, 0, 0, h], "filling": [h, 0, h, 0],
              "pouring": [h, 0, -h, 0], "stacking": [1, 0, 0, 0]}
    for name, rotation in table5.items():
        np.testing.assert_allclose(library[name].rotations[0], rotation, atol=1e-12)


def test_body_x_quarter_turn_is_covered_by_no_demo(library):
    # The assembling task's con_2 -> con_3: +90 deg about body x.
    assert matches(library, segment(X_AXIS, np.pi / 2, [0, 0, 0.1])) == {}
    assert matches(library, segment(X_AXIS, np.pi / 2, [0.1, 0.05, 0])) == {}


def test_body_y_quarter_turn_matches_filling(library):
    found = matches(library, segment(Y_AXIS, np.pi / 2, [0.15, 0, -0.1]))
    assert set(found) == {"filling"}
    assert found["filling"].cost < 0.05


def test_translation_without_rotation_matches_stacking_best(library):
    found = matches(library, segment(X_AXIS, 0.0, [0.25, 0, 0.02]))
    assert "stacking" in found
    assert found["stacking"].cost < 1e-9
    assert min(found, key=lambda name: found[name].cost) == "stacking"


def test_screw_segment_tells_clockwise_from_anticlockwise(library):
    found = matches(library, segment(Z_AXIS, -np.pi / 2, [0, 0, 0.05]))
    assert "screw_cw" in found and "screw_ccw" not in found
    assert found["screw_cw"].cost < 1e-9
