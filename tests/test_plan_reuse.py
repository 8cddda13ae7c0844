"""Planning work reused between checks and trials gives exactly what computing afresh
gives: a follow resumed from a shared prefix, a timed piece remembered by its inputs, and
a trial's whole plan whatever trials ran before it in the process."""

import math

import numpy as np
import pytest

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.exact_memo import ExactMemo, exact_key
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import Box, draw_trial
from drake_lfd.core.timing import time_plan
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.robot import path_timing
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import KinematicScene, table_under_robot

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])

# The paper's cost with the joint-space check: the plans these tests were written for.
PAPER_CHECKED = PlanningOptions(cost="paper")


def _plan_through(q_samples, critical):
    kinematics = UR5eKinematics()
    poses = dual_quaternion_from_matrices(np.array([kinematics.X_WE(q).GetAsMatrix4() for q in q_samples]))
    return time_plan(poses, critical)


def _two_plans_sharing_two_spans():
    """Plans through Q_HOME -> q_1 -> q_2 -> (q_a or q_b): the first two spans the same."""
    q_1 = Q_HOME + np.array([0.3, 0.1, -0.2, 0.1, 0.2, 0.3])
    q_2 = q_1 + np.array([0.2, -0.1, 0.1, 0.0, -0.1, 0.0])
    legs = [(Q_HOME, q_1), (q_1, q_2)]
    shared = [a + s * (b - a) for a, b in legs for s in np.linspace(0, 1, 15)[(0 if a is Q_HOME else 1):]]
    plans = []
    for q_end in (q_2 + np.array([-0.3, 0.0, 0.1, 0.0, 0.0, 0.2]), q_2 + np.array([0.2, 0.05, 0.0, 0.1, 0.1, 0.0])):
        samples = shared + [q_2 + s * (q_end - q_2) for s in np.linspace(0, 1, 15)[1:]]
        plans.append(_plan_through(samples, [0, 14, 28, 42]))
    return plans


def _scene_with_a_shell_by_the_path():
    """A shell near the wrist's path, so the clearance queries are skipped at some
    samples and measured at others (the records that depend on the loop's state)."""
    kinematics = UR5eKinematics()
    q = Q_HOME + np.array([0.3, 0.1, -0.2, 0.1, 0.2, 0.3])
    kinematics.plant.SetPositions(kinematics.context, q)
    p_wrist = kinematics.plant.GetFrameByName("wrist_1_link").CalcPoseInWorld(kinematics.context).translation()
    return KinematicScene(safety_shells=[Box(name="shell", centre=p_wrist + [0.0, 0.0, 0.25], size=[0.1, 0.1, 0.1])])


