"""The joint-path check's memory of its last follows, so a plan sharing a prefix resumes there.

A :class:`~drake_lfd.robot.joint_path.JointPathChecker` keeps a :class:`FollowMemory`:
its last follows (:class:`FollowRecord`) from each of its last start configurations,
each with the follow loop's whole state at the start of each span
(:class:`FollowCheckpoint`). :meth:`FollowMemory.reusable` finds the follow sharing the
longest prefix with a new plan (equal to the bit) and the checkpoint to resume it from;
the checker's loop writes the checkpoints and resumes from them (``joint_path.py``,
*Reuse*).

Not for: following a plan (``joint_path.py``).
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict

import numpy as np

from drake_lfd.robot.joint_path_records import JointPath

__all__ = ["FollowCheckpoint", "FollowRecord", "FollowMemory"]

# Follows a checker remembers for resuming, per start configuration (the lazy search's
# last compositions and the previous trials' plans; each holds one path and a checkpoint
# per critical configuration), and the starts it remembers them for (the search tries up
# to three branches and their windings).
_REMEMBERED_FOLLOWS = 4
_REMEMBERED_STARTS = 16


@dataclasses.dataclass(frozen=True)
class FollowCheckpoint:
    """The follow loop's whole state at the start of step ``k``, the first sample of the
    span from critical configuration ``con`` (0-based)."""

    con: int
    k: int
    q: np.ndarray
    wake: np.ndarray
    travel: np.ndarray
    q_previous: tuple
    slack: float
    minima: tuple[float, float, float, float]  # clearance, elbow, wrist, shoulder
    span: int
    next_con: int
    critical_errors: tuple


@dataclasses.dataclass(frozen=True)
class FollowRecord:
    """One follow: its start, its plan's samples, its path and its checkpoints by con."""

    q_start: bytes
    critical_indices: tuple[int, ...]
    times: np.ndarray
    poses: np.ndarray
    path: JointPath
    checkpoints: dict


def _equal_rows(a: np.ndarray, b: np.ndarray) -> int:
    """How many leading rows of the float arrays ``a`` and ``b`` are equal to the bit."""
    rows = min(len(a), len(b))
    if a.shape[1:] != b.shape[1:]:
        return 0
    differ = np.flatnonzero((a[:rows].view(np.uint64) != b[:rows].view(np.uint64)).reshape(rows, -1).any(axis=1))
    return int(differ[0]) if len(differ) else rows


class FollowMemory:
    """The last follows from each start configuration, newest first; the starts least
    recently used first."""

    def __init__(self) -> None:
        self._follows: OrderedDict[bytes, list[FollowRecord]] = OrderedDict()

    def reusable(self, q_start, critical_indices, times, poses):
        """The remembered follow from ``q_start`` sharing the longest prefix with the
        plan (``critical_indices``, ``times`` (n,), ``poses`` (n, 8)), and the checkpoint
        to resume it from: ``(record, None)`` when the whole plan is the same, ``(None,
        None)`` when nothing is shared. Shared means equal to the bit: the samples up to
        the checkpoint's critical configuration (the steps before it interpolate only
        those) and the critical indices up to it, with as many critical configurations."""
        best, best_point = None, None
        for record in self._follows.get(q_start.tobytes(), ()):
            if len(record.critical_indices) != len(critical_indices):
                continue
            shared = min(_equal_rows(record.times, times), _equal_rows(record.poses, poses))
            if record.critical_indices == critical_indices and shared == len(times) == len(record.times):
                return record, None
            for c in sorted(record.checkpoints, reverse=True):
                if best_point is not None and c <= best_point.con:
                    break
                if critical_indices[c] < shared and record.critical_indices[:c + 1] == critical_indices[:c + 1]:
                    best, best_point = record, record.checkpoints[c]
                    break
        return best, best_point

    def remember(self, record: FollowRecord) -> None:
        """Keeps the last :data:`_REMEMBERED_FOLLOWS` follows from each of the last
        :data:`_REMEMBERED_STARTS` starts."""
        records = self._follows.pop(record.q_start, [])
        records.insert(0, record)
        del records[_REMEMBERED_FOLLOWS:]
        self._follows[record.q_start] = records
        while len(self._follows) > _REMEMBERED_STARTS:
            self._follows.popitem(last=False)
