"""The compiled closed loop (the default controller) against the Python baseline, and the
shell monitor measuring the joint log in batches against the per-sample monitor."""

import dataclasses
import math

import numpy as np
import pytest

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import Box
from drake_lfd.diagrams.closed_loop import ClosedLoopRunner, plan_through_joint_configurations, run_closed_loop
from drake_lfd.diagrams.pipeline import build_pipeline, scheduled_plan_from_timed
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.simulation_config import PipelineConfig
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.systems.joint_path_source import JointPathSource
from drake_lfd.systems.joint_trajectory_controller import (
    CHUNK_SAMPLES, JointTrajectoryController, feed_forward_samples, joint_trajectory_of_plan,
)
from drake_lfd.systems.shell_monitor import _motion_bound, _motion_bounds

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])
Q_A = Q_HOME + np.array([0.25, 0.1, -0.15, 0.05, 0.1, 0.2])
Q_B = Q_HOME + np.array([-0.05, 0.05, 0.1, 0.1, -0.1, -0.2])
SHELL = Box(name="shell_below", centre=[-0.60, -0.25, 0.12], size=[0.3, 0.3, 0.1])


def test_the_default_controller_is_the_compiled_one_without_python_systems():
    pipeline = build_pipeline(plan=plan_through_joint_configurations([Q_HOME, Q_A]), with_table=False)
    assert pipeline.config.controller.method == "compiled"
    assert isinstance(pipeline.controller, JointTrajectoryController)
    # Every system of the controller is one of Drake's C++ primitives.
    names = {type(system).__name__ for system in pipeline.controller.GetSystems()}
    assert names == {"AffineSystem", "Adder", "Demultiplexer", "Multiplexer", "MatrixGain", "Saturation",
                     "LinearSystem", "SparseMatrixGain"}
    # The only Python system feeding it, the joint-path source, has no event in the 100 Hz
    # loop: one periodic update per chunk of CHUNK_SAMPLES (10) controller periods.
    assert isinstance(pipeline.source, JointPathSource)
    attribute = pipeline.source.GetUniquePeriodicDiscreteUpdateAttribute()
    assert attribute.period_sec() == pytest.approx(CHUNK_SAMPLES * pipeline.config.controller.time_step)
    assert CHUNK_SAMPLES >= 10
    # The monitor has no event of its own: it measures the joint log.
    assert pipeline.monitor.measures_log


def test_a_given_plan_becomes_a_joint_path_whose_kinematics_is_the_plan():
    plan = plan_through_joint_configurations([Q_HOME, Q_A, Q_B])
    pipeline = build_pipeline(plan=plan, with_table=False)
    scheduled = scheduled_plan_from_timed(plan, 0.5)
    trajectory = joint_trajectory_of_plan(scheduled, Q_HOME, pipeline.law)
    kinematics = UR5eKinematics()

    def gap(t):
        X_path, X_plan = kinematics.X_WE(trajectory.value(t)[:, 0]), scheduled.X_WE_desired(t)
        return np.linalg.norm(X_path.translation() - X_plan.translation())

    # At its samples (every controller period) the path is the plan; between them the
    # spline stays within a tenth of a millimetre.
    assert max(gap(0.5 + 0.01 * k) for k in range(0, int(plan.duration / 0.01), 7)) < 1e-9
    assert max(gap(t) for t in np.linspace(0.5, 0.5 + plan.duration, 97)) < 1e-4
    np.testing.assert_allclose(trajectory.value(0.0)[:, 0], Q_HOME)  # held before the start


@pytest.mark.slow
def test_compiled_tracking_is_at_least_as_good_as_the_python_controller():
    plan = plan_through_joint_configurations([Q_HOME, Q_A, Q_B])
    results = {method: run_closed_loop(plan, q_initial=Q_HOME, safety_shells=[SHELL], controller=method)
               for method in ("compiled", "drake")}
    worst = {method: max(e.position_m for e in result.critical_errors) for method, result in results.items()}
    assert worst["compiled"] <= max(worst["drake"], 1e-4)
    assert results["compiled"].max_joint_speed_fraction <= 1.0
    # The same motion: the logs agree to a millimetre-sized joint difference.
    assert np.max(np.abs(results["compiled"].q - results["drake"].q)) < 5e-3


