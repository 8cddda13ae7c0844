"""The legal-action table the planners use (CompositionProblem), tested for meaning.

Every test here goes through :class:`CompositionProblem`, the code the exact planner,
the Q-learner and the Gymnasium environment read legality and costs from: the paper's
verdicts, a brute-force allocation written with independent formulas, and the
boundaries of Definition 1 (tolerances inclusive, strict order).
"""

import itertools

import numpy as np
import pytest
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix

import drake_lfd.planning.composition as mut
from drake_lfd.core import similarity
from drake_lfd.core.dual_quaternion import dual_quaternion_from_translation_rotation, dual_quaternion_multiply
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.quaternion import quaternion_from_axis_angle
from drake_lfd.core.features import Feature
from drake_lfd.core.synthetic_library import PAPER5, synthetic_features

X_AXIS, Y_AXIS, Z_AXIS = np.eye(3)
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def demo_from_deltas(rotations, translations):
    """A demonstration feature given directly by its deltas' rotations and translations."""
    return Feature.from_deltas(dual_quaternion_from_translation_rotation(
        np.asarray(translations, dtype=float), np.asarray(rotations, dtype=float)))


def fixed_cons(positions, rotations=None):
    """Candidate poses of cons with one candidate each (identity rotation by default)."""
    positions = np.asarray(positions, dtype=float)
    rotations = np.tile(IDENTITY, (len(positions), 1)) if rotations is None else rotations
    return [dual_quaternion_from_translation_rotation(p, r)[None] for p, r in zip(positions, rotations)]


def legal_demos(problem, j, k):
    return {d for (jj, kk, d) in problem.cost if (jj, kk) == (j, k)}


# ---- the paper's verdicts (Section 6), through the planner's table ---------------------

@pytest.fixture(scope="module")
def library():
    return synthetic_features(PAPER5)


def one_segment_problem(library, body_axis, angle, body_translation):
    """A one-step task con_1 -> con_2 somewhere in the workspace, against the library."""
    D_j = dual_quaternion_from_euler_zyx([-0.3, 0.2, 0.4], [0.7, 0.2, -2.5])
    step = dual_quaternion_from_translation_rotation(body_translation, quaternion_from_axis_angle(body_axis, angle))
    D_k = dual_quaternion_multiply(D_j, step)
    return mut.CompositionProblem([D_j[None], D_k[None]], list(library.values()), similarity.Tolerances(0.5, -0.9))


def verdict(library, *segment):
    problem = one_segment_problem(library, *segment)
    names = list(library)
    return {names[d]: float(problem.cost[(0, 1, d)][0, 0]) for d in legal_demos(problem, 0, 1)}


def test_body_x_quarter_turn_is_covered_by_no_demo(library):
    # The assembling task's con_2 -> con_3: +90 deg about body x.
    assert verdict(library, X_AXIS, np.pi / 2, [0, 0, 0.1]) == {}
    assert verdict(library, X_AXIS, np.pi / 2, [0.1, 0.05, 0]) == {}


def test_body_y_quarter_turn_is_filling(library):
    found = verdict(library, Y_AXIS, np.pi / 2, [0.15, 0, -0.1])
    assert set(found) == {"filling"}
    assert found["filling"] < 0.05


def test_translation_without_rotation_is_stacking_best(library):
    found = verdict(library, X_AXIS, 0.0, [0.25, 0, 0.02])
    assert min(found, key=found.get) == "stacking"
    assert found["stacking"] < 1e-6


def test_screwing_tells_clockwise_from_anticlockwise(library):
    found = verdict(library, Z_AXIS, -np.pi / 2, [0, 0, 0.05])
    assert "screw_cw" in found and "screw_ccw" not in found
    found = verdict(library, Z_AXIS, np.pi / 2, [0, 0, 0.05])
    assert "screw_ccw" in found and "screw_cw" not in found


# ---- brute force with independent formulas ---------------------------------------------

def rotation_matrix(q):
    return RotationMatrix(Quaternion(np.asarray(q) / np.linalg.norm(q))).matrix()


def independent_alpha(R_a, R_b):
    """2 sin(theta / 4), theta the angle of the relative rotation (from the trace)."""
    theta = np.arccos(np.clip((np.trace(R_a.T @ R_b) - 1.0) / 2.0, -1.0, 1.0))
    return 2.0 * np.sin(theta / 4.0)


def independent_beta(t_a, t_b, min_length_m=1e-3):
    short_a, short_b = np.linalg.norm(t_a) < min_length_m, np.linalg.norm(t_b) < min_length_m
    if short_a and short_b:
        return 1.0
    if short_a or short_b:
        return -1.0
    return float(np.dot(t_a, t_b) / (np.linalg.norm(t_a) * np.linalg.norm(t_b)))


