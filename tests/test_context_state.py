"""The systems' run state lives in the Context, and abstract ports are typed.

One Diagram, many Contexts: a :class:`DemoRecorder` records each simulation's own
samples (also when two simulations advance in turns), as Drake's own per-Context
``VectorLogSink`` does; :class:`FeatureLibrarySystem` keeps the demonstrations it adds in
its state and writes no file while simulating; ``DiagramBuilder.Connect`` refuses to
connect abstract ports of different Python types (``systems/typed_ports.py``).
"""

import os
import types

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Adder, ConstantValueSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

import drake_lfd.io.atomic_files as atomic_files
import drake_lfd.io.demonstration_logs as demonstration_logs
from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import ConcreteTask
from drake_lfd.io.demonstration_logs import read_rtde_csv
from drake_lfd.io.library import Library, library_features
from drake_lfd.systems.demo_recorder import (
    NO_DEMONSTRATION,
    DemoRecorder,
    RecordedSamples,
    add_joint_logger,
    demonstration_from_log,
)
from drake_lfd.systems.feature_library import FeatureLibrarySystem, LibraryFeatures
from drake_lfd.systems.plan_trajectory_source import PlanTrajectorySource
from drake_lfd.systems.planner import NO_PLAN, PlannerSystem

SIMS = scenarios_directory()
RATE_HZ = 500.0


def ramp(t):
    """The input trajectory's value at times ``t`` (shape (m,)): joint j is ``(j + 1) t``."""
    return np.outer(np.asarray(t, dtype=float), np.arange(1.0, 7.0))


def recorder_diagram():
    """A recorder and a Drake log of ``ramp(t) + offset`` (``offset``: the Diagram's input)."""
    builder = DiagramBuilder()
    times = np.array([0.0, 1.0])
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(times, ramp(times).T)))
    adder = builder.AddSystem(Adder(2, 6))
    builder.Connect(source.get_output_port(), adder.get_input_port(0))
    builder.ExportInput(adder.get_input_port(1), "offset")
    recorder = DemoRecorder.AddToBuilder(
        builder=builder, measured_position_output_port=adder.get_output_port(), rate_hz=RATE_HZ)
    logger = add_joint_logger(builder, adder.get_output_port(), rate_hz=RATE_HZ)
    return builder.Build(), recorder, logger


def simulator_for(diagram, offset):
    simulator = Simulator(diagram, diagram.CreateDefaultContext())
    diagram.GetInputPort("offset").FixValue(simulator.get_mutable_context(), np.full(6, offset))
    simulator.Initialize()
    return simulator


def expected(end_s, offset):
    t = np.round(np.arange(int(round(end_s * RATE_HZ)) + 1) / RATE_HZ, 6)
    return t, ramp(t) + offset


def test_two_simulations_of_one_diagram_record_their_own_samples():
    diagram, recorder, logger = recorder_diagram()
    runs = ((0.1, 0.0), (0.06, 1.0))
    simulators = [simulator_for(diagram, offset) for _, offset in runs]
    for simulator, (end_s, _) in zip(simulators, runs):
        simulator.AdvanceTo(end_s)
        simulator.AdvancePendingEvents()  # the sample at end_s
    for simulator, (end_s, offset) in zip(simulators, runs):
        context = simulator.get_context()
        demonstration = recorder.demonstration(context, "ramp")
        t, q = expected(end_s, offset)
        assert recorder.num_samples(context) == t.shape[0]
        np.testing.assert_allclose(demonstration.timestamps, t, atol=1e-12)
        np.testing.assert_allclose(demonstration.joint_positions, q, atol=1e-12)
        # Drake's own per-Context log of the same port holds the same samples.
        logged = demonstration_from_log(logger.FindLog(context), name="ramp")
        np.testing.assert_array_equal(logged.timestamps, demonstration.timestamps)
        np.testing.assert_array_equal(logged.joint_positions, demonstration.joint_positions)
    # A fresh Context of the Diagram starts empty.
    assert recorder.num_samples(diagram.CreateDefaultContext()) == 0


