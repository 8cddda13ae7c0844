"""``drake-lfd export``: the paper's three plans as URScript, RTDE CSV and ROS 2 YAML.

The URScript program is parsed back here (its servoj lines), its targets replayed
through the UR5e's DH kinematics written in numpy in this file (not the URDF, not
Drake), and the tool path compared with the plan; speeds and accelerations are finite
differences of the 2 ms targets. Each task is planned once for the module.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from cli_subprocess import cli_command, cli_env
from drake_lfd.cli.app import main
from drake_lfd.experiments.rederive import dh_forward_kinematics
from drake_lfd.io.demonstration_logs import read_rtde_csv
from drake_lfd.io.trajectory_export import least_slow_down, load_plan_trajectory

REPOSITORY = Path(__file__).resolve().parent.parent
TASKS = {"transferring": "paper5", "filling_pouring": "paper5", "assembling": "paper6"}

SPEED_LIMIT = math.pi  # 180 deg/s
ACCELERATION_LIMIT = 40.0  # rad/s^2, docs/cli.rst
SERVOJ = re.compile(r"^\s*servoj\(\[([^\]]*)\], a=0, v=0, t=([0-9.]+), lookahead_time=([0-9.]+), gain=([0-9.]+)\)$")
MOVEJ = re.compile(r"^\s*movej\(\[([^\]]*)\], a=([0-9.]+), v=([0-9.]+)\)$")


# tool0 in the base frame from UR's DH table, q (m, 6) -> (m, 4, 4): independent of the
# project's Drake model (the kinematics the paper run re-derives its successes with).
dh_tool0 = dh_forward_kinematics


def matrix(pose):
    w, x, y, z = pose["q_wxyz"]
    R = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, pose["p"]
    return M


def parse_urscript(text):
    """(movej target, servoj targets (n, 6), servoj t) of a generated program."""
    lines = text.splitlines()
    assert lines[0].startswith("def ") and lines[-1] == "end"
    movej = [MOVEJ.match(line) for line in lines if line.strip().startswith("movej(")]
    assert len(movej) == 1 and float(movej[0].group(2)) <= 0.5 and float(movej[0].group(3)) <= 0.35
    servos = [SERVOJ.match(line) for line in lines if line.strip().startswith("servoj(")]
    assert servos and all(servos)
    assert {m.group(2) for m in servos} == {"0.002"}
    assert any(line.strip().startswith("stopj(") for line in lines[-3:])
    q = np.array([[float(v) for v in m.group(1).split(",")] for m in servos])
    return np.array([float(v) for v in movej[0].group(1).split(",")]), q, 0.002


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    """Each task planned once (in parallel): name -> plan JSON path."""
    folder = tmp_path_factory.mktemp("plans")
    processes = {}
    for name, library in TASKS.items():
        processes[name] = subprocess.Popen(
            cli_command("plan", REPOSITORY / "sims" / f"{name}.yaml", "--library", library,
                        "--json", folder / f"{name}.json"),
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=cli_env())
    for name, process in processes.items():
        _, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
    return {name: folder / f"{name}.json" for name in TASKS}


@pytest.mark.parametrize("name", list(TASKS))
def test_the_urscript_round_trip_follows_the_plan_within_limits(name, plans, tmp_path, capsys):
    document = json.loads(plans[name].read_text())
    slow_down = least_slow_down(load_plan_trajectory(plans[name]))
    script, csv, ros2 = tmp_path / "plan.script", tmp_path / "plan.csv", tmp_path / "plan.yaml"
    status = main(["export", str(plans[name]), "--slow-down", str(slow_down), "--urscript", str(script),
                   "--csv", str(csv), "--ros2", str(ros2), "--joint-prefix", "ur_"])
    assert status == 0, capsys.readouterr().err
    start, targets, dt = parse_urscript(script.read_text())
    t = np.arange(len(targets)) * dt

    plan_t = np.array(document["joint_trajectory"]["t"]) * slow_down
    plan_q = np.array(document["joint_trajectory"]["q"])
    np.testing.assert_allclose(start, plan_q[0], atol=1e-8)
    np.testing.assert_allclose(targets[0], plan_q[0], atol=1e-8)
    assert abs(t[-1] - plan_t[-1]) < dt

    X_WB, X_tool0_E = matrix(document["X_WB"]), matrix(document["X_tool0_E"])

    def tool_path(times):  # E along the URScript's targets, linearly between them
        q = np.stack([np.interp(times, t, targets[:, j]) for j in range(6)], axis=1)
        return X_WB @ dh_tool0(q) @ X_tool0_E

    # The plan's joint path, where its samples are due: within 0.1 mm.
    E_plan = X_WB @ dh_tool0(plan_q) @ X_tool0_E
    joint_path_error = np.linalg.norm(tool_path(plan_t)[:, :3, 3] - E_plan[:, :3, 3], axis=1)
    assert joint_path_error.max() < 1e-4, joint_path_error.max()

    # The plan's poses (not on the joint path's 10 ms grid): the export deviates from them
    # as the plan-time joint path does (the controller law's tracking, within 5 mm), up
    # to the difference of the export's spline and straight lines between 10 ms samples.
    pose_t = np.array([p["t"] for p in document["poses"]])
    pose_p = np.array([p["p"] for p in document["poses"]])
    q_at_poses = np.stack([np.interp(pose_t * slow_down, plan_t, plan_q[:, j]) for j in range(6)], axis=1)
    plan_error = np.linalg.norm((X_WB @ dh_tool0(q_at_poses) @ X_tool0_E)[:, :3, 3] - pose_p, axis=1)
    export_error = np.linalg.norm(tool_path(pose_t * slow_down)[:, :3, 3] - pose_p, axis=1)
    assert (export_error - plan_error).max() < 5e-4
    assert export_error.max() < 0.005
    critical = document["critical_indices"]
    assert export_error[critical].max() < 0.005

    speed = np.abs(np.diff(targets, axis=0)) / dt
    acceleration = np.abs(np.diff(targets, n=2, axis=0)) / dt**2
    assert speed.max() <= SPEED_LIMIT
    assert acceleration.max() <= ACCELERATION_LIMIT * (1 + 1e-6)  # 9-decimal rounding

    # The CSV reads back with the project's log reader: the same targets.
    demonstration = read_rtde_csv(csv).demonstration
    np.testing.assert_allclose(demonstration.joint_positions, targets, atol=1e-8)
    np.testing.assert_allclose(demonstration.timestamps, t, atol=1e-9)

    # The ROS 2 YAML is a JointTrajectory with the prefixed names, at rest at both ends.
    message = yaml.safe_load(ros2.read_text())
    assert message["joint_names"] == ["ur_shoulder_pan_joint", "ur_shoulder_lift_joint", "ur_elbow_joint",
                                      "ur_wrist_1_joint", "ur_wrist_2_joint", "ur_wrist_3_joint"]
    points = message["points"]
    assert len(points) == len(plan_q)
    times = [p["time_from_start"]["sec"] + p["time_from_start"]["nanosec"] * 1e-9 for p in points]
    assert all(isinstance(p["time_from_start"]["nanosec"], int) and 0 <= p["time_from_start"]["nanosec"] < 10**9
               for p in points)
    assert np.all(np.diff(times) > 0) and abs(times[-1] - plan_t[-1]) < 1e-6
    np.testing.assert_allclose([p["positions"] for p in points], plan_q, atol=1e-12)
    assert all(len(p["velocities"]) == 6 for p in points)
    assert points[0]["velocities"] == [0.0] * 6 and points[-1]["velocities"] == [0.0] * 6
    assert np.abs([p["velocities"] for p in points]).max() <= SPEED_LIMIT
    print(f"{name}: slow-down {slow_down}, joint path error {joint_path_error.max() * 1e3:.4f} mm, "
          f"pose error export {export_error.max() * 1e3:.3f} mm vs plan {plan_error.max() * 1e3:.3f} mm, "
          f"speed {speed.max() / SPEED_LIMIT:.1%}, acceleration {acceleration.max() / ACCELERATION_LIMIT:.1%}")


def _one_line_refusal(capsys, status):
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, err
    return err[0]


def test_a_plan_with_a_joint_jump_is_refused_in_one_line_and_nothing_is_written(plans, tmp_path, capsys):
    document = json.loads(plans["transferring"].read_text())
    q = document["joint_trajectory"]["q"]
    for sample in q[len(q) // 2:]:
        sample[2] += 0.3  # the elbow jumps 0.3 rad in 10 ms: 30 rad/s
    edited = tmp_path / "jump.json"
    edited.write_text(json.dumps(document))
    outputs = [tmp_path / "out.script", tmp_path / "out.csv", tmp_path / "out.yaml"]
    status = main(["export", str(edited), "--slow-down", "4", "--urscript", str(outputs[0]),
                   "--csv", str(outputs[1]), "--ros2", str(outputs[2])])
    line = _one_line_refusal(capsys, status)
    assert re.search(r"jump\.json: joint_trajectory: elbow_joint (speed|acceleration) [0-9.]+ rad/s(\^2)? "
                     r"exceeds the limit [0-9.]+ rad/s(\^2)? at t = [0-9.]+ s", line), line
    assert not any(path.exists() for path in outputs) and sorted(tmp_path.iterdir()) == [edited]


def test_a_start_outside_the_joint_limits_is_refused(plans, tmp_path, capsys):
    document = json.loads(plans["assembling"].read_text())
    for sample in document["joint_trajectory"]["q"]:
        sample[2] += 2 * math.pi  # the elbow one turn round: beyond +-pi
    edited = tmp_path / "wound.json"
    edited.write_text(json.dumps(document))
    line = _one_line_refusal(capsys, main(["export", str(edited), "--urscript", str(tmp_path / "out.script")]))
    assert "elbow_joint start position" in line and "limit 3.142 rad at t = 0.000 s" in line
    assert not (tmp_path / "out.script").exists()


def test_the_plans_own_timing_exports_and_a_faster_one_is_refused_naming_the_slow_down(plans, tmp_path, capsys):
    """A plan is timed within 0.9 of the joint limits (8 rad/s^2, far below the export's
    40): it exports as it is. Played 4x faster, its accelerations exceed 40 rad/s^2 and
    the refusal names the slow-down that fits."""
    for name in TASKS:
        assert least_slow_down(load_plan_trajectory(plans[name])) == 1.0
        assert main(["export", str(plans[name])]) == 0, capsys.readouterr().err
    document = json.loads(plans["transferring"].read_text())
    document["joint_trajectory"]["t"] = [t / 4.0 for t in document["joint_trajectory"]["t"]]
    fast = tmp_path / "fast.json"
    fast.write_text(json.dumps(document))
    line = _one_line_refusal(capsys, main(["export", str(fast)]))
    assert "exceeds the limit" in line
    assert re.search(r"--slow-down [0-9]+\.[0-9] would keep", line)


@pytest.mark.parametrize("change, field", [
    ({"status": "demonstration_requested"}, "status"),
    ({"status": "no_executable_plan", "joint_trajectory": {"t": [], "q": []}}, "status"),
    ({"joint_trajectory": {"t": [], "q": []}}, "joint_trajectory"),
    ({"joint_trajectory": None}, "joint_trajectory"),
    ({"joint_trajectory": {"t": [0.0, 0.01], "q": [[0.0] * 5, [0.0] * 5]}}, "joint_trajectory.q"),
])
def test_a_document_that_is_not_an_exportable_plan_is_refused(change, field, tmp_path, capsys):
    document = {"status": "planned", "task": "t",
                "joint_trajectory": {"t": [0.0, 0.01], "q": [[0.0] * 6, [0.0] * 6]}, **change}
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(document))
    line = _one_line_refusal(capsys, main(["export", str(path), "--csv", str(tmp_path / "out.csv")]))
    assert line.startswith(f"drake-lfd export: error: {path}: {field}: "), line
    assert not (tmp_path / "out.csv").exists()


def test_servoj_parameters_outside_their_ranges_are_refused(tmp_path, capsys):
    path = tmp_path / "plan.json"
    path.write_text(json.dumps({"status": "planned", "joint_trajectory": {"t": [0.0, 0.01], "q": [[0.0] * 6] * 2}}))
    line = _one_line_refusal(capsys, main(["export", str(path), "--lookahead-time", "0.5"]))
    assert "--lookahead-time" in line
    line = _one_line_refusal(capsys, main(["export", str(path), "--gain", "50"]))
    assert "--gain" in line
