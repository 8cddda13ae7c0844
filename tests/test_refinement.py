"""Refinement by trajectory optimization (``planning/refinement.py``): the refined plan is
checked executable, inside the tube, shorter, and meets every critical configuration;
a failure leaves the unrefined plan with a reason; ``plan --refine --json``; closed-loop
trials with refinement."""

import dataclasses
import json
import math

import numpy as np
import pytest

from cli_subprocess import run_cli
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial, rigid_transform_from_euler_zyx
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.diagrams.judging import SUCCESS_POSITION_TOLERANCE_M, SUCCESS_ROTATION_TOLERANCE_RAD
from drake_lfd.experiments.simulation import run_trial
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.plan_json import plan_json
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.core.timing import TimingLimits
from drake_lfd.planning.refinement import refine_plan
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.planning.refinement_tube import shape_deviation
from drake_lfd.planning.plain_optimizer import plain_plan
from drake_lfd.robot.trajectory_optimization import OptimizationScene, SolverBudget, TrajectoryLimits
from drake_lfd.robot.workcell import Workcell
import drake_lfd.planning.refinement as refinement_module
import drake_lfd.planning.refinement_tube as refinement_tube

SIMS = scenarios_directory()


def _composed(name: str, seed: int):
    """The composed plan of paper task ``name`` (``paper5``) at trial ``seed``, its
    checker and the program's scene."""
    task = load_task(SIMS / f"{name}.yaml")
    trial = draw_trial(task, seed)
    workcell = Workcell.of(trial)
    checker = joint_path_checker(workcell, task.simulation)
    result = plan_composition(trial, library_features(Library.open("paper5")), PlanningOptions(),
                              floor_z=workcell.planner_floor, checker=checker)
    assert result.planned and result.joint_path.executable
    return result, checker, OptimizationScene(workcell)


@pytest.fixture(scope="module")
def transferring():
    """The composed plan of transferring (seed 0), its checker and the program's scene."""
    return _composed("transferring", 0)


@pytest.fixture(scope="module")
def refined(transferring):
    result, checker, scene = transferring
    return refine_plan(result, checker, scene=scene)


def test_refined_transferring_is_executable_in_the_tube_and_shorter(transferring, refined):
    composed, checker, _ = transferring
    report = refined.refinement
    assert report.status == "refined", report.reason
    assert refined.joint_path is not composed.joint_path and refined.joint_path.executable
    # The check ran on the refined plan itself: its joint path spans the refined motion.
    assert refined.joint_path.t[-1] >= refined.timed.duration - 1e-9
    assert refined.timed.duration == pytest.approx(report.duration_s)
    assert refined.timed.duration < composed.timed.duration
    options = RefinementOptions()
    assert report.tube_max_position_m <= options.tube_position_m
    assert report.tube_max_rotation_rad <= options.tube_rotation_rad
    # Independently: no refined pose is farther from the composed path, as a set, than the
    # tube allows at matching fractions.
    position, _ = shape_deviation(composed.timed, refined.timed.X_WE_list())
    assert position <= options.tube_position_m


def test_refined_transferring_meets_every_critical_configuration_and_keeps_the_cup_upright(refined):
    task = refined.task
    X = refined.timed.X_WE_list()
    assert len(refined.timed.critical_indices) == len(task.critical_configurations)
    for i, (con, index) in enumerate(zip(task.critical_configurations, refined.timed.critical_indices)):
        X_con = rigid_transform_from_euler_zyx(con.p, refined.euler_zyx[i])
        assert np.linalg.norm(X[index].translation() - X_con.translation()) < SUCCESS_POSITION_TOLERANCE_M
        angle = X[index].rotation().inverse().multiply(X_con.rotation()).ToAngleAxis().angle()
        assert angle < SUCCESS_ROTATION_TOLERANCE_RAD
    for position, rotation in refined.joint_path.critical_errors:  # the followed path, when due
        assert position < SUCCESS_POSITION_TOLERANCE_M and rotation < SUCCESS_ROTATION_TOLERANCE_RAD
    (upright,) = task.path_constraints
    R_up = rigid_transform_from_euler_zyx(np.zeros(3), upright.euler_zyx).rotation()
    assert max(x.rotation().inverse().multiply(R_up).ToAngleAxis().angle() for x in X) <= upright.tolerance_rad


