"""The pipeline Diagram: library system -> planner system -> trajectory source -> diff IK
-> station -> monitor, one Diagram for many trials, replanning when the task changes."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from pydrake.common.value import AbstractValue

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.diagrams.closed_loop import ClosedLoopRunner
from drake_lfd.diagrams.pipeline import build_pipeline
from drake_lfd.diagrams.judging import judge_run
from drake_lfd.io.demonstration_logs import read_rtde_csv
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.systems.demo_recorder import DemoRecorder
from drake_lfd.systems.feature_library import FeatureLibrarySystem, LibraryFeatures
from drake_lfd.systems.planner import PlannerSystem

SIMS = scenarios_directory()


@pytest.fixture(scope="module")
def transferring():
    task = load_task(SIMS / "transferring.yaml")
    features = library_features(Library.open("paper5"))
    return task, features, ClosedLoopRunner(build_pipeline(task, features))


def moved(concrete, con_index, offset):
    cons = list(concrete.critical_configurations)
    cons[con_index] = dataclasses.replace(cons[con_index], p=np.asarray(cons[con_index].p) + offset)
    return dataclasses.replace(concrete, critical_configurations=tuple(cons))


def final_position_error(runner, result, target):
    X_WE = runner.kinematics.X_WE(result.q[-1])
    return float(np.linalg.norm(X_WE.translation() - target))


@pytest.mark.slow
def test_one_diagram_runs_a_trial_then_replans_when_con_4_moves(transferring):
    task, _features, runner = transferring
    concrete = draw_trial(task, 0)
    scheduled, result = runner.run(concrete)
    assert scheduled.planned and scheduled.revision == 0
    assert judge_run(result, path_constraints=concrete.path_constraints).success

    # Same Diagram, same Simulator: con_4 moves by 5 cm while the arm heads for con_3.
    due = runner.plan(concrete).due_times_s()
    changed = moved(concrete, 3, [0.05, 0.0, 0.0])
    t_change = 0.5 * (due[1] + due[2])
    scheduled, result = runner.run(concrete, task_changes=[(t_change, changed)])
    assert scheduled.revision == 1
    new_con_4 = changed.critical_configurations[3].p
    assert final_position_error(runner, result, new_con_4) <= 0.005
    assert result.critical_errors[3].position_m <= 0.005
    assert result.max_joint_speed_fraction <= 1.0
    verdict = judge_run(result, path_constraints=concrete.path_constraints)
    assert verdict.success, verdict.failures


@pytest.mark.slow
def test_replans_from_the_current_pose_when_the_configuration_ahead_moves(transferring):
    task, _features, runner = transferring
    concrete = draw_trial(task, 1)
    due = runner.plan(concrete).due_times_s()
    changed = moved(concrete, 3, [0.0, 0.05, 0.0])
    t_change = due[2] + 0.4 * (due[3] - due[2])  # on the way to con_4
    scheduled, result = runner.run(concrete, task_changes=[(t_change, changed)])
    assert scheduled.revision == 1
    assert final_position_error(runner, result, changed.critical_configurations[3].p) <= 0.005
    assert result.max_joint_speed_fraction <= 1.0
    # The commanded pose is continuous through the replan: no jump in the logged joints.
    assert np.abs(np.diff(result.q, axis=0)).max() < 0.05


def test_planner_system_plans_and_replans_on_a_changed_task():
    task = load_task(SIMS / "transferring.yaml")
    features = library_features(Library.open("paper5"))
    dut = PlannerSystem(options=PlanningOptions(cost="paper"), start_time_s=0.5)
    context = dut.CreateDefaultContext()
    concrete = draw_trial(task, 0)
    dut.task_input_port.FixValue(context, concrete)
    dut.library_input_port.FixValue(context, LibraryFeatures(features))
    first = dut.plan_now(context)
    assert first.planned and first.start_time_s == 0.5
    assert dut.plan_output_port.Eval(context) is first
    assert dut.next_plan(context) is first  # nothing changed: no replanning
    dut.task_input_port.FixValue(context, moved(concrete, 3, [0.0, 0.0, 0.05]))
    second = dut.next_plan(context)
    assert second is not first and second.revision == 1


@pytest.mark.slow
def test_record_library_plan_in_one_diagram():
    """A demonstration recorded in the Diagram reaches the library system, and the
    planner, which asked for it, plans the assembling task with it."""
    task = load_task(SIMS / "assembling.yaml")
    concrete = draw_trial(task, 0)
    library = Library.open("paper5")
    features = library_features(library)
    span = read_rtde_csv(SIMS / "libraries" / "paper6" / "demos" / "span.csv", name="span").demonstration
    t = span.timestamps - span.timestamps[0]

    builder = DiagramBuilder()
    # The recorded joints stand for the guided arm's measured positions.
    replay = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, span.joint_positions.T)))
    recorder = DemoRecorder.AddToBuilder(builder=builder, measured_position_output_port=replay.get_output_port(),
                                         finish_time_s=float(t[-1]), demo_name="span", rate_hz=125.0)
    library_system = FeatureLibrarySystem.AddToBuilder(
        builder=builder, features=features, X_tool0_E=library.X_tool0_E,
        demonstration_output_port=recorder.demonstration_output_port, check_period=0.1)
    task_source = builder.AddSystem(ConstantValueSource(AbstractValue.Make(concrete)))
    planner = PlannerSystem.AddToBuilder(builder=builder, library_output_port=library_system.library_output_port,
                                         task_output_port=task_source.get_output_port(), check_period=0.1,
                                         options=PlanningOptions(cost="paper"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    context = simulator.get_context()
    before = planner.plan_output_port.Eval(planner.GetMyContextFromRoot(context))
    assert before.result.status == "demonstration_requested"
    simulator.AdvanceTo(float(t[-1]) + 0.25)
    after = planner.plan_output_port.Eval(planner.GetMyContextFromRoot(context))
    assert after.planned
    assert "span" in [step.demo for step in after.result.composition]
    assert library_system.library_output_port.Eval(library_system.GetMyContextFromRoot(context)).revision == 1


def test_planner_system_replans_for_another_library_of_the_same_revision():
    task = load_task(SIMS / "assembling.yaml")
    dut = PlannerSystem(options=PlanningOptions(cost="paper"))
    context = dut.CreateDefaultContext()
    dut.task_input_port.FixValue(context, draw_trial(task, 0))
    dut.library_input_port.FixValue(context, LibraryFeatures(library_features(Library.open("paper5"))))
    assert dut.plan_now(context).result.status == "demonstration_requested"
    dut.library_input_port.FixValue(context, LibraryFeatures(library_features(Library.open("paper6"))))
    assert dut.plan_now(context).planned  # both are revision 0: their contents tell them apart


def test_the_library_is_prepared_when_the_pipeline_is_built_not_in_the_first_plan(monkeypatch):
    # The legal-action table's prepared library (stacks, span index, the index's
    # scipy.spatial import) is built with the Diagram; the first plan reuses it.
    from drake_lfd.planning import span_index

    task = load_task(SIMS / "transferring.yaml")
    # New feature objects: nothing of them is in the prepared libraries' cache yet.
    features = {name: dataclasses.replace(feature) for name, feature in library_features(Library.open("paper5")).items()}
    built = []
    original = span_index.PreparedLibrary.__init__

    def counting(self, *args, **kwargs):
        built.append(self)
        original(self, *args, **kwargs)

    monkeypatch.setattr(span_index.PreparedLibrary, "__init__", counting)
    runner = ClosedLoopRunner(build_pipeline(task, features, planning=PlanningOptions(joint_check=False)))
    assert len(built) == 1
    scheduled = runner.plan(draw_trial(task, 0))
    assert scheduled.result.planned
    assert len(built) == 1