def brute_force_cost(cons, demos, j, a_j, k, a_k, tolerances):
    """Least total alpha over every choice of intermediate candidates and strictly
    increasing demo indices (inf when none is valid).

    ``cons[l]`` is a list of candidates (R_WE, p_WE); ``demos[d]`` a list of deltas
    (R, t). The task delta of con l to con k is (R_l^T R_k, R_l^T (p_k - p_l)) (Eq. 18).
    """
    best = np.inf
    p = k - j
    middles = [range(len(cons[l])) for l in range(j + 1, k)]
    for middle in itertools.product(*middles):
        chosen = (a_j, *middle)
        R_k, p_k = cons[k][a_k]
        deltas = []
        for offset, a_l in enumerate(chosen):
            R_l, p_l = cons[j + offset][a_l]
            deltas.append((R_l.T @ R_k, R_l.T @ (p_k - p_l)))
        for indices in itertools.combinations(range(len(demos)), p):
            total = 0.0
            for (R_task, t_task), i in zip(deltas, indices):
                R_demo, t_demo = demos[i]
                alpha = independent_alpha(R_task, R_demo)
                if alpha > tolerances.d_alpha or independent_beta(t_task, t_demo) < tolerances.d_beta:
                    break
                total += alpha
            else:
                best = min(best, total)
    return best


def random_rotation_near(rng, q, spread):
    r = np.asarray(q, dtype=float) + spread * rng.normal(size=4)
    return r / np.linalg.norm(r)


def random_problem(rng):
    """A small task (3-4 cons, 1-3 candidates each) and 2 demos of 3-6 deltas, with
    rotations clustered so that both verdicts occur, and some short translations."""
    base = random_rotation_near(rng, IDENTITY, 1.0)
    num_cons = int(rng.integers(3, 5))
    cons_q = [[random_rotation_near(rng, base, 0.25) for _ in range(int(rng.integers(1, 4)))]
              for _ in range(num_cons)]
    positions = rng.normal(scale=0.2, size=(num_cons, 3))
    if rng.random() < 0.3:
        positions[-1] = positions[-2]  # a task delta without translation
    demos_q, demos_t = [], []
    for _ in range(2):
        n = int(rng.integers(3, 7))
        demos_q.append([random_rotation_near(rng, IDENTITY, 0.25) for _ in range(n)])
        t = rng.normal(scale=0.2, size=(n, 3))
        if rng.random() < 0.3:
            t[-1] *= 1e-3 / np.linalg.norm(t[-1]) / 2  # a demo delta shorter than 1 mm
        demos_t.append(t)
    candidate_poses = [
        np.array([dual_quaternion_from_translation_rotation(positions[l], q) for q in qs])
        for l, qs in enumerate(cons_q)
    ]
    features = [demo_from_deltas(q, t) for q, t in zip(demos_q, demos_t)]
    cons = [[(rotation_matrix(q), positions[l]) for q in qs] for l, qs in enumerate(cons_q)]
    demos = [[(rotation_matrix(q), t_i) for q, t_i in zip(qs, t)] for qs, t in zip(demos_q, demos_t)]
    return candidate_poses, features, cons, demos


def test_legal_costs_equal_an_independent_brute_force():
    rng = np.random.default_rng(7)
    tolerances = similarity.Tolerances(d_alpha=0.9, d_beta=-0.2)
    outcomes = {"legal": 0, "illegal": 0, "multi-delta legal": 0}
    for _ in range(25):
        candidate_poses, features, cons, demos = random_problem(rng)
        problem = mut.CompositionProblem(candidate_poses, features, tolerances)
        for j, k in itertools.combinations(range(len(cons)), 2):
            for d in range(len(demos)):
                matrix = problem.cost.get((j, k, d))
                for a_j, a_k in itertools.product(range(len(cons[j])), range(len(cons[k]))):
                    expected = brute_force_cost(cons, demos[d], j, a_j, k, a_k, tolerances)
                    found = np.inf if matrix is None else matrix[a_j, a_k]
                    if np.isinf(expected):
                        assert np.isinf(found), (j, k, d, a_j, a_k)
                        outcomes["illegal"] += 1
                        continue
                    assert found == pytest.approx(expected, abs=1e-6), (j, k, d, a_j, a_k)
                    outcomes["legal"] += 1
                    outcomes["multi-delta legal"] += k - j > 1
                    # The allocation the mapping gets is valid and least, checked independently.
                    span = problem.span_allocation(mut.Step(d, j, k, a_j, a_k, found))
                    chosen, indices = span.candidates, span.allocation.indices
                    assert chosen[0] == a_j and chosen[-1] == a_k and len(chosen) == k - j + 1
                    assert np.all(np.diff(indices) > 0)
                    R_k, p_k = cons[k][a_k]
                    total = 0.0
                    for offset, i in enumerate(indices):
                        R_l, p_l = cons[j + offset][chosen[offset]]
                        R_demo, t_demo = demos[d][i]
                        alpha = independent_alpha(R_l.T @ R_k, R_demo)
                        assert alpha <= tolerances.d_alpha + 1e-9
                        assert independent_beta(R_l.T @ (p_k - p_l), t_demo) >= tolerances.d_beta - 1e-9
                        total += alpha
                    assert span.allocation.cost == pytest.approx(expected, abs=1e-6)
                    assert total == pytest.approx(expected, abs=1e-6)
    assert min(outcomes.values()) > 10, outcomes


