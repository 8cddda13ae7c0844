"""One pipeline Diagram, many trials in many Contexts: Drake's own tools for many runs.

The pipeline keeps everything a trial needs in its Context (task input, plan, joint path,
arm state, log, monitor records), ends a run itself once the plan is executed, and judges
it from the Context alone; so ``MonteCarloSimulation`` runs it, and Contexts advanced in
turns do not disturb each other.
"""

import dataclasses

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import MonteCarloSimulation, Simulator

import drake_lfd
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import PathConstraint, draw_trial
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def task():
    return drake_lfd.load_task(scenarios_directory() / "transferring.yaml")


@pytest.fixture(scope="module")
def pipeline(task):
    return drake_lfd.build_pipeline(task, library="paper5")


def _log(pipeline, context):
    log = pipeline.logger.FindLog(context)
    return log.sample_times().copy(), log.data().copy()


def _random_simulation(pipeline, generator, final_time=60.0):
    """What Drake's RandomSimulation does, keeping the simulator to read its log."""
    simulator = pipeline.make_simulator(generator)
    pipeline.SetRandomContext(simulator.get_mutable_context(), generator)
    simulator.AdvanceTo(final_time)
    return simulator


def test_monte_carlo_simulation_runs_ten_trials_of_one_diagram_and_all_succeed(pipeline):
    finished = []

    def output(system, context):
        assert system is pipeline
        plan = pipeline.plan_output_port.Eval(context)
        # The Diagram ended the run itself, once the plan was executed (not at 60 s).
        finished.append((context.get_time(), float(plan.due_times_s()[-1]), plan.result.composition))
        return pipeline.trial_succeeded(system, context)

    runs = MonteCarloSimulation(make_simulator=pipeline.make_simulator, output=output, final_time=60.0,
                                num_samples=10, generator=RandomGenerator(7))
    assert [run.output for run in runs] == [1.0] * 10
    for end, due, composition in finished:
        assert due <= end <= due + pipeline.trial_end.period + 1e-9
        assert len(composition) >= 1
    # The samples are different trials (drawn from the generator).
    assert len({round(due, 9) for _, due, _ in finished}) > 1


def test_the_same_generator_state_gives_the_same_trial_and_the_same_joint_log(pipeline):
    first = _random_simulation(pipeline, RandomGenerator(11))
    second = _random_simulation(pipeline, RandomGenerator(11))
    t1, x1 = _log(pipeline, first.get_context())
    t2, x2 = _log(pipeline, second.get_context())
    assert len(t1) > 100
    np.testing.assert_array_equal(t1, t2)
    np.testing.assert_array_equal(x1, x2)
    other = _random_simulation(pipeline, RandomGenerator(12))
    assert not np.array_equal(_log(pipeline, other.get_context())[1][:, -1], x1[:, -1])


def test_two_contexts_advanced_in_turns_log_what_each_logs_alone(pipeline, task):
    trials = [draw_trial(task, 3), draw_trial(task, 4)]

    def prepared(trial):
        simulator = Simulator(pipeline)
        pipeline.prepare_trial(simulator.get_mutable_context(), trial)
        simulator.Initialize()
        return simulator

    alone = []
    for trial in trials:
        simulator = prepared(trial)
        simulator.AdvanceTo(20.0)
        alone.append(_log(pipeline, simulator.get_context()))
    together = [prepared(trial) for trial in trials]
    ended = [False, False]
    t = 0.0
    while t < 20.0 and not all(ended):
        t += 1.0
        for i, simulator in enumerate(together):  # 1 s of one, then 1 s of the other
            if not ended[i]:
                status = simulator.AdvanceTo(t)
                ended[i] = status.reason() == status.ReturnReason.kReachedTerminationCondition
    for simulator, (t_alone, x_alone) in zip(together, alone):
        t_turns, x_turns = _log(pipeline, simulator.get_context())
        np.testing.assert_array_equal(t_turns, t_alone)
        np.testing.assert_array_equal(x_turns, x_alone)
    assert not np.array_equal(alone[0][1][:, -1], alone[1][1][:, -1])


def test_trial_succeeded_gives_the_verdict_simulate_gives(pipeline, task):
    runner = TrialRunner(task, library_features(Library.open("paper5")))
    for seed in (0, 5):
        outcome = runner.run(trial=1, seed=seed)
        simulator = Simulator(pipeline)
        pipeline.prepare_trial(simulator.get_mutable_context(), draw_trial(task, seed))
        simulator.AdvanceTo(60.0)
        judgement = pipeline.trial_judgement(simulator.get_context())
        assert judgement.success == outcome.success
        assert pipeline.trial_succeeded(pipeline, simulator.get_context()) == float(outcome.success)
        assert [s.demo for s in outcome.plan.composition] == [
            s.demo for s in pipeline.plan_output_port.Eval(simulator.get_context()).result.composition]


def test_judge_run_reads_the_trials_path_constraints_from_the_run(pipeline, task):
    simulator = Simulator(pipeline)
    pipeline.prepare_trial(simulator.get_mutable_context(), draw_trial(task, 0))
    simulator.AdvanceTo(60.0)
    run = pipeline.trial_result(simulator.get_context())
    assert drake_lfd.judge_run(run).success
    # The same run, its trial holding the tool within 0.1 deg of level from con_1 to
    # con_4 (the transferring task tilts the cup): judged failed without being told again.
    level = PathConstraint("orientation", 1, 4, np.zeros(3), np.radians(0.1))
    strict = dataclasses.replace(run, path_constraints=(level,))
    judgement = drake_lfd.judge_run(strict)
    assert not judgement.success
    assert any(failure.startswith("path constraint con_1..con_4") for failure in judgement.failures)
    # Each failure is a record of its kind (summaries group by it, never by the text).
    assert [(f.kind, f.configuration) for f in judgement.failures] == [("path_constraint", 1)]
    # Constraints passed explicitly replace the run's own.
    assert drake_lfd.judge_run(strict, path_constraints=()).success


def test_a_run_stopped_before_the_plan_is_executed_is_not_a_success(pipeline, task):
    simulator = Simulator(pipeline)
    pipeline.prepare_trial(simulator.get_mutable_context(), draw_trial(task, 0))
    simulator.AdvanceTo(1.0)
    judgement = pipeline.trial_judgement(simulator.get_context())
    assert not judgement.success
    assert any("not reached" in failure for failure in judgement.failures)
    assert {f.kind for f in judgement.failures} == {"not_reached"}

