"""The trajectory-optimization program (``robot/trajectory_optimization.py``): the
shoulder-singularity margin, which the joint-path check demands and the program must
keep too; the scene's memory of solved programs (the same bits as a fresh solve)."""

import numpy as np
import pytest

from drake_lfd.robot.dh_kinematics import shoulder_singularity_distance
from drake_lfd.robot.optimization_records import SolverBudget, TrajectoryLimits
from drake_lfd.robot.optimization_scene import OptimizationScene
from drake_lfd.robot.trajectory_constraints import SHOULDER_FRAME_NAME, WRIST_CENTRE_FRAME_NAME
from drake_lfd.robot.trajectory_optimization import optimize_joint_trajectory
from drake_lfd.robot.trajectory_sampling import fit_bspline
from drake_lfd.robot.workcell import Workcell


@pytest.fixture(scope="module")
def scene():
    return OptimizationScene(Workcell.make())


def test_wrist_centre_x_in_the_shoulder_frame_is_the_shoulder_distance(scene):
    plant, context = scene.plant, scene.plant_context
    shoulder = plant.GetFrameByName(SHOULDER_FRAME_NAME, scene.model)
    wrist = plant.GetFrameByName(WRIST_CENTRE_FRAME_NAME, scene.model)
    rng = np.random.default_rng(3)
    for q in rng.uniform(-3.0, 3.0, (30, 6)):
        plant.SetPositions(context, scene.model, q)
        x = plant.CalcRelativeTransform(context, shoulder, wrist).translation()[0]
        assert x == pytest.approx(shoulder_singularity_distance(q), abs=1e-9)


def test_program_keeps_the_wrist_centre_off_the_shoulder_axis(scene):
    # Both ends well off the axis (on its negative side); the guess's middle passes
    # 5 mm from it.
    q_start = np.array([0.0, -2.0, 1.5, -1.5, 1.5, 0.0])
    q_goal = np.array([1.0, -2.0, 1.3, -1.6, 1.4, 0.5])
    q_mid = 0.5 * (q_start + q_goal)
    # Lift the upper arm (q2) until the wrist centre is 5 mm from the axis.
    q2 = np.linspace(q_mid[1] - 0.6, q_mid[1], 6001)
    distances = [shoulder_singularity_distance(np.r_[q_mid[0], x, q_mid[2:]]) for x in q2]
    q_mid[1] = q2[int(np.argmin(np.abs(np.array(distances) + 0.005)))]
    assert shoulder_singularity_distance(q_start) < -0.1 and shoulder_singularity_distance(q_goal) < -0.1
    assert -0.01 < shoulder_singularity_distance(q_mid) < 0.0
    s = np.linspace(0.0, 1.0, 41)
    samples = np.array([np.interp(s, [0.0, 0.5, 1.0], [q_start[j], q_mid[j], q_goal[j]]) for j in range(6)]).T
    guess = fit_bspline(s, samples, 9, rest_ends=True, pins=[(0.5, q_mid)])
    # Whatever local solution SNOPT reaches, each keeps its margin at the clearance
    # samples; the guess's middle (5 mm from the axis) does not keep 15 cm, so that margin
    # is a constraint the solver had to meet, not one the guess met already.
    assert shoulder_singularity_distance(guess.value(0.5)[:, 0]) > -0.15
    for margin in (0.0, 0.15):
        solved = optimize_joint_trajectory(scene, guess, 3.0, clearance_samples=15,
                                           limits=TrajectoryLimits(shoulder_margin_m=margin))
        assert solved.trajectory is not None, solved.status
        T = solved.duration
        closest = max(shoulder_singularity_distance(solved.trajectory.value(fraction * T)[:, 0])
                      for fraction in np.linspace(0.0, 1.0, 15))
        assert closest <= -margin + 1e-5


def _a_program(scene):
    q_start = np.array([0.0, -2.0, 1.5, -1.5, 1.5, 0.0])
    q_goal = np.array([1.0, -1.8, 1.3, -1.6, 1.4, 0.5])
    s = np.linspace(0.0, 1.0, 21)
    samples = np.array([np.interp(s, [0.0, 1.0], [q_start[j], q_goal[j]]) for j in range(6)]).T
    return fit_bspline(s, samples, 8, rest_ends=True)


def test_a_program_solved_before_is_answered_from_the_scenes_memory_with_the_same_bits():
    scene = OptimizationScene(Workcell.make())
    guess = _a_program(scene)
    first = optimize_joint_trajectory(scene, guess, 2.0, clearance_samples=8)
    assert first.trajectory is not None and first.solve_time_s > 0 and scene.solutions.misses == 1
    again = optimize_joint_trajectory(scene, guess, 2.0, clearance_samples=8)
    assert scene.solutions.hits == 1 and scene.solutions.misses == 1 and again.solve_time_s == 0.0
    assert again.evaluations == first.evaluations > 0 and again.status == first.status
    assert np.array_equal(np.hstack(again.trajectory.control_points()), np.hstack(first.trajectory.control_points()))
    # Solved afresh (memory cleared), the same bits: what the memory returns is the solve's.
    scene.solutions.clear()
    fresh = optimize_joint_trajectory(scene, guess, 2.0, clearance_samples=8)
    assert scene.solutions.misses == 2 and fresh.solve_time_s > 0
    assert np.array_equal(np.hstack(fresh.trajectory.control_points()), np.hstack(first.trajectory.control_points()))
    assert fresh.evaluations == first.evaluations
    # One bit of difference in an input is another program.
    optimize_joint_trajectory(scene, guess, np.nextafter(2.0, 3.0), clearance_samples=8)
    optimize_joint_trajectory(scene, guess, 2.0, clearance_samples=8, limits=TrajectoryLimits(clearance_m=0.021))
    assert scene.solutions.misses == 4 and scene.solutions.hits == 1


def test_a_solve_the_safety_stop_ended_is_not_remembered():
    scene = OptimizationScene(Workcell.make())
    guess = _a_program(scene)
    stopped = optimize_joint_trajectory(scene, guess, 2.0, clearance_samples=8,
                                        budget=SolverBudget(safety_stop_s=0.0))
    assert stopped.safety_stopped and stopped.trajectory is None
    assert len(scene.solutions) == 0
    again = optimize_joint_trajectory(scene, guess, 2.0, clearance_samples=8, budget=SolverBudget(safety_stop_s=0.0))
    assert again.safety_stopped and scene.solutions.hits == 0 and scene.solutions.misses == 2
