"""The scheduled plan as a Drake source of the desired end-effector pose and velocity.

``TrajectorySource`` does not accept a ``PiecewisePose`` (it needs a vector-valued
trajectory), so this small LeafSystem evaluates the one a
:class:`~drake_lfd.planning.replanning.ScheduledPlan` carries: ``X_WE_desired`` is its pose
at the current time and ``V_WE_desired`` its derivative. The plan arrives on an input
port, so a planner system upstream may replace it during a run. Before the plan starts
the source holds its first pose, after its end its last pose, both at zero velocity.

Not for: planning or timing (``planning/``) or tracking the pose (``differential_ik.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder, LeafSystem, OutputPort

from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.systems.planner import NO_PLAN

__all__ = ["PlanTrajectorySource"]


class PlanTrajectorySource(LeafSystem):
    """Desired pose and spatial velocity of E from the plan on its input.

    .. pydrake_system::

        name: PlanTrajectorySource
        input_ports:
        - plan
        output_ports:
        - X_WE_desired
        - V_WE_desired

    ``plan`` is an abstract :class:`~drake_lfd.planning.replanning.ScheduledPlan` (a
    demonstration request, which has no motion, holds the identity pose at zero
    velocity; so does :data:`~drake_lfd.systems.planner.NO_PLAN`). ``X_WE_desired`` is an abstract ``RigidTransform``; ``V_WE_desired`` is
    the spatial velocity of E in W, shape (6,), ``[omega_WE, v_WE]`` (angular first).
    """

    def __init__(self):
        super().__init__()
        self.plan_input_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(NO_PLAN))
        self.X_WE_desired_output_port = self.DeclareAbstractOutputPort(
            "X_WE_desired", lambda: AbstractValue.Make(RigidTransform()), self._calc_pose,
            prerequisites_of_calc={self.time_ticket(), self.plan_input_port.ticket()},
        )
        self.V_WE_desired_output_port = self.DeclareVectorOutputPort(
            "V_WE_desired", 6, self._calc_velocity,
            prerequisites_of_calc={self.time_ticket(), self.plan_input_port.ticket()},
        )

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, plan_output_port: OutputPort,
                     name: str = "plan_trajectory_source") -> "PlanTrajectorySource":
        """Adds a source named ``name`` fed by ``plan_output_port``; returns it."""
        source = builder.AddNamedSystem(name, PlanTrajectorySource())
        builder.Connect(plan_output_port, source.plan_input_port)
        return source

    def _scheduled(self, context) -> ScheduledPlan | None:
        plan = self.plan_input_port.Eval(context)
        # A ScheduledPlan with a motion (a request has no trajectory).
        return plan if isinstance(plan, ScheduledPlan) and plan.timed is not None else None

    def _calc_pose(self, context, output):
        plan = self._scheduled(context)
        output.set_value(RigidTransform() if plan is None else plan.X_WE_desired(context.get_time()))

    def _calc_velocity(self, context, output):
        plan = self._scheduled(context)
        output.SetFromVector(np.zeros(6) if plan is None else plan.V_WE_desired(context.get_time()))
