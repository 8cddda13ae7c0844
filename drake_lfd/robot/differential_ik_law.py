"""The differential-IK law: one joint-velocity step toward a desired end-effector motion.

One kernel for one equation, used by both the closed-loop controller
(:class:`drake_lfd.systems.differential_ik.DifferentialIKController`) and the plan-time
joint-space check (:mod:`drake_lfd.robot.joint_path`), so the joint path a plan promises
is the one the controller commands. For the commanded end-effector velocity

    V = V_WE_desired + K * (X_WE_desired [-] X_WE(q_measured))     (feed-forward + feedback)

it returns the joint velocity ``v``; the caller integrates the *command*,
``q_command <- q_command + time_step * v`` (Eq. 37-38's Euler step). Two solvers:

- ``method="drake"`` (default): Drake's ``DoDifferentialInverseKinematics`` QP, which
  keeps the command inside the joint position limits and the joint speeds inside
  ``velocity_limit_fraction`` of the limits, scaling the whole end-effector velocity
  down (never bending its direction) when a limit binds. For the UR5e's square,
  invertible Jacobian the QP's solution has a closed form, ``v = alpha J^-1 V`` with
  alpha the largest feasible scale <= 1, evaluated directly (equal to the QP's to 1e-13,
  an order of magnitude faster than a solver); the QP itself runs only when ``J`` is singular or
  the command is outside the limits. :attr:`DifferentialIKLaw.last_scale` tells which
  limit bound the last step, so a caller can say why a motion slowed down.
- ``method="pseudo_inverse"``: the paper's Eq. 35-36, ``qdot = J^T (J J^T)^-1 V``, with
  no limits. Eq. 35's ``J_2`` maps ``(p_dot, r_dot)`` to the spatial velocity; here the
  desired motion already is the spatial velocity ``V = [omega_WE, v_WE]`` and ``J`` is
  the Jacobian of E's origin, so ``J_2`` is the identity.

The gains, the period and the 0.97 speed fraction are measured choices, explained in the
controller's module.

Not for: the LeafSystem and its timing (``systems/differential_ik.py``), following a
whole plan (``joint_path.py``).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import (
    DifferentialInverseKinematicsParameters,
    DifferentialInverseKinematicsStatus,
    DoDifferentialInverseKinematics,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, JacobianWrtVariable, ModelInstanceIndex
from scipy.linalg.lapack import dgesv

__all__ = [
    "DEFAULT_TIME_STEP_S",
    "DEFAULT_VELOCITY_LIMIT_FRACTION",
    "DEFAULT_POSITION_GAIN",
    "METHODS",
    "pose_error",
    "right_pseudo_inverse_velocity",
    "DifferentialIKLaw",
]

DEFAULT_TIME_STEP_S = 0.01
DEFAULT_VELOCITY_LIMIT_FRACTION = 0.97
DEFAULT_POSITION_GAIN = 20.0  # 1/s, on the pose error (both translation and rotation)
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


class DifferentialIKLaw:
    """The joint velocity of one step, on a plant of the arm (its own context).

    Parameters
    ----------
    plant : MultibodyPlant
        A finalized plant holding the robot.
    model : ModelInstanceIndex
        The robot in ``plant``.
    frame_E : Frame
        The controlled end-effector frame, of ``plant``.
    time_step : float
        The step the caller integrates with, s (the position limits look one step ahead).
    method : {"drake", "pseudo_inverse"}
    position_gain : float
        K, 1/s.
    velocity_limit_fraction : float
        Fraction of the plant's joint speed limits commanded at most (``drake`` only).
    """

    def __init__(
        self,
        *,
        plant: MultibodyPlant,
        model: ModelInstanceIndex,
        frame_E: Frame,
        time_step: float = DEFAULT_TIME_STEP_S,
        method: str = "drake",
        position_gain: float = DEFAULT_POSITION_GAIN,
        velocity_limit_fraction: float = DEFAULT_VELOCITY_LIMIT_FRACTION,
    ):
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        self._plant = plant
        self._model = model
        self._frame_E = frame_E
        self._world_frame = plant.world_frame()
        self._plant_context = plant.CreateDefaultContext()
        self.time_step = float(time_step)
        self.method = method
        self.position_gain = float(position_gain)
        self.num_positions = n = plant.num_positions(model)
        joints = [plant.get_joint(index) for index in plant.GetJointIndices(model)]
        # Columns of the model's velocities in the plant's full Jacobian.
        self._velocity_columns = np.array(
            sorted(j.velocity_start() + k for j in joints for k in range(j.num_velocities())))
        self._select_columns = not np.array_equal(self._velocity_columns, np.arange(plant.num_velocities()))
        positions = np.array(sorted(j.position_start() + k for j in joints for k in range(j.num_positions())))
        self.position_lower = plant.GetPositionLowerLimits()[positions]
        self.position_upper = plant.GetPositionUpperLimits()[positions]
        self.velocity_limits = velocity_limit_fraction * plant.GetVelocityUpperLimits()[self._velocity_columns]
        self._p_EoEo = np.zeros(3)
        self._parameters = DifferentialInverseKinematicsParameters(n, n)
        self._parameters.set_time_step(self.time_step)
        self._parameters.set_joint_position_limits((self.position_lower, self.position_upper))
        self._parameters.set_joint_velocity_limits((-self.velocity_limits, self.velocity_limits))
        self._velocity_limit_list = self.velocity_limits.tolist()
        self._position_lower_list = self.position_lower.tolist()
        self._position_upper_list = self.position_upper.tolist()
        #: (scale, joint, kind) of the last closed-form step: the scale alpha applied to
        #: the end-effector velocity, the joint whose limit set it (-1: none) and
        #: ``"speed"`` or ``"position"``; ``(nan, -1, "qp")`` when the QP ran.
        self.last_scale: tuple[float, int, str] = (1.0, -1, "")
        #: The pose error ``X_WE_desired [-] X_WE(q_measured)`` of the last step, (6,).
        self.last_pose_error = np.zeros(6)

    def X_WE(self, q: np.ndarray) -> RigidTransform:
        """Forward kinematics of E at ``q`` (6,), on the law's own context."""
        self._plant.SetPositions(self._plant_context, self._model, q)
        return self._plant.CalcRelativeTransform(self._plant_context, self._world_frame, self._frame_E)

    def joint_velocity(self, q_command, q_measured, X_WE_desired: RigidTransform, V_WE_desired) -> np.ndarray:
        """The joint velocity ``v`` of one step, shape (6,) (pure function of its inputs).

        Zero when the QP finds no solution (the command then holds).
        """
        plant, plant_context = self._plant, self._plant_context
        X_WE = self.X_WE(q_measured)
        J = plant.CalcJacobianSpatialVelocity(
            plant_context, JacobianWrtVariable.kV, self._frame_E, self._p_EoEo, self._world_frame, self._world_frame)
        if self._select_columns:
            J = J[:, self._velocity_columns]
        self.last_pose_error = error = pose_error(X_WE_desired, X_WE)
        V = np.asarray(V_WE_desired, dtype=float) + self.position_gain * error
        if self.method == "pseudo_inverse":
            return right_pseudo_inverse_velocity(J, V)
        v = self.closed_form_qp_solution(q_command, J, V)
        if v is not None:
            return v
        self.last_scale = (math.nan, -1, "qp")
        result = DoDifferentialInverseKinematics(q_command, np.zeros(self.num_positions), V, J, self._parameters)
        if result.status == DifferentialInverseKinematicsStatus.kNoSolutionFound:
            return np.zeros(self.num_positions)
        return result.joint_velocities

    def closed_form_qp_solution(self, q_command, J, V):
        """Drake's differential-IK QP solved in closed form, or None to call the QP.

        For a square invertible Jacobian the QP (``J v = alpha V``, ``0 <= alpha <= 1``,
        maximise alpha; the nullspace term vanishes) has the unique solution
        ``v = alpha J^-1 V``, alpha the largest scale keeping ``v`` inside the speed
        limits and ``q + v dt`` inside the position limits. Evaluating that directly
        gives the QP's answer (measured equal to 1e-13 relative; the tests check 1e-7) at a
        fraction of its cost. Plain Python floats: for six numbers they beat numpy's
        per-call overhead.
        """
        v = self.closed_form_step(np.asarray(q_command, dtype=float).tolist(), J, V)
        return None if v is None else np.array(v)

    def closed_form_step(self, q_command: list, J, V) -> list | None:
        """:meth:`closed_form_qp_solution` on plain lists: ``q_command`` six floats,
        ``J`` and ``V`` arrays or nested lists; the joint velocity as a list, or None."""
        J = np.asarray(J, dtype=float)
        if J.ndim != 2 or J.shape[0] != J.shape[1]:
            return None
        # LAPACK's dgesv, as np.linalg.solve calls it, without numpy's checks (a
        # third of the cost for a 6 x 6); info > 0: singular.
        _, _, u, info = dgesv(J, np.asarray(V, dtype=float))
        if info != 0:
            return None  # singular: the QP handles the nullspace
        u = u.tolist()
        alpha, binding, kind = 1.0, -1, ""
        dt = self.time_step
        for j, (u_j, limit, lower, upper, q_j) in enumerate(zip(
            u, self._velocity_limit_list, self._position_lower_list, self._position_upper_list,
            q_command,
        )):
            if q_j > upper or q_j < lower:
                return None  # the command is outside the limits: let the QP report it
            if u_j > 0.0:
                speed, position = limit / u_j, (upper - q_j) / (u_j * dt)
            elif u_j < 0.0:
                speed, position = -limit / u_j, (lower - q_j) / (u_j * dt)
            else:
                continue
            if speed < alpha:
                alpha, binding, kind = speed, j, "speed"
            if position < alpha:
                alpha, binding, kind = position, j, "position"
        alpha = max(alpha, 0.0)
        self.last_scale = (alpha, binding, kind)
        return [alpha * u_j for u_j in u]
