"""Importing a demonstration from whatever log a user has: RTDE CSV or ROS bag.

:func:`read_demonstration_log` is what ``library add`` calls. It picks the reader from
the path (:func:`~drake_lfd.io.rosbag_logs.bag_location`: a ``.bag`` file or a ROS 2 bag
directory is a bag, anything else an RTDE CSV), applies the options that reader takes
and refuses the ones it does not (``topic`` for a CSV; ``rate_hz`` and ``tcp_offset``
for a bag), and cuts the time window ``start_s`` .. ``end_s`` (seconds from the first
sample of a CSV, before any ``runtime_state`` filter, or from a bag's first message;
both ends included). The result is a plain
:class:`~drake_lfd.core.demonstrations.Demonstration`, so the library adds and checks it
as any other and stores it as the project's RTDE-style CSV.

Not for: the readers (``demonstration_logs.py``, ``rtde_logs.py``, ``rosbag_logs.py``),
the library (``library.py``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.core.errors import InputError
from drake_lfd.io.demonstration_logs import read_rtde_log
from drake_lfd.io.rosbag_logs import DEFAULT_TOPIC, bag_location, read_joint_state_bag
from drake_lfd.io.rtde_logs import TCP_POSE_COLUMNS, check_tcp_pose, tcp_offset_transform

__all__ = ["ImportedLog", "check_time_window", "read_demonstration_log"]


class ImportedLog(NamedTuple):
    """A demonstration read from a log: warnings (for stderr) and reports (for stdout,
    such as the TCP offset check's discrepancy)."""

    demonstration: Demonstration
    warnings: tuple[str, ...]
    reports: tuple[str, ...]


def check_time_window(start_s, end_s):
    """Refuses a window that is not finite, starts before 0 or ends before it starts.

    Raises
    ------
    InputError
        Naming ``--start`` or ``--end``.
    """
    for value, option in ((start_s, "--start"), (end_s, "--end")):
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            raise InputError(f"{value!r} is not a time in seconds from the log's start (0 or more)", field=option)
    if start_s is not None and end_s is not None and not end_s > start_s:
        raise InputError(f"the window ends ({end_s!r} s) before it starts ({start_s!r} s)", field="--end")


def _cut(demonstration, keep, *, file, start_s, end_s):
    if int(np.count_nonzero(keep)) < 2:
        raise InputError(
            f"the time window {start_s if start_s is not None else 0:g} .. "
            f"{end_s if end_s is not None else 'end'} s holds {int(np.count_nonzero(keep))} sample(s); "
            "a demonstration needs at least 2",
            file=file,
            field="--start/--end",
        )
    return Demonstration(
        name=demonstration.name,
        timestamps=demonstration.timestamps[keep],
        joint_positions=demonstration.joint_positions[keep],
        description=demonstration.description,
    )


def read_demonstration_log(
    path,
    *,
    name=None,
    description="",
    filter_runtime_state=True,
    rate_hz=None,
    topic=None,
    start_s=None,
    end_s=None,
    tcp_offset=None,
):
    """Reads a UR5e demonstration from an RTDE CSV or a ROS 1/2 bag.

    Parameters
    ----------
    path : str or Path
    name : str, optional
    description : str
    filter_runtime_state : bool
        CSV only: the ``runtime_state`` filter (``read_rtde_log``).
    rate_hz : float, optional
        CSV only: the sample rate of a log without a ``timestamp`` column.
    topic : str, optional
        Bag only: the ``sensor_msgs/JointState`` topic (default ``/joint_states``).
    start_s, end_s : float, optional
        The time window to keep (module docstring).
    tcp_offset : sequence of float, optional
        CSV only: X Y Z [RX RY RZ] of the TCP on tool0; checks the joints against
        ``actual_TCP_pose`` (``rtde_logs.check_tcp_pose``) and reports the discrepancy.

    Returns
    -------
    ImportedLog

    Raises
    ------
    InputError
        One line, naming the file and what is wrong.
    """
    path = Path(path)
    check_time_window(start_s, end_s)
    if bag_location(path) is not None:
        for value, option in ((rate_hz, "--rate"), (tcp_offset, "--tcp-offset")):
            if value is not None:
                raise InputError(
                    f"{option} is for an RTDE CSV log; a bag's JointState messages carry their own times"
                    if option == "--rate" else
                    f"{option} is for an RTDE CSV log with actual_TCP_pose columns; a JointState bag has no TCP pose",
                    file=path,
                    field=option,
                )
        log = read_joint_state_bag(
            path, topic=DEFAULT_TOPIC if topic is None else topic, name=name, description=description,
            start_s=start_s, end_s=end_s,
        )
        return ImportedLog(log.demonstration, log.warnings, ())
    if topic is not None:
        raise InputError("--topic is for a ROS bag (a .bag file or a ROS 2 bag directory), not a CSV log",
                         file=path, field="--topic")
    X_tool0_TCP = None if tcp_offset is None else tcp_offset_transform(tcp_offset, field="--tcp-offset")
    log = read_rtde_log(
        path, name=name, description=description, filter_runtime_state=filter_runtime_state, rate_hz=rate_hz,
        extra_columns=TCP_POSE_COLUMNS if X_tool0_TCP is not None else (),
    )
    demonstration = log.demonstration
    keep = np.ones(demonstration.num_samples, dtype=bool)
    if start_s is not None or end_s is not None:
        elapsed = demonstration.timestamps - log.first_timestamp
        if start_s is not None:
            keep &= elapsed >= start_s - 1e-9
        if end_s is not None:
            keep &= elapsed <= end_s + 1e-9
        demonstration = _cut(demonstration, keep, file=path, start_s=start_s, end_s=end_s)
    reports = []
    if X_tool0_TCP is not None:
        extra = {column: values[keep] for column, values in log.extra.items()}
        discrepancy = check_tcp_pose(demonstration.joint_positions, extra, X_tool0_TCP, file=path)
        reports.append(f"TCP check of {path}: forward kinematics with the TCP offset vs actual_TCP_pose: "
                       f"{discrepancy.text()}")
    return ImportedLog(demonstration, log.warnings, tuple(reports))
