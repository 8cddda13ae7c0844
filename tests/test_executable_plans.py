"""Plans that execute: with the joint-space checker, both planners return only
compositions whose joint path (the controller's law, followed kinematically) keeps the
UR5e's limits, singularity margins and clearances; otherwise ``no_executable_plan`` with
the blocking segments and their causes."""

import dataclasses

import numpy as np
import pytest

from drake_lfd.core.dual_quaternion import translation_rotation_from_dual_quaternion
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import ConcreteCriticalConfiguration, draw_trial
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition

# The paper's cost, without and with the joint-space check (what these tests were written for).
UNCHECKED = PlanningOptions.paper_baseline()
CHECKED = PlanningOptions(cost="paper")
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.scene import KinematicScene, table_under_robot


@pytest.fixture(scope="module")
def transferring():
    return load_task(scenarios_directory() / "transferring.yaml")


@pytest.fixture(scope="module")
def paper5():
    return library_features(Library.open("paper5"))


@pytest.fixture(scope="module")
def checker(transferring):
    task = transferring
    table = table_under_robot(task.X_WB)
    scene = KinematicScene(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, obstacles=task.obstacles,
                           safety_shells=task.safety_shells, table=table, tool=task.tool)
    return JointPathChecker(scene, X_WB=task.X_WB, table_geometry_ids=[scene.geometry.table_geometry_id])


def _floor(task):
    table = table_under_robot(task.X_WB)
    return float(table.centre[2] + table.size[2] / 2)


@pytest.mark.parametrize("seed", [2, 4])
def test_a_blocked_plan_is_replaced_by_an_executable_one(transferring, paper5, checker, seed):
    """These trials' cheapest plans straighten the elbow (|sin q3| < 0.06): the search
    maps the blocked span from another demonstration suffix or with another twist (or,
    failing that, forbids it and takes another composition), and the plan it returns
    keeps every margin."""
    concrete = draw_trial(transferring, seed)
    unchecked = plan_composition(concrete, paper5, UNCHECKED, floor_z=_floor(transferring))
    starts = checker.start_candidates(unchecked.timed.X_WE_list()[0])
    blocked = checker.follow_from_candidates(unchecked.timed, starts)
    assert blocked.blocker is not None and blocked.blocker.reason == "singularity"
    assert "elbow" in blocked.blocker.detail or "speed limit" in blocked.blocker.detail
    checked = plan_composition(concrete, paper5, CHECKED, floor_z=_floor(transferring), checker=checker)
    assert checked.planned and checked.joint_path is not None and checked.joint_path.executable
    assert checked.timed.poses.shape != unchecked.timed.poses.shape or \
        not np.allclose(checked.timed.poses, unchecked.timed.poses)
    path = checked.joint_path
    assert path.min_elbow >= checker.limits.elbow_margin and path.min_wrist >= checker.limits.wrist_margin
    assert path.min_clearance_m >= checker.limits.clearance_m
    # The joint path reaches every critical configuration within the success tolerances.
    assert len(path.critical_errors) == len(concrete.critical_configurations)
    assert max(e[0] for e in path.critical_errors) < 0.005


def test_a_step_no_mapping_can_run_is_forbidden_and_reported(transferring, paper5, checker):
    """Without alternative mappings (one suffix, one twist), trial 2's blocked span is
    forbidden: the search takes another composition and reports the blocked segment."""
    import drake_lfd.planning.planner as planner

    concrete = draw_trial(transferring, 2)
    saved = planner.SUFFIX_ALTERNATIVES, planner.TWIST_ALTERNATIVES
    planner.SUFFIX_ALTERNATIVES, planner.TWIST_ALTERNATIVES = 1, 1
    try:
        checked = plan_composition(concrete, paper5, CHECKED, floor_z=_floor(transferring), checker=checker)
    finally:
        planner.SUFFIX_ALTERNATIVES, planner.TWIST_ALTERNATIVES = saved
    assert checked.planned and checked.joint_path.executable
    assert checked.search_rounds >= 2 and checked.infeasible
    assert checked.infeasible[0].reason == "singularity" and checked.infeasible[0].demo == "stacking"


