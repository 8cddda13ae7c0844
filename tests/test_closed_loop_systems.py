"""Each closed-loop LeafSystem driven alone: inputs fixed with FixValue, outputs Eval'd."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.inverse_kinematics import (
    DifferentialInverseKinematicsParameters,
    DoDifferentialInverseKinematics,
)
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

import drake_lfd.systems.differential_ik as mut_ik
import drake_lfd.systems.plan_trajectory_source as mut_source
import drake_lfd.systems.shell_monitor as mut_monitor
from drake_lfd.diagrams.closed_loop import plan_through_joint_configurations
from drake_lfd.diagrams.pipeline import scheduled_plan_from_timed
from drake_lfd.robot.initial_ik import UnreachableConfigurationError, solve_initial_configuration
from drake_lfd.robot.kinematics import UR5eKinematics, add_ur5e
from drake_lfd.robot.motion_bounds import motion_bounds
from drake_lfd.robot.scene import KinematicScene, add_scene, min_signed_distances, table_under_robot
from drake_lfd.diagrams.station import build_station
from drake_lfd.core.tasks import Box

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])
Q_OTHER = Q_HOME + np.array([0.3, 0.1, -0.2, 0.1, 0.2, 0.3])


# ---------------------------------------------------------------- PlanTrajectorySource


def test_plan_source_outputs_pose_velocity_and_holds_the_ends():
    plan = plan_through_joint_configurations([Q_HOME, Q_OTHER])
    dut = mut_source.PlanTrajectorySource()
    context = dut.CreateDefaultContext()
    dut.plan_input_port.FixValue(context, scheduled_plan_from_timed(plan, start_time_s=0.5))
    trajectory = plan.to_piecewise_pose()
    first, last = plan.X_WE_list()[0], plan.X_WE_list()[-1]

    def outputs(t):
        context.SetTime(t)
        return dut.X_WE_desired_output_port.Eval(context), dut.V_WE_desired_output_port.Eval(context)

    for t in (0.0, 0.3):  # before the start: the first pose, at rest
        X, V = outputs(t)
        assert X.IsNearlyEqualTo(first, 1e-12)
        np.testing.assert_array_equal(V, np.zeros(6))
    for t in (0.5 + plan.duration, 0.5 + plan.duration + 2.0):  # after the end: the last
        X, V = outputs(t)
        assert X.IsNearlyEqualTo(last, 1e-12)
        np.testing.assert_array_equal(V, np.zeros(6))

    # In between: GetPose at the plan's time, and V is its derivative.
    tau, h = 0.4 * plan.duration, 1e-6
    X, V = outputs(0.5 + tau)
    assert X.IsNearlyEqualTo(trajectory.GetPose(tau), 1e-12)
    X_next = trajectory.GetPose(tau + h)
    np.testing.assert_allclose(V[3:], (X_next.translation() - X.translation()) / h, atol=1e-5)
    omega = mut_ik.pose_error(X_next, X)[:3] / h
    np.testing.assert_allclose(V[:3], omega, atol=1e-5)
    assert np.linalg.norm(V[3:]) > 0.01  # it does move there


def test_plan_source_follows_a_new_plan_on_its_input():
    dut = mut_source.PlanTrajectorySource()
    context = dut.CreateDefaultContext()
    first = plan_through_joint_configurations([Q_HOME, Q_OTHER])
    second = plan_through_joint_configurations([Q_OTHER, Q_HOME])
    context.SetTime(0.0)
    dut.plan_input_port.FixValue(context, scheduled_plan_from_timed(first))
    assert dut.X_WE_desired_output_port.Eval(context).IsNearlyEqualTo(first.X_WE_list()[0], 1e-12)
    dut.plan_input_port.FixValue(context, scheduled_plan_from_timed(second))
    assert dut.X_WE_desired_output_port.Eval(context).IsNearlyEqualTo(second.X_WE_list()[0], 1e-12)


# ------------------------------------------------------------ DifferentialIKController


@pytest.fixture(scope="module")
def station():
    return build_station()


def _controller(station, **kwargs):
    plant = station.controller_plant
    return mut_ik.DifferentialIKController(
        plant=plant, model=station.controller_model, frame_E=plant.GetFrameByName("E"), **kwargs
    )


def _one_step(dut, q, X_WE_desired, V_WE_desired=np.zeros(6), q_command=None):
    context = dut.CreateDefaultContext()
    dut.set_initial_command(context, q if q_command is None else q_command)
    dut.q_measured_input_port.FixValue(context, q)
    dut.X_WE_desired_input_port.FixValue(context, X_WE_desired)
    dut.V_WE_desired_input_port.FixValue(context, V_WE_desired)
    assert np.array_equal(dut.q_command_output_port.Eval(context), q if q_command is None else q_command)
    return dut.EvalUniquePeriodicDiscreteUpdate(context).get_vector(0).value().copy()


@pytest.mark.parametrize("method", ["drake", "pseudo_inverse"])
def test_one_step_moves_toward_the_target(station, method):
    dut = _controller(station, method=method)
    kinematics = UR5eKinematics()
    X_start = kinematics.X_WE(Q_HOME)
    X_target = RigidTransform(
        X_start.rotation().multiply(RollPitchYaw(0.02, 0.0, 0.0).ToRotationMatrix()),
        X_start.translation() + [0.01, -0.005, 0.0],
    )
    q_next = _one_step(dut, Q_HOME, X_target)
    before = np.linalg.norm(mut_ik.pose_error(X_target, X_start))
    after = np.linalg.norm(mut_ik.pose_error(X_target, kinematics.X_WE(q_next)))
    # K = 20 /s for 10 ms: one step removes about 20 % of the error.
    assert after < 0.85 * before
    assert after > 0.7 * before


def test_velocity_limits_respected_where_the_baseline_ignores_them(station):
    kinematics = UR5eKinematics()
    X_start = kinematics.X_WE(Q_HOME)
    V_fast = np.array([0.0, 0.0, 0.0, 3.0, 0.0, 0.0])  # 3 m/s: far beyond the joints
    limited = _controller(station)
    step = (_one_step(limited, Q_HOME, X_start, V_fast) - Q_HOME) / limited.time_step
    limits = mut_ik.DEFAULT_VELOCITY_LIMIT_FRACTION * kinematics.velocity_limits()
    np.testing.assert_allclose(limited.velocity_limits, limits)
    assert np.all(np.abs(step) <= limits + 1e-9)
    assert np.isclose(np.max(np.abs(step) / limits), 1.0)  # scaled to the binding limit
    # The direction is kept: J v is parallel to the commanded V.
    kinematics.plant.SetPositions(kinematics.context, Q_HOME)
    J = kinematics.plant.CalcJacobianSpatialVelocity(
        kinematics.context, JacobianWrtVariable.kV, kinematics.end_effector_frame, np.zeros(3),
        kinematics.world_frame, kinematics.world_frame,
    )
    V_achieved = J @ step
    assert np.allclose(V_achieved / np.linalg.norm(V_achieved), V_fast / np.linalg.norm(V_fast), atol=1e-9)

    baseline = _controller(station, method="pseudo_inverse")
    step = (_one_step(baseline, Q_HOME, X_start, V_fast) - Q_HOME) / baseline.time_step
    assert np.max(np.abs(step) / limits) > 1.5


def test_position_limits_respected(station):
    # Elbow 1 mrad from its limit (pi) while the target asks it to open further.
    kinematics = UR5eKinematics()
    lower, upper = kinematics.position_limits()
    q = Q_HOME.copy()
    q[2] = upper[2] - 1e-3
    q_further = q.copy()
    q_further[2] = upper[2] + 0.2  # beyond the limit: unreachable for the elbow
    V = np.zeros(6)
    dut = _controller(station)
    q_next = _one_step(dut, q, kinematics.X_WE(q_further), V)
    assert np.all(q_next <= upper + 1e-12) and np.all(q_next >= lower - 1e-12)
    assert q_next[2] <= upper[2]


def test_closed_form_equals_drakes_qp(station):
    """The closed form used for the square Jacobian is Drake's QP's solution."""
    dut = _controller(station)
    kinematics = UR5eKinematics()
    rng = np.random.default_rng(7)
    lower, upper = kinematics.position_limits()
    limits = dut.velocity_limits
    parameters = DifferentialInverseKinematicsParameters(6, 6)
    parameters.set_time_step(dut.time_step)
    parameters.set_joint_position_limits((lower, upper))
    parameters.set_joint_velocity_limits((-limits, limits))
    for _ in range(50):
        q = rng.uniform(-3.0, 3.0, 6)
        kinematics.plant.SetPositions(kinematics.context, q)
        J = kinematics.plant.CalcJacobianSpatialVelocity(
            kinematics.context, JacobianWrtVariable.kV, kinematics.end_effector_frame, np.zeros(3),
            kinematics.world_frame, kinematics.world_frame,
        )
        V = rng.normal(size=6) * rng.choice([0.05, 1.0, 20.0])
        expected = DoDifferentialInverseKinematics(q, np.zeros(6), V, J, parameters).joint_velocities
        actual = dut._closed_form_qp_solution(q, J, V)
        np.testing.assert_allclose(actual, expected, rtol=1e-7, atol=1e-9)


def test_rejects_unknown_method(station):
    with pytest.raises(ValueError, match="method"):
        _controller(station, method="jacobian_transpose")


# -------------------------------------------------------------------------- ShellMonitor


def _flange_box(distance, name="shell"):
    """A 0.1 m box whose top face lies ``distance`` below the lowest point of the flange
    at Q_HOME (tool pointing down), with the expected signed distance computed by hand:
    the flange's bottom face is a disc of radius 0.032 m about tool0, tilted slightly."""
    X_Wtool0 = UR5eKinematics().X_Wtool0(Q_HOME)
    z_axis = X_Wtool0.rotation().matrix()[:, 2]
    lowest = X_Wtool0.translation()[2] - 0.032 * math.sqrt(max(1.0 - z_axis[2] ** 2, 0.0))
    centre = X_Wtool0.translation().copy()
    centre[2] = lowest - distance - 0.05
    return Box(name=name, centre=centre, size=[0.1, 0.1, 0.1])


