"""Layer 2, the robot: the UR5e as a MultibodyPlant and what is computed on it.

In the default pipeline the planner checks every plan in joint space and times the
joint path before promising it; the paper's baseline skips both and times the SE(3)
plan with ``drake_lfd.core.timing``::

    SE(3) plan  --follow with the diff-IK law-->  joint path   joint_path, differential_ik_law
    joint path  --TOPP-RA, the UR5e's limits-->   timed path   path_timing, toppra
    timed path  --source, controller-->           UR5e motion  drake_lfd.systems (layer 5)

The modules:

* ``kinematics``: the UR5e model loaded into a MultibodyPlant; forward kinematics of
  ``tool0`` and the end-effector frame E, joint limits.
* ``dh_kinematics``: forward kinematics and Jacobian from the DH table, in plain floats
  (the fast path of the joint-path check); the shoulder singularity's distance and the
  arm's reach.
* ``analytic_ik``: closed-form inverse kinematics, every branch reaching a flange pose.
* ``initial_ik``: the joint configuration at the first critical configuration.
* ``differential_ik_law``: the differential-IK law, one joint-velocity step toward a
  desired end-effector motion (shared by the check and the baseline controller).
* ``joint_path``: the plan-time joint-path check (``JointPathChecker``): a timed SE(3)
  plan followed as the controller will follow it.
* ``joint_path_records``: what the check keeps to and reports: ``JointPathLimits``,
  ``Blocker``, ``JointPath``, and how a shortfall is worded.
* ``follow_memory``: the check's memory of its last follows, so a plan sharing a prefix
  resumes where they part.
* ``pan_only``: the shapes shoulder_pan alone places (base, shoulder, shoulder_lift
  housing) and the one configuration they are measured at.
* ``path_constraints``: a task's path constraints measured on a motion (the one measure
  the check, the refinement and the judge share).
* ``path_timing``: time-optimal timing of a plan's joint path under the UR5e's limits.
* ``toppra``: TOPP-RA with each stage's linear program in closed form.
* ``trajectory_optimization``: Drake's kinematic trajectory optimization of a joint path
  in a work cell (``--refine``): the program, built and solved.
* ``optimization_records``: the program's inputs and answer: limits, SNOPT's work
  budget, pose targets and bounds, the optimized trajectory.
* ``optimization_scene``: the work cell as the program's clearance constraint sees it.
* ``trajectory_constraints``: the constraints the program writes itself (rotation
  targets, the speed at a target, the shoulder margin, singularity-free intervals).
* ``trajectory_sampling``: the program's B-spline guess fitted to joint samples, and its
  solution sampled at the controller's period.
* ``workcell``: the one description of the work cell: robot base, table, obstacles,
  shells and tool.
* ``scene``: the work cell's geometry on the plant; signed distances.
* ``clearance``: the tool's clearance points and their signed distances to keep-out
  boxes and the floor along a path of poses (plain numpy).
* ``motion_bounds``: how far a robot geometry can move when the joints turn (bounds
  that prune distance queries).

It exports the UR5e and its work cell as users build and query them (``from
drake_lfd.robot import UR5eKinematics``): the kinematics and joint names, the work cell
and its geometry, the joint-path check and its result, the joint path's timing and the
differential-IK law. ``__all__`` lists them and docs/api.rst documents them; each is
loaded from its module on first use, so importing the package loads none of the modules
that define them. Its other modules, and the names the exports leave out, are internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "UR5eKinematics": "drake_lfd.robot.kinematics",
    "UR5E_JOINT_NAMES": "drake_lfd.robot.kinematics",
    "END_EFFECTOR_FRAME_NAME": "drake_lfd.robot.kinematics",
    "Workcell": "drake_lfd.robot.workcell",
    "table_under_robot": "drake_lfd.robot.workcell",
    "KinematicScene": "drake_lfd.robot.scene",
    "JointPathChecker": "drake_lfd.robot.joint_path",
    "JointPath": "drake_lfd.robot.joint_path_records",
    "time_joint_path": "drake_lfd.robot.path_timing",
    "TimedJointPath": "drake_lfd.robot.path_timing",
    "PathTimingOptions": "drake_lfd.robot.path_timing",
    "DifferentialIKLaw": "drake_lfd.robot.differential_ik_law",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
