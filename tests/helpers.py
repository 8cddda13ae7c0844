"""What many tests do alike: wait for a condition, and write joint logs.

Waiting: :func:`wait_until` polls a condition until it holds, the process being watched
has ended, or a generous deadline has passed, and says whether the condition holds; a
test asserts on the condition and the process, never on how long it took.
:func:`line_count` is the usual condition: lines a process has written to a file.

Joint logs: a UR5e's joint log as its controller's RTDE CSV writes it (``timestamp``
and ``actual_q_0..5``, one row per sample, numbers as Python prints floats), from sample
times and joint angles (:func:`joint_log_text`, :func:`write_joint_log`), or any table
of columns (:func:`table_text`); :func:`linear_motion` is the plain motion most library
tests log: from :data:`Q_HOME`, a straight joint-space move of up to 0.6 rad per joint.

Test tooling, beside the tests that import it (``from helpers import ...``).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

__all__ = ["wait_until", "line_count", "JOINT_COLUMNS", "RTDE_COLUMNS", "RTDE_HEADER", "Q_HOME", "linear_motion",
           "table_text", "joint_log_text", "write_joint_log"]


# ---------------------------------------------------------------------------- waiting

def wait_until(condition: Callable[[], bool], *, timeout_s: float, while_running=None, interval_s: float = 0.02) -> bool:
    """Polls ``condition()`` every ``interval_s`` until it is true, ``while_running`` (a
    ``subprocess.Popen``) has ended, or ``timeout_s`` (make it generous: a loaded
    machine is slow) has passed; returns ``condition()`` then."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if while_running is not None and while_running.poll() is not None:
            break
        if time.monotonic() >= deadline:
            break
        time.sleep(interval_s)
    return bool(condition())


def line_count(path: Path) -> int:
    """Lines written to ``path`` so far (0 while it does not exist)."""
    return path.read_text().count("\n") if path.exists() else 0


# ------------------------------------------------------------------------- joint logs

JOINT_COLUMNS = [f"actual_q_{i}" for i in range(6)]
RTDE_COLUMNS = ["timestamp", *JOINT_COLUMNS]
RTDE_HEADER = ",".join(RTDE_COLUMNS)
#: Where the logged motions start: the arm upright, the wrist turned down.
Q_HOME = np.array([0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0])


def linear_motion(seed: int = 0, m: int = 40, still: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``(t, q)``: ``m`` samples over 2 s, a straight move from :data:`Q_HOME` by a seeded
    offset of up to 0.6 rad per joint (none when ``still``)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, m)
    motion = np.zeros(6) if still else rng.uniform(-0.6, 0.6, 6)
    return t, Q_HOME + np.outer(np.linspace(0, 1, m), motion)


def table_text(columns: Sequence[str], rows, delimiter: str = ",", end: str = "\n") -> str:
    """A header of ``columns`` and one line per row of numbers (``repr`` of each as a
    float), joined by ``delimiter``; the last line ends with ``end``."""
    lines = [delimiter.join(columns)]
    lines += [delimiter.join(repr(float(v)) for v in row) for row in rows]
    return "\n".join(lines) + end


def joint_log_text(t, q, delimiter: str = ",", end: str = "\n") -> str:
    """The RTDE CSV of sample times ``t`` (m,) and joint angles ``q`` (m, 6)."""
    return table_text(RTDE_COLUMNS, (np.concatenate([[t[k]], q[k]]) for k in range(len(t))), delimiter, end)


def write_joint_log(path: Path, t, q, delimiter: str = ",", end: str = "\n") -> Path:
    """Writes :func:`joint_log_text` to ``path``; returns ``path``."""
    path.write_text(joint_log_text(t, q, delimiter, end))
    return path
