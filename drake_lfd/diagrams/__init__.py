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

The names above are importable from this package (``from drake_lfd.diagrams import
Pipeline``). They are loaded on first use (PEP 562), so a module that needs only
``kinesthetic`` (``drake-lfd record``, and every start of the command line) does not
load the pipeline and the closed loop.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drake_lfd.diagrams.closed_loop import (
        ClosedLoopRunner,
        plan_through_joint_configurations,
        run_closed_loop,
    )
    from drake_lfd.diagrams.judging import RunJudgement, judge_run
    from drake_lfd.diagrams.pipeline import Pipeline, TrialStart, build_pipeline, joint_path_checker
    from drake_lfd.diagrams.station import Station, build_station
    from drake_lfd.diagrams.trial_result import ClosedLoopResult, CriticalError

# name -> module of this package that defines it (imported on first access).
_EXPORTS = {
    "Station": "station",
    "build_station": "station",
    "Pipeline": "pipeline",
    "build_pipeline": "pipeline",
    "TrialStart": "pipeline",
    "joint_path_checker": "pipeline",
    "ClosedLoopRunner": "closed_loop",
    "run_closed_loop": "closed_loop",
    "plan_through_joint_configurations": "closed_loop",
    "ClosedLoopResult": "trial_result",
    "CriticalError": "trial_result",
    "judge_run": "judging",
    "RunJudgement": "judging",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    # Literal imports (tests/test_layers.py checks every import's layer by its name).
    from drake_lfd.diagrams import closed_loop, judging, pipeline, station, trial_result

    modules = {"station": station, "pipeline": pipeline, "closed_loop": closed_loop,
               "trial_result": trial_result, "judging": judging}
    value = getattr(modules[_EXPORTS[name]], name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
