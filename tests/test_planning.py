"""Planners with hand-built demonstrations: composition, invariance, requests, oracle."""

import numpy as np
import pytest

import drake_lfd.planning.planner as mut
from drake_lfd.core.dual_quaternion import (
    dual_quaternion_from_translation_rotation,
    dual_quaternion_multiply,
    dual_quaternion_relative,
    rotation_from_dual_quaternion,
    translation_from_dual_quaternion,
    translation_rotation_from_dual_quaternion,
)
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.quaternion import quaternion_from_axis_angle
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.q_learning import QPolicy, greedy_walk, plan_q
from drake_lfd.planning.random_tasks import _euler_zyx_of, chained_task, random_training_task
from drake_lfd.core.similarity import rotation_distance
from drake_lfd.core.synthetic_library import PAPER5, PAPER6, synthetic_features
from drake_lfd.core.tasks import ConcreteCriticalConfiguration, ConcreteTask

# The paper's planning (Eq. 31, no joint-space check), which these tests check.
PAPER = PlanningOptions.paper_baseline()


@pytest.fixture(scope="module")
def paper5():
    return synthetic_features(PAPER5)


@pytest.fixture(scope="module")
def paper6():
    return synthetic_features(PAPER6)


def task_from_poses(poses, name="hand"):
    p, q = translation_rotation_from_dual_quaternion(np.asarray(poses))
    return ConcreteTask.from_fixed(name, p, [_euler_zyx_of(qi) for qi in q])


def relative_end(features, name):
    poses = features[name].poses
    return dual_quaternion_relative(poses[0], poses[-1])


def chain(features, names, start):
    poses = [start]
    for name in names:
        poses.append(dual_quaternion_multiply(poses[-1], relative_end(features, name)))
    return np.array(poses)


START = dual_quaternion_from_euler_zyx([0.5, -0.1, 0.3], [0.3, 0.2, 2.8])


def test_chain_of_two_demonstrations_is_planned_as_that_chain(paper5):
    task = task_from_poses(chain(paper5, ["screw_cw", "filling"], START))
    result = mut.plan_composition(task, paper5, PAPER)
    assert result.planned
    assert [(s.demo, s.con_from, s.con_to) for s in result.composition] == [
        ("screw_cw", 1, 2), ("filling", 2, 3)]
    assert result.total_cost < 1e-6


def test_plan_passes_exactly_through_every_critical_configuration(paper5):
    rng = np.random.default_rng(3)
    task, _ = chained_task(rng, paper5, num_cons=5)
    result = mut.plan_composition(task, paper5, PAPER)
    assert result.planned
    _, task_poses = mut.task_candidates(task)
    for con, index in enumerate(result.timed.critical_indices):
        D = result.timed.poses[index]
        np.testing.assert_allclose(translation_from_dual_quaternion(D),
                                   translation_from_dual_quaternion(task_poses[con][0]), atol=1e-9)
        assert rotation_distance(rotation_from_dual_quaternion(D), task_poses[con][0][:4]) < 1e-7


def test_rigid_motion_of_the_task_keeps_composition_and_cost(paper5):
    rng = np.random.default_rng(11)
    for _ in range(5):
        task, _ = chained_task(rng, paper5)
        _, poses = mut.task_candidates(task)
        X = dual_quaternion_from_translation_rotation(
            rng.uniform(-1, 1, 3), quaternion_from_axis_angle(rng.normal(size=3), 2.0))
        moved = task_from_poses(dual_quaternion_multiply(X, np.array([c[0] for c in poses])))
        a, b = mut.plan_composition(task, paper5, PAPER), mut.plan_composition(moved, paper5, PAPER)
        assert [(s.demo, s.con_from, s.con_to) for s in a.composition] == \
            [(s.demo, s.con_from, s.con_to) for s in b.composition]
        assert a.total_cost == pytest.approx(b.total_cost, abs=1e-6)


def test_removing_a_needed_demonstration_requests_the_right_segment(paper5):
    task = task_from_poses(chain(paper5, ["stacking", "screw_cw", "filling"], START))
    assert mut.plan_composition(task, paper5, PAPER).planned
    without = {k: v for k, v in paper5.items() if k != "screw_cw"}
    result = mut.plan_composition(task, without, PAPER)
    assert result.status == "demonstration_requested"
    assert [(u.con_from, u.con_to) for u in result.uncovered] == [(2, 3)]
    (u,) = result.uncovered
    # screw_cw turns -90 deg about body z: the request says so.
    assert np.degrees(u.angle_rad) == pytest.approx(90, abs=1e-6)
    assert abs(u.axis[2]) == pytest.approx(1, abs=1e-9)