def test_simulations_advanced_in_turns_record_as_each_alone():
    diagram, recorder, _ = recorder_diagram()
    alone = []
    for offset in (0.0, 2.0):
        simulator = simulator_for(diagram, offset)
        simulator.AdvanceTo(0.05)
        alone.append(recorder.demonstration(simulator.get_context()))
    turns = [simulator_for(diagram, offset) for offset in (0.0, 2.0)]
    for step in range(1, 11):
        for simulator in turns:
            simulator.AdvanceTo(0.005 * step)
    for simulator, reference in zip(turns, alone):
        demonstration = recorder.demonstration(simulator.get_context())
        assert demonstration.num_samples == reference.num_samples == 25
        np.testing.assert_array_equal(demonstration.timestamps, reference.timestamps)
        np.testing.assert_array_equal(demonstration.joint_positions, reference.joint_positions)


def test_the_demonstration_port_is_empty_until_the_finish_time_then_stays():
    builder = DiagramBuilder()
    times = np.array([0.0, 1.0])
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(times, ramp(times).T)))
    recorder = DemoRecorder.AddToBuilder(builder=builder, measured_position_output_port=source.get_output_port(),
                                         rate_hz=100.0, finish_time_s=0.05, demo_name="short", description="a ramp")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    port_context = recorder.GetMyContextFromRoot(simulator.get_context())
    simulator.AdvanceTo(0.05)
    assert recorder.demonstration_output_port.Eval(port_context) is NO_DEMONSTRATION
    simulator.AdvanceTo(0.2)
    demonstration = recorder.demonstration_output_port.Eval(port_context)
    assert (demonstration.name, demonstration.description) == ("short", "a ramp")
    np.testing.assert_allclose(demonstration.timestamps, np.arange(6) * 0.01, atol=1e-12)
    assert recorder.num_samples(simulator.get_context()) == 6  # recording stopped at the finish time


def test_recorded_samples_are_shared_not_copied():
    import copy

    samples = RecordedSamples().appended(0.0, np.zeros(6))
    longer = samples.appended(0.1, np.ones(6))
    assert copy.deepcopy(longer) is longer
    assert samples.num_samples == 1 and longer.num_samples == 2
    times, positions = longer.arrays(6)
    np.testing.assert_array_equal(times, [0.0, 0.1])
    np.testing.assert_array_equal(positions, [np.zeros(6), np.ones(6)])


def test_demonstration_from_log_drops_repeated_times():
    class Log:
        def sample_times(self):
            return np.array([0.0, 0.002, 0.002, 0.0040000000001])

        def data(self):
            return np.arange(24.0).reshape(4, 6).T

    demonstration = demonstration_from_log(Log(), name="x", description="d")
    np.testing.assert_array_equal(demonstration.timestamps, [0.0, 0.002, 0.004])
    np.testing.assert_array_equal(demonstration.joint_positions[:, 0], [0.0, 6.0, 18.0])


# ------------------------------------------------------------------ typed ports


class _Sink(LeafSystem):
    """A system with one abstract input port of ``model``'s type."""

    def __init__(self, model):
        super().__init__()
        self.DeclareAbstractInputPort("u", AbstractValue.Make(model))


def test_a_library_output_cannot_feed_a_task_input():
    builder = DiagramBuilder()
    library = builder.AddSystem(FeatureLibrarySystem(features={}))
    planner = builder.AddSystem(PlannerSystem())
    with pytest.raises(RuntimeError, match="Mismatched value types.*LibraryFeatures.*ConcreteTask"):
        builder.Connect(library.library_output_port, planner.task_input_port)
    builder.Connect(library.library_output_port, planner.library_input_port)  # the right input


