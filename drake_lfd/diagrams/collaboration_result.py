"""What the people in the cell did to a run: separation, protective distance, override.

:class:`CollaborationRecord` is read off a run's Context from the log of the time-scaled
source's ``status`` (``systems/speed_override.py``: the path position ``s``, the
override, the protective stops, and each person's distance, approach speed, ``S_p``,
margin and full-speed point speed, every controller period). It gives the figures
``simulate --json`` reports (:meth:`CollaborationRecord.to_json`) and the samples that
violate the protective separation distance, which judging counts.
:func:`scaled_due_times` turns the plan's due times into the times the path reached
them, when the critical configurations are judged.

The log at ``t_k`` holds the state the update at ``t_(k-1)`` wrote: the path position
for ``t_k`` (so ``s = t`` when nothing slowed the robot) and the separation measured at
``t_(k-1)``, which this module dates back by one period.

Not for: running (``closed_loop.py``) or the rest of a run's record (``trial_result.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_lfd.core.people import CollaborationParameters
from drake_lfd.systems.separation import SEPARATION_FIELDS
from drake_lfd.systems.speed_override import STATUS_FIELDS

__all__ = ["CollaborationRecord", "collaboration_record_from_log", "scaled_due_times"]


@dataclass(frozen=True, eq=False)
class CollaborationRecord:
    """The people's effect on one run.

    Attributes
    ----------
    t : array, shape (m,)
        Times of the path position and override, s.
    path_time_s, override : array, shape (m,)
        ``s`` and ``ds/dt`` at those times.
    separation_t : array, shape (k,)
        When each separation sample was measured, s.
    distance_m, speed_toward_m_s, protective_distance_m, margin_m : array, shape (k, P)
        Per sample and person: ``d``, ``v_r``, ``S_p``, ``d - S_p``.
    protective_stops : int
        How often the override fell to 0.
    people : tuple of str
        The people's names.
    moving_toward_speed_m_s : float
        Approach speeds above this count as moving toward a person.
    time_step : float
        The controller period, s.
    """

    t: np.ndarray
    path_time_s: np.ndarray
    override: np.ndarray
    separation_t: np.ndarray
    distance_m: np.ndarray
    speed_toward_m_s: np.ndarray
    protective_distance_m: np.ndarray
    margin_m: np.ndarray
    protective_stops: int
    people: tuple
    moving_toward_speed_m_s: float
    time_step: float

    @property
    def min_separation_m(self) -> float:
        """The least distance between any person and the robot (``inf`` without samples)."""
        return float(self.distance_m.min()) if self.distance_m.size else math.inf

    @property
    def min_margin_m(self) -> float:
        """The least ``d - S_p`` (``inf`` without samples)."""
        return float(self.margin_m.min()) if self.margin_m.size else math.inf

    @property
    def violations(self) -> np.ndarray:
        """Per separation sample, whether the robot moved toward a person closer than
        ``S_p`` (``v_r`` above :attr:`moving_toward_speed_m_s` and ``d < S_p``), (k,)."""
        if not self.distance_m.size:
            return np.zeros(0, dtype=bool)
        moving = self.speed_toward_m_s > self.moving_toward_speed_m_s
        return np.any(moving & (self.distance_m < self.protective_distance_m), axis=1)

    @property
    def violation_count(self) -> int:
        return int(np.count_nonzero(self.violations))

    @property
    def time_scaled_s(self) -> float:
        """How long the robot ran below full speed (override < 1), protective stops
        included, s."""
        return float(np.count_nonzero(self.override < 1.0 - 1e-12) * self.time_step)

    @property
    def time_lost_s(self) -> float:
        """How much later the run reached where it got than without people: the clock
        minus the path position at the last sample, s."""
        if not len(self.t):
            return 0.0
        return max(float(self.t[-1] - self.path_time_s[-1]), 0.0)

    @property
    def slowed(self) -> bool:
        """Whether the robot ever ran below full speed."""
        return bool(np.any(self.override < 1.0 - 1e-12))

    def first_violation_s(self) -> float | None:
        """When the first violation was measured (None without one)."""
        violations = self.violations
        return float(self.separation_t[int(np.argmax(violations))]) if violations.any() else None

    def to_json(self) -> dict:
        """The ``collaboration`` entry of a ``simulate --json`` trial (docs/cli.rst)."""

        def number(value):
            return float(value) if math.isfinite(value) else None

        return {
            "min_separation_m": number(self.min_separation_m),
            "min_margin_m": number(self.min_margin_m),
            "protective_stops": int(self.protective_stops),
            "time_scaled_s": self.time_scaled_s,
            "time_lost_s": self.time_lost_s,
        }


def collaboration_record_from_log(t: np.ndarray, data: np.ndarray, *, people, parameters: CollaborationParameters,
                                  time_step: float) -> CollaborationRecord:
    """The record of a run from the ``status`` log: sample times ``t`` (m,) and ``data``
    (3 + 5 P, m), as the logger keeps them."""
    # Copies: a logger's arrays are views of memory the next run reuses.
    t = np.array(t, dtype=float)
    data = np.array(data, dtype=float)
    fields, count = len(SEPARATION_FIELDS), len(people)
    offset = len(STATUS_FIELDS)
    # The first sample is the state before the first update (no separation measured yet).
    per_person = data[offset:, 1:].reshape(count, fields, -1) if len(t) > 1 else np.zeros((count, fields, 0))
    column = lambda name: per_person[:, SEPARATION_FIELDS.index(name), :].T.copy()  # noqa: E731
    return CollaborationRecord(
        t=t, path_time_s=data[0].copy(), override=data[1].copy(), separation_t=t[1:] - time_step,
        distance_m=column("distance_m"), speed_toward_m_s=column("speed_toward_m_s"),
        protective_distance_m=column("protective_distance_m"), margin_m=column("margin_m"),
        protective_stops=int(round(data[2, -1])) if len(t) else 0, people=tuple(p.name for p in people),
        moving_toward_speed_m_s=parameters.moving_toward_speed_m_s, time_step=float(time_step))


def scaled_due_times(due_times_s, t: np.ndarray, path_time_s: np.ndarray, now: float) -> np.ndarray:
    """When the path reached each nominal due time: the first logged time at which the
    path position is at or past it, linear between the samples around it. A due time the
    path had not reached by the last sample is put where it would be at full speed from
    there (after ``now``: not reached)."""
    t = np.asarray(t, dtype=float)
    s = np.asarray(path_time_s, dtype=float)
    scaled = []
    for due in np.asarray(due_times_s, dtype=float):
        if not len(s) or s[-1] < due - 1e-9:
            last_t, last_s = (t[-1], s[-1]) if len(s) else (now, 0.0)
            scaled.append(max(now, last_t) + (due - last_s) + 1e-6)
            continue
        k = int(np.argmax(s >= due - 1e-9))
        if k == 0 or s[k] - s[k - 1] <= 0.0:
            scaled.append(float(t[k]))
        else:
            fraction = (due - s[k - 1]) / (s[k] - s[k - 1])
            scaled.append(float(t[k - 1] + min(max(fraction, 0.0), 1.0) * (t[k] - t[k - 1])))
    return np.array(scaled)
