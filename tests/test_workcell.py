"""One work cell for plan and run (robot/workcell.py), oriented boxes, and the tool's
geometry in every clearance and shell check (core/tool.py, robot/scene.py)."""

import json
import math

import numpy as np
import pytest
from pydrake.geometry import Role
from pydrake.math import RigidTransform, RollPitchYaw

from drake_lfd.cli.app import main
from drake_lfd.core.tasks import Box, draw_trial, rigid_transform_from_euler_zyx
from drake_lfd.core.tool import DEFAULT_TOOL_RADIUS_M, ToolShape, default_tool
from drake_lfd.diagrams.closed_loop import plan_through_joint_configurations, run_closed_loop
from drake_lfd.diagrams.station import Station
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task, task_from_spec, task_spec_from_text
from drake_lfd.core.errors import InputError
from drake_lfd.robot.clearance import box_signed_distance
from drake_lfd.robot.initial_ik import solve_initial_configuration
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.robot.workcell import Workcell, table_under_robot

SIMS = __import__("pathlib").Path(__file__).resolve().parents[1] / "sims"
X_TOOL0_E = rigid_transform_from_euler_zyx([0.0, 0.0, 0.2], [0.0, math.pi / 2, 0.0])
Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])


# ------------------------------------------------------------------ one scene


@pytest.mark.parametrize("scenario", ["transferring", "filling_pouring"])
def test_plan_json_is_the_plan_the_pipeline_runs(scenario, tmp_path):
    """``drake-lfd plan --json`` and the simulate pipeline's planner give the same SE(3)
    path for the same seed (before the one work cell they differed by 173 and 626 mm:
    the CLI ignored the table under the robot)."""
    out = tmp_path / "plan.json"
    assert main(["plan", str(SIMS / f"{scenario}.yaml"), "--library", "paper5", "--seed", "2",
                 "--json", str(out)]) == 0
    document = json.loads(out.read_text())
    task = load_task(SIMS / f"{scenario}.yaml")
    runner = TrialRunner(task, library_features(Library.open("paper5")))  # plans as drake-lfd plan does
    scheduled = runner._runner.plan(draw_trial(task, 2))
    X = scheduled.result.timed.X_WE_list()
    assert len(document["poses"]) == len(X)
    p_json = np.array([pose["p"] for pose in document["poses"]])
    p_run = np.array([pose.translation() for pose in X])
    assert np.max(np.linalg.norm(p_json - p_run, axis=1)) < 1e-9
    t_json = np.array([pose["t"] for pose in document["poses"]])
    np.testing.assert_allclose(t_json, scheduled.result.timed.times, atol=1e-9)


def test_the_table_turns_with_a_tilted_base():
    X_WB = RigidTransform(RollPitchYaw(0.3, -0.2, 0.5), [0.1, -0.2, 0.4])
    table = table_under_robot(X_WB)
    np.testing.assert_allclose(table.rotation, X_WB.rotation().matrix(), atol=1e-15)
    # The top face's centre is the base origin; the robot's z axis is its normal.
    base = X_WB.translation()
    assert table.height_above_top(base[None])[0] == pytest.approx(0.0, abs=1e-12)
    above = base + 0.1 * X_WB.rotation().matrix()[:, 2]
    assert table.height_above_top(above[None])[0] == pytest.approx(0.1, abs=1e-12)
    cell = Workcell.make(X_WB=X_WB, table=table)
    assert cell.planner_floor is table  # a tilted top is a plane, not a height
    level = Workcell.make(X_WB=RigidTransform([0.0, 0.0, -0.2]), table=table_under_robot(RigidTransform([0, 0, -0.2])))
    assert level.planner_floor == pytest.approx(-0.2, abs=1e-15)
    # On the plant too: the point just above the tilted top is 0.1 m from the table box.
    scene = KinematicScene(cell)
    query = scene.scene_graph.get_query_output_port().Eval(scene.scene_graph.GetMyContextFromRoot(scene.context))
    distance = {r.id_G: r.distance for r in query.ComputeSignedDistanceToPoint(above)}
    assert distance[scene.geometry.table_geometry_id] == pytest.approx(0.1, abs=1e-9)


