"""A joint logger that samples like the UR5e's RTDE interface, its samples in the Context.

A real kinesthetic demonstration is what the robot logs while a person guides it: the
measured joint angles at the RTDE rate (500 Hz on an e-Series). :class:`DemoRecorder`
is that logger in a Drake diagram: a periodic unrestricted-update event samples its
input into the recorder's abstract state (a :class:`RecordedSamples`, an immutable log
that shares its earlier samples when one is added), so every Context of a Diagram holds
its own recording; the samples come out as a
:class:`~drake_lfd.core.demonstrations.Demonstration` (:meth:`DemoRecorder.demonstration`,
the ``demonstration`` output port) and as the project's RTDE-style CSV
(``timestamp, actual_q_0 .. actual_q_5``; :meth:`DemoRecorder.write_csv`, called after a
simulation, never from an event).

A Diagram that only needs the log (no ``demonstration`` port) can use Drake's own
per-Context log instead: :func:`add_joint_logger` (``LogVectorOutput``) and
:func:`demonstration_from_log` give the same demonstration.

Not for: simulating the guided arm (``kinesthetic.py``) or reading logs
(``demonstrations.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, DiagramBuilder, EventStatus, LeafSystem, OutputPort
from pydrake.systems.primitives import LogVectorOutput, VectorLog, VectorLogSink

from drake_lfd.core.demonstrations import NUM_JOINTS, RTDE_RATE_HZ, Demonstration
from drake_lfd.io.demonstration_logs import write_rtde_csv

__all__ = [
    "NO_DEMONSTRATION",
    "RecordedSamples",
    "DemoRecorder",
    "add_joint_logger",
    "demonstration_from_log",
]

# Timestamps are rounded to this many decimals (1 us): sample times are multiples of
# the period, and rounding keeps the CSV free of 0.30000000000000004-style digits.
_TIMESTAMP_DECIMALS = 6
# A sample this close to ``finish_time_s`` completes the demonstration.
_FINISH_TOLERANCE_S = 1e-9

#: What the ``demonstration`` port of a :class:`DemoRecorder` (and the ``demonstration``
#: input of a :class:`~drake_lfd.systems.feature_library.FeatureLibrarySystem`) carries
#: while there is no demonstration yet: a Demonstration without samples, so the port is
#: typed ``Demonstration`` throughout. Receivers ignore demonstrations of fewer than 2
#: samples.
NO_DEMONSTRATION = Demonstration(name="", timestamps=np.empty(0), joint_positions=np.empty((0, NUM_JOINTS)))


class RecordedSamples:
    """An immutable log of ``(t, q)`` samples: a persistent list, newest first.

    :meth:`appended` returns a new log that shares every earlier sample, so adding a
    sample costs the same at any length, and Drake's copies of a Context (which copy
    its abstract state) share one log instead of copying it.

    Attributes
    ----------
    num_samples : int
    last_time_s : float
        Time of the newest sample (``-inf`` when empty).
    """

    __slots__ = ("_previous", "_t", "_q", "num_samples")

    def __init__(self):
        self._previous = None
        self._t = -np.inf
        self._q = ()
        self.num_samples = 0

    @property
    def last_time_s(self) -> float:
        return self._t

    def appended(self, t: float, q) -> "RecordedSamples":
        """This log with ``(t, q)`` added (``q`` copied into a tuple of floats)."""
        log = RecordedSamples.__new__(RecordedSamples)
        log._previous = self
        log._t = float(t)
        log._q = tuple(float(value) for value in q)
        log.num_samples = self.num_samples + 1
        return log

    def arrays(self, num_joints: int) -> tuple[np.ndarray, np.ndarray]:
        """``(timestamps, joint_positions)``, shapes (m,) and (m, num_joints), oldest first."""
        times = np.empty(self.num_samples)
        positions = np.empty((self.num_samples, num_joints))
        node, row = self, self.num_samples - 1
        while row >= 0:
            times[row] = node._t
            positions[row] = node._q
            node, row = node._previous, row - 1
        return times, positions

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of a Context share it


class DemoRecorder(LeafSystem):
    """Samples measured joint positions at a fixed rate, as the UR's RTDE log does.

    .. pydrake_system::

        name: DemoRecorder
        input_ports:
        - measured_position
        output_ports:
        - demonstration

    The input ``measured_position`` is a vector of ``num_joints`` joint angles (rad).
    A periodic unrestricted-update event at ``rate_hz`` (first sample at ``t = 0``)
    adds ``(t, q)`` to the recorder's abstract state, a :class:`RecordedSamples`: the
    samples belong to the Context, so simulations on different Contexts of one Diagram
    record independently, and a fresh (or reset) Context starts with no samples. Drake
    applies an update at time ``t`` when a step starts at ``t``: after
    ``AdvanceTo(t_end)`` the sample at ``t_end`` is still pending
    (``Simulator.AdvancePendingEvents()`` takes it).

    The output ``demonstration`` is an abstract
    :class:`~drake_lfd.core.demonstrations.Demonstration`: :data:`NO_DEMONSTRATION` until
    the state holds a sample at ``finish_time_s``, then the recorded demonstration
    (named ``demo_name``), so a
    :class:`~drake_lfd.systems.feature_library.FeatureLibrarySystem` can take it in the
    same Diagram. Recording stops at ``finish_time_s``.

    Parameters
    ----------
    num_joints : int
        Size of the input, 6 for the UR5e (a Demonstration has 6 joints).
    rate_hz : float
        Sampling rate, > 0; the RTDE rate (500 Hz) by default.
    finish_time_s : float, optional
        When the demonstration is complete (None: recording goes on, never put out).
    demo_name, description : str
        Name and description of the demonstration put out.
    """

    def __init__(self, *, num_joints: int = NUM_JOINTS, rate_hz: float = RTDE_RATE_HZ,
                 finish_time_s: float | None = None, demo_name: str = "demo", description: str = ""):
        super().__init__()
        if not rate_hz > 0.0 or not np.isfinite(rate_hz):
            raise ValueError(f"rate_hz must be a finite number > 0, got {rate_hz!r}")
        self._num_joints = int(num_joints)
        self._period_s = 1.0 / float(rate_hz)
        self._finish_time_s = None if finish_time_s is None else float(finish_time_s)
        self._demo_name = demo_name
        self._description = description
        self._measured_position_port = self.DeclareVectorInputPort("measured_position", self._num_joints)
        self._samples_index = self.DeclareAbstractState(AbstractValue.Make(RecordedSamples()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(self._period_s, 0.0, self._record)
        self.demonstration_output_port = self.DeclareAbstractOutputPort(
            "demonstration", lambda: AbstractValue.Make(NO_DEMONSTRATION), self._calc_demonstration,
            prerequisites_of_calc={self.abstract_state_ticket(self._samples_index)})

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, measured_position_output_port: OutputPort,
                     num_joints: int = NUM_JOINTS, rate_hz: float = RTDE_RATE_HZ, name: str = "demo_recorder",
                     **kwargs) -> "DemoRecorder":
        """Adds a recorder named ``name`` fed by ``measured_position_output_port``; returns
        it (``kwargs``: ``finish_time_s``, ``demo_name``, ``description``)."""
        recorder = builder.AddNamedSystem(name, DemoRecorder(num_joints=num_joints, rate_hz=rate_hz, **kwargs))
        builder.Connect(measured_position_output_port, recorder.get_input_port())
        return recorder

    @property
    def period_s(self) -> float:
        """Time between samples, seconds."""
        return self._period_s

    def _finished(self, samples: RecordedSamples) -> bool:
        return self._finish_time_s is not None and samples.last_time_s >= self._finish_time_s - _FINISH_TOLERANCE_S

    def _record(self, context, state):
        samples = context.get_abstract_state(self._samples_index).get_value()
        t = round(context.get_time(), _TIMESTAMP_DECIMALS)
        # A repeated event at one time (AdvancePendingEvents twice, say) must not add a
        # sample the log reader would reject as not strictly increasing.
        if self._finished(samples) or t <= samples.last_time_s:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._samples_index).set_value(
            samples.appended(t, self._measured_position_port.Eval(context)))
        return EventStatus.Succeeded()

    def _calc_demonstration(self, context, output):
        samples = context.get_abstract_state(self._samples_index).get_value()
        done = self._finished(samples) and samples.num_samples >= 2
        output.set_value(self._demonstration_of(samples, self._demo_name, self._description)
                         if done else NO_DEMONSTRATION)

    def _own_context(self, context: Context) -> Context:
        """``context`` when it is this recorder's, else this recorder's part of the root ``context``."""
        try:
            self.ValidateContext(context)
        except RuntimeError:
            return self.GetMyContextFromRoot(context)
        return context

    def samples(self, context: Context) -> RecordedSamples:
        """The samples in ``context`` (the recorder's Context or its Diagram's root Context)."""
        return self._own_context(context).get_abstract_state(self._samples_index).get_value()

    def num_samples(self, context: Context) -> int:
        """How many samples ``context`` holds."""
        return self.samples(context).num_samples

    def _demonstration_of(self, samples: RecordedSamples, name: str, description: str) -> Demonstration:
        timestamps, joint_positions = samples.arrays(self._num_joints)
        return Demonstration(name=name, timestamps=timestamps, joint_positions=joint_positions,
                             description=description)

    def demonstration(self, context: Context, name: str | None = None, description: str | None = None
                      ) -> Demonstration:
        """The samples in ``context`` so far as a
        :class:`~drake_lfd.core.demonstrations.Demonstration` (named ``demo_name`` and
        described by ``description`` unless given)."""
        return self._demonstration_of(self.samples(context), self._demo_name if name is None else name,
                                      self._description if description is None else description)

    def write_csv(self, context: Context, path, *, name: str | None = None, description: str | None = None):
        """Writes the samples in ``context`` as the project's RTDE-style CSV, atomically
        (temporary file, fsync, rename; see :func:`~drake_lfd.io.demonstration_logs.write_rtde_csv`).

        Call it after a simulation (no event writes files)."""
        if self._num_joints != 6:
            raise ValueError("an RTDE-style UR log has 6 joints")
        write_rtde_csv(self.demonstration(context, name, description), path)


def add_joint_logger(builder: DiagramBuilder, measured_position_port: OutputPort, *,
                     rate_hz: float = RTDE_RATE_HZ, name: str = "joint_logger") -> VectorLogSink:
    """Drake's per-Context log of ``measured_position_port`` at ``rate_hz`` (a
    ``VectorLogSink`` from ``LogVectorOutput``, named ``name``): read it with
    ``logger.FindLog(root_context)`` and turn it into a demonstration with
    :func:`demonstration_from_log`."""
    if not rate_hz > 0.0 or not np.isfinite(rate_hz):
        raise ValueError(f"rate_hz must be a finite number > 0, got {rate_hz!r}")
    logger = LogVectorOutput(measured_position_port, builder, 1.0 / float(rate_hz))
    logger.set_name(name)
    return logger


def demonstration_from_log(log: VectorLog, *, name: str = "demo", description: str = "") -> Demonstration:
    """A :class:`~drake_lfd.core.demonstrations.Demonstration` of a Drake ``VectorLog``
    of joint positions.

    Times are rounded to 1 us as :class:`DemoRecorder`'s are; a sample whose rounded
    time is not after the previous one (a forced publish repeating a time) is dropped,
    so the times are strictly increasing.

    Parameters
    ----------
    log : VectorLog
        Of a 6-vector of joint angles (rad).
    name, description : str
    """
    times = np.round(np.asarray(log.sample_times(), dtype=float), _TIMESTAMP_DECIMALS)
    data = np.asarray(log.data(), dtype=float)
    if data.shape[0] != NUM_JOINTS:
        raise ValueError(f"a demonstration logs {NUM_JOINTS} joints, the log has {data.shape[0]}")
    # Kept: a time after every time before it.
    keep = times > np.maximum.accumulate(np.concatenate([[-np.inf], times[:-1]]))
    return Demonstration(name=name, timestamps=times[keep], joint_positions=data[:, keep].T,
                         description=description)