# ---- boundaries of Definition 1 ----------------------------------------------------------

def one_delta_problem(demo_rotation, demo_translation, tolerances):
    """con_1 -> con_2 moving 0.25 m along x without turning (an exactly representable
    task delta), against a one-delta demonstration."""
    demo = demo_from_deltas([demo_rotation], [demo_translation])
    problem = mut.CompositionProblem(fixed_cons([[0, 0, 0], [0.25, 0, 0]]), [demo], tolerances)
    return problem, demo


def kernel_alpha_beta(demo):
    alpha, beta = similarity.alpha_beta_matrices([IDENTITY], [[0.25, 0, 0]], demo.rotations, demo.translations)
    return float(alpha[0, 0]), float(beta[0, 0])


def test_alpha_equal_to_the_tolerance_is_similar_and_just_above_is_not():
    _, demo = one_delta_problem(quaternion_from_axis_angle(Z_AXIS, 0.8), [0.1, 0, 0], similarity.Tolerances())
    alpha, _ = kernel_alpha_beta(demo)
    assert 0.3 < alpha < 0.5
    at, _ = one_delta_problem(demo.rotations[0], demo.translations[0], similarity.Tolerances(d_alpha=alpha))
    assert at.cost[(0, 1, 0)][0, 0] == alpha
    below, _ = one_delta_problem(demo.rotations[0], demo.translations[0],
                                 similarity.Tolerances(d_alpha=np.nextafter(alpha, 0.0)))
    assert (0, 1, 0) not in below.cost


def test_beta_equal_to_the_tolerance_is_similar_and_just_below_is_not():
    _, demo = one_delta_problem(IDENTITY, [-0.1, 0.03, 0], similarity.Tolerances())
    _, beta = kernel_alpha_beta(demo)
    assert -1.0 < beta < -0.9
    at, _ = one_delta_problem(IDENTITY, demo.translations[0], similarity.Tolerances(d_beta=beta))
    assert (0, 1, 0) in at.cost
    above, _ = one_delta_problem(IDENTITY, demo.translations[0], similarity.Tolerances(d_beta=np.nextafter(beta, 1.0)))
    assert (0, 1, 0) not in above.cost


def test_short_translation_rule_at_the_tolerances():
    # Both shorter than 1 mm: beta is exactly 1, similar even with d_beta = 1.
    demo = demo_from_deltas([IDENTITY], [[0.0004, 0, 0]])
    still = mut.CompositionProblem(fixed_cons([[0.1, 0, 0], [0.1, 0, 0.0002]]), [demo],
                                   similarity.Tolerances(d_beta=1.0))
    assert (0, 1, 0) in still.cost
    # One short, one long: beta is exactly -1, similar only with d_beta = -1.
    moving = fixed_cons([[0, 0, 0], [0.25, 0, 0]])
    assert (0, 1, 0) in mut.CompositionProblem(moving, [demo], similarity.Tolerances(d_beta=-1.0)).cost
    assert (0, 1, 0) not in mut.CompositionProblem(
        moving, [demo], similarity.Tolerances(d_beta=np.nextafter(-1.0, 0.0))).cost


def test_two_task_deltas_never_share_one_demo_delta():
    # con_1 -> con_3 has two deltas (0.2 m and 0.1 m along x, no turn); only the demo's
    # first delta is similar to either of them, so the span needs i_1 < i_2 and fails.
    turn = quaternion_from_axis_angle(Z_AXIS, 2.0)
    only_first = demo_from_deltas([IDENTITY, turn, turn], [[0.3, 0, 0], [-0.1, 0, 0], [-0.1, 0, 0]])
    cons = fixed_cons([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]])
    problem = mut.CompositionProblem(cons, [only_first])
    assert set(problem.cost) == {(0, 1, 0), (1, 2, 0)}
    # With a second similar delta later in the demo the span is legal, in order.
    two = demo_from_deltas([IDENTITY, turn, IDENTITY], [[0.3, 0, 0], [-0.1, 0, 0], [0.1, 0, 0]])
    problem = mut.CompositionProblem(cons, [two])
    assert (0, 2, 0) in problem.cost
    span = problem.span_allocation(mut.Step(0, 0, 2, 0, 0, problem.cost[(0, 2, 0)][0, 0]))
    assert list(span.allocation.indices) == [0, 2]


def test_max_span_limits_the_actions():
    cons = fixed_cons([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0, 0]])
    demo = demo_from_deltas([IDENTITY] * 4, [[0.1, 0, 0]] * 4)
    assert max(k - j for j, k, _ in mut.CompositionProblem(cons, [demo]).cost) == 3
    assert max(k - j for j, k, _ in mut.CompositionProblem(cons, [demo], max_span=1).cost) == 1
