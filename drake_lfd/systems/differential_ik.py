"""Differential inverse kinematics: desired end-effector motion -> joint position command.

The SE(3) plan reaches the UR5e through this controller (docs/method.rst, Closed loop and success). Every ``time_step`` it
computes a joint velocity ``v`` for the commanded end-effector velocity

    V = V_WE_desired + K * (X_WE_desired [-] X_WE(q_measured))     (feed-forward + feedback)

and integrates the *command*: ``q_command <- q_command + time_step * v`` (Eq. 37-38's
Euler step). Two solvers for ``v``:

- ``method="drake"`` (default): Drake's ``DoDifferentialInverseKinematics`` QP, which
  keeps the command inside the joint position limits and the joint speeds inside
  ``velocity_limit_fraction`` (0.7) of the UR5e's 180 deg/s, scaling the whole
  end-effector velocity down (never bending its direction) when a limit binds. The 30 %
  margin leaves the servos headroom to catch up with a command moving at the limit
  without exceeding the limit themselves: with 10 % the measured speed overshot the
  limit by up to 11 % (3.49 rad/s) near the transferring task's singular regions. For the UR5e's square, invertible Jacobian the
  QP's solution has a closed form, ``v = alpha J^-1 V`` with alpha the largest feasible
  scale <= 1, evaluated directly (equal to the QP's to 1e-13; about 10 us instead of
  150-270 us); the QP itself runs only when ``J`` is singular or the command is
  outside the limits.
- ``method="pseudo_inverse"``: the paper's Eq. 35-36, ``qdot = J^T (J J^T)^-1 V``, with
  no limits (the paper leaves joint limits as future work). Eq. 35's ``J_2`` maps
  ``(p_dot, r_dot)`` to the spatial velocity; here the desired motion already is the
  spatial velocity ``V = [omega_WE, v_WE]`` and ``J`` is the Jacobian of E's origin, so
  ``J_2`` is the identity. With ``position_gain=0`` this is Eq. 38 exactly (open loop).

Choices, measured on a 10 s, four-configuration plan (``benchmarks/bench_closed_loop.py``):

- The Jacobian and the pose error are evaluated at the *measured* joint positions, so
  the feedback sees the real end-effector pose; the command integrates from the
  previous *command*. Restarting each step from the measured positions loses the servo
  lag every step (the command stays one small step ahead of the measurement); feeding back the command's own pose instead of the
  measured one leaves the servo lag uncorrected (path rms 0.6 mm against 0.2 mm).
- The feedback gain K = 20 /s: K = 0 (pure feed-forward) ends 0.9 mm off at the
  critical configurations, K = 5-20 brings that to 0.13-0.03 mm; K = 40 starts to ring
  (0.2 mm). It integrates on the command side, i.e. acts as integral action on the
  tracking error, and stays well below the servo bandwidth (40 rad/s).
- The controller updates ``COMMAND_READY_BEFORE_SAMPLE_S`` (0.1 ms) before each multiple
  of its period, the instant the drive samples the command, and targets the pose due one
  period later: the drive then holds a command that is centred on the interval it is
  applied over. Updating at the sampling instants themselves delays every command by
  a full period (the drive still holds the old one), and halfway leaves half of it:
  path rms 0.84 and 0.74 mm against 0.20 mm with a 5 ms plant step.
- A 10 ms period: 5 ms and 2 ms track somewhat better (path max
  0.8 and 0.6 mm against 1.1 mm) but cost proportionally more Python calls.

Not for: the drive (``station.py``), the plan (``plan_trajectory_source.py``) or the
initial configuration (``initial_ik.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import (
    DifferentialInverseKinematicsParameters,
    DifferentialInverseKinematicsStatus,
    DoDifferentialInverseKinematics,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, JacobianWrtVariable, ModelInstanceIndex
from pydrake.systems.framework import LeafSystem

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

DEFAULT_CONTROLLER_PERIOD_S = 0.01
DEFAULT_VELOCITY_LIMIT_FRACTION = 0.7
DEFAULT_POSITION_GAIN = 20.0  # 1/s, on the pose error (both translation and rotation)
# The controller updates this long before each multiple of its period, when the drive
# samples the command (see the module docstring).
COMMAND_READY_BEFORE_SAMPLE_S = 1e-4
METHODS = ("drake", "pseudo_inverse")


def pose_error(X_WE_desired: RigidTransform, X_WE: RigidTransform) -> np.ndarray:
    """Spatial displacement from ``X_WE`` to ``X_WE_desired`` in W, shape (6,).

    ``[theta * k, p_desired - p]``: the rotation vector of ``R_desired R^T`` (in W, angle in
    [0, pi]) and the translation difference; Drake's spatial-velocity order.
    """
    angle_axis = (X_WE_desired.rotation().multiply(X_WE.rotation().inverse())).ToAngleAxis()
    error = np.empty(6)
    error[:3] = angle_axis.angle() * angle_axis.axis()
    error[3:] = X_WE_desired.translation() - X_WE.translation()
    return error


def right_pseudo_inverse_velocity(J: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Eq. 35: ``qdot = J^T (J J^T)^-1 V`` (least-norm joint velocity), shape (n,).

    Falls back to the SVD pseudo-inverse when ``J J^T`` is singular.
    """
    try:
        return J.T @ np.linalg.solve(J @ J.T, V)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(J) @ V


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
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        self._plant = plant
        self._model = model
        self._frame_E = frame_E
        self._world_frame = plant.world_frame()
        self._plant_context = plant.CreateDefaultContext()
        self._time_step = float(time_step)
        self._method = method
        self._position_gain = float(position_gain)
        self._num_positions = plant.num_positions(model)
        # Columns of the model's velocities in the plant's full Jacobian.
        joints = [plant.get_joint(index) for index in plant.GetJointIndices(model)]
        self._velocity_columns = np.array(
            sorted(j.velocity_start() + k for j in joints for k in range(j.num_velocities()))
        )
        self._select_columns = not np.array_equal(self._velocity_columns, np.arange(plant.num_velocities()))
        self._position_lower = plant.GetPositionLowerLimits()[self._position_indices(plant, joints)]
        self._position_upper = plant.GetPositionUpperLimits()[self._position_indices(plant, joints)]
        self._velocity_limit = velocity_limit_fraction * plant.GetVelocityUpperLimits()[self._velocity_columns]
        self._p_EoEo = np.zeros(3)

        n = self._num_positions
        self._parameters = DifferentialInverseKinematicsParameters(n, n)
        self._parameters.set_time_step(self._time_step)
        self._parameters.set_joint_position_limits((self._position_lower, self._position_upper))
        self._parameters.set_joint_velocity_limits((-self._velocity_limit, self._velocity_limit))
        self._zero_velocity = np.zeros(n)
        self._velocity_limit_list = self._velocity_limit.tolist()
        self._position_lower_list = self._position_lower.tolist()
        self._position_upper_list = self._position_upper.tolist()

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

    @staticmethod
    def _position_indices(plant, joints):
        return np.array(sorted(j.position_start() + k for j in joints for k in range(j.num_positions())))

    # -- properties -----------------------------------------------------------------------
    @property
    def time_step(self) -> float:
        return self._time_step

    @property
    def method(self) -> str:
        return self._method

    @property
    def velocity_limits(self) -> np.ndarray:
        """Joint speed limits the QP commands, shape (6,), rad/s."""
        return self._velocity_limit.copy()

    def set_initial_command(self, context, q) -> None:
        """Sets the command state, for driving the system without a Simulator (a
        Simulator's ``Initialize`` sets it to the measured positions)."""
        context.SetDiscreteState(self._command_state, np.asarray(q, dtype=float))

    # -- the update ---------------------------------------------------------------------
    def _initialize(self, context, discrete_state):
        discrete_state.set_value(self._command_state, self.q_measured_input_port.Eval(context))

    def joint_velocity(self, q_command, q_measured, X_WE_desired, V_WE_desired) -> np.ndarray:
        """The joint velocity ``v`` of one step, shape (6,) (pure function of its inputs).

        Zero when the QP finds no solution (the command then holds).
        """
        plant, plant_context = self._plant, self._plant_context
        plant.SetPositions(plant_context, self._model, q_measured)
        X_WE = plant.CalcRelativeTransform(plant_context, self._world_frame, self._frame_E)
        J = plant.CalcJacobianSpatialVelocity(
            plant_context,
            JacobianWrtVariable.kV,
            self._frame_E,
            self._p_EoEo,
            self._world_frame,
            self._world_frame,
        )
        if self._select_columns:
            J = J[:, self._velocity_columns]
        V = np.asarray(V_WE_desired, dtype=float) + self._position_gain * pose_error(X_WE_desired, X_WE)
        if self._method == "pseudo_inverse":
            return right_pseudo_inverse_velocity(J, V)
        v = self._closed_form_qp_solution(q_command, J, V)
        if v is not None:
            return v
        result = DoDifferentialInverseKinematics(q_command, self._zero_velocity, V, J, self._parameters)
        if result.status == DifferentialInverseKinematicsStatus.kNoSolutionFound:
            return np.zeros(self._num_positions)
        return result.joint_velocities

    def _closed_form_qp_solution(self, q_command, J, V):
        """Drake's differential-IK QP solved in closed form, or None to call the QP.

        For a square invertible Jacobian the QP (``J v = alpha V``, ``0 <= alpha <= 1``,
        maximise alpha; the nullspace term vanishes) has the unique solution
        ``v = alpha J^-1 V``, alpha the largest scale keeping ``v`` inside the speed
        limits and ``q + v dt`` inside the position limits. Evaluating that directly
        gives the QP's answer (measured equal to 1e-13 relative; the tests check 1e-7) at a
        fraction of its cost. Plain Python
        floats: for six numbers they beat numpy's per-call overhead.
        """
        if J.shape[0] != J.shape[1]:
            return None
        try:
            u = np.linalg.solve(J, V)
        except np.linalg.LinAlgError:
            return None  # singular: the QP handles the nullspace
        alpha = 1.0
        dt = self._time_step
        for u_j, limit, lower, upper, q_j in zip(
            u.tolist(), self._velocity_limit_list, self._position_lower_list, self._position_upper_list,
            q_command.tolist(),
        ):
            if q_j > upper or q_j < lower:
                return None  # the command is outside the limits: let the QP report it
            if u_j > 0.0:
                alpha = min(alpha, limit / u_j, (upper - q_j) / (u_j * dt))
            elif u_j < 0.0:
                alpha = min(alpha, -limit / u_j, (lower - q_j) / (u_j * dt))
        return max(alpha, 0.0) * u

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
