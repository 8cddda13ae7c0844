"""A joint logger that samples like the UR5e's RTDE interface and writes its CSV.

A real kinesthetic demonstration is what the robot logs while a person guides it: the
measured joint angles at the RTDE rate (500 Hz on an e-Series). :class:`DemoRecorder`
is that logger in a Drake diagram: a periodic publish event samples its input and keeps
the samples, which come out as a :class:`~drake_lfd.core.demonstrations.Demonstration` or as
the project's RTDE-style CSV (``timestamp, actual_q_0 .. actual_q_5``).

Not for: simulating the guided arm (``kinesthetic.py``) or reading logs
(``demonstrations.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from drake_lfd.core.demonstrations import RTDE_RATE_HZ, Demonstration
from drake_lfd.io.demonstration_logs import write_rtde_csv

__all__ = ['DemoRecorder']

# Timestamps are rounded to this many decimals (1 us): sample times are multiples of
# the period, and rounding keeps the CSV free of 0.30000000000000004-style digits.
_TIMESTAMP_DECIMALS = 6


class DemoRecorder(LeafSystem):
    """Samples measured joint positions at a fixed rate, as the UR's RTDE log does.

    .. pydrake_system::

        name: DemoRecorder
        input_ports:
        - measured_position
        output_ports:
        - demonstration

    The input ``measured_position`` is a vector of ``num_joints`` joint angles (rad).
    The output ``demonstration`` is None until simulation time ``finish_time_s``, then
    the recorded :class:`~drake_lfd.core.demonstrations.Demonstration` (named
    ``demo_name``), so a :class:`~drake_lfd.systems.feature_library.FeatureLibrarySystem`
    can take it in the same Diagram.
    A periodic publish event at ``rate_hz`` (first sample at ``t = 0``) appends
    ``(t, q)``; nothing is stored in the context, so the recorder holds the samples of
    the last simulation it was part of (call :meth:`clear` before reusing it).

    Parameters
    ----------
    num_joints : int
        Size of the input, 6 for the UR5e.
    rate_hz : float
        Sampling rate, > 0; the RTDE rate (500 Hz) by default.
    finish_time_s : float, optional
        When the demonstration is complete (None: never put out).
    demo_name, description : str
        Name and description of the demonstration put out.
    """

    def __init__(self, *, num_joints: int = 6, rate_hz: float = RTDE_RATE_HZ, finish_time_s: float | None = None,
                 demo_name: str = "demo", description: str = ""):
        super().__init__()
        if not rate_hz > 0.0 or not np.isfinite(rate_hz):
            raise ValueError(f"rate_hz must be a finite number > 0, got {rate_hz!r}")
        self._num_joints = int(num_joints)
        self._period_s = 1.0 / float(rate_hz)
        self._measured_position_port = self.DeclareVectorInputPort("measured_position", self._num_joints)
        self.DeclarePeriodicPublishEvent(period_sec=self._period_s, offset_sec=0.0, publish=self._record)
        self._timestamps = []
        self._joint_positions = []
        self._finish_time_s = None if finish_time_s is None else float(finish_time_s)
        self._demo_name = demo_name
        self._description = description
        # The samples live outside the Context, so the output depends on time only.
        self.demonstration_output_port = self.DeclareAbstractOutputPort(
            "demonstration", lambda: AbstractValue.Make(object()), self._calc_demonstration,
            prerequisites_of_calc={self.time_ticket()})

    @staticmethod
    def AddToBuilder(builder, measured_position_port, *, num_joints=6, rate_hz=RTDE_RATE_HZ, name="demo_recorder",
                     **kwargs):
        """Adds a recorder named ``name`` fed by ``measured_position_port``; returns it
        (``kwargs``: ``finish_time_s``, ``demo_name``, ``description``)."""
        recorder = builder.AddSystem(DemoRecorder(num_joints=num_joints, rate_hz=rate_hz, **kwargs))
        recorder.set_name(name)
        builder.Connect(measured_position_port, recorder.get_input_port())
        return recorder

    @property
    def period_s(self) -> float:
        """Time between samples, seconds."""
        return self._period_s

    def _record(self, context):
        t = round(context.get_time(), _TIMESTAMP_DECIMALS)
        # A repeated publish at one time (e.g. a forced publish) must not add a sample
        # the log reader would reject as not strictly increasing.
        if self._timestamps and t <= self._timestamps[-1]:
            return
        self._timestamps.append(t)
        self._joint_positions.append(np.array(self._measured_position_port.Eval(context), dtype=float))

    def _calc_demonstration(self, context, output):
        done = (self._finish_time_s is not None and context.get_time() >= self._finish_time_s - 1e-9
                and self.num_samples >= 2)
        output.set_value(self.demonstration(self._demo_name, self._description) if done else None)

    def clear(self):
        """Forgets every sample."""
        self._timestamps.clear()
        self._joint_positions.clear()

    @property
    def num_samples(self) -> int:
        return len(self._timestamps)

    def timestamps(self) -> np.ndarray:
        """Sample times, array shape (m,), seconds."""
        return np.array(self._timestamps, dtype=float)

    def joint_positions(self) -> np.ndarray:
        """Samples, array shape (m, num_joints), radians."""
        return np.array(self._joint_positions, dtype=float).reshape(-1, self._num_joints)

    def demonstration(self, name: str = "demo", description: str = "") -> Demonstration:
        """The samples so far as a :class:`~drake_lfd.core.demonstrations.Demonstration`."""
        return Demonstration(
            name=name, timestamps=self.timestamps(), joint_positions=self.joint_positions(), description=description
        )

    def write_csv(self, path, *, name: str = "demo", description: str = ""):
        """Writes the samples as the project's RTDE-style CSV, atomically
        (temporary file, fsync, rename; see :func:`~drake_lfd.io.demonstration_logs.write_rtde_csv`)."""
        if self._num_joints != 6:
            raise ValueError("an RTDE-style UR log has 6 joints")
        write_rtde_csv(self.demonstration(name, description), path)