def _query_object(scene, q):
    scene.plant.SetPositions(scene.plant_context, q)
    return scene.scene_graph.get_query_output_port().Eval(scene.scene_graph.GetMyContextFromRoot(scene.context))


# Drake measures cylinder-box pairs iteratively (FCL GJK/EPA): about 0.3 um off.
@pytest.mark.parametrize("distance", [0.1, 0.02, -0.003])
def test_monitor_measures_a_box_at_a_known_distance(distance):
    box = _flange_box(distance)
    far = Box(name="far_obstacle", centre=[0.6, 0.6, 0.1], size=[0.1, 0.1, 0.1])
    scene = KinematicScene(obstacles=[far], safety_shells=[box])
    dut = mut_monitor.ShellMonitor(
        plant=scene.plant,
        robot_geometry_ids=scene.geometry.robot_geometry_ids,
        shell_geometry_ids=scene.geometry.keep_out_geometry_ids,
        names=scene.geometry.names,
        kinds=scene.geometry.kinds,
    )
    context = dut.CreateDefaultContext()
    assert dut.min_distance_output_port.Eval(context)[0] == math.inf  # nothing sampled yet
    dut.query_object_input_port.FixValue(context, _query_object(scene, Q_HOME))
    simulator = Simulator(dut, context)  # samples at 0, 0.01, ... (periodic update)
    simulator.AdvanceTo(0.1)
    assert dut.min_distance_output_port.Eval(context)[0] == pytest.approx(distance, abs=1e-6)
    far_record, shell_record = dut.clearances(context)
    assert shell_record.box == "shell" and shell_record.kind == "safety shell"
    assert shell_record.robot_geometry == "wrist_3_link/flange"
    assert shell_record.distance_m == pytest.approx(distance, abs=1e-6)
    assert shell_record.time_s == 0.0
    assert far_record.box == "far_obstacle" and far_record.kind == "obstacle"
    assert far_record.distance_m > 0.3

    # The record keeps the minimum and when it happened: moving away does not raise it.
    dut.query_object_input_port.FixValue(context, _query_object(scene, Q_OTHER))
    simulator.AdvanceTo(0.2)
    assert dut.clearances(context)[1].distance_m == pytest.approx(distance, abs=1e-6)
    assert dut.clearances(context)[1].time_s == 0.0


