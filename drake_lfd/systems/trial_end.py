"""Ends a closed-loop run once its plan has been executed (Drake's termination event).

:class:`TrialEnd` watches the plan on its input and, at a coarse period, returns
``EventStatus.ReachedTermination`` once the simulation time has reached the plan's end
(the due time of its last critical configuration, the plan in force after any
replanning), or at once when nothing was planned. So a Simulator may be advanced to any
``final_time`` at or beyond a trial's end, as Drake's ``MonteCarloSimulation`` does: the
Diagram stops itself, and the run's Context holds everything its verdict needs.

Not for: judging the run (``diagrams/judging.py``) or measuring it
(``shell_monitor.py``).
"""

from __future__ import annotations

import math

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem

from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.systems.planner import NO_PLAN

__all__ = ["TrialEnd", "plan_end_time_s", "TRIAL_END_PERIOD_S"]

# How often the plan's end is checked by default, s. A Python event costs tens of
# microseconds whatever it does; at 2 Hz it adds well under 1 % to a closed loop's time.
TRIAL_END_PERIOD_S = 0.5


def plan_end_time_s(plan: ScheduledPlan | None) -> float | None:
    """When the run of ``plan`` is over: its last critical configuration's due time
    (None when nothing is planned)."""
    if not isinstance(plan, ScheduledPlan) or not plan.planned:
        return None
    return float(plan.due_times_s()[-1])


class TrialEnd(LeafSystem):
    """Terminates the simulation once the plan on ``plan`` has been executed.

    .. pydrake_system::

        name: TrialEnd
        input_ports:
        - plan
        - path_time (optional)

    ``plan``: an abstract :class:`~drake_lfd.planning.replanning.ScheduledPlan` (the
    planner system's output). A periodic publish every ``period`` s (the only event;
    nothing in the control loop) ends the run at the first check at or after the plan's
    end, or at the first check when the input holds no plan. With ``path_time=True`` the
    plan's end is compared with the ``path_time`` input (the path position of a run whose
    speed is scaled, ``speed_override.py``) instead of the clock, and a run still short
    of it ``time_limit_s`` after the plan's end is ended there.

    Parameters
    ----------
    period : float
        How often the plan's end is checked, s: the run ends at most this much after it
        (:data:`TRIAL_END_PERIOD_S` by default).
    path_time : bool
        Declare the ``path_time`` input (1,).
    time_limit_s : float
        With ``path_time``: how long after the plan's end a run may go on.
    """

    def __init__(self, *, period: float = TRIAL_END_PERIOD_S, path_time: bool = False,
                 time_limit_s: float = math.inf):
        super().__init__()
        if not period > 0.0:
            raise ValueError(f"period must be > 0, got {period!r}")
        self._period = float(period)
        self._time_limit_s = float(time_limit_s)
        self.plan_input_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(NO_PLAN))
        self.path_time_input_port = self.DeclareVectorInputPort("path_time", 1) if path_time else None
        self.DeclarePeriodicPublishEvent(period_sec=self._period, offset_sec=0.0, publish=self._check)

    @staticmethod
    def AddToBuilder(*, builder, plan_output_port, period: float = TRIAL_END_PERIOD_S,
                     name: str = "trial_end", path_time_output_port=None,
                     time_limit_s: float = math.inf) -> "TrialEnd":
        """Adds a TrialEnd named ``name`` watching ``plan_output_port`` (and, when given,
        ``path_time_output_port`` instead of the clock)."""
        system = builder.AddNamedSystem(name, TrialEnd(period=period, path_time=path_time_output_port is not None,
                                                       time_limit_s=time_limit_s))
        builder.Connect(plan_output_port, system.plan_input_port)
        if path_time_output_port is not None:
            builder.Connect(path_time_output_port, system.path_time_input_port)
        return system

    @property
    def period(self) -> float:
        return self._period

    def _check(self, context):
        plan = self.plan_input_port.Eval(context)
        end = plan_end_time_s(plan)
        if end is None:
            return EventStatus.ReachedTermination(self, "nothing planned")
        now = context.get_time()
        if self.path_time_input_port is not None:
            if self.path_time_input_port.Eval(context)[0] >= end - 1e-9:
                return EventStatus.ReachedTermination(self, f"plan executed at t = {now:.3f} s")
            if now >= end + self._time_limit_s - 1e-9:
                return EventStatus.ReachedTermination(
                    self, f"the path was still unfinished {self._time_limit_s:g} s after the plan's end")
            return EventStatus.DidNothing()
        if now >= end - 1e-9:
            return EventStatus.ReachedTermination(self, f"plan executed at t = {end:.3f} s")
        return EventStatus.DidNothing()