def test_the_plain_optimizer_is_the_peer_without_a_tube(transferring, refined):
    composed, checker, scene = transferring
    plain = plain_plan(composed, checker, scene=scene)
    assert plain.refinement.method == "plain"
    assert plain.refinement.status == "refined", plain.refinement.reason
    # Same start and goal configurations as the composed plan.
    np.testing.assert_allclose(plain.joint_path.q[0], composed.joint_path.q[0])
    assert plain.timed.duration < composed.timed.duration


@pytest.mark.slow
@pytest.mark.parametrize("options, expected", [
    (RefinementOptions(tube_position_m=1e-4, tube_rotation_rad=math.radians(0.01)), ""),
    # The wall-clock safety stop is an error, said as such (never a quiet change of plan).
    (RefinementOptions(budget=SolverBudget(safety_stop_s=0.0)), "error: wall-clock safety stop (SNOPT stopped)"),
])
def test_a_failed_refinement_leaves_the_unrefined_plan_and_says_why(transferring, options, expected):
    composed, checker, scene = transferring
    result = refine_plan(composed, checker, scene=scene, options=options)
    report = result.refinement
    assert report.status == "failed" and report.reason and expected in report.reason
    assert result.timed is composed.timed and result.joint_path is composed.joint_path
    document = json.loads(json.dumps(plan_json(result)))
    assert document["refinement"]["status"] == "failed"
    assert document["refinement"]["reason"] == report.reason
    assert document["poses"][-1]["t"] == pytest.approx(composed.timed.duration)


@pytest.mark.slow
def test_the_refinement_is_the_same_bits_whatever_ran_before_it(transferring, refined):
    """The budget counts iterations, SNOPT keeps no state between solves and the scene
    is reused: refining the same plan again, after a different refinement on the same
    scene, gives the identical plan and report (all but the wall times)."""
    composed, checker, scene = transferring
    trial = draw_trial(load_task(SIMS / "transferring.yaml"), 3)
    other = plan_composition(trial, library_features(Library.open("paper5")), PlanningOptions(),
                             floor_z=Workcell.of(trial).planner_floor, checker=checker)
    assert not np.array_equal(other.timed.poses[-1], composed.timed.poses[-1]) or len(other.timed.times) != len(
        composed.timed.times)
    refine_plan(other, checker, scene=scene)
    # Solved afresh (the scene's memory of solved programs cleared), then answered from
    # that memory: the same bits both ways.
    scene.solutions.clear()
    misses = scene.solutions.misses
    again = refine_plan(composed, checker, scene=scene)
    assert scene.solutions.misses - misses == again.refinement.attempts
    remembered = refine_plan(composed, checker, scene=scene)
    assert scene.solutions.misses - misses == again.refinement.attempts
    for result in (again, remembered):
        assert result.refinement.to_json(wall_times=False) == refined.refinement.to_json(wall_times=False)
        assert np.array_equal(result.timed.poses, refined.timed.poses)
        assert np.array_equal(result.timed.times, refined.timed.times)
        assert np.array_equal(result.joint_path.q, refined.joint_path.q)
        assert result.refinement.evaluations == refined.refinement.evaluations > 0
    assert remembered.refinement.solve_time_s == 0.0


@pytest.fixture(scope="module")
def transferring_1():
    return _composed("transferring", 1)


def _spying_on_checks(monkeypatch, refuse=()):
    """Records every motion the refinement checks (its solve and its check), refusing
    the checks numbered in ``refuse`` (from 0) as a failed check would."""
    checked_motions = []
    check_motion = refinement_module.check_motion

    def spy(result, checker, scene, solved, *args, **kwargs):
        checked = check_motion(result, checker, scene, solved, *args, **kwargs)
        if len(checked_motions) in refuse:
            checked = dataclasses.replace(checked, reason="collision with safety shell 'shell' (refused by the test)")
        checked_motions.append((solved, checked))
        return checked

    monkeypatch.setattr(refinement_module, "check_motion", spy)
    return checked_motions