def test_shell_does_not_push_the_robot_but_obstacles_collide():
    """Robot-vs-shell pairs are filtered from contact; robot-vs-obstacle pairs are not."""
    scene = KinematicScene(
        obstacles=[_flange_box(-0.003, name="obstacle")], safety_shells=[_flange_box(-0.003, name="shell")]
    )
    query_object = _query_object(scene, Q_HOME)
    penetrations = query_object.ComputePointPairPenetration()
    names = {scene.geometry.names.get(p.id_A, "") for p in penetrations} | {
        scene.geometry.names.get(p.id_B, "") for p in penetrations
    }
    assert "obstacle" in names and "shell" not in names
    # ... while the monitor's pair query still sees the shell.
    (shell_id,) = scene.geometry.shell_geometry_ids
    distances = min_signed_distances(query_object, scene.geometry.robot_geometry_ids, [shell_id])
    assert distances.min() == pytest.approx(-0.003, abs=1e-6)


def test_monitor_stops_the_simulation_on_penetration():
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    model = add_ur5e(plant)
    geometry = add_scene(plant, scene_graph, model=model, safety_shells=[_flange_box(-0.003)])
    plant.Finalize()
    dut = builder.AddSystem(
        mut_monitor.ShellMonitor(
            plant=plant,
            robot_geometry_ids=geometry.robot_geometry_ids,
            shell_geometry_ids=geometry.shell_geometry_ids,
            stop_on_penetration=True,
            names=geometry.names,
            kinds=geometry.kinds,
        )
    )
    builder.Connect(scene_graph.get_query_output_port(), dut.query_object_input_port)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    plant.SetPositions(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()), Q_HOME)
    plant.get_actuation_input_port().FixValue(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()), np.zeros(6))
    status = simulator.AdvanceTo(1.0)
    assert status.reason() == status.ReturnReason.kReachedTerminationCondition
    assert simulator.get_context().get_time() < 0.02
    assert "wrist_3_link/flange penetrated safety shell 'shell'" in status.message()