def test_miswired_abstract_ports_raise_at_connect():
    builder = DiagramBuilder()
    times = np.array([0.0, 1.0])
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(times, ramp(times).T)))
    recorder = DemoRecorder.AddToBuilder(
        builder=builder, measured_position_output_port=source.get_output_port())
    planner = builder.AddSystem(PlannerSystem())
    trajectory = builder.AddSystem(PlanTrajectorySource())
    task = builder.AddSystem(ConstantValueSource(AbstractValue.Make(ConcreteTask("t", ()))))
    with pytest.raises(RuntimeError, match="Mismatched value types"):
        builder.Connect(recorder.demonstration_output_port, planner.library_input_port)
    with pytest.raises(RuntimeError, match="Mismatched value types"):
        builder.Connect(task.get_output_port(), trajectory.plan_input_port)
    with pytest.raises(RuntimeError, match="Mismatched value types"):
        builder.Connect(planner.plan_output_port, builder.AddSystem(_Sink(NO_DEMONSTRATION)).get_input_port())
    builder.Connect(planner.plan_output_port, trajectory.plan_input_port)
    builder.Connect(task.get_output_port(), planner.task_input_port)
    # A port declared with a plain object() takes anything.
    builder.Connect(recorder.demonstration_output_port, builder.AddSystem(_Sink(object())).get_input_port())


def test_the_typed_defaults_read_as_nothing_yet():
    planner = PlannerSystem()
    context = planner.CreateDefaultContext()
    assert planner.plan_output_port.Eval(context) is NO_PLAN
    assert planner.scheduled_plan(context) is None
    assert isinstance(NO_DEMONSTRATION, Demonstration) and NO_DEMONSTRATION.num_samples == 0


# ------------------------------------------------------------------ no file I/O in events


def _no_writes(*args, **kwargs):
    raise AssertionError("a file was written during the simulation")


def _snapshot(root):
    return sorted((str(path.relative_to(root)), path.stat().st_mtime_ns, path.stat().st_size)
                  for path in root.rglob("*"))


@pytest.mark.slow
def test_the_feature_library_writes_no_file_while_simulating(tmp_path, monkeypatch):
    paper5 = Library.open("paper5")
    library = Library.create(tmp_path / "lib", X_tool0_E=paper5.X_tool0_E)
    before = _snapshot(tmp_path)
    span = read_rtde_csv(SIMS / "libraries" / "paper6" / "demos" / "span.csv", name="span").demonstration
    t = span.timestamps - span.timestamps[0]
    builder = DiagramBuilder()
    replay = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, span.joint_positions.T)))
    recorder = DemoRecorder.AddToBuilder(builder=builder, measured_position_output_port=replay.get_output_port(),
                                         finish_time_s=float(t[-1]), demo_name="span", description="the span",
                                         rate_hz=125.0)
    dut = FeatureLibrarySystem.AddToBuilder(
        builder=builder, features=library_features(paper5), X_tool0_E=paper5.X_tool0_E,
        demonstration_output_port=recorder.demonstration_output_port, check_period=0.1)
    diagram = builder.Build()

    with monkeypatch.context() as patches:
        for module, name in ((atomic_files, "atomic_write_bytes"), (atomic_files, "atomic_write_many"),
                             (atomic_files, "atomic_write_json"), (demonstration_logs, "write_rtde_csv"),
                             (Library, "add"), (Library, "add_prepared"), (os, "replace"), (os, "rename")):
            patches.setattr(module, name, _no_writes)
        simulator = Simulator(diagram)
        simulator.Initialize()
        simulator.AdvanceTo(float(t[-1]) + 0.25)
    assert _snapshot(tmp_path) == before
    context = simulator.get_context()
    features = dut.library_output_port.Eval(dut.GetMyContextFromRoot(context))
    assert features.revision == 1 and "span" in features.names
    (added,) = dut.added_demonstrations(context)
    assert (added.name, added.description) == ("span", "the span")
    assert dut.added_demonstrations(diagram.CreateDefaultContext()) == ()  # per Context

    # After the run, the added demonstration goes to the library (once).
    assert dut.write_added_demonstrations(context, library) == ("span",)
    assert dut.write_added_demonstrations(context, library) == ()
    reopened = Library.open(tmp_path / "lib")
    assert reopened.names == ("span",)
    np.testing.assert_allclose(reopened.demonstration("span").joint_positions, added.joint_positions, atol=1e-9)


def test_library_features_default_is_typed():
    dut = FeatureLibrarySystem(features={}, accept_demonstrations=True)
    context = dut.CreateDefaultContext()
    dut.demonstration_input_port.FixValue(context, NO_DEMONSTRATION)
    value = dut.library_output_port.Eval(context)
    assert isinstance(value, LibraryFeatures) and value.names == ()
    assert value.features == types.MappingProxyType({})
