"""UR5e model loading and forward kinematics of ``tool0`` and the end-effector frame E.

This module finds the UR5e model shipped with drake-lfd (inside the installed package, or
the repository's ``models/`` when run from a checkout), adds it to a MultibodyPlant, and
gives batched forward kinematics ``X_WE = X_WB * FK(q) * X_tool0_E`` on a
kinematics-only plant, also of whole demonstrations
(:func:`dual_quaternions_from_demonstration`).

A :class:`UR5eKinematics` owns its plant and one mutable context, so whoever needs
kinematics creates one and keeps it (about a millisecond to build); there is no shared
instance, and two callers never write each other's context.

Not for: simulation diagrams (``diagrams/``), inverse kinematics (``initial_ik.py``),
reading logs (:mod:`drake_lfd.io.demonstration_logs`).
"""

from __future__ import annotations

import os
import threading

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import FixedOffsetFrame, ModelInstanceIndex

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.network_policy import NETWORK_VARIABLE, drake_allows
from drake_lfd.core.resources import models_directory
from drake_lfd.robot.dh_kinematics import DHArm

__all__ = [
    "UR5E_PACKAGE_NAME",
    "UR5E_URL",
    "UR5E_JOINT_NAMES",
    "BASE_FRAME_NAME",
    "TOOL0_FRAME_NAME",
    "END_EFFECTOR_FRAME_NAME",
    "NUM_JOINTS",
    "make_parser",
    "add_ur5e",
    "UR5eKinematics",
    "poses_from_demonstration",
    "dual_quaternions_from_demonstration",
]

UR5E_PACKAGE_NAME = "drake_lfd_models"
UR5E_URL = f"package://{UR5E_PACKAGE_NAME}/ur5e/ur5e.urdf"
UR5E_JOINT_NAMES = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
BASE_FRAME_NAME = "base_link"
TOOL0_FRAME_NAME = "tool0"
END_EFFECTOR_FRAME_NAME = "E"
NUM_JOINTS = len(UR5E_JOINT_NAMES)


_ENVIRONMENT_LOCK = threading.Lock()


def make_parser(plant: MultibodyPlant) -> Parser:
    """A Parser whose package map resolves ``package://drake_lfd_models/...`` offline.

    Works under ``DRAKE_ALLOW_NETWORK=none`` too, with an empty download cache
    (:mod:`drake_lfd.core.network_policy`): Drake's check that ``drake_models`` could
    be fetched is lifted only while the Parser is constructed (construction downloads
    nothing), and ``drake_models`` is then removed from the Parser, so nothing of it can
    ever be fetched through it.
    """
    if drake_allows("package_map"):
        parser = Parser(plant)
    else:
        with _ENVIRONMENT_LOCK:
            saved = os.environ.get(NETWORK_VARIABLE)
            os.environ[NETWORK_VARIABLE] = "package_map"
            try:
                parser = Parser(plant)
            finally:
                if saved is None:
                    del os.environ[NETWORK_VARIABLE]
                else:
                    os.environ[NETWORK_VARIABLE] = saved
        if parser.package_map().Contains("drake_models"):
            parser.package_map().Remove("drake_models")
    parser.package_map().AddPackageXml(str(models_directory() / "package.xml"))
    return parser


def add_ur5e(
    plant: MultibodyPlant,
    *,
    X_WB: RigidTransform | None = None,
    X_tool0_E: RigidTransform | None = None,
    model_name: str = "ur5e",
) -> ModelInstanceIndex:
    """Adds the UR5e welded at ``X_WB`` and the end-effector frame ``E`` at ``X_tool0_E``.

    Must be called before ``plant.Finalize()``. Returns the model instance.
    """
    parser = make_parser(plant)
    parser.SetAutoRenaming(True)
    (model,) = parser.AddModels(url=UR5E_URL)
    if plant.GetModelInstanceName(model) != model_name:
        plant.RenameModelInstance(model, model_name)
    plant.WeldFrames(
        plant.world_frame(),
        plant.GetFrameByName(BASE_FRAME_NAME, model),
        RigidTransform() if X_WB is None else X_WB,
    )
    plant.AddFrame(
        FixedOffsetFrame(
            END_EFFECTOR_FRAME_NAME,
            plant.GetFrameByName(TOOL0_FRAME_NAME, model),
            RigidTransform() if X_tool0_E is None else X_tool0_E,
        )
    )
    return model


