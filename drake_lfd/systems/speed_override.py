"""The speed override with people in the cell: the plan's joint path followed in scaled time.

:class:`TimeScaledJointPathSource` replaces the compiled controller's source and
controller when a trial has people (without people the pipeline is built exactly as
before, with no system of this module). It keeps in discrete state the path position
``s`` (the time along the run's joint path, which equals the simulation time when nothing
slows the robot), the speed override ``o = ds/dt`` in [0, 1], the number of protective
stops, the joint command, and the separation numbers its last decision used. Once every
controller period ``dt`` it

1. reads the :class:`~drake_lfd.systems.separation.SeparationMonitor` (distance ``d``
   and full-speed point speed ``u`` per person) and takes the override the policy allows:
   speed and separation monitoring
   (:func:`~drake_lfd.core.people.separation_override`, the least over the people) or
   the stop-only baseline (:func:`~drake_lfd.core.people.stop_only_override`);
2. rate-limits it by ``dt / T_s`` (an override of 1 falls to 0 within the stopping time;
   the joints' acceleration from the change, ``|dq/ds| do/dt``, stays within joint speed
   limit / T_s, the acceleration limit);
3. advances ``s`` by ``o dt`` and steps the command with the compiled controller's law in
   path time: ``q_c <- q_c + clip(q_d(s' + o dt) - q_d(s') + dt K (q_d(s + o lead) -
   q_measured))``, the speed clip per joint as there; the command is clipped to the
   joint position limits. During a protective stop (``o = 0``) the command is held (the
   feedback alone would creep the arm the last millimetres onto the path, toward the
   person who stopped it).

With ``o = 1`` throughout the command is the compiled controller's, so the robot follows
the same joint path, slower or stopped where people are: every critical configuration is
still met, at the time the path's sample is reached. The run ends when ``s`` reaches the
plan's end (``TrialEnd`` with a ``path_time`` input), not at the nominal time. The joint
path is a cache entry of the plan and the run's start (latched at initialization), as in
:class:`~drake_lfd.systems.joint_path_source.JointPathSource`. This is a Python system in
the 100 Hz loop; only trials with people pay for it.

Not for: the geometry of people (``people.py``), the distances (``separation.py``), the
maths of the override (``core/people.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem, ValueProducer

from drake_lfd.core.people import (
    SSM_POLICY, CollaborationParameters, rate_limited, separation_override, stop_only_override, stop_only_radius_m,
)
from drake_lfd.robot.differential_ik_law import DifferentialIKLaw
from drake_lfd.systems.joint_path_source import JointPathSource, run_joint_path
from drake_lfd.systems.planner import NO_PLAN
from drake_lfd.systems.separation import SEPARATION_FIELDS

__all__ = ["TimeScaledJointPathSource", "STATUS_FIELDS"]

#: The first numbers of the ``status`` output (then :data:`SEPARATION_FIELDS` per person).
STATUS_FIELDS = ("path_time_s", "override", "protective_stops")


class TimeScaledJointPathSource(LeafSystem):
    """Follows the plan's joint path at a speed override set by the people's separation.

    .. pydrake_system::

        name: TimeScaledJointPathSource
        input_ports:
        - plan
        - q_measured
        - separation
        output_ports:
        - q_command
        - path_rate
        - path_time
        - status

    ``plan``: the planner's ScheduledPlan; ``q_measured``: (6,); ``separation``: the
    monitor's; ``q_command``: (6,) joint position command; ``path_rate``: (6,) ``dq/ds``
    at ``s``; ``path_time``: (1,) ``s``; ``status``: ``[s, o, stops]`` then the
    separation numbers of the last decision, :data:`SEPARATION_FIELDS` per person (what
    the run's log records).

    Parameters
    ----------
    law : DifferentialIKLaw
        The controller's period, gain and limits.
    parameters : CollaborationParameters
    stopping_time_s : float
        T_s (the override's ramp: 1 to 0 within it).
    num_people : int
    lead_s : float
        As the compiled controller's.
    """

    def __init__(self, *, law: DifferentialIKLaw, parameters: CollaborationParameters, stopping_time_s: float,
                 num_people: int, lead_s: float = 0.0):
        super().__init__()
        self._law = law
        self._dt = float(law.time_step)
        self._gain = float(law.position_gain)
        self._lead_s = float(lead_s)
        self._parameters = parameters
        self._stopping_time_s = float(stopping_time_s)
        self._ssm = parameters.policy == SSM_POLICY
        self._stop_radius_m = stop_only_radius_m(parameters, self._stopping_time_s, self._dt)
        self._speed_limit = self._dt * np.asarray(law.velocity_limits, dtype=float)
        self._lower = np.asarray(law.position_lower, dtype=float)
        self._upper = np.asarray(law.position_upper, dtype=float)
        self.num_people = int(num_people)
        fields = len(SEPARATION_FIELDS)
        n = 6
        self.plan_input_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(NO_PLAN))
        self.q_measured_input_port = self.DeclareVectorInputPort("q_measured", n)
        self.separation_input_port = self.DeclareVectorInputPort("separation", fields * self.num_people)
        self._start_index = self.DeclareAbstractState(AbstractValue.Make(np.zeros(n)))
        # [s, o, stops, separation numbers of the last decision]; the command apart.
        self._status_index = self.DeclareDiscreteState(len(STATUS_FIELDS) + fields * self.num_people)
        self._command_index = self.DeclareDiscreteState(n)
        self._path_cache = self.DeclareCacheEntry(
            "joint_path", ValueProducer(allocate=lambda: AbstractValue.Make(object()), calc=self._calc_path),
            prerequisites_of_calc={self.input_port_ticket(self.plan_input_port.get_index()),
                                   self.abstract_state_ticket(self._start_index)})
        self.q_command_output_port = self.DeclareVectorOutputPort(
            "q_command", n, self._calc_command, prerequisites_of_calc={self.discrete_state_ticket(self._command_index)})
        self.path_rate_output_port = self.DeclareVectorOutputPort(
            "path_rate", n, self._calc_path_rate,
            prerequisites_of_calc={self.discrete_state_ticket(self._status_index), self._path_cache.ticket()})
        self.path_time_output_port = self.DeclareVectorOutputPort(
            "path_time", 1, self._calc_path_time, prerequisites_of_calc={self.discrete_state_ticket(self._status_index)})
        self.status_output_port = self.DeclareStateOutputPort("status", self._status_index)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._latch_start)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._step)

    @staticmethod
    def AddToBuilder(*, builder, plan_output_port, q_measured_output_port, q_command_input_port=None,
                     name: str = "time_scaled_joint_path", **kwargs) -> "TimeScaledJointPathSource":
        """Adds a source named ``name`` fed by the plan and the measured positions and
        (when given) commanding ``q_command_input_port``; connect its ``separation``
        input to the monitor (``kwargs``: the constructor's)."""
        source = builder.AddNamedSystem(name, TimeScaledJointPathSource(**kwargs))
        builder.Connect(plan_output_port, source.plan_input_port)
        builder.Connect(q_measured_output_port, source.q_measured_input_port)
        if q_command_input_port is not None:
            builder.Connect(source.q_command_output_port, q_command_input_port)
        return source

    @property
    def stop_radius_m(self) -> float:
        """The stop-only policy's radius (used only with that policy)."""
        return self._stop_radius_m

    def joint_path(self, root_context) -> tuple[np.ndarray, np.ndarray]:
        """The run's desired joint path: times (m,) and positions (m, 6)."""
        return self._path_cache.Eval(self.GetMyContextFromRoot(root_context))

    # -- the path ---------------------------------------------------------------------
    def _calc_path(self, context, value):
        q_start = context.get_abstract_state(self._start_index).get_value()
        t, q = run_joint_path(self.plan_input_port.Eval(context), q_start, self._law)
        value.set_value((np.asarray(t, dtype=float), np.asarray(q, dtype=float)))

    @staticmethod
    def _at(path, s: float) -> np.ndarray:
        """q_d(s): the path linear between its samples, held outside them."""
        t, q = path
        if s <= t[0]:
            return q[0]
        if s >= t[-1]:
            return q[-1]
        i = int(np.searchsorted(t, s, side="right")) - 1
        fraction = (s - t[i]) / (t[i + 1] - t[i])
        return q[i] + fraction * (q[i + 1] - q[i])

    def _calc_command(self, context, output):
        q_command = context.get_discrete_state(self._command_index).get_value()
        output.SetFromVector(np.clip(q_command, self._lower, self._upper))

    def _calc_path_rate(self, context, output):
        s = context.get_discrete_state(self._status_index).get_value()[0]
        path = self._path_cache.Eval(context)
        output.SetFromVector((self._at(path, s + self._dt) - self._at(path, s)) / self._dt)

    def _calc_path_time(self, context, output):
        output.SetAtIndex(0, context.get_discrete_state(self._status_index).get_value()[0])

    # -- events -------------------------------------------------------------------------
    # The run's start, q_0, latched as the compiled source latches it (same port and state names).
    _latch_start = JointPathSource._latch_start

    def _initialize(self, context, discrete_state):
        q_start = context.get_abstract_state(self._start_index).get_value()
        status = np.zeros(discrete_state.get_vector(self._status_index).size())
        status[0], status[1] = context.get_time(), 1.0
        discrete_state.set_value(self._status_index, status)
        discrete_state.set_value(self._command_index, q_start)
        return EventStatus.Succeeded()

    def _override(self, separation: np.ndarray) -> float:
        """The policy's override before the rate limit (the least over the people)."""
        fields = len(SEPARATION_FIELDS)
        target = 1.0
        for person in range(self.num_people):
            distance, _, _, _, full_speed = separation[fields * person:fields * (person + 1)]
            if self._ssm:
                allowed = separation_override(distance, full_speed, self._parameters, self._stopping_time_s,
                                              self._dt)
            else:
                allowed = stop_only_override(distance, self._stop_radius_m)
            target = min(target, allowed)
        return target

    def _step(self, context, discrete_state):
        status = context.get_discrete_state(self._status_index).get_value()
        s, override, stops = float(status[0]), float(status[1]), float(status[2])
        separation = np.asarray(self.separation_input_port.Eval(context))
        new_override = rate_limited(self._override(separation), override, self._dt / self._stopping_time_s)
        if new_override == 0.0 and override > 0.0:
            stops += 1.0
        path = self._path_cache.Eval(context)
        step = new_override * self._dt
        s_next = s + step
        q_measured = np.asarray(self.q_measured_input_port.Eval(context))
        w = (self._at(path, s_next + step) - self._at(path, s_next)
             + self._dt * self._gain * (self._at(path, s + new_override * self._lead_s) - q_measured))
        q_command = context.get_discrete_state(self._command_index).get_value()
        if new_override > 0.0:
            discrete_state.set_value(self._command_index,
                                     q_command + np.clip(w, -self._speed_limit, self._speed_limit))
        # else a protective stop: the command is held where it is (the feedback would
        # creep the arm onto the path, toward whoever stopped it).
        discrete_state.set_value(self._status_index,
                                 np.concatenate([[s_next, new_override, stops], separation]))
        return EventStatus.Succeeded()