def test_an_executable_plan_is_found_in_one_round_when_the_best_runs(transferring, paper5, checker):
    concrete = draw_trial(transferring, 0)
    unchecked = plan_composition(concrete, paper5, UNCHECKED, floor_z=_floor(transferring))
    checked = plan_composition(concrete, paper5, CHECKED, floor_z=_floor(transferring), checker=checker)
    assert checked.search_rounds == 1 and not checked.infeasible
    assert [s.demo for s in checked.composition] == [s.demo for s in unchecked.composition]
    # Same critical configurations; the checked plan is timed along its joint path.
    assert checked.timing == "time_optimal" and unchecked.timing == "geometric"
    cons_checked = checked.timed.poses[list(checked.timed.critical_indices)]
    cons_unchecked = unchecked.timed.poses[list(unchecked.timed.critical_indices)]
    p_checked, _ = translation_rotation_from_dual_quaternion(cons_checked)
    p_unchecked, _ = translation_rotation_from_dual_quaternion(cons_unchecked)
    np.testing.assert_allclose(p_checked, p_unchecked, atol=5e-4)
    assert checked.timed.duration < 0.6 * unchecked.timed.duration


@pytest.mark.parametrize("distance", [5.0, 1e20])
def test_a_configuration_out_of_reach_is_refused_fast_naming_it(transferring, paper5, checker, distance,
                                                                monkeypatch):
    import drake_lfd.planning.planner as planner_module

    concrete = draw_trial(transferring, 0)
    cons = list(concrete.critical_configurations)
    cons[2] = ConcreteCriticalConfiguration.fixed([distance, 0.2, 0.3], [0.0, -np.pi / 2, 0.0])
    far = dataclasses.replace(concrete, critical_configurations=tuple(cons))

    def no_search(*args, **kwargs):
        raise AssertionError("the reach check refuses before any composition is searched")

    # Fast means no search at all (work, not seconds: a busy machine must not fail it).
    monkeypatch.setattr(planner_module, "CompositionProblem", no_search)
    result = plan_composition(far, paper5, CHECKED, floor_z=_floor(transferring), checker=checker)
    assert result.status == "no_executable_plan" and result.timed is None
    (segment,) = result.infeasible
    assert segment.reason == "reach" and segment.con_to == 3 and "con_3" in segment.detail


@pytest.mark.slow
def test_the_planned_joint_path_is_the_path_the_closed_loop_runs(transferring, paper5):
    """``plan --json``'s joint trajectory and a simulated trial of the same seed: the
    simulated joints follow the planned ones (the servos' lag aside) and E stays within
    the tracking tolerance (1 cm; measured 4.5 mm at worst and 1.1 mm median at the
    time-optimal timing, a median of 1.5 mrad per joint: the drive holds each 10 ms
    command, so at speed it trails the motion by a part of a period) of where the
    planned joints put it."""
    from drake_lfd.experiments.simulation import TrialRunner
    from drake_lfd.io.plan_json import plan_json
    from drake_lfd.robot.kinematics import UR5eKinematics

    runner = TrialRunner(transferring, paper5, options=CHECKED)
    outcome = runner.run(trial=1, seed=0)
    assert outcome.success, outcome.failures
    document = plan_json(outcome.plan)
    t_plan = np.array(document["joint_trajectory"]["t"])
    q_plan = np.array(document["joint_trajectory"]["q"])
    run = outcome.run
    np.testing.assert_allclose(q_plan[0], run.q[0], atol=1e-9)  # the run starts where the plan does
    tau = run.t - run.plan_start_time_s
    inside = (tau >= 0.0) & (tau <= t_plan[-1])
    planned = np.array([np.interp(tau[inside], t_plan, q_plan[:, j]) for j in range(6)]).T
    difference = np.abs(planned - run.q[inside])
    assert np.median(difference) < 3e-3  # rad
    assert difference.max() < 0.03  # rad: the servos lag most where the joints turn fastest
    kinematics = UR5eKinematics(X_WB=transferring.X_WB, X_tool0_E=transferring.X_tool0_E)
    gap = max(np.linalg.norm(kinematics.X_WE(a).translation() - kinematics.X_WE(b).translation())
              for a, b in zip(planned[::5], run.q[inside][::5]))
    assert gap < 0.01


