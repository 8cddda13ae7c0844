"""The virtual hand: a LeafSystem pulling frame E towards the guidance pose.

In a simulated kinesthetic demonstration the person's hand is a spring-damper wrench on
the end-effector frame E (an ``ExternallyAppliedSpatialForce`` into the plant), capped at
what a hand exerts, that pulls E towards the pose of a
:class:`~drake_lfd.core.guidance.SampledGuidance`. The guidance itself (waypoints, pace,
wobble) is computed in :mod:`drake_lfd.core.guidance`; this system only looks it up and
turns the pose error into a wrench.

Not for: the guidance path (:mod:`drake_lfd.core.guidance`), the free-driven arm and the
recording (:mod:`drake_lfd.diagrams.kinesthetic`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import ExternallyAppliedSpatialForce_
from pydrake.systems.framework import LeafSystem

from drake_lfd.core.guidance import SampledGuidance

__all__ = ["VirtualHandGains", "VirtualHand"]


@dataclasses.dataclass(frozen=True)
class VirtualHandGains:
    """Spring-damper of the guiding hand on frame E, and the most a hand exerts.

    The rotational damping is applied explicitly (it is an external wrench), so it must
    stay below ``2 I / dt`` for the smallest inertia it acts on: wrist 3 about its axis,
    about 4e-4 kg m^2, allows 0.8 N m s/rad at 1 ms.
    """

    translational_stiffness: float = 2000.0  # N/m
    translational_damping: float = 60.0  # N s/m
    rotational_stiffness: float = 20.0  # N m/rad
    rotational_damping: float = 0.2  # N m s/rad
    max_force: float = 80.0  # N
    max_torque: float = 8.0  # N m


class VirtualHand(LeafSystem):
    """A hand pulling frame E towards the guidance pose with a spring-damper wrench.

    .. pydrake_system::

        name: VirtualHand
        input_ports:
        - body_poses
        - body_spatial_velocities
        output_ports:
        - spatial_force

    ``body_poses`` and ``body_spatial_velocities`` are the plant's outputs of those
    names; ``spatial_force`` (a list with one ``ExternallyAppliedSpatialForce``) goes to
    the plant's ``applied_spatial_force`` input. The wrench, applied at E's origin, is

        f = K_t (p_WH - p_WE) + D_t (v_WH - v_WE)
        tau = K_r log(R_WH R_WE^T) + D_r (w_WH - w_WE)

    with the guidance pose ``X_WH`` and velocity looked up in a :class:`SampledGuidance`
    at the nearest grid time; force and torque are capped at the gains' maxima.

    Parameters
    ----------
    guidance : SampledGuidance
    body_index : BodyIndex
        The body frame E is fixed to.
    X_BE : RigidTransform
        Pose of E in that body.
    gains : VirtualHandGains
    """

    def __init__(self, *, guidance: SampledGuidance, body_index, X_BE: RigidTransform, gains=VirtualHandGains()):
        super().__init__()
        self._guidance = guidance
        self._body = int(body_index)
        self._body_index = body_index
        self._p_BE = np.array(X_BE.translation())
        self._R_BE = np.array(X_BE.rotation().matrix())
        self._gains = gains
        self._body_poses_port = self.DeclareAbstractInputPort("body_poses", AbstractValue.Make([RigidTransform()]))
        self._body_velocities_port = self.DeclareAbstractInputPort(
            "body_spatial_velocities", AbstractValue.Make([SpatialVelocity()])
        )
        self.DeclareAbstractOutputPort(
            "spatial_force",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce_[float]()]),
            self._calc_spatial_force,
        )

    @staticmethod
    def AddToBuilder(*, builder, plant, frame_E, guidance: SampledGuidance, gains=VirtualHandGains(), name="virtual_hand"):
        """Adds a hand pulling ``frame_E`` (a frame fixed to a body of ``plant``) and wires it:
        ``plant.body_poses, body_spatial_velocities -> hand -> plant.applied_spatial_force``.
        Returns the hand."""
        hand = builder.AddSystem(
            VirtualHand(
                guidance=guidance,
                body_index=frame_E.body().index(),
                X_BE=frame_E.GetFixedPoseInBodyFrame(),
                gains=gains,
            )
        )
        hand.set_name(name)
        builder.Connect(plant.get_body_poses_output_port(), hand.GetInputPort("body_poses"))
        builder.Connect(plant.get_body_spatial_velocities_output_port(), hand.GetInputPort("body_spatial_velocities"))
        builder.Connect(hand.GetOutputPort("spatial_force"), plant.get_applied_spatial_force_input_port())
        return hand

    def _calc_spatial_force(self, context, output):
        gains = self._gains
        guidance = self._guidance
        k = guidance.index(context.get_time())
        X_WB = self._body_poses_port.Eval(context)[self._body]
        V_WB = self._body_velocities_port.Eval(context)[self._body]
        R_WB = X_WB.rotation().matrix()
        p_BE_W = R_WB @ self._p_BE
        p_WE = X_WB.translation() + p_BE_W
        R_WE = R_WB @ self._R_BE
        w_WE = V_WB.rotational()
        v_WE = V_WB.translational() + np.cross(w_WE, p_BE_W)
        force = gains.translational_stiffness * (guidance.p_WH[k] - p_WE) + gains.translational_damping * (
            guidance.v_WH[k] - v_WE
        )
        rotation_error = RotationMatrix(guidance.R_WH[k] @ R_WE.T).ToAngleAxis()
        torque = gains.rotational_stiffness * rotation_error.angle() * rotation_error.axis() + (
            gains.rotational_damping * (guidance.w_WH[k] - w_WE)
        )
        force = _capped(force, gains.max_force)
        torque = _capped(torque, gains.max_torque)
        wrench = ExternallyAppliedSpatialForce_[float]()
        wrench.body_index = self._body_index
        wrench.p_BoBq_B = self._p_BE
        wrench.F_Bq_W = SpatialForce(tau=torque, f=force)
        output.set_value([wrench])


def _capped(vector, limit):
    norm = float(np.linalg.norm(vector))
    return vector if norm <= limit else vector * (limit / norm)