# -------------------------------------------------------------------------- initial IK


def test_initial_ik_reaches_the_pose_elbow_up_and_reports_clearance():
    kinematics = UR5eKinematics()
    X_WE = kinematics.X_WE(Q_OTHER)
    shell = _flange_box(0.05)  # under the flange at Q_HOME; Q_OTHER is elsewhere
    result = solve_initial_configuration(X_WE, safety_shells=[shell])
    assert result.position_error_m < 1e-5 and result.rotation_error_rad < 1e-4
    # Elbow up: the elbow above the line from shoulder to wrist.
    kinematics.plant.SetPositions(kinematics.context, result.q)
    p = {
        name: kinematics.plant.CalcRelativeTransform(
            kinematics.context, kinematics.world_frame, kinematics.plant.GetFrameByName(name)
        ).translation()
        for name in ("upper_arm_link", "forearm_link", "wrist_1_link")
    }
    s = np.linalg.norm(p["forearm_link"][:2] - p["upper_arm_link"][:2]) / max(
        np.linalg.norm(p["wrist_1_link"][:2] - p["upper_arm_link"][:2]), 1e-9
    )
    z_on_line = p["upper_arm_link"][2] + s * (p["wrist_1_link"][2] - p["upper_arm_link"][2])
    assert p["forearm_link"][2] > z_on_line
    assert result.collision_free and result.min_distance_m > 0.0
    # Deterministic.
    again = solve_initial_configuration(X_WE, safety_shells=[shell])
    np.testing.assert_array_equal(again.q, result.q)


def test_initial_ik_reports_a_configuration_inside_a_shell():
    X_WE = UR5eKinematics().X_WE(Q_HOME)
    result = solve_initial_configuration(X_WE, safety_shells=[_flange_box(-0.01, name="too_close")])
    assert not result.collision_free
    assert result.closest_box == "safety shell 'too_close'"


def test_initial_ik_names_an_unreachable_configuration():
    with pytest.raises(UnreachableConfigurationError, match="con_3") as error:
        solve_initial_configuration(RigidTransform([1.5, 0.0, 0.3]), con=3)
    assert error.value.field == "critical_configurations[2]"


def test_table_under_the_robot_touches_nothing_at_rest():
    X_WB = RigidTransform([0.1, -0.2, 0.3])
    table = table_under_robot(X_WB)
    assert table.centre[2] + 0.5 * table.size[2] == pytest.approx(0.3)  # flush with the base
    scene = KinematicScene(X_WB=X_WB, table=table)
    assert scene.geometry.names[scene.geometry.table_geometry_id] == "table"
    # The base sits on the table (both welded to the world: filtered), the arm is clear.
    assert len(_query_object(scene, Q_HOME).ComputePointPairPenetration()) == 0