def _records(task, features, trials, **monitor):
    config = dataclasses.replace(task.simulation, monitor=dataclasses.replace(task.simulation.monitor, **monitor))
    runner = TrialRunner(task, features, config=config, options=PlanningOptions(cost="paper"))
    assert runner._runner.pipeline.monitor.measures_log == monitor["from_log"]
    records = []
    for i in range(trials):
        outcome = runner.run(trial=i + 1, seed=i)
        records.append(None if outcome.run is None else outcome.run.clearances)
    return records, runner._runner.pipeline.monitor.num_pair_queries


@pytest.mark.slow
def test_the_batched_monitor_keeps_every_record_of_the_per_sample_monitor():
    task = load_task(scenarios_directory() / "transferring.yaml")
    features = library_features(Library.open("paper5"))
    per_sample, per_sample_queries = _records(task, features, 3, from_log=False)
    batched, batched_queries = _records(task, features, 3, from_log=True)
    assert all(r is not None for r in per_sample)
    # The same minimum, geometry and time of every box, to the bit.
    assert batched == per_sample
    # The batch skips the same pairs (it poses the arm only where some pair is due).
    assert batched_queries == per_sample_queries > 0


@pytest.mark.slow
def test_runs_with_a_penetration_stop_keep_sampling_each_period():
    plan = plan_through_joint_configurations([Q_HOME, Q_A])
    config = PipelineConfig()
    config.monitor.stop_on_penetration = True
    pipeline = build_pipeline(plan=plan, safety_shells=[SHELL], with_table=False, config=config)
    assert not pipeline.monitor.measures_log
    _, result = ClosedLoopRunner(pipeline).run(q_initial=Q_HOME)
    assert not result.stopped_early and math.isfinite(result.min_shell_distance_m)


def test_batched_motion_bounds_are_the_per_sample_bounds_to_the_bit_and_nondecreasing():
    rng = np.random.default_rng(3)
    travel = np.cumsum(rng.random((200, 6)) * 1e-3, axis=0)  # (K, J): a joint travel grows
    radii = (rng.random((4, 6)) * 0.8).tolist()
    bounds = _motion_bounds(radii, [True, True, False, True], travel)
    assert bounds.shape == (200, 4)
    for k in range(0, 200, 17):
        for i in (0, 1, 3):
            assert bounds[k, i] == _motion_bound(radii[i], travel[k].tolist())
    assert np.all(np.isinf(bounds[:, 2]))
    # The batch finds each pair's next due sample by bisection: the bound never decreases.
    assert np.all(np.diff(bounds[:, [0, 1, 3]], axis=0) >= 0.0)


def _controller_and_path():
    law = build_pipeline(plan=plan_through_joint_configurations([Q_HOME, Q_A]), with_table=False).law
    controller = JointTrajectoryController.for_law(law)
    dt = controller.time_step
    # A path sampled at the controller instants from 0.05 s, held before and after.
    t = 0.05 + dt * np.arange(40)
    s = 0.5 - 0.5 * np.cos(np.pi * np.arange(40) / 39)
    q = Q_HOME + s[:, None] * (Q_A - Q_HOME)
    return controller, t, q, law


