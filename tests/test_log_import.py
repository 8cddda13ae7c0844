"""``library add`` from the logs integrators have: full RTDE recordings and ROS bags.

Every test writes its input itself (the bags with rosbags' own writers) and compares
what the library stores (features and resampled poses) with the same motion added from
the project's clean RTDE CSV.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from pydrake.math import RotationMatrix

from drake_lfd.cli import main
from drake_lfd.core.errors import InputError
from drake_lfd.io.library import Library
from drake_lfd.io.rtde_logs import TCP_POSE_COLUMNS, rotation_matrices_from_rotation_vectors
from drake_lfd.robot.kinematics import UR5eKinematics
from helpers import JOINT_COLUMNS, Q_HOME, RTDE_COLUMNS, table_text, write_joint_log

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

IDENTITY = ["--tool0-E-p", "0", "0", "0", "--tool0-E-euler-zyx", "0", "0", "0"]
RATE_HZ = 50
M = 60
UR_NAMES = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
            "wrist_3_joint"]
GRIPPER = "robotiq_85_left_knuckle_joint"


def motion(m=M, seed=3):
    """Sample times at 50 Hz and a smooth joint motion (well under the speed limit)."""
    rng = np.random.default_rng(seed)
    t = np.arange(m) / RATE_HZ
    s = 0.5 - 0.5 * np.cos(np.linspace(0.0, math.pi, m))
    q = Q_HOME + 0.3 * np.sin(np.pi * s)[:, None] * rng.uniform(-1, 1, 6) + np.outer(s, rng.uniform(-0.5, 0.5, 6))
    return t, q


def tcp_poses(q, offset=(0.0, 0.0, 0.1)):
    """actual_TCP_pose as the controller logs it: FK(q) * offset, x y z and a rotation vector."""
    X = UR5eKinematics().X_Wtool0_batch(q)
    p = X[:, :3, :3] @ np.asarray(offset) + X[:, :3, 3]
    vectors = []
    for R in X[:, :3, :3]:
        angle_axis = RotationMatrix(R).ToAngleAxis()
        vectors.append(angle_axis.axis() * angle_axis.angle())
    vectors = np.array(vectors)
    assert np.allclose(rotation_matrices_from_rotation_vectors(vectors), X[:, :3, :3], atol=1e-9)
    return np.hstack([p, vectors])


def add(tmp_path, log, *options, name="demo", library="lib"):
    root = tmp_path / library
    code = main(["library", "add", str(root), str(log), "--name", name, *IDENTITY, *options])
    return code, root


def stored(root, name="demo"):
    library = Library.open(root)
    feature = library.feature(name)
    return np.asarray(feature.rotations), np.asarray(feature.translations), np.asarray(library.resampled_poses(name))


@pytest.fixture
def reference(tmp_path, capsys):
    """The motion's features added from the clean RTDE CSV."""
    t, q = motion()
    code, root = add(tmp_path, write_joint_log(tmp_path / "clean.csv", t, q), library="reference")
    assert code == 0
    capsys.readouterr()
    return stored(root)


def assert_same_features(root, reference, name="demo"):
    for ours, theirs in zip(stored(root, name), reference):
        assert ours.shape == theirs.shape
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)


# ------------------------------------------------------------------------------ RTDE CSV


def test_space_separated_free_drive_without_timestamps(tmp_path, reference, capsys):
    t, q = motion()
    poses = tcp_poses(q)
    log = tmp_path / "freedrive.csv"
    log.write_text(table_text(JOINT_COLUMNS + list(TCP_POSE_COLUMNS), np.hstack([q, poses]), delimiter=" "))

    code, root = add(tmp_path, log)
    assert code == 2 and "--rate HZ" in capsys.readouterr().err  # no timestamps, no rate
    code, root = add(tmp_path, log, "--rate", "50")
    assert code == 0, capsys.readouterr().err
    assert_same_features(root, reference)
    stored_log = (root / "demos" / "demo.csv").read_text().splitlines()
    assert stored_log[0] == "timestamp," + ",".join(JOINT_COLUMNS)
    assert float(stored_log[-1].split(",")[0]) == pytest.approx((M - 1) / RATE_HZ)


