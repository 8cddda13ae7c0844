"""Layer 6, Diagrams: the systems wired with the UR5e MultibodyPlant.

The default closed loop (``drake-lfd simulate``), one line per arrow, with the module
that makes the arrow's output (paths below ``drake_lfd``); ``Pipeline`` wires it in
``pipeline``, one ``Connect`` per arrow::

    library         --FeatureLibrarySystem-->       features       systems.feature_library
    features + task --PlannerSystem-->              ScheduledPlan  systems.planner
      (plan_composition, joint-path check, TOPP-RA:  planning.planner, robot.joint_path,
                                                     robot.path_timing, robot.toppra)
    plan            --JointPathSource-->            chunk          systems.joint_path_source
    chunk           --JointTrajectoryController-->  q_command      systems.joint_trajectory_controller
    q_command       --Station-->                    q_measured     diagrams.station
    joint log       --ShellMonitor-->               clearances     systems.shell_monitor
    plan            --TrialEnd-->                   end of run     systems.trial_end
    Context         --Pipeline.trial_result-->      the run        diagrams.trial_result
    the run         --judge_run-->                  verdict        diagrams.judging

The paper's baseline beside it (``PlanningOptions.paper_baseline()``: Eq. 31's cost, no
joint check; controller ``drake`` or ``pseudo_inverse``)::

    features + task --PlannerSystem, timing law-->  ScheduledPlan  systems.planner, core.timing
    plan            --PlanTrajectorySource-->       X_WE, V_WE     systems.plan_trajectory_source
    X_WE, V_WE      --DifferentialIKController-->   q_command      systems.differential_ik
    q_command       --Station-->                    q_measured     diagrams.station

The modules:

* ``station``: ``Station`` (made by ``build_station``),
  the UR5e work cell, owning its plants.
* ``pipeline``: ``Pipeline`` and ``build_pipeline``, the whole pipeline as one Diagram,
  and the trial set-up (``TrialStart``, ``joint_path_checker``).
* ``trial_result``: ``ClosedLoopResult`` and ``CriticalError``, what a run did, read off
  its Context.
* ``judging``: ``judge_run`` and ``RunJudgement``, the success criteria.
* ``collaboration_result``: ``CollaborationRecord``, what people in the cell did to a run
  (separation, protective separation distance, speed override), read off its Context.
* ``override_indicator``: the speed override in Meshcat recordings, a traffic light above
  the robot's base.
* ``closed_loop``: ``ClosedLoopRunner`` and ``run_closed_loop``, trials run in turn on
  one pipeline, with Meshcat recordings and task changes;
  ``plan_through_joint_configurations``.
* ``kinesthetic``: simulated kinesthetic demonstrations (a virtual hand guides a
  free-driven UR5e).
* ``model_preview``: a Meshcat HTML animation of the arm (``drake-lfd show-model``).
* ``plan_markers``: the planned tool path and a triad per critical configuration, in
  Meshcat.
* ``recording_meshcat``: a Meshcat for recordings only, made without announcing a viewer.

It exports the station, the pipeline, closed-loop runs, their results and judging,
reading a run off a Context, kinesthetic recording and the model preview (``from
drake_lfd.diagrams import Pipeline``): ``__all__`` lists them and docs/api.rst documents
them. Each is loaded from its module on first use (PEP 562), so a module that needs only
``kinesthetic`` (``drake-lfd record``, and every start of the command line) does not
load the pipeline and the closed loop. Its other modules, and the names the exports
leave out, are internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "Station": "drake_lfd.diagrams.station",
    "build_station": "drake_lfd.diagrams.station",
    "Pipeline": "drake_lfd.diagrams.pipeline",
    "build_pipeline": "drake_lfd.diagrams.pipeline",
    "TrialStart": "drake_lfd.diagrams.pipeline",
    "joint_path_checker": "drake_lfd.diagrams.pipeline",
    "ClosedLoopRunner": "drake_lfd.diagrams.closed_loop",
    "run_closed_loop": "drake_lfd.diagrams.closed_loop",
    "plan_through_joint_configurations": "drake_lfd.diagrams.closed_loop",
    "ClosedLoopResult": "drake_lfd.diagrams.trial_result",
    "CriticalError": "drake_lfd.diagrams.trial_result",
    "read_trial": "drake_lfd.diagrams.trial_result",
    "judge_run": "drake_lfd.diagrams.judging",
    "RunJudgement": "drake_lfd.diagrams.judging",
    "record_demonstration": "drake_lfd.diagrams.kinesthetic",
    "write_configurations_html": "drake_lfd.diagrams.model_preview",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