@pytest.mark.slow
def test_a_request_comes_with_a_guidance_script_that_records_the_missing_demonstration(tmp_path):
    """assembling with paper5: exit 3 and a guidance script; recording it and adding the
    recording to a copy of the library makes the task plan, with the new demonstration
    on the requested segment."""
    import json

    import drake_lfd.cli as cli
    from drake_lfd.io.guidance_scripts import load_guidance_script

    task = str(scenarios_directory() / "assembling.yaml")
    script = tmp_path / "request.yaml"
    assert cli.main(["plan", task, "--library", "paper5", "--request-script", str(script),
                     "--json", str(tmp_path / "request.json")]) == 3
    guidance = load_guidance_script(script)
    (uncovered,) = json.loads((tmp_path / "request.json").read_text())["uncovered"]
    assert (uncovered["from"], uncovered["to"]) == (2, 3)
    assert uncovered["guidance_script"] == script.read_text()
    assert len(guidance.waypoints) >= 2
    assert cli.main(["record", str(script), "--out", str(tmp_path / "new.csv"), "--quiet"]) == 0
    assert cli.main(["library", "copy", "paper5", str(tmp_path / "lib")]) == 0
    assert cli.main(["library", "add", str(tmp_path / "lib"), str(tmp_path / "new.csv"), "--name", "new"]) == 0
    assert cli.main(["plan", task, "--library", str(tmp_path / "lib"), "--json", str(tmp_path / "plan.json")]) == 0
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert {"demo": "new", "from": 2, "to": 3} in [{k: c[k] for k in ("demo", "from", "to")} for c in plan["composition"]]


@pytest.mark.slow
def test_a_task_needing_the_wrist_3_winding_of_the_whole_plan_succeeds_in_closed_loop():
    """Four 'span' demonstrations chained: the tool turns a full -2 pi about its axis.
    Inverse kinematics of con_1 alone gives wrist 3 at -1.01 rad, from which the twist
    would end at -7.3 rad, past the -2 pi limit; the plan starts one turn higher (5.27
    rad), and the closed loop, started there, succeeds."""
    from pydrake.math import RigidTransform, RollPitchYaw

    from drake_lfd.core.dual_quaternion import dual_quaternion_multiply, dual_quaternion_relative
    from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx, matrices_from_dual_quaternion
    from drake_lfd.core.tasks import ConcreteTask
    from drake_lfd.diagrams.closed_loop import ClosedLoopRunner
    from drake_lfd.diagrams.pipeline import build_pipeline
    from drake_lfd.diagrams.judging import judge_run

    features = library_features(Library.open("paper6"))
    step = dual_quaternion_relative(features["span"].poses[0], features["span"].poses[-1])
    poses = [dual_quaternion_from_euler_zyx(np.array([0.4, 0.1, 0.3]), np.array([2.5, -np.pi / 2, 0.0]))]
    for _ in range(4):
        poses.append(dual_quaternion_multiply(poses[-1], step))
    X = [RigidTransform(T) for T in matrices_from_dual_quaternion(np.array(poses))]
    euler = [[r.yaw_angle(), r.pitch_angle(), r.roll_angle()] for r in (RollPitchYaw(x.rotation()) for x in X)]
    task = ConcreteTask.from_fixed("winding", np.array([x.translation() for x in X]), np.array(euler),
                                   X_tool0_E=RigidTransform(RollPitchYaw(0, np.pi / 2, 0), [0, 0, 0.2]))
    runner = ClosedLoopRunner(build_pipeline(task, features))
    scheduled, run = runner.run(task)
    path = scheduled.result.joint_path
    assert scheduled.planned and path is not None
    assert path.q[0][5] == pytest.approx(-1.0134 + 2 * np.pi, abs=1e-3)
    assert path.q[-1][5] == pytest.approx(-1.0147, abs=1e-2)
    np.testing.assert_allclose(run.q[0], path.q[0], atol=1e-9)
    judgement = judge_run(run)
    assert judgement.success, judgement.failures
    assert run.q[:, 5].min() > -2 * np.pi and run.q[:, 5].max() < 2 * np.pi