RTDE_FULL_VECTORS = [  # (name, size) of a full RTDE output recipe, as the recorders name them
    ("target_q", 6), ("target_qd", 6), ("target_qdd", 6), ("target_current", 6), ("target_moment", 6),
    ("actual_q", 6), ("actual_qd", 6), ("actual_current", 6), ("joint_control_output", 6),
    ("actual_TCP_pose", 6), ("actual_TCP_speed", 6), ("actual_TCP_force", 6), ("target_TCP_pose", 6),
    ("target_TCP_speed", 6), ("joint_temperatures", 6), ("joint_mode", 6), ("actual_joint_voltage", 6),
    ("actual_tool_accelerometer", 3), ("elbow_position", 3), ("elbow_velocity", 3),
]
RTDE_FULL_SCALARS = [
    "timestamp", "actual_digital_input_bits", "actual_execution_time", "robot_mode", "safety_mode",
    "speed_scaling", "target_speed_fraction", "actual_momentum", "actual_main_voltage", "actual_robot_voltage",
    "actual_robot_current", "actual_digital_output_bits", "runtime_state",
]


def full_rtde_columns():
    columns = list(RTDE_FULL_SCALARS)
    for name, size in RTDE_FULL_VECTORS:
        columns += [f"{name}_{i}" for i in range(size)]
    columns.append("speed_scaling")  # an unused column named twice
    return columns


def test_full_125_column_recording_with_a_duplicated_unused_column(tmp_path, reference, capsys):
    t, q = motion()
    columns = full_rtde_columns()
    assert len(columns) == 125
    rng = np.random.default_rng(7)
    order = rng.permutation(len(columns))  # any column order
    columns = [columns[i] for i in order]
    poses = tcp_poses(q)
    lines = [",".join(columns)]
    for k in range(M):
        row = []
        for column in columns:
            if column == "timestamp":
                row.append(repr(float(t[k])))
            elif column.startswith("actual_q_"):
                row.append(repr(float(q[k, int(column[-1])])))
            elif column.startswith("actual_TCP_pose_"):
                row.append(repr(float(poses[k, int(column[-1])])))
            elif column == "runtime_state":
                row.append("2")
            else:
                row.append(repr(float(rng.normal())))
        lines.append(",".join(row))
    log = tmp_path / "full.csv"
    log.write_text("\n".join(lines) + "\n")

    code, root = add(tmp_path, log, "--tcp-offset", "0", "0", "0.1")
    out, err = capsys.readouterr()
    assert code == 0, err
    assert_same_features(root, reference)
    report = [line for line in out.splitlines() if line.startswith("TCP check")]
    assert len(report) == 1 and "position max 0.000 mm" in report[0], out

    # A duplicated column the import reads is still refused.
    lines[0] = lines[0].replace("speed_scaling", "actual_q_3", 1)
    log.write_text("\n".join(lines) + "\n")
    code, _ = add(tmp_path, log, library="other")
    err = capsys.readouterr().err.strip()
    assert code == 2 and "'actual_q_3' twice" in err and "\n" not in err


def tcp_log(tmp_path, q, poses, name="tcp.csv"):
    t = np.arange(len(q)) / RATE_HZ
    path = tmp_path / name
    path.write_text(table_text([*RTDE_COLUMNS, *TCP_POSE_COLUMNS], np.column_stack([t, q, poses]), delimiter=" "))
    return path


def tcp_numbers(out):
    """(max position mm, max rotation deg) of the TCP check's report."""
    line = next(line for line in out.splitlines() if line.startswith("TCP check"))
    position = float(line.split("position max ")[1].split(" mm")[0])
    rotation = float(line.split("rotation max ")[1].split(" deg")[0])
    return position, rotation


def test_tcp_offset_check(tmp_path, capsys):
    _, q = motion()
    # Consistent: the log's TCP pose is FK with the offset the robot was set to.
    log = tcp_log(tmp_path, q, tcp_poses(q, (0.0, 0.02, 0.15)))
    code, _ = add(tmp_path, log, "--tcp-offset", "0", "0.02", "0.15", library="a")
    out, err = capsys.readouterr()
    assert code == 0, err
    position, rotation = tcp_numbers(out)
    assert position < 1.0 and rotation < 0.01

    # Inconsistent: the robot's TCP was 20 mm longer than the offset given. Reported, added.
    code, _ = add(tmp_path, log, "--tcp-offset", "0", "0.02", "0.13", library="b")
    out, err = capsys.readouterr()
    assert code == 0, err
    position, _ = tcp_numbers(out)
    assert position == pytest.approx(20.0, abs=0.01)

    # Without the option nothing is checked or reported.
    code, _ = add(tmp_path, log, library="c")
    assert code == 0 and "TCP check" not in capsys.readouterr().out

    # Gross: the offset in millimetres instead of metres; refused with one line.
    code, root = add(tmp_path, log, "--tcp-offset", "0", "20", "150", library="d")
    err = capsys.readouterr().err.strip()
    assert code == 2 and "grossly" in err and "\n" not in err and not root.exists()

    # A log without actual_TCP_pose cannot be checked.
    t, q = motion()
    code, _ = add(tmp_path, write_joint_log(tmp_path / "plain.csv", t, q), "--tcp-offset", "0", "0", "0.1", library="e")
    err = capsys.readouterr().err.strip()
    assert code == 2 and "actual_TCP_pose_0" in err