def test_an_oriented_box_measures_like_drake():
    R = RollPitchYaw(0.4, 0.7, -1.1).ToRotationMatrix().matrix()
    box = Box(name="turned", centre=[0.5, 0.2, 0.3], size=[0.3, 0.1, 0.2], rotation=R)
    scene = KinematicScene(obstacles=[box])
    query = scene.scene_graph.get_query_output_port().Eval(scene.scene_graph.GetMyContextFromRoot(scene.context))
    (box_id,) = scene.geometry.obstacle_geometry_ids
    points = np.random.default_rng(3).uniform(-0.3, 0.3, (200, 3)) + box.centre
    drake = []
    for point in points:
        (result,) = [r for r in query.ComputeSignedDistanceToPoint(point) if r.id_G == box_id]
        drake.append(result.distance)
    np.testing.assert_allclose(box.signed_distance(points), drake, atol=1e-9)
    np.testing.assert_allclose(box_signed_distance(points, box.centre, box.size, R), drake, atol=1e-9)
    inside = np.sum(np.asarray(drake) < 0)
    assert 0 < inside < len(points)  # both sides were tested


# ------------------------------------------------------------------ the tool


def test_the_default_tool_runs_from_the_flange_to_E():
    (cylinder,) = default_tool(X_TOOL0_E)
    assert cylinder.kind == "cylinder" and cylinder.geometry_name == "tool/default"
    assert cylinder.radius == DEFAULT_TOOL_RADIUS_M and cylinder.length == pytest.approx(0.2)
    # Its axis (S's z) ends at the flange and at E.
    for end, expected in ((-0.1, [0, 0, 0]), (0.1, [0, 0, 0.2])):
        np.testing.assert_allclose(cylinder.X_tool0_S.multiply([0, 0, end]), expected, atol=1e-12)
    assert default_tool(RigidTransform()) == ()
    assert default_tool(RigidTransform(RollPitchYaw(0, 1, 0), [0, 0, 0.001])) == ()


def _tool_only_shell(kinematics, q, *, out_m=0.15, size=0.04):
    """A shell centred on the flange axis ``out_m`` beyond the flange at ``q``: only a
    tool reaching out there can enter it."""
    X = kinematics.X_Wtool0(q)
    centre = X.multiply([0.0, 0.0, out_m])
    return Box(name="tool_shell", centre=centre, size=[size] * 3)


def test_only_the_tool_enters_the_shell_and_is_named():
    kinematics = UR5eKinematics(X_tool0_E=X_TOOL0_E)
    shell = _tool_only_shell(kinematics, Q_HOME)
    bare = KinematicScene(X_tool0_E=X_TOOL0_E, safety_shells=[shell], tool=())
    distance, link, _ = bare.clearance(Q_HOME)
    assert distance > 0.08 and link.startswith("wrist_3_link/")  # the links stay clear
    scene = KinematicScene(X_tool0_E=X_TOOL0_E, safety_shells=[shell])  # the default tool
    distance, geometry, box = scene.clearance(Q_HOME)
    assert geometry == "tool/default" and box == "safety shell 'tool_shell'"
    # The shell is 4 cm across about the tool's axis: the 3 cm radius tool is 5 cm deep in it.
    assert distance == pytest.approx(-(0.02 + DEFAULT_TOOL_RADIUS_M), abs=1e-6)
    # A tool described by shapes: a thin probe misses a shell off its axis, a box hits it.
    off_axis = Box(name="off", centre=kinematics.X_Wtool0(Q_HOME).multiply([0.04, 0.0, 0.1]), size=[0.02] * 3)
    probe = ToolShape.cylinder("probe", 0.005, 0.2, RigidTransform([0, 0, 0.1]))
    block = ToolShape.box("cup", [0.1, 0.1, 0.1], RigidTransform([0, 0, 0.1]))
    assert KinematicScene(X_tool0_E=X_TOOL0_E, safety_shells=[off_axis], tool=[probe]).clearance(Q_HOME)[0] > 0
    distance, geometry, _ = KinematicScene(X_tool0_E=X_TOOL0_E, safety_shells=[off_axis],
                                           tool=[probe, block]).clearance(Q_HOME)
    assert geometry == "tool/cup" and distance < 0


def test_the_initial_ik_counts_the_tool():
    kinematics = UR5eKinematics(X_tool0_E=X_TOOL0_E)
    shell = _tool_only_shell(kinematics, Q_HOME)
    solution = solve_initial_configuration(kinematics.X_WE(Q_HOME), X_tool0_E=X_TOOL0_E, safety_shells=[shell])
    assert solution.closest_robot_geometry == "tool/default" and not solution.collision_free