@pytest.mark.parametrize("cost", ["paper", "fidelity"])
@pytest.mark.parametrize("seed", [0, 3])
def test_a_rigid_motion_of_the_whole_problem_keeps_the_plan(transferring, paper5, seed, cost):
    """Robot base, table, critical configurations, obstacles, shells and path constraints turned by 0.4 rad
    about the vertical and moved: the same composition, the same twists and suffixes, the
    same joint path; the poses are the original ones moved rigidly (ties between equally
    good choices are not decided by floating-point noise)."""
    from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

    from drake_lfd.core.tasks import Box
    from drake_lfd.diagrams.pipeline import joint_path_checker
    from drake_lfd.robot.workcell import Workcell

    T = RigidTransform(RotationMatrix.MakeZRotation(0.4), [0.3, -0.2, 0.0])
    concrete = draw_trial(transferring, seed)

    def moved_con(con):
        X = T.multiply(RigidTransform(RollPitchYaw(np.array(con.euler_zyx)[::-1]), np.array(con.p)))
        rpy = RollPitchYaw(X.rotation())
        return ConcreteCriticalConfiguration.fixed(X.translation(), [rpy.yaw_angle(), rpy.pitch_angle(),
                                                                     rpy.roll_angle()])

    def moved_box(box):
        return Box(name=box.name, centre=T.multiply(np.array(box.centre)), size=box.size,
                   rotation=T.rotation().matrix() @ box.rotation)

    def moved_constraint(constraint):
        rpy = RollPitchYaw(T.rotation().multiply(RollPitchYaw(np.array(constraint.euler_zyx)[::-1]).ToRotationMatrix()))
        return dataclasses.replace(constraint, euler_zyx=[rpy.yaw_angle(), rpy.pitch_angle(), rpy.roll_angle()])

    moved = dataclasses.replace(
        concrete, critical_configurations=tuple(moved_con(c) for c in concrete.critical_configurations),
        X_WB=T.multiply(concrete.X_WB), obstacles=tuple(moved_box(b) for b in concrete.obstacles),
        safety_shells=tuple(moved_box(b) for b in concrete.safety_shells),
        path_constraints=tuple(moved_constraint(c) for c in concrete.path_constraints))
    results = []
    for task in (concrete, moved):
        workcell = Workcell.of(task)
        results.append(plan_composition(task, paper5, PlanningOptions(cost=cost), floor_z=workcell.planner_floor,
                                        checker=joint_path_checker(workcell)))
    original, rigid = results
    assert original.planned and rigid.planned
    assert [(s.demo, s.con_from, s.con_to) for s in original.composition] == \
        [(s.demo, s.con_from, s.con_to) for s in rigid.composition]
    if cost == "fidelity":  # seed 3 needs the search's alternative suffixes; no tool-turning filling span
        assert all(s.demo == "stacking" for s in original.composition)
    # The start is solved by inverse kinematics to its tolerance: the joint paths are
    # equal to 1e-4 rad, so their timing and tool paths agree to the same order.
    assert abs(original.timed.duration - rigid.timed.duration) < 1e-3
    X_original = original.timed.X_WE_list()
    X_rigid = rigid.timed.X_WE_list()
    for i, j in zip(original.timed.critical_indices, rigid.timed.critical_indices):
        assert np.linalg.norm(T.multiply(X_original[i]).translation() - X_rigid[j].translation()) < 1e-4
    shared = min(len(original.joint_path.q), len(rigid.joint_path.q))
    np.testing.assert_allclose(original.joint_path.q[:shared, 1:], rigid.joint_path.q[:shared, 1:], atol=1e-3)