def test_csv_time_window(tmp_path, capsys):
    t, q = motion()
    log = write_joint_log(tmp_path / "clean.csv", t + 100.0, q)  # any origin: seconds from the first sample
    code, root = add(tmp_path, log, "--start", "0.2", "--end", "0.8")
    assert code == 0, capsys.readouterr().err
    keep = (t >= 0.2 - 1e-9) & (t <= 0.8 + 1e-9)
    code, expected = add(tmp_path, write_joint_log(tmp_path / "cut.csv", t[keep], q[keep]), library="expected")
    assert code == 0
    assert Library.open(root).entry("demo").samples == int(keep.sum()) == 31
    assert_same_features(root, stored(expected))


# ------------------------------------------------------------------------------ ROS bags


def joint_state_messages(typestore, t, q, *, prefix="", order_seed=5, ros1=False, drop=None):
    """(time ns, serialized JointState) with the UR joints and a gripper's, shuffled."""
    JointState = typestore.types["sensor_msgs/msg/JointState"]
    Header = typestore.types["std_msgs/msg/Header"]
    Time = typestore.types["builtin_interfaces/msg/Time"]
    names = [prefix + name for name in UR_NAMES] + [GRIPPER]
    rng = np.random.default_rng(order_seed)
    messages = []
    for k in range(len(t)):
        order = rng.permutation(len(names))  # a new order in every message
        position = np.append(q[k], 0.4)[order]
        ns = 1_700_000_000_000_000_000 + k * (1_000_000_000 // RATE_HZ)
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        header = Header(seq=k, stamp=stamp, frame_id="") if ros1 else Header(stamp=stamp, frame_id="")
        chosen = [names[i] for i in order]
        keep = [i for i, n in enumerate(chosen) if n != drop]
        message = JointState(
            header=header,
            name=[chosen[i] for i in keep],
            position=position[keep],
            velocity=np.zeros(len(keep)),
            effort=np.zeros(len(keep)),
        )
        data = (typestore.serialize_ros1 if ros1 else typestore.serialize_cdr)(message, JointState.__msgtype__)
        messages.append((ns, data))
    return messages


def write_ros2_bag(path, messages, *, storage=StoragePlugin.MCAP, topic="/joint_states", extra_topic=True):
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    with Writer2(path, version=9, storage_plugin=storage) as writer:
        connection = writer.add_connection(topic, "sensor_msgs/msg/JointState", typestore=typestore)
        if extra_topic:
            other = writer.add_connection("/rosout_count", "std_msgs/msg/Int32", typestore=typestore)
            Int32 = typestore.types["std_msgs/msg/Int32"]
            writer.write(other, messages[0][0], typestore.serialize_cdr(Int32(data=1), "std_msgs/msg/Int32"))
        for ns, data in messages:
            writer.write(connection, ns, data)
    return path


def write_ros1_bag(path, messages, *, topic="/joint_states"):
    typestore = get_typestore(Stores.ROS1_NOETIC)
    with Writer1(path) as writer:
        connection = writer.add_connection(topic, "sensor_msgs/msg/JointState", typestore=typestore)
        for ns, data in messages:
            writer.write(connection, ns, data)
    return path


def test_ros2_mcap_bag(tmp_path, reference, capsys):
    t, q = motion()
    messages = joint_state_messages(get_typestore(Stores.ROS2_HUMBLE), t, q, prefix="ur5e_")
    bag = write_ros2_bag(tmp_path / "demo_bag", messages)
    code, root = add(tmp_path, bag)
    assert code == 0, capsys.readouterr().err
    assert_same_features(root, reference)
    assert (root / "demos" / "demo.csv").read_text().startswith("timestamp," + ",".join(JOINT_COLUMNS) + "\n0.0,")


def test_ros2_sqlite3_bag(tmp_path, reference, capsys):
    t, q = motion()
    messages = joint_state_messages(get_typestore(Stores.ROS2_HUMBLE), t, q, prefix="ur_")
    bag = write_ros2_bag(tmp_path / "demo_bag", messages, storage=StoragePlugin.SQLITE3)
    code, root = add(tmp_path, bag)
    assert code == 0, capsys.readouterr().err
    assert_same_features(root, reference)


def test_ros1_bag(tmp_path, reference, capsys):
    t, q = motion()
    messages = joint_state_messages(get_typestore(Stores.ROS1_NOETIC), t, q, ros1=True, order_seed=9)
    bag = write_ros1_bag(tmp_path / "demo.bag", messages)
    code, root = add(tmp_path, bag)
    assert code == 0, capsys.readouterr().err
    assert_same_features(root, reference)


def test_bag_missing_joint_is_one_line_naming_it(tmp_path, capsys):
    t, q = motion()
    messages = joint_state_messages(get_typestore(Stores.ROS2_HUMBLE), t, q, prefix="ur_", drop="ur_wrist_3_joint")
    bag = write_ros2_bag(tmp_path / "bag", messages)
    code, root = add(tmp_path, bag)
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert "'wrist_3_joint'" in err and GRIPPER in err and not root.exists()


def test_bag_missing_topic_is_one_line_naming_it_and_the_topics(tmp_path, capsys):
    t, q = motion()
    messages = joint_state_messages(get_typestore(Stores.ROS1_NOETIC), t, q, ros1=True)
    bag = write_ros1_bag(tmp_path / "demo.bag", messages, topic="/ur/joint_states")
    code, root = add(tmp_path, bag)
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert "'/joint_states'" in err and "/ur/joint_states (sensor_msgs/msg/JointState)" in err
    code, root = add(tmp_path, bag, "--topic", "/ur/joint_states")
    assert code == 0, capsys.readouterr().err


def test_bag_time_window(tmp_path, capsys):
    t, q = motion()
    messages = joint_state_messages(get_typestore(Stores.ROS2_HUMBLE), t, q)
    bag = write_ros2_bag(tmp_path / "bag", messages)
    code, root = add(tmp_path, bag, "--start", "0.2", "--end", "0.8")
    assert code == 0, capsys.readouterr().err
    keep = (t >= 0.2 - 1e-9) & (t <= 0.8 + 1e-9)
    code, expected = add(tmp_path, write_joint_log(tmp_path / "cut.csv", t[keep] - t[keep][0], q[keep]), library="x")
    assert code == 0
    assert Library.open(root).entry("demo").samples == 31
    assert_same_features(root, stored(expected))
    # A window with fewer than 2 messages, and one ending before it starts, are refused.
    assert add(tmp_path, bag, "--start", "5", library="y")[0] == 2
    assert "at least 2" in capsys.readouterr().err
    assert add(tmp_path, bag, "--start", "0.5", "--end", "0.1", library="z")[0] == 2
    assert "--end" in capsys.readouterr().err


def test_options_for_the_other_format_are_refused(tmp_path, capsys):
    t, q = motion()
    bag = write_ros1_bag(tmp_path / "demo.bag", joint_state_messages(get_typestore(Stores.ROS1_NOETIC), t, q, ros1=True))
    assert add(tmp_path, bag, "--rate", "50")[0] == 2
    assert "--rate" in capsys.readouterr().err
    log = write_joint_log(tmp_path / "clean.csv", t, q)
    assert add(tmp_path, log, "--topic", "/joint_states")[0] == 2
    assert "--topic" in capsys.readouterr().err


def test_unreadable_bag_is_one_line(tmp_path, capsys):
    bag = tmp_path / "broken.bag"
    bag.write_bytes(b"not a bag\n")
    assert add(tmp_path, bag)[0] == 2
    err = capsys.readouterr().err.strip()
    assert "cannot read the bag" in err and "\n" not in err
    assert add(tmp_path, tmp_path / "absent.bag")[0] == 2
    assert "no such file" in capsys.readouterr().err


# -- only regular files of bounded size are read as logs ------------------------------------
def test_a_device_or_a_pipe_is_refused_without_reading_it(tmp_path):
    from drake_lfd.io.demonstration_logs import read_rtde_log

    with pytest.raises(InputError, match="is not a regular file") as refused:
        read_rtde_log("/dev/zero")  # read whole, it was 2.4 GB and a MemoryError
    assert str(refused.value).startswith("/dev/zero: ")
    fifo = tmp_path / "log.csv"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="is not a regular file"):
        read_rtde_log(fifo)  # opening it would wait for a writer


def test_a_log_larger_than_the_limit_is_refused_before_it_is_read(tmp_path):
    from drake_lfd.io.demonstration_logs import MAX_LOG_BYTES, read_rtde_log

    huge = tmp_path / "huge.csv"
    with open(huge, "wb") as log:
        log.truncate(MAX_LOG_BYTES + 1)  # sparse: no disk used
    with pytest.raises(InputError, match="a joint log is at most"):
        read_rtde_log(huge)