class UR5eKinematics:
    """Forward kinematics of the UR5e on a kinematics-only (continuous) plant.

    Parameters
    ----------
    X_WB : RigidTransform, optional
        Pose of the robot base frame B (``base_link``) in the world W. Identity by default.
    X_tool0_E : RigidTransform, optional
        Pose of the end-effector frame E in ``tool0``. Identity by default.
    """

    def __init__(self, *, X_WB: RigidTransform | None = None, X_tool0_E: RigidTransform | None = None):
        self.X_WB = RigidTransform() if X_WB is None else RigidTransform(X_WB)
        self.X_tool0_E = RigidTransform() if X_tool0_E is None else RigidTransform(X_tool0_E)
        self.plant = MultibodyPlant(time_step=0.0)
        self.model = add_ur5e(self.plant, X_WB=self.X_WB, X_tool0_E=self.X_tool0_E)
        self.plant.Finalize()
        self.context = self.plant.CreateDefaultContext()
        self.world_frame = self.plant.world_frame()
        self.tool0_frame = self.plant.GetFrameByName(TOOL0_FRAME_NAME, self.model)
        self.end_effector_frame = self.plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
        self.joints = [self.plant.GetJointByName(name, self.model) for name in UR5E_JOINT_NAMES]
        self._table_arm = DHArm(self.X_tool0_E)  # X_WE_table_batch's

    # -- limits -------------------------------------------------------------------------
    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper joint position limits, each shape (6,), radians."""
        return self.plant.GetPositionLowerLimits(), self.plant.GetPositionUpperLimits()

    def velocity_limits(self) -> np.ndarray:
        """Joint speed limits, shape (6,), rad/s (symmetric)."""
        return self.plant.GetVelocityUpperLimits()

    def effort_limits(self) -> np.ndarray:
        """Actuator torque limits in joint order, shape (6,), N m."""
        limits = []
        for joint in self.joints:
            (actuator_index,) = [
                index
                for index in self.plant.GetJointActuatorIndices(self.model)
                if self.plant.get_joint_actuator(index).joint().index() == joint.index()
            ]
            limits.append(self.plant.get_joint_actuator(actuator_index).effort_limit())
        return np.array(limits)

    # -- forward kinematics ---------------------------------------------------------------
    def _pose_of(self, frame, q: np.ndarray) -> RigidTransform:
        self.plant.SetPositions(self.context, self.model, np.asarray(q, dtype=float))
        return self.plant.CalcRelativeTransform(self.context, self.world_frame, frame)

    def X_Wtool0(self, q: np.ndarray) -> RigidTransform:
        """Pose of ``tool0`` in W for joint angles ``q`` (shape (6,))."""
        return self._pose_of(self.tool0_frame, q)

    def X_WE(self, q: np.ndarray) -> RigidTransform:
        """Pose of the end-effector frame E in W for joint angles ``q`` (shape (6,))."""
        return self._pose_of(self.end_effector_frame, q)

    def X_WE_batch(self, q_samples: np.ndarray) -> np.ndarray:
        """Homogeneous matrices of X_WE, array shape (m, 4, 4), for ``q_samples`` (m, 6)."""
        q_samples = np.atleast_2d(np.asarray(q_samples, dtype=float))
        return np.stack([self.X_WE(q).GetAsMatrix4() for q in q_samples])

    def X_WE_table_batch(self, q_samples: np.ndarray) -> np.ndarray:
        """:meth:`X_WE_batch` from the UR5e's DH table in numpy (equal to the plant's to
        5e-16; :class:`~drake_lfd.robot.dh_kinematics.DHArm`), four times faster: for
        figures compared against a threshold (the timing's tool deviation). Poses a plan
        or a feature is made of keep the plant's (:meth:`X_WE_batch`): SNOPT's
        refinement from a plan moves with their last bit."""
        return self.X_WB.GetAsMatrix4() @ self._table_arm.poses_batch(q_samples)

    def X_Wtool0_batch(self, q_samples: np.ndarray) -> np.ndarray:
        """Homogeneous matrices of X_Wtool0, shape (m, 4, 4), for ``q_samples`` (m, 6)."""
        q_samples = np.atleast_2d(np.asarray(q_samples, dtype=float))
        return np.stack([self.X_Wtool0(q).GetAsMatrix4() for q in q_samples])


# ----------------------------------------------------------------- demonstrations


def poses_from_demonstration(demonstration, kinematics: UR5eKinematics) -> np.ndarray:
    """End-effector poses of every sample of a demonstration by forward kinematics.

    Parameters
    ----------
    demonstration : Demonstration
    kinematics : UR5eKinematics
        Carries ``X_WB`` and ``X_tool0_E``; a library uses ``X_WB = identity``.

    Returns
    -------
    X_WE : array, shape (m, 4, 4)
        Homogeneous matrices.
    """
    return kinematics.X_WE_batch(demonstration.joint_positions)


def dual_quaternions_from_demonstration(demonstration, kinematics: UR5eKinematics) -> np.ndarray:
    """End-effector poses of every sample as dual quaternions, shape (m, 8)."""
    return dual_quaternion_from_matrices(poses_from_demonstration(demonstration, kinematics))