def _assert_same_path(a, b):
    for name in ("t", "q", "clearances"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and x.tobytes() == y.tobytes(), name
    assert a.blocker == b.blocker and a.critical_errors == b.critical_errors
    assert (a.min_clearance_m, a.min_elbow, a.min_wrist, a.min_shoulder_m) == \
        (b.min_clearance_m, b.min_elbow, b.min_wrist, b.min_shoulder_m)


class _CountingLaw:
    """Counts the law's steps the checker takes (a resumed follow takes fewer)."""

    def __init__(self, checker):
        self.steps = 0
        law_step = checker._law_step

        def counted(*args):
            self.steps += 1
            return law_step(*args)

        checker._law_step = counted


def test_a_follow_resumed_from_a_shared_prefix_equals_a_fresh_one_to_the_bit():
    plan_a, plan_b = _two_plans_sharing_two_spans()
    scene = _scene_with_a_shell_by_the_path()
    checker = JointPathChecker(scene)
    checker.follow(plan_a, Q_HOME)
    counter = _CountingLaw(checker)
    resumed = checker.follow(plan_b, Q_HOME)
    fresh_checker = JointPathChecker(scene)
    fresh_counter = _CountingLaw(fresh_checker)
    fresh = fresh_checker.follow(plan_b, Q_HOME)
    assert np.isfinite(fresh.clearances).any() and np.isinf(fresh.clearances).any()
    _assert_same_path(resumed, fresh)
    # It resumed at con_3's first sample (two spans shared), not from the start.
    con_3 = math.ceil(float(plan_b.times[plan_b.critical_indices[2]]) / checker.time_step - 1e-9)
    assert counter.steps == fresh_counter.steps - con_3 > 0
    # The same plan again: the path remembered, no step followed.
    steps = counter.steps
    assert checker.follow(plan_b, Q_HOME) is resumed and counter.steps == steps
    # Another start shares nothing.
    other = checker.follow(plan_b, Q_HOME + 1e-9)
    assert other.q[0].tobytes() != resumed.q[0].tobytes()


def test_a_plan_differing_before_a_checkpoint_is_followed_afresh():
    plan_a, plan_b = _two_plans_sharing_two_spans()
    poses = plan_b.poses.copy()
    poses[3, 7] = np.nextafter(poses[3, 7], 1.0)  # one bit, in the first span
    changed = type(plan_b)(plan_b.times, poses, plan_b.critical_indices)
    checker = JointPathChecker(KinematicScene())
    checker.follow(plan_a, Q_HOME)
    _assert_same_path(checker.follow(changed, Q_HOME), JointPathChecker(KinematicScene()).follow(changed, Q_HOME))


def test_a_remembered_timed_piece_equals_one_timed_afresh():
    kinematics = UR5eKinematics()
    q = Q_HOME + np.linspace(0.0, 1.0, 120)[:, None] * np.array([0.8, -0.3, 0.4, 0.2, 0.5, -0.6])
    path_timing._PIECES.clear()
    first = path_timing.time_joint_path(q, [0, 60, 119], [True, False, True], kinematics)
    hits = path_timing._PIECES.hits
    again = path_timing.time_joint_path(q, [0, 60, 119], [True, False, True], kinematics)
    assert path_timing._PIECES.hits == hits + 1
    path_timing._PIECES.clear()
    fresh = path_timing.time_joint_path(q, [0, 60, 119], [True, False, True], kinematics)
    for name in ("t", "q", "qdot"):
        assert getattr(again, name).tobytes() == getattr(fresh, name).tobytes() == getattr(first, name).tobytes()
    # Other limits are another key.
    slower = path_timing.time_joint_path(q, [0, 60, 119], [True, False, True], kinematics,
                                         path_timing.TimingLimits(joint_speed_rad_s=1.0))
    assert slower.duration > fresh.duration


def test_exact_keys_and_the_memo_bound():
    assert exact_key(np.array([0.0])) != exact_key(np.array([-0.0]))
    assert exact_key(np.zeros((2, 3))) != exact_key(np.zeros((3, 2)))
    assert exact_key(np.arange(3.0), 1) == exact_key(np.arange(3.0), 1)
    memo = ExactMemo(maxsize=2)
    calls = []
    for key in ("a", "b", "a", "c", "b"):
        memo.get(key, lambda key=key: calls.append(key) or key.upper())
    assert calls == ["a", "b", "c", "b"] and len(memo) == 2  # "b" was the least recently used
    with pytest.raises(ValueError):
        ExactMemo(maxsize=0)


def test_a_result_the_memo_is_told_not_to_keep_is_returned_and_computed_again():
    memo = ExactMemo(maxsize=4)
    calls = []
    for _ in range(2):
        assert memo.get("x", lambda: calls.append("x") or -1, keep=lambda result: result >= 0) == -1
    assert calls == ["x", "x"] and len(memo) == 0
    assert memo.get("y", lambda: 1, keep=lambda result: result >= 0) == 1 and len(memo) == 1


def _checker_and_floor(task):
    table = table_under_robot(task.X_WB)
    scene = KinematicScene(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, obstacles=task.obstacles,
                           safety_shells=task.safety_shells, table=table, tool=task.tool)
    checker = JointPathChecker(scene, X_WB=task.X_WB, table_geometry_ids=[scene.geometry.table_geometry_id])
    return checker, float(table.centre[2] + table.size[2] / 2)


def _fingerprint(result):
    path = result.joint_path
    return (result.status, result.composition, result.timed.times.tobytes(), result.timed.poses.tobytes(),
            path.q.tobytes(), path.clearances.tobytes(), path.critical_errors, path.min_clearance_m)


@pytest.mark.slow
def test_a_trials_plan_does_not_depend_on_the_trials_planned_before_it():
    """Filling and pouring shares its first spans between trials (reused: checkpoints and
    timed pieces) and trial 2 of transferring tries other mappings of a blocked span (the
    search resumes its follows): each plan is the same, to the bit, in either order and in
    a process that planned nothing before."""
    cases = [("filling_pouring", "paper5", [1, 0]), ("transferring", "paper5", [2, 0])]
    for name, library, seeds in cases:
        task = load_task(scenarios_directory() / f"{name}.yaml")
        features = library_features(Library.open(library))
        plans = {}
        for order in (seeds, seeds[::-1]):
            checker, floor = _checker_and_floor(task)
            for seed in order:
                plans.setdefault(seed, []).append(
                    _fingerprint(plan_composition(draw_trial(task, seed), features, PAPER_CHECKED, floor_z=floor,
                                                   checker=checker)))
        for seed in seeds:
            path_timing._PIECES.clear()
            checker, floor = _checker_and_floor(task)
            fresh = _fingerprint(plan_composition(draw_trial(task, seed), features, PAPER_CHECKED, floor_z=floor,
                                                   checker=checker))
            assert plans[seed] == [fresh, fresh], (name, seed)