def _fix_chunk(controller, context, t, q, k):
    """Fixes the chunk holding controller instant k, as the joint-path source puts it out."""
    M, dt = controller.chunk_samples, controller.time_step
    first = (k // M) * M  # the controller counts instants from t = 0
    w = feed_forward_samples(t, q, dt, controller.position_gain, controller.lead_s, first, M)
    controller.chunk_input_port.FixValue(context, np.concatenate([q[0], w.ravel()]))


def _step(controller, context):
    update = controller.EvalUniquePeriodicDiscreteUpdate(context)
    for group in range(update.num_groups()):
        context.SetDiscreteState(group, update.get_vector(group).value().copy())


def test_the_compiled_command_is_held_between_updates_without_feed_through():
    controller = _controller_and_path()[0]
    # The command depends on the measurement only through the integrator's state: the
    # drive holds it between updates and nothing upstream is evaluated at plant steps.
    # (The chunk's q_0 passes to the command: it is the source's state, set once a run.)
    assert not controller.HasDirectFeedthrough(controller.q_measured_input_port.get_index(),
                                               controller.q_command_output_port.get_index())


def test_open_loop_the_compiled_command_is_the_path_one_period_ahead_sample_for_sample():
    controller, t, q, _ = _controller_and_path()
    context = controller.CreateDefaultContext()
    dt = controller.time_step
    desired = lambda time: np.array([np.interp(time, t, q[:, j]) for j in range(6)])
    for k in range(60):  # across two chunk boundaries
        context.SetTime(k * dt)
        _fix_chunk(controller, context, t, q, k)
        # The sample the controller picks is the path's w_k, to the bit.
        np.testing.assert_array_equal(
            controller.feed_forward(context),
            feed_forward_samples(t, q, dt, controller.position_gain, controller.lead_s, k, 1)[0])
        # The arm exactly on the path: no feedback, the feed-forward alone.
        controller.q_measured_input_port.FixValue(context, desired(k * dt))
        np.testing.assert_allclose(controller.q_command_output_port.Eval(context), desired((k + 1) * dt),
                                   atol=1e-12)
        _step(controller, context)
    # Held after the end: the command stays at the path's last sample.
    np.testing.assert_allclose(controller.q_command_output_port.Eval(context), q[-1], atol=1e-12)


def test_two_contexts_of_one_controller_follow_their_own_chunks():
    controller, t, q, _ = _controller_and_path()
    first, second = controller.CreateDefaultContext(), controller.CreateDefaultContext()
    _fix_chunk(controller, first, t, q, 0)
    _fix_chunk(controller, second, t, q[::-1], 0)
    dt, K = controller.time_step, controller.position_gain
    # w_0 (the path held before its start) differs: each Context has its own chunk.
    np.testing.assert_allclose(controller.feed_forward(first), dt * K * q[0], atol=1e-12)
    np.testing.assert_allclose(controller.feed_forward(second), dt * K * q[-1], atol=1e-12)


def test_the_compiled_feedback_pulls_the_command_towards_the_path_at_the_clipped_speed():
    controller, t, q, law = _controller_and_path()
    context = controller.CreateDefaultContext()
    _fix_chunk(controller, context, t, q, 0)
    dt, K = controller.time_step, controller.position_gain
    # 1 mrad behind on every joint, before the path starts: dt K of it corrected per period.
    controller.q_measured_input_port.FixValue(context, q[0] - 1e-3)
    _step(controller, context)
    np.testing.assert_allclose(controller.q_command_output_port.Eval(context), q[0] + dt * K * 1e-3, atol=1e-12)
    # Far behind: each joint's step is clipped at its speed limit.
    controller.q_measured_input_port.FixValue(context, q[0] - 1.0)
    before = controller.q_command_output_port.Eval(context).copy()
    context.SetTime(dt)
    _step(controller, context)
    step = controller.q_command_output_port.Eval(context) - before
    np.testing.assert_allclose(step, dt * law.velocity_limits, rtol=1e-12)


@pytest.mark.slow
def test_with_sampled_output_ports_the_feedback_compares_the_path_a_plant_step_later():
    # The plant's step then comes before the controller's update at the same instant: the
    # measurement is of t + h, and the feedback compares it with the path at t + h.
    plan = plan_through_joint_configurations([Q_HOME, Q_A, Q_B])
    config = PipelineConfig()
    config.station.sampled_output_ports = True
    pipeline = build_pipeline(plan=plan, with_table=False, config=config)
    assert pipeline.controller.lead_s == pipeline.station.time_step > 0.0
    _, result = ClosedLoopRunner(pipeline).run(q_initial=Q_HOME)
    assert max(e.position_m for e in result.critical_errors) < 1e-4
