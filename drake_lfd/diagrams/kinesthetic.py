"""Kinesthetic demonstrations in simulation: a virtual hand guides a free-driven UR5e.

On the real robot a person switches the UR5e to free drive (the controller cancels
gravity and adds a little damping) and pulls the tool along the motion while the
controller logs the joints over RTDE. This module does the same in Drake:

- the UR5e is a discrete MultibodyPlant (1 ms, SAP) whose actuation is gravity
  compensation only (``InverseDynamics`` in gravity-compensation mode on a kinematics
  plant); the free-drive damping is viscous joint damping, which the discrete solver
  integrates implicitly (an explicit damping torque on wrist 3, whose inertia about its
  axis is 4e-4 kg m^2, would go unstable at 1 ms);
- a :class:`~drake_lfd.systems.virtual_hand.VirtualHand` pulls the end-effector frame E
  towards the guidance pose with a spring-damper wrench (``ExternallyAppliedSpatialForce``),
  capped at what a hand exerts;
- the guidance pose comes from a *guidance script* (a
  :class:`~drake_lfd.core.guidance.GuidanceScript`): waypoints joined by screw motions
  (ScLERP) with a minimum-jerk time profile, perturbed like a human hand (seeded smooth
  wobble of about a millimetre and half a degree, and a slightly uneven pace), then held
  still at the last waypoint so the arm settles (:class:`~drake_lfd.core.guidance.GuidancePath`);
- a :class:`~drake_lfd.systems.demo_recorder.DemoRecorder` samples the measured joints at
  the RTDE rate (500 Hz) into its state in the Context; :func:`record_demonstration`
  returns them as a demonstration (``drake-lfd record`` writes it as an RTDE-style CSV).

The arm starts at rest at the inverse-kinematics solution of the first waypoint with an
elbow-up preference (:func:`initial_joint_positions`, from ``initial_ik.py``). Nothing
here commands joint positions: the recorded joints are whatever the arm's dynamics made
of the hand's pull.

The script format is in docs/guidance_scripts.rst (read by
:mod:`drake_lfd.io.guidance_scripts`).

Not for: reading scripts (:mod:`drake_lfd.io.guidance_scripts`), the guidance path
(:mod:`drake_lfd.core.guidance`), the hand's wrench (:mod:`drake_lfd.systems.virtual_hand`),
reading or storing logs (``demonstration_logs.py``, ``library.py``), executing plans
(the closed-loop diagram).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Callable, NamedTuple

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Demultiplexer

from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.core.dual_quaternion import dual_quaternion_relative
from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices, matrices_from_dual_quaternion
from drake_lfd.core.quaternion import axis_angle_from_quaternion
from drake_lfd.core.errors import InputError
from drake_lfd.core.guidance import KINESTHETIC_TIME_STEP_S, GuidancePath, GuidanceScript
from drake_lfd.robot.initial_ik import UnreachableConfigurationError, solve_initial_configuration
from drake_lfd.robot.kinematics import (
    END_EFFECTOR_FRAME_NAME,
    NUM_JOINTS,
    UR5E_JOINT_NAMES,
    UR5eKinematics,
    add_ur5e,
)
from drake_lfd.systems.demo_recorder import DemoRecorder
from drake_lfd.systems.virtual_hand import VirtualHand, VirtualHandGains

__all__ = [
    "FREE_DRIVE_DAMPING",
    "MAX_FINAL_POSITION_ERROR_M",
    "MAX_FINAL_ROTATION_ERROR_RAD",
    "initial_joint_positions",
    "KinestheticSetup",
    "make_kinesthetic_diagram",
    "RecordedDemonstration",
    "record_demonstration",
]

# Free-drive damping per joint (N m s/rad), shoulder_pan .. wrist_3: enough that the arm
# stops within a few tenths of a second when the hand stops, small against the hand's
# pull (a 1 rad/s shoulder motion costs 2 N m, about 4 N at the tool).
FREE_DRIVE_DAMPING = (2.0, 2.0, 1.5, 0.3, 0.3, 0.2)
# A guided arm that ends farther than this from the last waypoint did not follow the
# hand (out of reach, a joint limit, a singularity): the script is at fault.
MAX_FINAL_POSITION_ERROR_M = 0.005
MAX_FINAL_ROTATION_ERROR_RAD = math.radians(2.0)


# ------------------------------------------------------------------ initial configuration


def initial_joint_positions(X_WE, *, X_WB=None, X_tool0_E=None, file=None, field=None):
    """Joint angles that put frame E at ``X_WE`` in an elbow-up posture.

    The project's initial inverse kinematics (``initial_ik.solve_initial_configuration``:
    Drake's ``InverseKinematics`` from a fixed list of guesses, cost towards an elbow-up
    posture facing the target; deterministic), with its error re-addressed to the script.

    Raises
    ------
    InputError
        The pose is out of reach, naming ``file`` and ``field``.
    """
    try:
        solution = solve_initial_configuration(RigidTransform(X_WE), X_WB=X_WB, X_tool0_E=X_tool0_E)
    except UnreachableConfigurationError:
        raise InputError(
            "no joint configuration of the UR5e reaches this pose (out of reach?)", file=file, field=field
        ) from None
    return np.array(solution.q, dtype=float)


# ------------------------------------------------------------------ the diagram


class KinestheticSetup(NamedTuple):
    """What :func:`make_kinesthetic_diagram` builds."""

    diagram: object
    plant: MultibodyPlant
    model: object
    hand: VirtualHand
    recorder: DemoRecorder
    guidance: GuidancePath
    q_initial: np.ndarray
    # InverseDynamics refers to this plant without owning it: keep it alive with the diagram.
    kinematics_plant: MultibodyPlant


def make_kinesthetic_diagram(
    script: GuidanceScript, *, gains=VirtualHandGains(), damping=FREE_DRIVE_DAMPING, time_step_s=KINESTHETIC_TIME_STEP_S
) -> KinestheticSetup:
    """The free-driven UR5e, the virtual hand and the RTDE-rate recorder, wired.

    Pipeline: ``plant.state -> InverseDynamics (gravity) -> plant.actuation``;
    ``plant.body_poses, body_spatial_velocities -> VirtualHand -> plant.applied_spatial_force``;
    ``plant.state -> positions -> DemoRecorder``. The plant's default positions are the
    initial configuration (:func:`initial_joint_positions` of the first waypoint).
    """
    first = script.waypoints[0]
    q_initial = initial_joint_positions(
        first.X_WE, X_WB=script.X_WB, X_tool0_E=script.X_tool0_E, file=script.source, field="waypoints[0]"
    )
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(time_step=time_step_s))
    plant.set_name("plant")
    # SAP (not TAMSI): it integrates joint damping implicitly and keeps the actuation input live.
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    model = add_ur5e(plant, X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
    joints = [plant.GetJointByName(name, model) for name in UR5E_JOINT_NAMES]
    for joint, b in zip(joints, damping):
        joint.set_default_damping(float(b))
    plant.Finalize()
    for joint, q in zip(joints, q_initial):
        joint.set_default_angle(float(q))

    # Free drive: gravity compensation computed on a kinematics-only copy of the arm.
    kinematics_plant = MultibodyPlant(time_step=0.0)
    add_ur5e(kinematics_plant, X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
    kinematics_plant.Finalize()
    gravity = builder.AddSystem(
        InverseDynamics(kinematics_plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation)
    )
    gravity.set_name("gravity_compensation")
    builder.Connect(plant.get_state_output_port(model), gravity.get_input_port_estimated_state())
    builder.Connect(gravity.get_output_port_generalized_force(), plant.get_actuation_input_port(model))

    guidance = GuidancePath(script)
    hand = VirtualHand.AddToBuilder(
        builder=builder,
        plant=plant,
        frame_E=plant.GetFrameByName(END_EFFECTOR_FRAME_NAME),
        guidance=guidance.sample(time_step_s),
        gains=gains,
    )

    positions = builder.AddSystem(Demultiplexer([NUM_JOINTS, NUM_JOINTS]))
    positions.set_name("measured_position")
    builder.Connect(plant.get_state_output_port(model), positions.get_input_port())
    recorder = DemoRecorder.AddToBuilder(builder=builder, measured_position_output_port=positions.get_output_port(0),
                                         num_joints=NUM_JOINTS, rate_hz=script.sample_rate_hz)
    diagram = builder.Build()
    diagram.set_name(f"kinesthetic_{script.name}")
    return KinestheticSetup(diagram, plant, model, hand, recorder, guidance, q_initial, kinematics_plant)


# ------------------------------------------------------------------ recording


@dataclasses.dataclass(frozen=True)
class RecordedDemonstration:
    """A simulated kinesthetic demonstration and how well the arm followed the hand.

    Attributes
    ----------
    demonstration : Demonstration
        The joint log at ``script.sample_rate_hz``.
    q_initial : array, shape (6,)
    max_position_error_m, max_rotation_error_rad : float
        Largest distance between frame E and the hand's pose over the log.
    final_position_error_m, final_rotation_error_rad : float
        Distance of the last sample from the last waypoint.
    sim_time_s, wall_time_s : float
    """

    demonstration: Demonstration
    q_initial: np.ndarray
    max_position_error_m: float
    max_rotation_error_rad: float
    final_position_error_m: float
    final_rotation_error_rad: float
    sim_time_s: float
    wall_time_s: float


def _pose_errors(D_a, D_b):
    """Position distance (m) and rotation angle (rad) between poses, each shape (N,)."""
    p_a = matrices_from_dual_quaternion(D_a)[:, :3, 3]
    p_b = matrices_from_dual_quaternion(D_b)[:, :3, 3]
    _, angle = axis_angle_from_quaternion(dual_quaternion_relative(D_a, D_b)[:, :4])
    return np.linalg.norm(p_b - p_a, axis=-1), angle


def record_demonstration(
    script: GuidanceScript,
    *,
    progress: Callable[[float, float], None] | None = None,
    progress_interval_s: float = 1.0,
    gains=VirtualHandGains(),
    damping=FREE_DRIVE_DAMPING,
) -> RecordedDemonstration:
    """Simulates the guided demonstration of ``script`` and returns its joint log.

    Parameters
    ----------
    script : GuidanceScript
    progress : callable, optional
        Called as ``progress(sim_time_s, duration_s)`` every ``progress_interval_s`` of
        simulated time and at the end.

    Raises
    ------
    InputError
        The first waypoint is out of reach, or the arm ended farther than 5 mm / 2 deg
        from the last waypoint (it could not follow: out of reach, a joint limit or a
        singularity on the way).
    """
    wall_start = time.perf_counter()
    setup = make_kinesthetic_diagram(script, gains=gains, damping=damping)
    simulator = Simulator(setup.diagram)
    simulator.Initialize()
    duration = script.duration_s
    t = 0.0
    while t < duration:
        t = min(duration, t + progress_interval_s)
        simulator.AdvanceTo(t)
        if progress is not None:
            progress(t, duration)
    # The recorder samples in update events, which Drake applies when a step starts:
    # the sample at the end time is pending until this.
    simulator.AdvancePendingEvents()
    demonstration = setup.recorder.demonstration(simulator.get_context(), script.name, script.description)

    kinematics = UR5eKinematics(X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
    D_measured = dual_quaternion_from_matrices(kinematics.X_WE_batch(demonstration.joint_positions))
    D_hand = setup.guidance.poses(demonstration.timestamps)
    p_error, r_error = _pose_errors(D_measured, D_hand)
    final_p, final_r = _pose_errors(D_measured[-1:], setup.guidance.waypoint_poses[-1:])
    if final_p[0] > MAX_FINAL_POSITION_ERROR_M or final_r[0] > MAX_FINAL_ROTATION_ERROR_RAD:
        worst = int(np.argmax(p_error / MAX_FINAL_POSITION_ERROR_M + r_error / MAX_FINAL_ROTATION_ERROR_RAD))
        raise InputError(
            f"the arm did not follow the hand: it ended {1000 * final_p[0]:.1f} mm / "
            f"{math.degrees(final_r[0]):.1f} deg from the last waypoint (worst at t = "
            f"{demonstration.timestamps[worst]:.2f} s: {1000 * p_error[worst]:.0f} mm, "
            f"{math.degrees(r_error[worst]):.0f} deg); a pose is out of reach or the path "
            "crosses a joint limit or a singularity",
            file=script.source,
            field=f"waypoints[{len(script.waypoints) - 1}]",
        )
    return RecordedDemonstration(
        demonstration=demonstration,
        q_initial=setup.q_initial,
        max_position_error_m=float(p_error.max()),
        max_rotation_error_rad=float(r_error.max()),
        final_position_error_m=float(final_p[0]),
        final_rotation_error_rad=float(final_r[0]),
        sim_time_s=duration,
        wall_time_s=time.perf_counter() - wall_start,
    )
