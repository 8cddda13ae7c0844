"""The people's LeafSystems driven alone: the geometry source, the separation monitor and
the end of a time-scaled run, inputs fixed with FixValue, outputs Eval'd."""

import math

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder, EventStatus

from drake_lfd.core.people import CollaborationParameters, Person, ScriptedPath, Waypoint, protective_separation_distance
from drake_lfd.diagrams.closed_loop import plan_through_joint_configurations
from drake_lfd.diagrams.pipeline import scheduled_plan_from_timed
from drake_lfd.diagrams.station import Station
from drake_lfd.systems.separation import SEPARATION_FIELDS, SeparationMonitor
from drake_lfd.systems.trial_end import TrialEnd

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])
T_S = math.pi / 8.0


def walker(name, x_start, x_end):
    return Person(name, ScriptedPath((Waypoint(0.0, [x_start, -1.5]), Waypoint(2.0, [x_end, -1.5]))))


def station_with_people(people):
    builder = DiagramBuilder()
    station = Station.AddToBuilder(builder=builder, people=people, floor_z=-0.75)
    parameters = CollaborationParameters()
    monitor = builder.AddSystem(SeparationMonitor(
        plant=station.plant, model=station.model, scene_graph=station.scene_graph,
        robot_geometry_ids=station.scene.robot_geometry_ids, people_geometry_ids=station.people.geometry_ids,
        parameters=parameters, stopping_time_s=T_S))
    builder.Connect(station.GetOutputPort("query_object"), monitor.query_object_input_port)
    builder.Connect(station.GetOutputPort(station.port_name("state")), monitor.state_input_port)
    builder.ExportInput(monitor.path_rate_input_port, "path_rate")
    builder.ExportInput(station.GetInputPort(station.port_name("position_command")), "command")
    return builder.Build(), station, monitor


@pytest.fixture(scope="module")
def cell():
    return station_with_people([walker("near", -1.0, 1.0), walker("far", 3.0, 3.0)])


def test_people_need_distinct_names():
    with pytest.raises(ValueError, match="distinct names"):
        station_with_people([walker("a", 0.0, 0.0), walker("a", 1.0, 1.0)])


def test_people_are_proximity_and_illustration_geometry_filtered_out_of_contact(cell):
    from pydrake.geometry import Role

    _, station, _ = cell
    inspector = station.scene_graph.model_inspector()
    person = station.people.geometry_ids[0]
    assert len(person) == 4 and len(station.people.geometry_ids) == 2
    for geometry_id in person:
        assert inspector.GetProximityProperties(geometry_id) is not None
        assert inspector.GetIllustrationProperties(geometry_id) is not None
        for robot_id in station.scene.robot_geometry_ids:
            assert inspector.CollisionFiltered(geometry_id, robot_id)


def test_the_poses_are_a_function_of_time(cell):
    diagram, station, _ = cell
    context = diagram.CreateDefaultContext()
    people_context = station.people.GetMyContextFromRoot(context)
    context.SetTime(1.0)
    poses = station.people.geometry_pose_output_port.Eval(people_context)
    frame_ids = poses.ids()
    assert len(frame_ids) == 8
    torso = station.people.capsule_poses(1.0)[0]
    np.testing.assert_allclose(torso.translation()[:2], [0.0, -1.5])


def test_the_monitor_measures_distance_speed_and_protective_distance(cell):
    diagram, station, monitor = cell
    context = diagram.CreateDefaultContext()
    station.set_initial_positions(context, Q_HOME)
    diagram.GetInputPort("command").FixValue(context, Q_HOME)
    rate = np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
    diagram.GetInputPort("path_rate").FixValue(context, rate)
    context.SetTime(1.0)
    values = monitor.separation_output_port.Eval(monitor.GetMyContextFromRoot(context))
    fields = len(SEPARATION_FIELDS)
    near, far = values[:fields], values[fields:]
    parameters = CollaborationParameters()
    for distance, speed_toward, protective, margin, full_speed in (near, far):
        assert distance > 0.0
        assert speed_toward == pytest.approx(0.0, abs=1e-12)  # the arm is at rest
        assert protective == pytest.approx(protective_separation_distance(0.0, parameters, T_S))
        assert margin == pytest.approx(distance - protective)
        assert full_speed > 0.0  # the base turning moves every point off its axis
    assert near[0] < far[0]
    # Moving the arm: the closest point's velocity along the direction to the person.
    plant_context = station.plant.GetMyMutableContextFromRoot(context)
    station.plant.SetVelocities(plant_context, station.model, rate)
    moving = monitor.separation_output_port.Eval(monitor.GetMyContextFromRoot(context))
    assert abs(moving[1]) > 0.0
    assert moving[1] <= moving[4] + 1e-12  # a component of the point's speed, at most all of it
    assert moving[2] == pytest.approx(protective_separation_distance(moving[1], parameters, T_S))


def test_trial_end_with_a_path_time_waits_for_the_path_not_the_clock():
    plan = scheduled_plan_from_timed(plan_through_joint_configurations([Q_HOME, Q_HOME + 0.2]), start_time_s=0.5)
    end = float(plan.due_times_s()[-1])
    dut = TrialEnd(path_time=True, time_limit_s=5.0)
    context = dut.CreateDefaultContext()
    dut.plan_input_port.FixValue(context, plan)

    def status(time_s, path_time_s):
        context.SetTime(time_s)
        dut.path_time_input_port.FixValue(context, [path_time_s])
        return dut._check(context).severity()

    assert TrialEnd().path_time_input_port is None
    # After the plan's nominal end, still running while the path is short of its end ...
    assert status(end + 1.0, end - 0.5) == EventStatus.Severity.kDidNothing
    # ... over once the path is, or once it has run out of time.
    assert status(end + 1.0, end) == EventStatus.Severity.kReachedTermination
    assert status(end + 5.0, 0.0) == EventStatus.Severity.kReachedTermination