def test_the_tube_program_runs_from_every_start_and_keeps_the_shortest_that_passes(transferring_1, monkeypatch):
    """Which local solution SNOPT reaches from one start moves with the last bits of the
    plan (transferring seed 1: from the composed path 2.70 s on one machine, 2.38 s on
    another), so the tube program runs from each start (the plain program's motion, the
    composed path, straight joint-space lines) and the plan is the motion of the first
    start whose program duration is within ``equal_duration`` of the shortest among those
    that pass every check: a property of every answer, whichever minima SNOPT reaches."""
    composed, checker, scene = transferring_1
    checked_motions = _spying_on_checks(monkeypatch)
    report = refine_plan(composed, checker, scene=scene).refinement
    assert report.status == "refined", report.reason
    options = RefinementOptions()
    # The plain program, then the tube program from each start (and once more from a
    # motion through the clearance); a solve without a motion is not checked.
    assert report.attempts >= 1 + len(options.starts)
    assert 1 <= len(checked_motions) <= report.attempts - 1
    passed = [(solved, checked) for solved, checked in checked_motions if checked.reason is None]
    shortest = min(solved.duration for solved, _ in passed)
    first = next(checked for solved, checked in passed if solved.duration <= (1 + options.equal_duration) * shortest)
    assert report.duration_s == first.plan.duration


@pytest.mark.slow
def test_a_start_whose_motion_fails_a_check_is_passed_over(transferring, monkeypatch):
    """The first start's motion refused (as a failed check would): the plan is the best
    of the others', with the same work."""
    composed, checker, scene = transferring
    checked_motions = _spying_on_checks(monkeypatch, refuse=(0,))
    report = refine_plan(composed, checker, scene=scene).refinement
    assert report.status == "refined", report.reason
    options = RefinementOptions()
    assert report.attempts >= 1 + len(options.starts)
    others = [(solved, checked) for solved, checked in checked_motions[1:] if checked.reason is None]
    shortest = min(solved.duration for solved, _ in others)
    first = next(checked for solved, checked in others if solved.duration <= (1 + options.equal_duration) * shortest)
    assert report.duration_s == first.plan.duration
    # Every start refused: the unrefined plan stands, the reason naming each start.
    monkeypatch.undo()
    _spying_on_checks(monkeypatch, refuse=range(100))
    result = refine_plan(composed, checker, scene=scene)
    assert result.refinement.status == "failed" and result.timed is composed.timed
    assert "from the composed path: " in result.refinement.reason
    assert "from straight joint-space lines: " in result.refinement.reason


def test_the_plan_document_holds_no_wall_time(refined):
    document = plan_json(refined)["refinement"]
    assert "solve_time_s" not in document and "total_time_s" not in document
    assert document["evaluations"] == refined.refinement.evaluations and document["attempts"] >= 1
    assert set(refined.refinement.to_json()) == set(document) | {"solve_time_s", "total_time_s"}


def _critical_pose_errors(result, composed):
    X, X_ref = result.timed.X_WE_list(), composed.timed.X_WE_list()
    return [(float(np.linalg.norm(X[i].translation() - X_ref[j].translation())),
             X[i].rotation().inverse().multiply(X_ref[j].rotation()).ToAngleAxis().angle())
            for i, j in zip(result.timed.critical_indices, composed.timed.critical_indices)]


@pytest.mark.parametrize("budget", [SolverBudget(major_iterations=3), SolverBudget(iterations=100)])
def test_an_iterate_at_the_iteration_limit_is_checked_like_a_solution(transferring, refined, budget):
    """SNOPT stopped at an iteration limit: its last iterate is sampled and checked like a
    solution. Whether that iterate passes depends on where SNOPT stood; every answer
    either refines with a motion that passes every check, or leaves the composed plan
    saying the iterates were refused."""
    composed, checker, scene = transferring
    assert refined.refinement.refined and not refined.refinement.budget_spent
    stopped = refine_plan(composed, checker, scene=scene, options=RefinementOptions(budget=budget))
    report = stopped.refinement
    assert report.attempts >= 1 + len(RefinementOptions().starts)
    if report.refined:
        assert stopped.joint_path.executable and stopped.timed.duration < composed.timed.duration
        for position, rotation in _critical_pose_errors(stopped, composed):
            assert position <= 0.0018 and rotation <= math.radians(0.45)
    else:
        assert "SNOPT's last iterate at its iteration limit" in report.reason or "optimizer: " in report.reason
        assert stopped.timed is composed.timed and stopped.joint_path is composed.joint_path


