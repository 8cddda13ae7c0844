"""Time-optimal timing of the checked joint path (robot/path_timing.py) and what it
gives the plans: limits kept, velocity continuous, stops where the task says."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial, stops_of
from drake_lfd.core.timing import TimingLimits
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.path_timing import corner_samples, time_joint_path
from drake_lfd.robot.workcell import Workcell

PERIOD = 0.01
PAPER_TASKS = (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6"))


@pytest.fixture(scope="module")
def kinematics():
    return UR5eKinematics()


def _line(q0, q1, n=200):
    return np.linspace(q0, q1, n)


def test_a_straight_wrist_turn_takes_the_trapezoid_time(kinematics):
    """Wrist 3 turning 2 rad alone (E on its axis: the tool does not move): speed and
    acceleration limited, rest to rest, so T = D / v + v / a at 0.9 of the limits."""
    q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    q1 = q0 + [0, 0, 0, 0, 0, 2.0]
    timed = time_joint_path(_line(q0, q1), [0, 199], [True, True], kinematics)
    v, a = 0.9 * math.pi, 0.9 * 8.0
    assert timed.duration == pytest.approx(2.0 / v + v / a, rel=0.02)
    assert np.abs(timed.qdot[:, 5]).max() == pytest.approx(v, rel=0.01)
    np.testing.assert_allclose(timed.q[0], q0, atol=1e-12)
    np.testing.assert_allclose(timed.q[-1], q1, atol=1e-12)


def test_limits_bind_and_halving_the_acceleration_slows_an_acceleration_limited_move(kinematics):
    q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    q1 = q0 + [0, 0, 0, 0, 0, 0.2]  # short: never reaches full speed
    fast = time_joint_path(_line(q0, q1), [0, 199], [True, True], kinematics)
    slow = time_joint_path(_line(q0, q1), [0, 199], [True, True], kinematics,
                           TimingLimits(joint_acceleration_rad_s2=4.0))
    assert slow.duration == pytest.approx(math.sqrt(2.0) * fast.duration, rel=0.03)  # T = 2 sqrt(D / a)


def test_a_stop_in_the_middle_brings_the_joints_to_rest_and_takes_longer(kinematics):
    q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    q1 = q0 + [0.8, 0, 0, 0, 0, 0]
    path = _line(q0, q1, 401)
    passing = time_joint_path(path, [0, 200, 400], [True, False, True], kinematics)
    stopping = time_joint_path(path, [0, 200, 400], [True, True, True], kinematics)
    middle_pass = passing.critical_indices[1]
    middle_stop = stopping.critical_indices[1]
    assert np.linalg.norm(passing.qdot[middle_pass]) > 0.5
    assert np.linalg.norm(stopping.qdot[middle_stop]) == 0.0
    assert stopping.duration > passing.duration + 0.1
    assert passing.stops == (True, False, True)
    # The critical configuration's sample is exactly the recorded one, at its exact time.
    np.testing.assert_allclose(passing.q[middle_pass], path[200], atol=1e-12)


def test_a_corner_at_a_critical_configuration_is_a_stop(kinematics):
    q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])
    corner = q0 + [0.5, 0, 0, 0, 0, 0]
    end = corner + [0, 0, 0.5, 0, 0, 0]
    path = np.vstack([_line(q0, corner, 101), _line(corner, end, 101)[1:]])
    assert corner_samples(path, [100], angle_deg=30.0, window_rad=0.05) == [100]
    timed = time_joint_path(path, [0, 100, 200], [True, False, True], kinematics)
    assert timed.corners == (2,) and timed.stops == (True, True, True)
    assert np.linalg.norm(timed.qdot[timed.critical_indices[1]]) == 0.0


@pytest.fixture(scope="module")
def paper_plans():
    plans = []
    for name, library in PAPER_TASKS:
        task = load_task(scenarios_directory() / f"{name}.yaml")
        concrete = draw_trial(task, 0)
        workcell = Workcell.of(concrete)
        checker = joint_path_checker(workcell)
        features = library_features(Library.open(library))
        plans.append((name, concrete, checker, features, workcell))
    return plans


def _plan(entry, **options):
    name, concrete, checker, features, workcell = entry
    result = plan_composition(concrete, features, PlanningOptions(cost="paper", **options),
                              floor_z=workcell.planner_floor, checker=checker)
    assert result.planned and result.timing == "time_optimal", name
    return result


def _commanded_tool_velocity(result) -> np.ndarray:
    """What the trajectory source commands at each controller update: v_WE, (k, 3)."""
    scheduled = ScheduledPlan(result)
    times = np.arange(0.0, result.timed.duration + PERIOD, PERIOD)
    return np.array([scheduled.V_WE_desired(t)[3:] for t in times])


@pytest.mark.parametrize("index", range(3), ids=[name for name, _ in PAPER_TASKS])
def test_the_paper_plans_keep_the_limits_and_have_no_velocity_jump(paper_plans, index):
    """The joint path stays within 0.9 of the speed and acceleration limits (finite
    differences at the controller period, a 3 % allowance for the spline between
    Toppra's grid points), and with a tool acceleration limit the commanded tool velocity
    changes by at most that limit times one controller step."""
    entry = paper_plans[index]
    result = _plan(entry)
    q = result.joint_path.q
    speed = np.abs(np.diff(q, axis=0)) / PERIOD
    acceleration = np.abs(np.diff(q, n=2, axis=0)) / PERIOD**2
    assert speed.max() <= 1.03 * 0.9 * math.pi
    assert np.percentile(acceleration, 99.5) <= 1.03 * 0.9 * 8.0
    # Stops at the first and last configurations: at rest there.
    v = _commanded_tool_velocity(result)
    assert np.linalg.norm(v[0]) < 1e-9 and np.linalg.norm(v[-1]) < 1e-9

    limit = 2.0  # m/s^2: a task carrying water
    careful = _plan(entry, timing=TimingLimits(tool_acceleration_m_s2=limit))
    v = _commanded_tool_velocity(careful)
    jumps = np.linalg.norm(np.diff(v, axis=0), axis=1)
    assert jumps.max() <= 1.05 * limit * PERIOD, f"{entry[0]}: {jumps.max():.4f} m/s in one step"
    assert careful.timed.duration > result.timed.duration


def test_stop_flags_of_a_task_reach_the_plan(paper_plans):
    name, concrete, checker, features, workcell = paper_plans[1]  # filling and pouring
    assert stops_of(concrete) == (True, False, False, False, True)
    cons = list(concrete.critical_configurations)
    cons[3] = dataclasses.replace(cons[3], stop=True)
    stopping = dataclasses.replace(concrete, critical_configurations=tuple(cons))
    result = plan_composition(stopping, features, PlanningOptions(cost="paper"), floor_z=workcell.planner_floor,
                              checker=checker)
    v = _commanded_tool_velocity(result)
    due = result.timed.times[result.timed.critical_indices[3]]
    k = int(round(due / PERIOD))
    assert np.linalg.norm(v[k]) < 0.02  # at rest (within one step of its due time)