def test_the_shell_monitor_reports_the_tool():
    """A short closed-loop hold near Q_HOME: only the tool is inside the shell, and the
    monitor names it."""
    kinematics = UR5eKinematics(X_tool0_E=X_TOOL0_E)
    shell = _tool_only_shell(kinematics, Q_HOME)
    q_end = Q_HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.3])  # turn about the tool axis
    plan = plan_through_joint_configurations([Q_HOME, q_end], X_tool0_E=X_TOOL0_E, samples_per_span=5)
    result = run_closed_loop(plan, X_tool0_E=X_TOOL0_E, safety_shells=[shell], q_initial=Q_HOME)
    assert result.min_distance_pair == ("tool/default", "safety shell 'tool_shell'")
    assert result.min_shell_distance_m == pytest.approx(-0.05, abs=2e-3)
    without = run_closed_loop(plan, X_tool0_E=X_TOOL0_E, safety_shells=[shell], q_initial=Q_HOME, tool=())
    assert without.min_shell_distance_m > 0.08


def test_the_station_shows_the_tool_and_keeps_it_out_of_self_contact():
    station = Station(X_tool0_E=X_TOOL0_E, tool=[ToolShape.box("cup", [0.08, 0.08, 0.1], RigidTransform([0, 0, 0.2]))])
    inspector = station.scene_graph.model_inspector()
    (tool_id,) = station.scene.tool_geometry_ids
    assert tool_id in station.scene.robot_geometry_ids and station.scene.names[tool_id] == "tool/cup"
    frame = inspector.GetFrameId(tool_id)
    visual = [inspector.GetName(g) for g in inspector.GetGeometries(frame, Role.kIllustration)]
    assert any(name.endswith("tool/cup") for name in visual)  # drawn in Meshcat recordings
    arm = [g for g in station.scene.robot_geometry_ids if g != tool_id]
    assert all(inspector.CollisionFiltered(tool_id, g) for g in arm)
    assert station.workcell.tool[0].name == "cup"


# ------------------------------------------------------------------ the task file


_MINIMAL = ("critical_configurations:\n  - {p: [0.4, 0, 0.3], euler_zyx: [0, 0, 0]}\n"
            "  - {p: [0.4, 0.1, 0.3], euler_zyx: [0, 0, 0]}\n")


def _task(text):
    return task_from_spec(task_spec_from_text(_MINIMAL + text, file="t.yaml"), file="t.yaml")


def test_the_tool_block_and_box_orientation_are_read():
    task = _task("X_tool0_E: {p: [0, 0, 0.2]}\n"
                 "obstacles:\n  - {name: b, centre: [0, 0, 1], size: [0.1, 0.2, 0.3], euler_zyx: [90deg, 0, 0]}\n"
                 "tool:\n  - {name: holder, cylinder: {radius: 0.03, length: 0.15}, p: [0, 0, 0.075]}\n"
                 "  - {name: cup, box: [0.08, 0.08, 0.1], p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}\n")
    holder, cup = task.tool
    assert (holder.kind, holder.radius, holder.length) == ("cylinder", 0.03, 0.15)
    assert cup.kind == "box" and np.allclose(cup.X_tool0_S.translation(), [0, 0, 0.2])
    np.testing.assert_allclose(task.obstacles[0].rotation, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    assert draw_trial(task, 0).tool == task.tool
    assert Workcell.of(task).tool == task.tool
    # Absent: the default from X_tool0_E; [] for none.
    absent = _task("X_tool0_E: {p: [0, 0, 0.2]}\n")
    assert absent.tool is None and Workcell.of(absent).tool[0].name == "default"
    assert Workcell.of(_task("X_tool0_E: {p: [0, 0, 0.2]}\ntool: []\n")).tool == ()
    assert _task("").obstacles == () and Workcell.of(_task("")).tool == ()


@pytest.mark.parametrize("text, field", [
    ("tool: [{name: a}]", "tool[0]"),
    ("tool: [{name: a, box: [0.1, 0.1, 0]}]", "tool[0].box[2]"),
    ("tool: [{name: a, cylinder: {radius: 0.1}}]", "tool[0].cylinder.length"),
    ("tool: [{name: a, box: [1, 1, 1]}, {name: a, box: [1, 1, 1]}]", "tool[1].name"),
    ("tool: [{name: a, sphere: 1}]", "tool[0].sphere"),
    ("tool:", "tool"),
])
def test_a_bad_tool_block_names_the_field(text, field):
    with pytest.raises(InputError) as error:
        _task(text + "\n")
    assert f"t.yaml: {field}:" in str(error.value)
