"""Differential inverse kinematics: desired end-effector motion -> joint position command.

The SE(3) plan reaches the UR5e through this controller (docs/method.rst, Closed loop and success). Every ``time_step`` it
computes a joint velocity ``v`` for the commanded end-effector velocity

    V = V_WE_desired + K * (X_WE_desired [-] X_WE(q_measured))     (feed-forward + feedback)

and integrates the *command*: ``q_command <- q_command + time_step * v`` (Eq. 37-38's
Euler step). The law of each step (Drake's differential-IK QP with joint position and
speed limits, solved in closed form for the UR5e's square Jacobian, or the paper's
pseudo-inverse, Eq. 35-36) is :class:`drake_lfd.robot.differential_ik_law.DifferentialIKLaw`,
shared with the plan-time joint-space check so a plan's joint path is the one this
controller commands. The ``drake`` law keeps the joint speeds inside
``velocity_limit_fraction`` (0.97) of the UR5e's 180 deg/s. Plans are timed within 0.9
of the limits, time-optimally and with continuous velocity (``robot/path_timing.py``), so
the controller has the rest to correct tracking errors: on the paper's tasks and 50
pick-and-place tasks the measured joint speeds stay within 0.92 of the limit
(``benchmarks/bench_motion_timing.py``). The bound was 0.7 while plans moved at
0.25 m/s and their velocity jumped where spans joined: with 0.9 the servos then overshot
the limit by up to 11 % near the transferring task's singular regions. With ``position_gain=0`` and
``method="pseudo_inverse"`` this is Eq. 38 exactly (open loop).

Choices, measured on a 10 s, four-configuration plan (``benchmarks/bench_closed_loop.py``):

- The Jacobian and the pose error are evaluated at the *measured* joint positions, so
  the feedback sees the real end-effector pose; the command integrates from the
  previous *command*. Restarting each step from the measured positions loses the servo
  lag every step (the command stays one small step ahead of the measurement); feeding back the command's own pose instead of the
  measured one leaves the servo lag uncorrected (a path error several times larger).
- The feedback gain K = 20 /s: K = 0 (pure feed-forward) ends visibly off at the
  critical configurations, K = 5-20 brings that down by an order of magnitude; K = 40
  starts to ring. It integrates on the command side, i.e. acts as integral action on the
  tracking error, and stays well below the servo bandwidth (40 rad/s).
- The controller updates ``COMMAND_READY_BEFORE_SAMPLE_S`` (0.1 ms) before each multiple
  of its period, the instant the drive samples the command, and targets the pose due one
  period later: the drive then holds a command that is centred on the interval it is
  applied over. Updating at the sampling instants themselves delays every command by
  a full period (the drive still holds the old one), and halfway leaves half of it:
  either way the path error is several times larger.
- A 10 ms period: 5 ms and 2 ms track somewhat better but cost proportionally more
  Python calls.

Not for: the drive (``station.py``), the plan (``plan_trajectory_source.py``) or the
initial configuration (``initial_ik.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex
from pydrake.systems.framework import LeafSystem

from drake_lfd.robot.differential_ik_law import (
    DEFAULT_POSITION_GAIN,
    DEFAULT_TIME_STEP_S,
    DEFAULT_VELOCITY_LIMIT_FRACTION,
    METHODS,
    DifferentialIKLaw,
    pose_error,
    right_pseudo_inverse_velocity,
)

__all__ = [
    'DEFAULT_CONTROLLER_PERIOD_S',
    'DEFAULT_VELOCITY_LIMIT_FRACTION',
    'DEFAULT_POSITION_GAIN',
    'COMMAND_READY_BEFORE_SAMPLE_S',
    'METHODS',
    'pose_error',
    'right_pseudo_inverse_velocity',
    'DifferentialIKController',
]

DEFAULT_CONTROLLER_PERIOD_S = DEFAULT_TIME_STEP_S
# The controller updates this long before each multiple of its period, when the drive
# samples the command (see the module docstring).
COMMAND_READY_BEFORE_SAMPLE_S = 1e-4


class DifferentialIKController(LeafSystem):
    """Joint position command tracking a desired end-effector pose and velocity.

    .. pydrake_system::

        name: DifferentialIKController
        input_ports:
        - X_WE_desired
        - V_WE_desired
        - q_measured
        output_ports:
        - q_command

    ``X_WE_desired``: abstract ``RigidTransform``; ``V_WE_desired``: (6,) ``[omega, v]`` in W;
    ``q_measured``, ``q_command``: (6,) joint positions of ``model`` in UR joint order.
    The command is a discrete state updated every ``time_step``; at initialization it is
    set to the measured positions (override with :meth:`set_initial_command`).

    Parameters
    ----------
    plant : MultibodyPlant
        A plant holding the robot (its own context is used; the station's
        ``controller_plant`` or any finalized plant of the same arm).
    model : ModelInstanceIndex
        The robot in ``plant``.
    frame_E : Frame
        The controlled end-effector frame, of ``plant``.
    time_step : float
        Update period, s (10 ms, see the module docstring; the station's
        ``command_period`` must match).
    method : {"drake", "pseudo_inverse"}
    position_gain : float
        K, 1/s, on the pose error (0 gives pure feed-forward, the paper's Eq. 38).
    velocity_limit_fraction : float
        Fraction of the plant's joint speed limits the QP may command (``drake`` only).
    offset_s : float, optional
        Time of the first update, s; ``time_step - COMMAND_READY_BEFORE_SAMPLE_S`` by
        default (just before the drive samples the command, see the module docstring).
    """

    def __init__(
        self,
        *,
        plant: MultibodyPlant,
        model: ModelInstanceIndex,
        frame_E: Frame,
        time_step: float = DEFAULT_CONTROLLER_PERIOD_S,
        method: str = "drake",
        position_gain: float = DEFAULT_POSITION_GAIN,
        velocity_limit_fraction: float = DEFAULT_VELOCITY_LIMIT_FRACTION,
        offset_s: float | None = None,
    ):
        super().__init__()
        self._law = DifferentialIKLaw(plant=plant, model=model, frame_E=frame_E, time_step=time_step,
                                      method=method, position_gain=position_gain,
                                      velocity_limit_fraction=velocity_limit_fraction)
        self._time_step = self._law.time_step
        n = self._law.num_positions

        self.X_WE_desired_input_port = self.DeclareAbstractInputPort(
            "X_WE_desired", AbstractValue.Make(RigidTransform())
        )
        self.V_WE_desired_input_port = self.DeclareVectorInputPort("V_WE_desired", 6)
        self.q_measured_input_port = self.DeclareVectorInputPort("q_measured", n)
        self._command_state = self.DeclareDiscreteState(n)
        if offset_s is None:
            offset_s = max(self._time_step - COMMAND_READY_BEFORE_SAMPLE_S, 0.0)
        self._offset_s = float(offset_s)
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, self._offset_s, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.q_command_output_port = self.DeclareStateOutputPort("q_command", self._command_state)

    @staticmethod
    def AddToBuilder(*, builder, plant: MultibodyPlant, model: ModelInstanceIndex, frame_E: Frame,
                     X_WE_desired_output_port, V_WE_desired_output_port, q_measured_output_port,
                     q_command_input_port=None, name: str = "differential_ik",
                     **kwargs) -> "DifferentialIKController":
        """Adds a controller named ``name`` fed by the desired pose, velocity and measured
        positions; connects its command to ``q_command_input_port`` when given.
        ``kwargs`` are the constructor's (``time_step``, ``method``, ...)."""
        controller = builder.AddNamedSystem(
            name, DifferentialIKController(plant=plant, model=model, frame_E=frame_E, **kwargs))
        builder.Connect(X_WE_desired_output_port, controller.X_WE_desired_input_port)
        builder.Connect(V_WE_desired_output_port, controller.V_WE_desired_input_port)
        builder.Connect(q_measured_output_port, controller.q_measured_input_port)
        if q_command_input_port is not None:
            builder.Connect(controller.q_command_output_port, q_command_input_port)
        return controller

    # -- properties -----------------------------------------------------------------------
    @property
    def time_step(self) -> float:
        return self._time_step

    @property
    def method(self) -> str:
        return self._law.method

    @property
    def law(self) -> DifferentialIKLaw:
        """The differential-IK law of each step (shared with the plan-time joint check)."""
        return self._law

    @property
    def velocity_limits(self) -> np.ndarray:
        """Joint speed limits the QP commands, shape (6,), rad/s."""
        return self._law.velocity_limits.copy()

    def set_initial_command(self, context, q) -> None:
        """Sets the command state, for driving the system without a Simulator (a
        Simulator's ``Initialize`` sets it to the measured positions)."""
        context.SetDiscreteState(self._command_state, np.asarray(q, dtype=float))

    # -- the update ---------------------------------------------------------------------
    def _initialize(self, context, discrete_state):
        discrete_state.set_value(self._command_state, self.q_measured_input_port.Eval(context))

    def joint_velocity(self, q_command, q_measured, X_WE_desired, V_WE_desired) -> np.ndarray:
        """The joint velocity ``v`` of one step, shape (6,) (pure function of its inputs;
        :meth:`DifferentialIKLaw.joint_velocity`)."""
        return self._law.joint_velocity(q_command, q_measured, X_WE_desired, V_WE_desired)

    def _closed_form_qp_solution(self, q_command, J, V):
        return self._law.closed_form_qp_solution(q_command, J, V)

    def _update(self, context, discrete_state):
        q_command = context.get_discrete_state(self._command_state).value()
        v = self.joint_velocity(
            q_command,
            self.q_measured_input_port.Eval(context),
            self.X_WE_desired_input_port.Eval(context),
            self.V_WE_desired_input_port.Eval(context),
        )
        # Eq. 37-38: Euler step of the command.
        discrete_state.set_value(self._command_state, q_command + self._time_step * v)
