"""The station Diagram owns what it uses, names its ports ``ur5e.<quantity>`` and is
configured by typed dataclasses (``drake_lfd.io.simulation_config``)."""

import dataclasses
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from pydrake.systems.analysis import ApplySimulatorConfig, ExtractSimulatorConfig, Simulator, SimulatorConfig

import drake_lfd.diagrams.station as mut
from drake_lfd.core.errors import InputError
from drake_lfd.io.simulation_config import PipelineConfig, StationConfig
from drake_lfd.io.task_files import load_task

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -np.pi / 2, 0.0])


def test_keeping_only_the_returned_diagram_simulates_without_a_crash():
    # In a subprocess: a controller plant freed under the Diagram crashes the interpreter.
    script = textwrap.dedent(
        """
        import gc
        import numpy as np
        from pydrake.systems.analysis import Simulator
        from drake_lfd.diagrams.station import build_station

        diagram = build_station()
        gc.collect()
        context = diagram.CreateDefaultContext()
        q = np.array([0.0, -1.2, 1.6, -1.97, -np.pi / 2, 0.0])
        diagram.set_initial_positions(context, q)
        diagram.GetInputPort("ur5e.position_command").FixValue(context, q)
        simulator = Simulator(diagram, context)
        simulator.AdvanceTo(1.0)
        print("drift", float(np.abs(diagram.GetOutputPort("ur5e.position_measured").Eval(context) - q).max()))
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    drift = float(done.stdout.split("drift")[1])
    assert drift < 1e-3  # gravity-compensated and held: the arm stays where it was put


def test_station_diagram_owns_its_controller_plant_inside_a_parent_diagram():
    script = textwrap.dedent(
        """
        import gc
        import numpy as np
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder
        from pydrake.systems.primitives import ConstantVectorSource
        from drake_lfd.diagrams.station import build_station

        q = np.array([0.0, -1.2, 1.6, -1.97, -np.pi / 2, 0.0])
        builder = DiagramBuilder()
        station = builder.AddSystem(build_station())
        source = builder.AddSystem(ConstantVectorSource(q))
        builder.Connect(source.get_output_port(), station.GetInputPort("ur5e.position_command"))
        diagram = builder.Build()
        del station, source, builder
        gc.collect()
        simulator = Simulator(diagram)
        simulator.AdvanceTo(0.5)
        print("ok")
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("ok")


def test_ports_are_named_model_quantity():
    dut = mut.build_station(config=StationConfig(model_name="ur5e"))
    assert dut.GetInputPort("ur5e.position_command").size() == 6
    for name, size in (("ur5e.position_measured", 6), ("ur5e.velocity_measured", 6), ("ur5e.state", 12)):
        assert dut.GetOutputPort(name).size() == size
    dut.GetOutputPort("query_object")


def test_the_station_tracks_a_step_with_the_configured_gains():
    softer = StationConfig()
    softer.drive.proportional_gains = [g / 4 for g in softer.drive.proportional_gains]
    errors = {}
    for label, config in (("default", StationConfig()), ("softer", softer)):
        dut = mut.build_station(config=config)
        context = dut.CreateDefaultContext()
        dut.set_initial_positions(context, Q_HOME)
        dut.GetInputPort("ur5e.position_command").FixValue(context, Q_HOME + 0.05)
        simulator = Simulator(dut, context)
        simulator.AdvanceTo(0.05)
        errors[label] = float(np.abs(dut.GetOutputPort("ur5e.position_measured").Eval(context) - (Q_HOME + 0.05)).max())
    assert errors["softer"] > errors["default"]  # the gains in the config are the ones used


TASK_HEAD = "name: t\ncritical_configurations:\n  - {p: [0.4, 0, 0.3], euler_zyx: [0, 0, 0]}\n  - {p: [0.4, 0.1, 0.3], euler_zyx: [0, 0, 0]}\n"


def load_task_text(tmp_path, text):
    path = tmp_path / "task.yaml"
    path.write_text(text)
    return load_task(path)


def test_simulation_block_is_loaded_typed_and_checked(tmp_path):
    config = load_task_text(tmp_path, TASK_HEAD + "simulation:\n  station: {time_step: 0.002}\n"
                            "  controller: {time_step: 0.02}\n  settle_s: 0.3\n").simulation
    assert config.station.time_step == 0.002
    assert config.station.command_period == 0.02  # tied to the controller's period
    assert config.settle_s == 0.3
    assert load_task_text(tmp_path, TASK_HEAD).simulation == PipelineConfig().checked()


@pytest.mark.parametrize("block, field", [
    ("simulation:\n  stationx: 1\n", "simulation.stationx"),
    ("simulation:\n  settle_s: abc\n", "simulation.settle_s"),
    ("simulation:\n  controller: {method: foo}\n", "simulation.controller.method"),
    ("simulation:\n  station: {time_step: -1}\n", "simulation.station.time_step"),
    ("simulation:\n  station: {drive: {proportional_gains: [1, 2]}}\n", "simulation.station.drive.proportional_gains"),
])
def test_bad_simulation_blocks_are_refused_naming_the_field(tmp_path, block, field):
    with pytest.raises(InputError) as error:
        load_task_text(tmp_path, TASK_HEAD + block)
    assert error.value.field == field
    assert "task.yaml" in str(error.value)


def test_a_task_files_simulation_block_configures_the_pipeline(tmp_path):
    from drake_lfd.core.resources import scenarios_directory
    from drake_lfd.diagrams.pipeline import build_pipeline
    from drake_lfd.io.library import Library, library_features
    from drake_lfd.io.task_files import load_task

    text = (scenarios_directory() / "transferring.yaml").read_text()
    path = tmp_path / "task.yaml"
    path.write_text(text + "\nsimulation:\n  settle_s: 0.3\n  station: {time_step: 0.002}\n")
    task = load_task(path)
    assert task.simulation.settle_s == 0.3 and task.simulation.station.time_step == 0.002
    pipeline = build_pipeline(task, library_features(Library.open("paper5")), config=task.simulation)
    assert pipeline.station.time_step == 0.002
    context = pipeline.CreateDefaultContext()
    from drake_lfd.core.tasks import draw_trial

    pipeline.task_input_port.FixValue(context, draw_trial(task, 0))
    assert pipeline.planner.plan_now(context).start_time_s == 0.3
    path.write_text(text + "\nsimulation:\n  settle_s: abc\n")
    with pytest.raises(InputError) as error:
        load_task(path)
    assert error.value.field == "simulation.settle_s"


def test_drakes_config_structs_load_from_the_simulation_block_and_reach_the_plant(tmp_path):
    config = load_task_text(tmp_path, TASK_HEAD + "simulation:\n  station:\n"
                            "    plant: {time_step: 0.002, penetration_allowance: 0.002}\n"
                            "    visualization: {publish_period: 0.05}\n"
                            "  simulator: {target_realtime_rate: 2.0}\n").simulation
    assert config.station.time_step == 0.002  # the short spelling reads the struct
    assert config.station.visualizer_publish_period == 0.05
    station = mut.build_station(config=config.station)
    assert station.plant.time_step() == 0.002 == station.time_step
    assert station.plant.get_discrete_contact_approximation().name == "kSap"  # kept from the default
    simulator = Simulator(station)
    ApplySimulatorConfig(config.simulator, simulator)
    assert simulator.get_target_realtime_rate() == 2.0


def test_the_default_configs_keep_todays_plant_and_simulator():
    assert StationConfig().plant.time_step == 1e-3 and PipelineConfig().station.plant.time_step == 5e-3
    station = mut.build_station()
    assert station.plant.get_discrete_contact_approximation().name == "kSap"
    assert not station.plant.has_sampled_output_ports()
    # The default SimulatorConfig is a fresh Simulator's own: applying it changes nothing.
    simulator = Simulator(station)
    before = repr(ExtractSimulatorConfig(simulator))
    ApplySimulatorConfig(PipelineConfig().simulator, simulator)
    assert repr(ExtractSimulatorConfig(simulator)) == before == repr(SimulatorConfig())


def test_the_short_spellings_and_the_structs_are_one_value():
    config = StationConfig(time_step=0.004)
    assert config.plant.time_step == 0.004
    config.plant.time_step = 0.003
    assert config.time_step == 0.003
    copy = dataclasses.replace(config, command_period=0.02)
    copy.time_step = 0.002
    assert config.time_step == 0.003  # each config owns its structs


@pytest.mark.parametrize("block, field", [
    ("simulation:\n  station: {plant: {time_stepx: 0.002}}\n", "simulation.station.plant.time_stepx"),
    ("simulation:\n  station: {plant: {time_step: abc}}\n", "simulation.station.plant.time_step"),
    ("simulation:\n  station: {plant: {time_step: 0}}\n", "simulation.station.time_step"),
    ("simulation:\n  station: {plant: {discrete_contact_approximation: tamsi}}\n",
     "simulation.station.plant.discrete_contact_approximation"),
    ("simulation:\n  station: {plant: {contact_model: springs}}\n", "simulation.station.plant.contact_model"),
    ("simulation:\n  station: {visualization: {publish_period: -1}}\n", "simulation.station.visualization.publish_period"),
    ("simulation:\n  simulator: {integration_scheme: magic}\n", "simulation.simulator.integration_scheme"),
    ("simulation:\n  simulator: {accuracy: 0}\n", "simulation.simulator.accuracy"),
])
def test_bad_drake_config_structs_are_refused_naming_the_field(tmp_path, block, field):
    with pytest.raises(InputError) as error:
        load_task_text(tmp_path, TASK_HEAD + block)
    assert error.value.field == field
    assert "task.yaml" in str(error.value) and "\n" not in str(error.value)


def test_every_plant_output_port_is_exported_with_the_model_prefix():
    station = mut.build_station()
    plant = station.plant
    exported = {station.get_output_port(i).get_name() for i in range(station.num_output_ports())}
    names = mut.plant_output_port_names(plant, station.model)
    assert len(names) == plant.num_output_ports()  # one name per port, none lost to a clash
    assert set(names) <= exported
    assert all(name.startswith(("ur5e.", "WorldModelInstance.", "DefaultModelInstance.")) for name in names)
    assert {"ur5e.state", "ur5e.body_poses", "ur5e.contact_results", "ur5e.plant_state",
            "ur5e.generalized_contact_forces"} <= set(names)
    assert names["ur5e.state"] is plant.get_state_output_port(station.model)
    assert names["ur5e.plant_state"] is plant.get_state_output_port()
    # What the rest of drake-lfd uses keeps its name.
    assert {"ur5e.position_measured", "ur5e.velocity_measured", "query_object"} <= exported
    context = station.CreateDefaultContext()
    station.set_initial_positions(context, Q_HOME)
    station.GetInputPort("ur5e.position_command").FixValue(context, Q_HOME)
    poses = station.GetOutputPort("ur5e.body_poses").Eval(context)
    assert len(poses) == plant.num_bodies()


@pytest.mark.parametrize("gravity_compensation", ["inverse_dynamics", "arm_weightless"])
@pytest.mark.parametrize("q", [Q_HOME, np.array([0.3, -0.4, 0.3, -1.0, -1.2, 0.5])])
def test_an_arm_told_to_hold_still_stays_within_a_tenth_of_a_millimetre(q, gravity_compensation):
    # Either way the drive carries the arm's weight: nothing pulls it from the held pose
    # (with the arm nearly outstretched; with gravity on and no compensation the tool
    # sags 8 and 13 mm).
    from drake_lfd.robot.kinematics import UR5eKinematics

    station = mut.build_station(config=StationConfig(gravity_compensation=gravity_compensation))
    context = station.CreateDefaultContext()
    station.set_initial_positions(context, q)
    station.GetInputPort("ur5e.position_command").FixValue(context, q)
    Simulator(station, context).AdvanceTo(2.0)
    q_held = station.GetOutputPort("ur5e.position_measured").Eval(context)
    kinematics = UR5eKinematics()
    drift_m = np.linalg.norm(kinematics.X_WE(q_held).translation() - kinematics.X_WE(q).translation())
    assert drift_m < 1e-4
    assert np.abs(station.GetOutputPort("ur5e.velocity_measured").Eval(context)).max() < 1e-4


def test_gravity_compensation_is_inverse_dynamics_by_default_and_weightless_on_request(tmp_path):
    names = {system.get_name() for system in mut.build_station().GetSystems()}
    assert "gravity_compensation" in names
    weightless = mut.build_station(config=StationConfig(gravity_compensation="arm_weightless"))
    assert "gravity_compensation" not in {system.get_name() for system in weightless.GetSystems()}
    with pytest.raises(InputError, match="simulation.station.gravity_compensation"):
        PipelineConfig(station=StationConfig(gravity_compensation="floating")).checked()
