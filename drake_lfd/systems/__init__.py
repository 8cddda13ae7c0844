"""Layer 5, the Drake LeafSystems, one per stage, thin wrappers over the layers below.

The default pipeline (``drake-lfd simulate``), one line per arrow, with the module of
the system that makes the arrow's output (``drake_lfd.diagrams.pipeline`` wires them)::

    library            --FeatureLibrarySystem-->       features      feature_library
    features + task    --PlannerSystem-->              ScheduledPlan planner
    plan + q_measured  --JointPathSource-->            chunk         joint_path_source
    chunk + q_measured --JointTrajectoryController-->  q_command     joint_trajectory_controller
    q_command          --Station-->                    q_measured    diagrams.station (layer 6)
    plan               --TrialEnd-->                   end of run    trial_end
    logged joints      --ShellMonitor-->               clearances    shell_monitor

The planner system plans with ``drake_lfd.planning.planner.plan_composition``, checks
the plan's joint path (``drake_lfd.robot.joint_path``) and times it with TOPP-RA
(``drake_lfd.robot.path_timing``, ``drake_lfd.robot.toppra``). In the paper's baseline
(``PlanningOptions.paper_baseline()``: Eq. 31's cost, no joint check) the plan is timed
by the SE(3) timing law (``drake_lfd.core.timing``), and with ``controller.method:
drake`` or ``pseudo_inverse`` two Python systems replace the two middle arrows::

    plan               --PlanTrajectorySource-->       X_WE, V_WE    plan_trajectory_source
    X_WE, V_WE         --DifferentialIKController-->   q_command     differential_ik

With people in the cell (a trial with ``people:``), the compiled pair is replaced::

    plan + q_measured + separation --TimeScaledJointPathSource--> q_command   speed_override
    query_object + state + dq/ds   --SeparationMonitor-->        separation  separation
    time                           --PeopleGeometry-->           poses       people

Recording a simulated demonstration (``drake_lfd.diagrams.kinesthetic``)::

    guidance pose      --VirtualHand-->                wrench on E   virtual_hand
    measured joints    --DemoRecorder-->               samples       demo_recorder

The modules:

* ``demo_recorder``: :class:`DemoRecorder`, a joint logger that samples like the UR5e's
  RTDE interface, its samples in the Context; :func:`add_joint_logger`,
  :func:`demonstration_from_log`.
* ``feature_library``: :class:`FeatureLibrarySystem`, a library's features
  (:class:`LibraryFeatures`) on an output port.
* ``planner``: :class:`PlannerSystem`, task and library in, a scheduled plan out
  (:data:`NO_PLAN` when there is none); :class:`GivenPlan`, a fixed plan in its place.
* ``joint_path_source``: :class:`JointPathSource`, the compiled loop's trajectory source:
  the plan's joint path, in chunks.
* ``joint_trajectory_controller``: :class:`JointTrajectoryController`, the plan's joint
  path tracked by Drake's own C++ systems (the default controller).
* ``plan_trajectory_source``: :class:`PlanTrajectorySource`, the scheduled plan as the
  desired end-effector pose and velocity (baseline).
* ``differential_ik``: :class:`DifferentialIKController`, desired end-effector motion to
  joint position command, in Python (baseline).
* ``shell_monitor``: :class:`ShellMonitor`, how close the robot came to each obstacle and
  safety shell.
* ``trial_end``: :class:`TrialEnd`, ends a run once its plan has been executed.
* ``people``: :class:`PeopleGeometry`, the people in the cell as a SceneGraph geometry
  source.
* ``separation``: :class:`SeparationMonitor`, each person's distance to the robot, the
  robot's approach speed and ISO/TS 15066's protective separation distance.
* ``speed_override``: :class:`TimeScaledJointPathSource`, the plan's joint path followed
  at the speed override the people's separation allows (replaces the compiled source and
  controller when a trial has people).
* ``virtual_hand``: :class:`VirtualHand`, the spring-damper hand that guides the arm in
  a simulated kinesthetic demonstration.
* ``typed_ports``: type checks at ``DiagramBuilder.Connect`` for abstract ports.

Every abstract port carries a model value of its real type; importing this package
installs ``typed_ports.install_connect_check``, so ``DiagramBuilder.Connect`` refuses to
connect two abstract ports whose Python classes differ (Drake itself only compares C++
types, and every Python object is the one C++ type ``Value[object]``).

It exports the systems above, each with the model values of its ports and the helpers
that build it (``from drake_lfd.systems import PlannerSystem``): ``__all__`` lists them
and docs/api.rst documents them. Each is loaded from its module on first use; importing
the package loads only ``typed_ports`` (and with it Drake) to install the check. Its
other names are internal, and so is ``typed_ports``.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports
from drake_lfd.systems.typed_ports import install_connect_check as _install_connect_check

_install_connect_check()

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "DemoRecorder": "drake_lfd.systems.demo_recorder",
    "NO_DEMONSTRATION": "drake_lfd.systems.demo_recorder",
    "add_joint_logger": "drake_lfd.systems.demo_recorder",
    "demonstration_from_log": "drake_lfd.systems.demo_recorder",
    "FeatureLibrarySystem": "drake_lfd.systems.feature_library",
    "LibraryFeatures": "drake_lfd.systems.feature_library",
    "PlannerSystem": "drake_lfd.systems.planner",
    "NO_PLAN": "drake_lfd.systems.planner",
    "GivenPlan": "drake_lfd.systems.planner",
    "JointPathSource": "drake_lfd.systems.joint_path_source",
    "JointTrajectoryController": "drake_lfd.systems.joint_trajectory_controller",
    "law_for_plant": "drake_lfd.systems.joint_trajectory_controller",
    "PlanTrajectorySource": "drake_lfd.systems.plan_trajectory_source",
    "DifferentialIKController": "drake_lfd.systems.differential_ik",
    "ShellMonitor": "drake_lfd.systems.shell_monitor",
    "TrialEnd": "drake_lfd.systems.trial_end",
    "PeopleGeometry": "drake_lfd.systems.people",
    "SeparationMonitor": "drake_lfd.systems.separation",
    "TimeScaledJointPathSource": "drake_lfd.systems.speed_override",
    "VirtualHand": "drake_lfd.systems.virtual_hand",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
