"""The compiled closed loop's trajectory source: the plan's joint path, in chunks.

:class:`JointPathSource` takes the planner's plan on its ``plan`` port and the arm's
measured positions on ``q_measured``. At initialization it latches the arm's positions
(the run's start, ``q_0``, in abstract state); the run's joint path
(:func:`~drake_lfd.systems.joint_trajectory_controller.joint_path_of_plan`) and its
feed-forward samples ``w_k``, one per controller period up to the path's end
(:func:`~drake_lfd.systems.joint_trajectory_controller.feed_forward_samples`), are a
cache entry of the plan and ``q_0``: they live in the Context and are computed once a
run. Its ``chunk`` output is its discrete state, ``[q_0, w_k .. w_(k+M-1)]``,
written at initialization and then once every ``M`` controller periods, at the last
instant of a chunk, with the next one (a discrete update: the controller's update at the
same instant still reads the chunk it is in). So no Python runs in the 100 Hz loop, and
one Diagram runs many trials in many Contexts.

Not for: the tracking law (``joint_trajectory_controller.py``) or planning
(``planner.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem, ValueProducer

from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.robot.differential_ik_law import DifferentialIKLaw
from drake_lfd.systems.joint_trajectory_controller import (
    CHUNK_SAMPLES, chunk_size, feed_forward_samples, joint_path_of_plan,
)
from drake_lfd.systems.planner import NO_PLAN

__all__ = ["JointPathSource", "run_joint_path"]


def run_joint_path(plan, q_start, law: DifferentialIKLaw) -> tuple[np.ndarray, np.ndarray]:
    """The joint path a run follows from ``q_start``: times (m,) and positions (m, 6), the
    plan's (:func:`~drake_lfd.systems.joint_trajectory_controller.joint_path_of_plan`),
    or the start held when ``plan`` is no plan (or a request)."""
    if isinstance(plan, ScheduledPlan) and plan.planned:
        return joint_path_of_plan(plan, q_start, law)
    return np.zeros(1), np.asarray(q_start, dtype=float)[None, :]


class JointPathSource(LeafSystem):
    """Puts out the plan's joint path, ``M`` controller instants at a time.

    .. pydrake_system::

        name: JointPathSource
        input_ports:
        - plan
        - q_measured
        output_ports:
        - chunk

    ``plan``: an abstract :class:`~drake_lfd.planning.replanning.ScheduledPlan` (the
    planner system's); ``q_measured``: (6,) joint positions; ``chunk``: see
    :class:`~drake_lfd.systems.joint_trajectory_controller.JointTrajectoryController`.
    Without a plan (or with a request) the chunk holds the arm where it started.

    Parameters
    ----------
    law : DifferentialIKLaw
        The controller's law: its period and gain, and following a plan that has no joint
        path (on the controller plant).
    lead_s : float
        The controller's ``lead_s``.
    chunk_samples : int
        M, the controller's.
    """

    def __init__(self, *, law: DifferentialIKLaw, lead_s: float = 0.0, chunk_samples: int = CHUNK_SAMPLES):
        super().__init__()
        self._law = law
        self._time_step = float(law.time_step)
        self._gain = float(law.position_gain)
        self._lead_s = float(lead_s)
        self._samples = int(chunk_samples)
        n = self._num_joints = 6
        self.plan_input_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(NO_PLAN))
        self.q_measured_input_port = self.DeclareVectorInputPort("q_measured", n)
        # The run's start, q_0: latched by an unrestricted update at initialization (before
        # the discrete ones), in abstract state, which the chunks' discrete updates leave
        # alone, so the path's cache entry stays valid for the whole run.
        self._start_index = self.DeclareAbstractState(AbstractValue.Make(np.zeros(n)))
        self._chunk_index = self.DeclareDiscreteState(chunk_size(n, self._samples))
        self._path_cache = self.DeclareCacheEntry(
            "joint_path", ValueProducer(allocate=lambda: AbstractValue.Make(object()), calc=self._calc_path),
            prerequisites_of_calc={self.input_port_ticket(self.plan_input_port.get_index()),
                                   self.abstract_state_ticket(self._start_index)})
        self.chunk_output_port = self.DeclareStateOutputPort("chunk", self._chunk_index)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._latch_start)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        # At the last instant of each chunk, the next one: the controller's update at that
        # instant still reads the chunk it is in (simultaneous discrete updates).
        self.DeclarePeriodicDiscreteUpdateEvent(self._samples * self._time_step,
                                                (self._samples - 1) * self._time_step, self._next_chunk)

    @staticmethod
    def AddToBuilder(*, builder, plan_output_port, q_measured_output_port, law: DifferentialIKLaw,
                     name: str = "joint_path_source", **kwargs) -> "JointPathSource":
        """Adds a source named ``name`` fed by the plan and the measured positions
        (``kwargs``: ``lead_s``, ``chunk_samples``)."""
        source = builder.AddNamedSystem(name, JointPathSource(law=law, **kwargs))
        builder.Connect(plan_output_port, source.plan_input_port)
        builder.Connect(q_measured_output_port, source.q_measured_input_port)
        return source

    def joint_path(self, root_context) -> tuple[np.ndarray, np.ndarray]:
        """The run's desired joint path in ``root_context``: simulation times (m,) and
        positions (m, 6) (the arm held at its start without a plan)."""
        path = self._path_cache.Eval(self.GetMyContextFromRoot(root_context))
        return path[0], path[1]

    def _calc_path(self, context, value):
        """(t, q, w): the run's joint path and ``w_k`` from instant 0 to three periods
        past its end (held after)."""
        q_start = context.get_abstract_state(self._start_index).get_value()
        t, q = run_joint_path(self.plan_input_port.Eval(context), q_start, self._law)
        count = max(int(np.ceil(t[-1] / self._time_step - 1e-9)), 0) + 3
        value.set_value((t, q, feed_forward_samples(t, q, self._time_step, self._gain, self._lead_s, 0, count)))

    def _chunk(self, context, q_start: np.ndarray, first: int) -> np.ndarray:
        """The chunk of instants ``first .. first + M - 1``."""
        w = self._path_cache.Eval(context)[2]
        rows = np.minimum(np.arange(first, first + self._samples), len(w) - 1)
        return np.concatenate([q_start, w[rows].ravel()])

    def _latch_start(self, context, state):
        q_start = np.array(self.q_measured_input_port.Eval(context), dtype=float)
        state.get_mutable_abstract_state(self._start_index).set_value(q_start)
        return EventStatus.Succeeded()

    def _initialize(self, context, discrete_state):
        # After every unrestricted initialization: the planner's plan and q_0 are in.
        q_start = context.get_abstract_state(self._start_index).get_value()
        first = int(round(context.get_time() / self._time_step))
        if first % self._samples:
            # The controller counts a chunk's instants from its own start (its Context's
            # default state): a run starts at a chunk's first instant, t = 0.
            raise RuntimeError(f"a compiled run starts at a multiple of {self._samples * self._time_step:g} s "
                               f"(t = 0); this one starts at t = {context.get_time():g} s")
        discrete_state.set_value(self._chunk_index, self._chunk(context, q_start, first))
        return EventStatus.Succeeded()

    def _next_chunk(self, context, discrete_state):
        q_start = context.get_abstract_state(self._start_index).get_value()
        first = int(round(context.get_time() / self._time_step)) + 1
        discrete_state.set_value(self._chunk_index, self._chunk(context, q_start, first))
        return EventStatus.Succeeded()
