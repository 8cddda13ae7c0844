"""The timed plan as a Drake source of the desired end-effector pose and velocity.

``TrajectorySource`` does not accept a ``PiecewisePose`` (DRAKE_NOTES), so this small
LeafSystem evaluates one: ``X_WE_desired`` is ``PiecewisePose.GetPose(t)`` and
``V_WE_desired`` its derivative (``MakeDerivative()``). Before ``start_time_s`` the
source holds the plan's first pose, after the plan's end its last pose, both at zero
velocity.

Not for: timing a plan (``timing.py``) or tracking it (``differential_ik.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from drake_lfd.core.timing import TimedPlan


class PlanTrajectorySource(LeafSystem):
    """Desired pose and spatial velocity of E from a :class:`~drake_lfd.core.timing.TimedPlan`.

    .. pydrake_system::

        name: PlanTrajectorySource
        output_ports:
        - X_WE_desired
        - V_WE_desired

    ``X_WE_desired`` is an abstract ``RigidTransform``; ``V_WE_desired`` is the spatial
    velocity of E in W, shape (6,), ``[omega_WE, v_WE]`` (Drake's order: angular first).

    Parameters
    ----------
    plan : TimedPlan
        Poses at times starting from 0.
    start_time_s : float
        Simulation time at which the plan's time 0 falls (for example after a settling
        period).
    """

    def __init__(self, *, plan: TimedPlan, start_time_s: float = 0.0):
        super().__init__()
        self._plan = plan
        self._start_time_s = float(start_time_s)
        self._duration_s = plan.duration
        self._trajectory = plan.to_piecewise_pose()
        self._velocity = self._trajectory.MakeDerivative()
        self.X_WE_desired_output_port = self.DeclareAbstractOutputPort(
            "X_WE_desired", lambda: AbstractValue.Make(RigidTransform()), self._calc_pose
        )
        self.V_WE_desired_output_port = self.DeclareVectorOutputPort("V_WE_desired", 6, self._calc_velocity)

    @property
    def plan(self) -> TimedPlan:
        return self._plan

    @property
    def start_time_s(self) -> float:
        return self._start_time_s

    @property
    def end_time_s(self) -> float:
        """Simulation time at which the plan ends."""
        return self._start_time_s + self._duration_s

    def plan_time(self, t: float) -> float:
        """The plan's time at simulation time ``t``, clamped to ``[0, duration]``."""
        return min(max(t - self._start_time_s, 0.0), self._duration_s)

    def _calc_pose(self, context, output):
        output.set_value(self._trajectory.GetPose(self.plan_time(context.get_time())))

    def _calc_velocity(self, context, output):
        tau = context.get_time() - self._start_time_s
        if tau <= 0.0 or tau >= self._duration_s:
            output.SetFromVector(np.zeros(6))
        else:
            output.SetFromVector(self._velocity.value(tau)[:, 0])