def test_the_limits_are_the_timing_blocks_at_its_fraction(refined):
    limits = TrajectoryLimits.of_timing(TimingLimits())
    assert limits.joint_speed_rad_s == pytest.approx(0.9 * math.pi)
    assert limits.acceleration_rad_s2 == pytest.approx(7.2) and limits.tool_speed_m_s == pytest.approx(1.35)
    slow = TrajectoryLimits.of_timing(TimingLimits(joint_speed_rad_s=1.0, tool_acceleration_m_s2=2.0,
                                                   limit_fraction=0.5))
    assert slow.joint_speed_rad_s == 0.5 and slow.tool_acceleration_m_s2 == 1.0
    # The refined motion keeps to them (its 10 ms samples, by finite differences).
    dt = np.diff(refined.timed.times)
    p = np.array([x.translation() for x in refined.timed.X_WE_list()])
    assert np.max(np.linalg.norm(np.diff(p, axis=0), axis=1) / dt) <= limits.tool_speed_m_s + 1e-9
    # No joint faster than the bound (with room for the follow's corrections).
    q = refined.joint_path.q[refined.joint_path.t <= refined.timed.duration]
    speeds = np.abs(np.diff(q, axis=0)) / checker_period(refined)
    assert np.max(speeds) <= 1.02 * limits.joint_speed_rad_s


def checker_period(result):
    return float(result.joint_path.t[1] - result.joint_path.t[0])


def test_a_plan_without_refinement_has_no_refinement_object(transferring):
    composed, _, _ = transferring
    assert "refinement" not in plan_json(composed)


@pytest.mark.slow
def test_plan_refine_json_on_the_command_line(tmp_path):
    out = tmp_path / "plan.json"
    status, stdout, stderr, _, _ = run_cli("plan", SIMS / "transferring.yaml", "--library", "paper5", "--refine",
                                           "--json", out, timeout=180)
    assert status == 0, stderr
    document = json.loads(out.read_text())
    refinement = document["refinement"]
    assert refinement["method"] == "refine" and refinement["status"] in ("refined", "failed")
    assert ("refined by trajectory optimization" in stdout) == (refinement["status"] == "refined")
    if refinement["status"] == "refined":
        assert document["poses"][-1]["t"] == pytest.approx(refinement["duration_s"])
        assert refinement["duration_s"] < refinement["unrefined_duration_s"]
        assert document["joint_trajectory"]["t"][-1] >= refinement["duration_s"] - 1e-9


def test_the_tube_is_sampled_evenly_in_s_and_along_the_arc_length(transferring):
    composed, _, _ = transferring
    # Evenly in s, and evenly along the composed path (where a span is passed quickly for
    # its length, samples evenly in s leave the path room to stray between them).
    reference = refinement_tube.ComposedPathReference(composed.timed)
    bounds = refinement_tube.tube_bounds(reference, RefinementOptions(tube_samples=5))
    fractions = [b.s for b in bounds]
    assert len(fractions) == len(set(fractions)) and 5 < len(fractions) <= 10
    np.testing.assert_allclose(reference.evenly_along(5), [f for f in fractions if f not in
                                                           set(np.linspace(0, 1, 7)[1:-1])], atol=1e-12)
    lengths = np.interp(reference.evenly_along(5), reference._s, reference._length)
    np.testing.assert_allclose(np.diff(lengths), lengths[0], rtol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("name, library", [
    ("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6")])
def test_one_refined_closed_loop_trial_per_paper_task_succeeds(name, library):
    task = load_task(SIMS / f"{name}.yaml")
    outcome = run_trial(task, library_features(Library.open(library)), trial=1, seed=0,
                        options=PlanningOptions(refine=True))
    assert outcome.plan.refinement is not None
    assert outcome.plan.refinement.status == "refined", outcome.plan.refinement.reason
    assert outcome.success, outcome.failures
    assert outcome.run.critical_errors[-1].time_s - outcome.run.critical_errors[0].time_s == pytest.approx(
        outcome.plan.timed.duration, abs=0.02)