def test_plan_of_a_configuration_5_m_away_exits_4_naming_it(tmp_path, capsys, monkeypatch):
    import json

    import drake_lfd.cli as cli
    import drake_lfd.planning.planner as planner_module

    task = tmp_path / "far.yaml"
    task.write_text("""\
name: far
X_tool0_E: {p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}
critical_configurations:
  - {p: [0.4, -0.2, 0.2], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.4, 0.0, 0.3], euler_zyx: [0, -pi/2, 0]}
  - {p: [5.0, 0.2, 0.3], euler_zyx: [0, -pi/2, 0]}
""")
    out = tmp_path / "far.json"

    def no_search(*args, **kwargs):
        raise AssertionError("the reach check refuses before any composition is searched")

    # The refusal costs no search (work, not seconds: a busy machine must not fail it).
    monkeypatch.setattr(planner_module, "CompositionProblem", no_search)
    assert cli.main(["plan", str(task), "--library", "paper5", "--json", str(out)]) == 4
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("far: no executable plan: con_2 -> con_3: reach: con_3 at p = [5.0, 0.2, 0.3] m")
    text = out.read_text()
    assert "NaN" not in text and "Infinity" not in text
    document = json.loads(text)
    assert document["status"] == "no_executable_plan" and document["total_cost"] is None
    assert document["infeasible"][0]["reason"] == "reach" and document["joint_trajectory"] == {"t": [], "q": []}


@pytest.mark.slow
def test_simulate_meshcat_shows_the_plan_live(capsys):
    """``simulate --meshcat`` prints the viewer's address and draws the planned path and
    the critical configurations there (the same markers as the recordings)."""
    import drake_lfd.cli as cli
    import drake_lfd.diagrams.closed_loop as closed_loop

    drawn = []
    original = closed_loop.draw_plan

    def spy(meshcat, plan, **kwargs):
        drawn.append((meshcat.HasPath("/drake"), len(plan.critical_indices)))
        original(meshcat, plan, **kwargs)
        assert meshcat.HasPath("/drake/plan/tool_path") and meshcat.HasPath("/drake/plan/con_1/x")

    closed_loop.draw_plan = spy
    try:
        code = cli.main(["simulate", str(scenarios_directory() / "assembling.yaml"), "--library", "paper6",
                         "--meshcat"])
    finally:
        closed_loop.draw_plan = original
    assert code == 0
    assert "Meshcat viewer at http://" in capsys.readouterr().out
    assert drawn and drawn[0][1] == 4


def test_the_margins_are_configurable_in_the_task_file(tmp_path, capsys):
    import drake_lfd.cli as cli

    task = tmp_path / "strict.yaml"
    head = """\
name: strict
X_tool0_E: {p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}
critical_configurations:
  - {p: [0.4, -0.2, 0.2], euler_zyx: [0, -pi/2, 0]}
  - {p: [0.4, 0.0, 0.3], euler_zyx: [0, -pi/2, 0]}
"""
    task.write_text(head)
    assert cli.main(["plan", str(task), "--library", "paper5"]) == 0
    task.write_text(head + "simulation:\n  joint_check: {elbow_margin: 0.99}\n")
    assert cli.main(["plan", str(task), "--library", "paper5"]) == 4
    assert "elbow straight" in capsys.readouterr().err
    task.write_text(head + "simulation:\n  joint_check: {clearance_m: -1}\n")
    assert cli.main(["plan", str(task), "--library", "paper5"]) == 2
    assert "simulation.joint_check.clearance_m" in capsys.readouterr().err


@pytest.mark.slow
def test_simulate_exit_codes_say_what_happened(tmp_path):
    """0 when every trial succeeded, 3 when every trial needs a demonstration, 4 when a
    trial has no executable plan (or failed)."""
    import drake_lfd.cli as cli

    sims = scenarios_directory()
    assert cli.main(["simulate", str(sims / "assembling.yaml"), "--library", "paper6"]) == 0
    assert cli.main(["simulate", str(sims / "assembling.yaml"), "--library", "paper5", "--trials", "2"]) == 3
    far = tmp_path / "far.yaml"
    far.write_text("""\
name: far
X_tool0_E: {p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}
critical_configurations:
  - {p: [0.4, -0.2, 0.2], euler_zyx: [0, -pi/2, 0]}
  - {p: [5.0, 0.2, 0.3], euler_zyx: [0, -pi/2, 0]}
""")
    assert cli.main(["simulate", str(far), "--library", "paper5"]) == 4
