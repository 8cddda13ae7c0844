"""UR5e joint logs from ROS 1 and ROS 2 bags: ``sensor_msgs/JointState`` as a demonstration.

Integrators on ROS record the driver's ``/joint_states`` (``ur_robot_driver``) in a bag.
This module reads them with the pure-Python ``rosbags`` library (no ROS install): a
ROS 1 ``.bag`` file, or a ROS 2 bag directory (``metadata.yaml`` with sqlite3 or mcap
storage; the ``.db3``/``.mcap`` file inside one names its directory).

Choices:

- Joints are found by name, in any order: a name that is one of UR's
  (:data:`UR_JOINT_NAMES`, ``shoulder_pan_joint`` .. ``wrist_3_joint``) or ends with
  one after a prefix (``ur_``, ``ur5e_``, ``arm/``) is that joint; other joints (a
  gripper's) are ignored. Two names for one UR joint (two arms) are refused, naming
  both. A message on the topic with none of the six (a gripper's own publisher on
  ``/joint_states``) is skipped, with a warning counting them; one with some but not
  all of them is refused, naming the missing joint.
- Sample times are the messages' ``header.stamp`` when every kept message has a
  non-zero one, else the bag's receive times (with a warning); they start at 0 at the
  first kept message (integer nanoseconds, so no precision is lost to the epoch).
- ``start_s``/``end_s`` cut a time window, in seconds from the bag's first message (any
  topic, as ``ros2 bag info`` and rqt_bag count), on the receive time; both ends
  included.
- A topic missing from the bag is refused naming the topics present (with their types);
  a topic of another type is refused naming it.

Every check the CSV path makes on the samples runs on the result
(:func:`~drake_lfd.core.demonstrations.check_demonstration`,
:func:`~drake_lfd.io.demonstration_logs.check_plausible_motion`), naming the message.

Not for: RTDE CSV logs (``demonstration_logs.py``, ``rtde_logs.py``), choosing the
reader (``log_import.py``).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from drake_lfd.core.demonstrations import NUM_JOINTS, Demonstration, check_demonstration
from drake_lfd.core.errors import InputError
from drake_lfd.io.demonstration_logs import check_plausible_motion
from drake_lfd.robot.kinematics import UR5E_JOINT_NAMES

__all__ = [
    "UR_JOINT_NAMES",
    "DEFAULT_TOPIC",
    "JOINT_STATE_TYPE",
    "ROS2_STORAGE_SUFFIXES",
    "BagJointLog",
    "is_bag",
    "bag_location",
    "ur_joint_indices",
    "read_joint_state_bag",
]

#: UR's joint names, in the project's joint order (shoulder_pan .. wrist_3).
UR_JOINT_NAMES = UR5E_JOINT_NAMES
#: Where ``ur_robot_driver`` publishes the joints.
DEFAULT_TOPIC = "/joint_states"
#: The message type read (ROS 1's ``sensor_msgs/JointState``; rosbags names both so).
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
#: The storage files of a ROS 2 bag directory.
ROS2_STORAGE_SUFFIXES = (".db3", ".mcap")


class BagJointLog(NamedTuple):
    """What :func:`read_joint_state_bag` read: the demonstration and its warnings."""

    demonstration: Demonstration
    warnings: tuple[str, ...]


def bag_location(path):
    """The path rosbags opens for ``path``, or None if it is not a bag: a ``.bag`` file
    (ROS 1), a directory with ``metadata.yaml`` (ROS 2), or the ``.db3``/``.mcap`` file
    of such a directory (its directory)."""
    path = Path(path)
    if path.suffix == ".bag":
        return path
    if path.is_dir() and (path / "metadata.yaml").is_file():
        return path
    if path.suffix in ROS2_STORAGE_SUFFIXES and (path.parent / "metadata.yaml").is_file():
        return path.parent
    return None


def is_bag(path):
    """Whether ``path`` names a ROS 1 or ROS 2 bag (:func:`bag_location`)."""
    return bag_location(path) is not None


def ur_joint_indices(names, *, file, field):
    """Where each UR joint is in a JointState's ``name`` list.

    Parameters
    ----------
    names : sequence of str
    file, field : str
        Named in the errors.

    Returns
    -------
    indices : list of int or None
        One per :data:`UR_JOINT_NAMES`; None for a joint the message lacks.

    Raises
    ------
    InputError
        Two names for one UR joint.
    """
    indices = []
    for joint in UR_JOINT_NAMES:
        found = [i for i, name in enumerate(names) if name == joint or name.endswith(joint)]
        if len(found) > 1:
            raise InputError(
                f"joints {', '.join(repr(names[i]) for i in found)} are all {joint!r}: the message holds more "
                "than one arm, and which is the UR5e's is ambiguous",
                file=file,
                field=field,
            )
        indices.append(found[0] if found else None)
    return indices


def _window_bounds(start_s, end_s, first_ns):
    lower = None if start_s is None else first_ns + int(round(start_s * 1e9))
    upper = None if end_s is None else first_ns + int(round(end_s * 1e9))
    return lower, upper


def read_joint_state_bag(path, *, topic=DEFAULT_TOPIC, name=None, description="", start_s=None, end_s=None):
    """Reads a UR5e's ``sensor_msgs/JointState`` messages from a bag as a demonstration.

    Parameters
    ----------
    path : str or Path
        A ROS 1 ``.bag`` file or a ROS 2 bag directory (:func:`bag_location`).
    topic : str
        The JointState topic.
    name : str, optional
        The demonstration's name; the bag's stem by default.
    description : str
    start_s, end_s : float, optional
        Keep the messages received this many seconds after the bag's first message
        (both included); checked by the caller to be finite and ordered.

    Returns
    -------
    BagJointLog

    Raises
    ------
    InputError
        One line naming the bag: not a readable bag, the topic missing (naming the
        topics present) or of another type, a UR joint missing from a message (naming
        it), positions missing or not finite, fewer than 2 messages (in the window),
        timestamps not increasing, angles in degrees or a joint jump.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    location = bag_location(path)
    if location is None:
        raise InputError("not a ROS bag (a .bag file, or a ROS 2 bag directory with metadata.yaml)", file=path)
    if not location.exists():
        raise InputError("no such file", file=path)
    warnings = []
    stamps, received, joints = [], [], []
    skipped = 0
    try:
        with AnyReader([location], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections:
                present = ", ".join(f"{c.topic} ({c.msgtype})" for c in sorted(reader.connections, key=lambda c: c.topic))
                raise InputError(
                    f"the bag has no topic {topic!r} (choose one with --topic); its topics: {present or 'none'}",
                    file=path,
                    field="topic",
                )
            types = {c.msgtype for c in connections}
            if types != {JOINT_STATE_TYPE}:
                raise InputError(
                    f"topic {topic!r} carries {', '.join(sorted(types))}, not sensor_msgs/JointState",
                    file=path,
                    field="topic",
                )
            lower, upper = _window_bounds(start_s, end_s, reader.start_time)
            for number, (connection, timestamp, rawdata) in enumerate(reader.messages(connections=connections), 1):
                if lower is not None and timestamp < lower:
                    continue
                if upper is not None and timestamp > upper:
                    break
                message = reader.deserialize(rawdata, connection.msgtype)
                where = f"topic {topic}, message {number}"
                indices = ur_joint_indices(list(message.name), file=path, field=where)
                if all(i is None for i in indices):
                    skipped += 1
                    continue
                if None in indices:
                    missing = UR_JOINT_NAMES[indices.index(None)]
                    raise InputError(
                        f"no joint {missing!r} (with or without a prefix such as ur_); the message's joints: "
                        f"{', '.join(message.name)}",
                        file=path,
                        field=where,
                    )
                position = np.asarray(message.position, dtype=float)
                if len(position) != len(message.name):
                    raise InputError(
                        f"{len(message.name)} joint names but {len(position)} positions", file=path, field=where
                    )
                joints.append(position[indices])
                stamp = message.header.stamp
                stamps.append(int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec))
                received.append(int(timestamp))
    except AnyReaderError as error:
        raise InputError(f"cannot read the bag: {error}", file=path) from None
    except OSError as error:
        raise InputError(f"cannot read the bag: {error.strerror or error}", file=path) from None
    if skipped:
        warnings.append(f"{path}: skipped {skipped} message(s) on {topic} with none of the UR joints")
    if len(joints) < 2:
        window = "" if start_s is None and end_s is None else " in the time window"
        raise InputError(
            f"has {len(joints)} UR5e JointState message(s) on {topic}{window}; a demonstration needs at least 2",
            file=path,
            field="samples",
        )
    times_ns = np.array(stamps, dtype=np.int64)
    if np.any(times_ns == 0):
        warnings.append(f"{path}: some messages on {topic} have no header.stamp; used the bag's receive times")
        times_ns = np.array(received, dtype=np.int64)
    timestamps = (times_ns - times_ns[0]).astype(float) / 1e9
    q = np.vstack(joints)
    demonstration = Demonstration(
        name=(location.stem if name is None else name),
        timestamps=timestamps,
        joint_positions=q,
        description=description,
    )
    check_demonstration(demonstration, file=path)
    check_plausible_motion(timestamps, q, file=path, field_of=lambda i: f"topic {topic}, sample {i}")
    assert q.shape[1] == NUM_JOINTS
    return BagJointLog(demonstration, tuple(warnings))
