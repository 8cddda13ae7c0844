"""The UR5e joint configuration at the first critical configuration (inverse kinematics).

Differential IK needs a starting joint configuration. It comes from full inverse
kinematics of con_1: position and orientation constraints with tight tolerances, the
joint limits, and a quadratic cost towards a preferred elbow-up posture turned towards
the target. A fixed list of initial guesses (the same for every call) covers the
UR5e's IK branches (shoulder towards / away from the target, elbow up / down, wrist
flipped or not); among the solutions found, a collision-free one (no link or tool
shape inside an obstacle or safety shell) is preferred, then the lowest cost, then the earliest
guess. The result is therefore deterministic for a given task. docs/method.rst (Closed
loop and success) says where this enters a run. The plan-time check asks for every
branch in closed form instead (``method="closed_form"``, :mod:`analytic_ik`): the same
branches, exact, none missed, in microseconds.

Not for: tracking the plan (``systems/differential_ik.py``), forward kinematics
(``kinematics.py``), the scene's geometry (``scene.py``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from drake_lfd.core.errors import InputError
from drake_lfd.core.read_only_arrays import read_only_array
from drake_lfd.core.tasks import Box
from drake_lfd.robot.analytic_ik import UR5E_DH_D, ur5e_branches
from drake_lfd.robot.kinematics import BASE_FRAME_NAME, END_EFFECTOR_FRAME_NAME, TOOL0_FRAME_NAME
from drake_lfd.robot.scene import KinematicScene

__all__ = [
    "IK_POSITION_TOLERANCE_M",
    "IK_ROTATION_TOLERANCE_RAD",
    "ACCEPTED_POSITION_ERROR_M",
    "ACCEPTED_ROTATION_ERROR_RAD",
    "NOMINAL_WEIGHTS",
    "ELBOW_UP_POSTURE",
    "IK_METHODS",
    "UnreachableConfigurationError",
    "InitialConfiguration",
    "elbow_up_nominal",
    "initial_guesses",
    "solve_initial_configuration",
    "initial_configuration_candidates",
]

# Constraint tolerances handed to the IK solver (not the closed loop's success
# tolerances), and the errors a solution may show when checked by forward kinematics
# afterwards.
IK_POSITION_TOLERANCE_M = 1e-6
IK_ROTATION_TOLERANCE_RAD = 1e-5
ACCEPTED_POSITION_ERROR_M = 1e-5
ACCEPTED_ROTATION_ERROR_RAD = 1e-4
# How the branches are found (initial_configuration_candidates' ``method``).
IK_METHODS = ("program", "closed_form")
# Cost weights on (q - q_nominal): the arm joints decide the posture; the wrist angles
# follow from the orientation and matter less.
NOMINAL_WEIGHTS = read_only_array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1])
# The elbow-up posture of UR's documentation, tool pointing down, at shoulder_pan 0
# (where the arm reaches along the base's -x axis).
ELBOW_UP_POSTURE = read_only_array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])
# The UR5e's lateral offset of the wrist from the arm's plane (d4 of the DH table), metres.
_WRIST_OFFSET_M = UR5E_DH_D[3]


class UnreachableConfigurationError(InputError):
    """No joint configuration reaches a critical configuration within the tolerances."""


@dataclass(frozen=True)
class InitialConfiguration:
    """A joint configuration for a critical configuration.

    Attributes
    ----------
    q : array, shape (6,)
        Joint positions, rad.
    position_error_m, rotation_error_rad : float
        Errors of ``X_WE(q)`` against the target, by forward kinematics.
    collision_free : bool
        No robot geometry penetrates an obstacle or a safety shell.
    min_distance_m : float
        Minimum signed distance to any obstacle or shell (``inf`` if there are none).
    closest_robot_geometry, closest_box : str or None
        The pair realising ``min_distance_m``.
    guess_index : int
        Which initial guess led to it (0 is the preferred posture).
    """

    q: np.ndarray
    position_error_m: float
    rotation_error_rad: float
    collision_free: bool
    min_distance_m: float
    closest_robot_geometry: str | None
    closest_box: str | None
    guess_index: int


def elbow_up_nominal(p_WE, X_WB: RigidTransform | None = None) -> np.ndarray:
    """The preferred posture for reaching ``p_WE`` (3,): elbow up, facing the target.

    Returns
    -------
    q_nominal : array, shape (6,)
        ``ELBOW_UP_POSTURE`` with the shoulder pan turned so the arm's plane (offset
        sideways by the wrist's 0.133 m) passes through the target.
    """
    X_WB = RigidTransform() if X_WB is None else X_WB
    x, y, _ = X_WB.inverse().multiply(np.asarray(p_WE, dtype=float))
    radial = math.sqrt(max(x * x + y * y - _WRIST_OFFSET_M**2, 0.0))
    # At pan 0 the wrist sits at (-radial, -offset) in the base's xy plane.
    pan = math.atan2(y, x) - math.atan2(-_WRIST_OFFSET_M, -radial)
    q = ELBOW_UP_POSTURE.copy()
    q[0] = math.remainder(pan, 2.0 * math.pi)
    return q


def initial_guesses(q_nominal: np.ndarray) -> np.ndarray:
    """The fixed list of initial guesses, shape (8, 6): ``q_nominal`` first, then the
    other IK branches (wrist flipped, elbow down, shoulder turned away from the target).
    """
    guesses = []
    for away in (False, True):
        for elbow_up in (True, False):
            for wrist_flipped in (False, True):
                q = np.array(q_nominal, dtype=float)
                if away:
                    # Mirror the arm's plane through the base's z axis.
                    q[0] = math.remainder(q[0] + math.pi, 2.0 * math.pi)
                    q[1] = -math.pi - q[1]
                    q[2] = -q[2]
                    q[3] = -math.pi - q[3]
                if not elbow_up:
                    # Mirror the elbow about the shoulder-wrist line (the links are
                    # about equally long), keeping the forearm-to-wrist angle sum.
                    q[1], q[2], q[3] = q[1] + q[2], -q[2], q[3] + q[2]
                if wrist_flipped:
                    q[4] = -q[4]
                    q[5] = math.remainder(q[5] + math.pi, 2.0 * math.pi)
                guesses.append(q)
    return np.array(guesses)


def _centred_turns(q: np.ndarray, plant) -> np.ndarray:
    """The same pose with every joint that can turn a full circle each way (the UR5e's
    +-2 pi joints) brought into (-pi, pi], leaving the most room for the motion ahead."""
    q = np.array(q, dtype=float)
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    full = (upper - lower) >= 4 * np.pi - 1e-9
    q[full] = np.pi - np.mod(np.pi - q[full], 2 * np.pi)
    return q


def _program_solutions(plant, X_WE_desired: RigidTransform, q_nominal: np.ndarray, guesses: np.ndarray):
    """``(guess index, q)`` of the inverse-kinematics program solved from each guess
    (module docstring), q with its full-turn joints centred."""
    frame_E = plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
    p_WE = X_WE_desired.translation()
    ik = InverseKinematics(plant, with_joint_limits=True)
    ik.AddPositionConstraint(
        frameB=frame_E,
        p_BQ=np.zeros(3),
        frameA=plant.world_frame(),
        p_AQ_lower=p_WE - IK_POSITION_TOLERANCE_M,
        p_AQ_upper=p_WE + IK_POSITION_TOLERANCE_M,
    )
    ik.AddOrientationConstraint(
        frameAbar=plant.world_frame(),
        R_AbarA=X_WE_desired.rotation(),
        frameBbar=frame_E,
        R_BbarB=RotationMatrix(),
        theta_bound=IK_ROTATION_TOLERANCE_RAD,
    )
    prog = ik.get_mutable_prog()
    q_variables = ik.q()
    prog.AddQuadraticErrorCost(np.diag(NOMINAL_WEIGHTS), q_nominal, q_variables)
    for index, guess in enumerate(guesses):
        result = Solve(prog, guess)
        yield index, _centred_turns(result.GetSolution(q_variables), plant)


def _closed_form_solutions(plant, model, context, X_WE_desired: RigidTransform, q_nominal: np.ndarray,
                           guesses: np.ndarray):
    """``(index of the nearest guess, q)`` of every branch in closed form (the flange's
    pose in the base frame from the plant's own base and E frames), q with its
    full-turn joints centred."""
    world = plant.world_frame()
    X_WB = plant.CalcRelativeTransform(context, world, plant.GetFrameByName(BASE_FRAME_NAME, model))
    X_tool0_E = plant.CalcRelativeTransform(context, plant.GetFrameByName(TOOL0_FRAME_NAME, model),
                                            plant.GetFrameByName(END_EFFECTOR_FRAME_NAME))
    T_B_tool0 = X_WB.inverse().multiply(X_WE_desired).multiply(X_tool0_E.inverse()).GetAsMatrix4()
    for q_branch in ur5e_branches(T_B_tool0, q6_free=float(q_nominal[5])):
        q = _centred_turns(q_branch, plant)
        difference = np.remainder(guesses - q + np.pi, 2.0 * np.pi) - np.pi
        yield int(np.argmin(np.sum(NOMINAL_WEIGHTS * difference**2, axis=1))), q


def _rotation_angle(R_a: RotationMatrix, R_b: RotationMatrix) -> float:
    return float(R_a.inverse().multiply(R_b).ToAngleAxis().angle())


def solve_initial_configuration(X_WE_desired: RigidTransform, **kwargs) -> InitialConfiguration:
    """Joint configuration placing E at ``X_WE_desired``, elbow up when possible: the
    first of :func:`initial_configuration_candidates` (the same keyword parameters)."""
    return initial_configuration_candidates(X_WE_desired, **kwargs)[0]


def initial_configuration_candidates(
    X_WE_desired: RigidTransform,
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    obstacles: Iterable[Box] = (),
    safety_shells: Iterable[Box] = (),
    con: int = 1,
    q_nominal: np.ndarray | None = None,
    scene: KinematicScene | None = None,
    tool=None,
    method: str = "program",
) -> list[InitialConfiguration]:
    """Every distinct joint configuration (IK branch) placing E at ``X_WE_desired``, best
    first: collision-free before colliding, then closest to the preferred posture (elbow
    up, facing the target), then by guess.

    Parameters
    ----------
    X_WE_desired : RigidTransform
        The critical configuration's pose.
    X_WB, X_tool0_E : RigidTransform, optional
        Robot base in W and E on ``tool0`` (identity by default).
    obstacles, safety_shells : iterable of Box
        Checked for collisions (the solution prefers collision-free branches).
    con : int
        The critical configuration's number, for the error message.
    q_nominal : array, shape (6,), optional
        Preferred posture; :func:`elbow_up_nominal` of the target by default.
    scene : KinematicScene, optional
        Reuse a scene already built for these frames and boxes (a work cell's: its
        tool's shapes count in the clearance like the links).
    tool : tuple of ToolShape, optional
        Without ``scene``: the tool (None: the default of ``X_tool0_E``).
    method : {"program", "closed_form"}
        ``"program"``: the nonlinear program from each guess (module docstring; what
        the bundled demonstrations were recorded from). ``"closed_form"``: every branch
        exactly, by :func:`~drake_lfd.robot.analytic_ik.ur5e_branches` (microseconds
        instead of milliseconds; each branch placed as the guess nearest it, wrist_3
        at the preferred posture's where the wrist is aligned): what the plan-time
        check uses, which must see every branch.

    Returns
    -------
    list of InitialConfiguration
        Solutions closer than 1e-6 rad (all joints) to a better one are left out.

    Raises
    ------
    UnreachableConfigurationError
        When no guess yields a configuration within ``ACCEPTED_*_ERROR``.
    """
    if scene is None:
        scene = KinematicScene(
            X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles, safety_shells=safety_shells, tool=tool
        )
    plant, model = scene.plant, scene.model
    frame_E = plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
    world = plant.world_frame()
    p_WE = X_WE_desired.translation()
    R_WE = X_WE_desired.rotation()
    if q_nominal is None:
        q_nominal = elbow_up_nominal(p_WE, X_WB)
    q_nominal = np.asarray(q_nominal, dtype=float)

    if method not in IK_METHODS:
        raise ValueError(f"method must be one of {IK_METHODS}, got {method!r}")
    candidates = []
    kinematics_context = plant.CreateDefaultContext()
    guesses = initial_guesses(q_nominal)
    if method == "closed_form":
        solutions = _closed_form_solutions(plant, model, kinematics_context, X_WE_desired, q_nominal, guesses)
    else:
        solutions = _program_solutions(plant, X_WE_desired, q_nominal, guesses)
    for index, q in solutions:
        plant.SetPositions(kinematics_context, model, q)
        X_WE = plant.CalcRelativeTransform(kinematics_context, world, frame_E)
        position_error = float(np.linalg.norm(X_WE.translation() - p_WE))
        rotation_error = _rotation_angle(X_WE.rotation(), R_WE)
        lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
        within_limits = bool(np.all(q >= lower - 1e-9) and np.all(q <= upper + 1e-9))
        if not (
            within_limits
            and position_error <= ACCEPTED_POSITION_ERROR_M
            and rotation_error <= ACCEPTED_ROTATION_ERROR_RAD
        ):
            continue
        distance, robot_geometry, box = scene.clearance(q)
        cost = float(np.sum(NOMINAL_WEIGHTS * (q - q_nominal) ** 2))
        candidates.append(
            (
                not distance > 0.0,
                round(cost, 9),
                index,
                InitialConfiguration(
                    q=q,
                    position_error_m=position_error,
                    rotation_error_rad=rotation_error,
                    collision_free=bool(distance > 0.0),
                    min_distance_m=distance,
                    closest_robot_geometry=robot_geometry,
                    closest_box=box,
                    guess_index=index,
                ),
            )
        )
    if not candidates:
        rpy = np.degrees(X_WE_desired.rotation().ToRollPitchYaw().vector())
        raise UnreachableConfigurationError(
            f"con_{con} at p = {np.round(p_WE, 4).tolist()} m, euler_zyx = "
            f"{np.round(rpy[::-1], 2).tolist()} deg is out of the UR5e's reach "
            + (f"(inverse kinematics failed from all {len(guesses)} initial guesses)" if method == "program"
               else "(no inverse-kinematics branch inside the joint limits reaches it)"),
            field=f"critical_configurations[{con - 1}]",
        )
    candidates.sort(key=lambda item: item[:3])
    distinct: list[InitialConfiguration] = []
    for *_, candidate in candidates:
        if all(np.max(np.abs(candidate.q - kept.q)) > 1e-6 for kept in distinct):
            distinct.append(candidate)
    return distinct