def test_assembling_like_segment_asks_for_a_quarter_turn_about_body_x(paper5, paper6):
    pi = np.pi
    task = ConcreteTask.from_fixed(
        "assembling", [[0, 0.5, 0.6], [0.1, 0.5, 0.6], [0.5, 0.1, 0.6], [0.5, 0, 0.6]],
        [[-pi / 2, 0, pi / 2], [0, -pi / 2, 0], [0, -pi / 2, pi / 2], [pi, 0, -pi / 2]])
    result = mut.plan_composition(task, paper5, PAPER)
    assert result.status == "demonstration_requested"
    assert [(u.con_from, u.con_to) for u in result.uncovered] == [(2, 3)]
    (u,) = result.uncovered
    np.testing.assert_allclose(np.abs(u.axis), [1, 0, 0], atol=1e-9)
    assert np.degrees(u.angle_rad) == pytest.approx(90)
    with_span = mut.plan_composition(task, paper6, PAPER)
    assert with_span.planned
    assert ("span", 2, 3) in [(s.demo, s.con_from, s.con_to) for s in with_span.composition]


def brute_force_best(problem):
    """Least total cost over every sequence of legal actions (small problems only)."""
    best = np.inf

    def walk(j, a, total):
        nonlocal best
        if j == problem.num_cons - 1:
            best = min(best, total)
            return
        for step in problem.actions_from(j, a):
            walk(step.k, step.a_k, total + step.cost)

    for a in range(problem.num_candidates[0]):
        walk(0, a, 0.0)
    return best


def test_exact_planner_matches_brute_force_with_bounded_angles(paper5):
    rng = np.random.default_rng(5)
    pi = np.pi
    solved = 0
    for trial in range(6):
        task, _ = chained_task(rng, paper5, num_cons=4)
        # Free the roll of the middle configurations: a planner freedom on a 45 deg grid.
        cons = list(task.critical_configurations)
        for i in (1, 2):
            e = cons[i].euler_zyx
            cons[i] = ConcreteCriticalConfiguration(
                p=cons[i].p, euler_zyx_lower=[e[0], e[1], e[2] - pi / 2],
                euler_zyx_upper=[e[0], e[1], e[2] + pi / 2], angle_grid_deg=45)
        task = ConcreteTask("bounded", cons)
        problem = mut.build_problem(task, paper5)
        steps = plan_exact(problem)
        expected = brute_force_best(problem)
        assert steps is not None and np.isfinite(expected)
        assert sum(s.cost for s in steps) == pytest.approx(expected, abs=1e-5)
        solved += 1
    assert solved == 6


def test_q_planner_plans_exactly_what_the_exact_planner_plans(paper5):
    policy = QPolicy()  # an untrained table still gives valid plans: legality is recomputed
    rng = np.random.default_rng(21)
    for _ in range(10):
        for task in (chained_task(rng, paper5)[0], random_training_task(rng)):
            problem = mut.build_problem(task, paper5)
            exact = plan_exact(problem)
            q = plan_q(problem, policy)
            assert (exact is None) == (q.steps is None)
            if q.steps is not None and q.fallback is None:
                assert greedy_walk(problem, policy) == q.steps


def test_timing_law_respects_speed_limits_and_stops_at_each_con(paper5):
    rng = np.random.default_rng(2)
    task, _ = chained_task(rng, paper5)
    timed = mut.plan_composition(task, paper5, PAPER.replace(max_speed_m_s=0.2, max_angular_speed_rad_s=0.8)).timed
    p = translation_from_dual_quaternion(timed.poses)
    dt = np.diff(timed.times)
    assert np.all(dt > 0)
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    assert speed.max() <= 0.2 * 1.02
    r = rotation_from_dual_quaternion(timed.poses)
    angle = 2 * np.arccos(np.clip(np.abs(np.sum(r[1:] * r[:-1], axis=1)), 0, 1))
    assert (angle / dt).max() <= 0.8 * 1.02
    # At rest at each critical configuration: the first step after it is slow.
    for index in timed.critical_indices[:-1]:
        assert speed[index] < 0.1 * speed.max() + 1e-9