def test_systems_wire_themselves_with_add_to_builder():
    """Each stage's AddToBuilder connects it as the pipeline does; 0.3 s of tracking."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantValueSource
    from pydrake.common.value import AbstractValue

    from drake_lfd.core.tasks import Box
    from drake_lfd.systems.differential_ik import DifferentialIKController
    from drake_lfd.systems.shell_monitor import ShellMonitor

    builder = DiagramBuilder()
    station = builder.AddSystem(build_station(safety_shells=[Box(name="far", centre=[2.0, 2.0, 2.0], size=[0.1] * 3)]))
    plan = plan_through_joint_configurations([Q_HOME, Q_OTHER])
    given = builder.AddSystem(ConstantValueSource(AbstractValue.Make(scheduled_plan_from_timed(plan))))
    source = mut_source.PlanTrajectorySource.AddToBuilder(builder=builder, plan_output_port=given.get_output_port())
    plant = station.controller_plant
    controller = DifferentialIKController.AddToBuilder(
        builder=builder, plant=plant, model=station.controller_model, frame_E=plant.GetFrameByName("E"),
        X_WE_desired_output_port=source.X_WE_desired_output_port,
        V_WE_desired_output_port=source.V_WE_desired_output_port,
        q_measured_output_port=station.GetOutputPort("ur5e.position_measured"),
        q_command_input_port=station.GetInputPort("ur5e.position_command"))
    monitor = ShellMonitor.AddToBuilder(
        builder=builder, plant=station.plant, query_object_output_port=station.GetOutputPort("query_object"),
        robot_geometry_ids=station.scene.robot_geometry_ids, shell_geometry_ids=station.scene.keep_out_geometry_ids)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    station.set_initial_positions(simulator.get_mutable_context(), Q_HOME)
    simulator.AdvanceTo(0.3)
    context = simulator.get_context()
    moved = station.GetOutputPort("ur5e.position_measured").Eval(station.GetMyContextFromRoot(context))
    assert np.abs(moved - Q_HOME).max() > 1e-4  # the arm follows the plan
    assert controller.q_command_output_port.Eval(controller.GetMyContextFromRoot(context)).shape == (6,)
    (clearance,) = monitor.clearances(monitor.GetMyContextFromRoot(context))
    assert clearance.distance_m > 1.0


def test_monitor_pruning_keeps_every_record_exact_with_fewer_queries():
    """Given the joint positions, the monitor skips pairs its motion bound proves cannot
    lower a record; along a random joint path its records equal, to the bit, those of a
    monitor querying every pair, with a fraction of the queries."""
    near = _flange_box(0.02, name="near_shell")
    far = Box(name="far_obstacle", centre=[0.6, 0.6, 0.1], size=[0.1, 0.1, 0.1])
    scene = KinematicScene(obstacles=[far], safety_shells=[near])
    monitors, simulators = [], []
    for pruned in (True, False):
        dut = mut_monitor.ShellMonitor(
            plant=scene.plant, robot_geometry_ids=scene.geometry.robot_geometry_ids,
            shell_geometry_ids=scene.geometry.keep_out_geometry_ids, names=scene.geometry.names)
        monitors.append(dut)
        simulators.append(Simulator(dut))
    rng = np.random.default_rng(7)
    q = Q_HOME.copy()
    for step in range(300):
        q = q + rng.normal(scale=0.01, size=6)  # a wandering arm, ~0.5 rad per joint in all
        query_object = _query_object(scene, q)
        for pruned, dut, simulator in zip((True, False), monitors, simulators):
            context = simulator.get_mutable_context()
            dut.query_object_input_port.FixValue(context, query_object)
            if pruned:
                dut.robot_positions_input_port.FixValue(context, q)
            simulator.AdvanceTo(0.01 * step + 0.005)  # one periodic sample, at 0.01 * step
        pruned_records, full_records = (dut.clearances(simulator.get_context())
                                        for dut, simulator in zip(monitors, simulators))
        assert pruned_records == full_records
    num_pairs = len(scene.geometry.robot_geometry_ids) * len(scene.geometry.keep_out_geometry_ids)
    assert monitors[1].num_pair_queries == 300 * num_pairs
    assert monitors[0].num_pair_queries < 0.5 * monitors[1].num_pair_queries


def test_motion_bounds_cover_the_farthest_point_of_each_geometry():
    """The bound of the base joint is at least how far the flange is from the base axis."""
    scene = KinematicScene()
    inspector = scene.scene_graph.model_inspector()
    names = scene.geometry.names
    flange = next(g for g in scene.geometry.robot_geometry_ids if names[g] == "wrist_3_link/flange")
    bounds = motion_bounds(scene.plant, inspector, flange)
    assert np.all(np.isfinite(bounds)) and np.all(bounds > 0)
    assert np.all(np.diff(bounds) <= 1e-12)  # nearer joints, smaller bounds
    X_Wtool0 = UR5eKinematics().X_Wtool0(Q_HOME)
    assert bounds[0] >= np.linalg.norm(X_Wtool0.translation()[:2])
