"""drake-lfd: compose kinesthetic demonstrations into UR5e motion plans, on Drake.

Implements (and extends) Yu & Chang, "Reinforcement Learning Based User-Guided Motion
Planning for Human-Robot Collaboration". The pipeline, and where each arrow lives::

    joint log (RTDE CSV) --read, check-->        Demonstration       io.demonstration_logs
    joint samples --UR5e forward kinematics-->   poses X_WE          robot.kinematics
    poses --Eq. 7-->                             dual quaternions    core.dual_quaternion
    dual quaternions --Eq. 12, resampling-->     feature HD_k        core.features
    features --store-->                          library LB          io.library
    task YAML --load, check-->                   critical configs    io.task_files, core.tasks
    task + LB --Eq. 19-21-->                     legal actions       core.similarity, planning.composition
    legal actions --exact DP / Q-learning-->     composition         planning.exact_planner, planning.q_learning
    composition --Eq. 22-25-->                   SE(3) plan          core.mapping, planning.planner

From the SE(3) plan on, what runs by default (``drake-lfd simulate``, ``build_pipeline``)::

    SE(3) plan --joint-path check-->             joint path          robot.joint_path, planning.executable
    joint path --TOPP-RA-->                      timed joint path    robot.path_timing, robot.toppra
    timed joint path --in chunks-->              joint references    systems.joint_path_source
    references --compiled Drake primitives-->    q_command           systems.joint_trajectory_controller
    q_command --UR5e MultibodyPlant, drive-->    UR5e joint motion   diagrams.station
    joint motion --clearances, end of run-->     monitored run       systems.shell_monitor, systems.trial_end
    monitored run --success criteria-->          verdict             diagrams.trial_result, diagrams.judging

and the paper's baseline beside it (``PlanningOptions.paper_baseline()``, controller
``drake`` or ``pseudo_inverse``)::

    SE(3) plan --timing law-->                   X_WE(t), V_WE(t)    core.timing
    X_WE(t) --scheduled plan as a source-->      desired X_WE, V_WE  systems.plan_trajectory_source
    X_WE, V_WE --differential IK, Python-->      q_command           systems.differential_ik
    q_command --UR5e MultibodyPlant, drive-->    UR5e joint motion   diagrams.station

Each stage is also a Drake LeafSystem (``systems/``): ``FeatureLibrarySystem`` ->
``PlannerSystem`` -> ``JointPathSource`` -> ``JointTrajectoryController`` -> the UR5e
``Station``, watched by a ``ShellMonitor`` and ended by ``TrialEnd`` (the baseline puts
``PlanTrajectorySource`` -> ``DifferentialIKController`` in the middle);
``DemoRecorder`` records demonstrations; :func:`build_pipeline` wires them in one
Diagram.

Layers, lowest first; a module imports only from its own layer or lower ones (a test
checks it):

``core``
    Pure maths and data types: dual quaternions, features, similarity, mapping, timing,
    tasks, demonstrations, errors. No Diagram, no files.
``robot``
    The UR5e: kinematics (a MultibodyPlant), inverse kinematics, scene geometry, the
    plan-time joint-path check and TOPP-RA timing.
``planning``
    The composition problem and its MDP, the exact and Q-learning planners, training,
    the Gymnasium environment, replanning.
``io``
    Files: task files, demonstration logs, libraries, policies, JSON records.
``systems``
    The LeafSystems, thin wrappers over the layers below.
``diagrams``
    The station, the pipeline, closed-loop runs, their results and judging, kinesthetic
    recording, model preview.
``experiments``
    Trials, the public ``plan_task``, the paper's Section 6, figures.
``cli``
    The ``drake-lfd`` command line.

Conventions: metres, radians, seconds; quaternions (w, x, y, z); task orientations
``euler_zyx: [yaw, pitch, roll]`` with R = Rz(yaw) Ry(pitch) Rx(roll); monogram names
(``X_WE`` is the pose of frame E in frame W). See ``docs/`` for the method and formats.

The main entry points are importable from the package itself (loaded on first use, so
``import drake_lfd`` stays cheap): :func:`load_task`, :class:`Library`,
:func:`library_features`, :func:`plan_task` (with :class:`PlanningOptions`; it plans as
``drake-lfd plan`` does), :func:`build_station`,
:func:`build_pipeline`, :class:`ClosedLoopRunner`, :func:`run_trials`. Each sub-package
exports the rest of what users need the same way (``from drake_lfd.systems import
PlannerSystem``); docs/api.rst documents every exported name, and the modules that
define them are internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

__version__ = "0.1.0"

# name -> module that defines it (imported on first access, PEP 562).
_ENTRY_POINTS = {
    "load_task": "drake_lfd.io.task_files",
    "draw_trial": "drake_lfd.core.tasks",
    "Library": "drake_lfd.io.library",
    "library_features": "drake_lfd.io.library",
    "plan_task": "drake_lfd.experiments.planning_api",
    "PlanningOptions": "drake_lfd.planning.options",
    "PlanResult": "drake_lfd.planning.planner",
    "build_station": "drake_lfd.diagrams.station",
    "Station": "drake_lfd.diagrams.station",
    "build_pipeline": "drake_lfd.diagrams.pipeline",
    "Pipeline": "drake_lfd.diagrams.pipeline",
    "PipelineConfig": "drake_lfd.io.simulation_config",
    "ClosedLoopRunner": "drake_lfd.diagrams.closed_loop",
    "run_trials": "drake_lfd.experiments.simulation",
    "judge_run": "drake_lfd.diagrams.judging",
}

__all__ = ["__version__", *_ENTRY_POINTS]
__getattr__, __dir__ = lazy_exports(globals(), _ENTRY_POINTS)
