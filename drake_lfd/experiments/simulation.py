"""Closed-loop evaluation trials of a task: plan each concrete trial, run it, judge it.

Trial i (0-based) draws its concrete task with seed ``seed + i``; it is planned as the
:class:`~drake_lfd.planning.options.PlanningOptions` say (by default as ``drake-lfd plan``
plans), simulated closed loop on the UR5e and judged
(:mod:`drake_lfd.diagrams.judging`: critical configurations within 5 mm / 2 deg, path
constraints, no penetration of obstacles or shells, joint position and speed limits).
All trials of a task run on one pipeline Diagram (:class:`TrialRunner`): the task is set
in the Context, the plant is not rebuilt. A trial whose task the library cannot cover,
or whose first configuration the UR5e cannot reach, fails with the reason.

Not for: the command line (``cli/simulate.py``) or the paper's report (``paper.py``).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from pydrake.geometry import Meshcat

from drake_lfd.diagrams.closed_loop import ClosedLoopRunner
from drake_lfd.diagrams.trial_result import ClosedLoopResult
from drake_lfd.io.simulation_config import PipelineConfig
from drake_lfd.diagrams.pipeline import build_pipeline
from drake_lfd.diagrams.recording_meshcat import recording_meshcat
from drake_lfd.diagrams.judging import judge_run
from drake_lfd.core.failures import Failure, failure_labels
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import Feature
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.io.plan_json import composition_json, critical_configurations_json
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.problem_size import check_problem_size
from drake_lfd.io.pose_records import pose_json_from_rigid_transform
from drake_lfd.planning.q_learning import QPolicy
from drake_lfd.core.tasks import Task, draw_trial

__all__ = [
    'TrialOutcome',
    'TrialRunner',
    'run_trial',
    'run_trials',
    'trial_json',
    'trial_record',
    'simulate_json',
    'composition_counts',
    'clearance_over_time',
    'write_trial_figures',
    'trial_summary_line',
    'SUMMARY_REASON_CHARACTERS',
    'shorten_reason',
    'describe_boxes',
    'people_cost',
]


@dataclasses.dataclass
class TrialOutcome:
    trial: int  # 1-based
    seed: int
    plan: PlanResult | None
    run: ClosedLoopResult | None
    success: bool
    failures: list[Failure]  # (core/failures.py: each its line, with its kind)

    @property
    def composition_label(self) -> str | None:
        """``"filling+stacking+screw_ccw"``, or None without a plan."""
        if self.plan is None or not self.plan.planned:
            return None
        return "+".join(step.demo for step in self.plan.composition)


class TrialRunner:
    """Runs the trials of one task on one pipeline Diagram (built once, reused).

    The scene (base, tool, table, obstacles, shells) is the task's and does not change
    between trials; each trial sets its concrete task on the Diagram's ``task`` input.
    A trial to be recorded runs on a second pipeline built with a Meshcat (made on the
    first such request), so the others do not pay for visualisation.

    Parameters
    ----------
    task : Task
    features : Mapping[str, Feature]
        The library's features.
    options : PlanningOptions
        How every trial is planned (default: as ``drake-lfd plan`` plans: exact planner,
        fidelity cost, joint-space check, no refinement).
    policy : QPolicy, optional
        The Q-policy of ``options.planner == "q"``.
    with_table : bool
        Put the table under the robot.
    config : PipelineConfig, optional
        The pipeline's settings (default: the task's ``simulation`` block).
    meshcat : Meshcat, optional
        Show every trial there as it runs.
    controller : str, optional
        The controller method, over the task's (``"compiled"``, ``"drake"``,
        ``"pseudo_inverse"``).
    """

    def __init__(self, task: Task, features: Mapping[str, Feature], *, options: PlanningOptions = PlanningOptions(),
                 policy: QPolicy | None = None, with_table: bool = True, config: PipelineConfig | None = None,
                 meshcat: Meshcat | None = None, controller: str | None = None):
        if not isinstance(options, PlanningOptions):
            raise TypeError(f"options must be PlanningOptions, got {type(options).__name__}")
        # A problem too large is refused before the pipeline is built.
        check_problem_size(task, features, options.max_span, options.cost)
        self.task = task
        config = config if config is not None else task.simulation
        if controller is not None:  # the controller method, over the task's (``simulate --controller``)
            config = dataclasses.replace(config, controller=dataclasses.replace(config.controller, method=controller))
        self.options = options
        self._options = dict(features=features, planning=options, policy=policy, with_table=with_table,
                             config=config)
        self._recording_runner = None
        if meshcat is not None:
            # Live: every trial runs on the pipeline that draws into ``meshcat``.
            self._runner = self._recording_runner = ClosedLoopRunner(
                build_pipeline(task, meshcat=meshcat, **self._options), record_meshcat=meshcat)
        else:
            self._runner = ClosedLoopRunner(build_pipeline(task, **self._options))
        kinematics = self._runner.kinematics
        self._joint_limits = kinematics.position_limits()
        self._velocity_limits = kinematics.velocity_limits()

    @property
    def features(self) -> Mapping[str, Feature]:
        """The library's features the trials are planned with (name -> Feature, read-only)."""
        return self._options["features"]

    def _recorder(self) -> ClosedLoopRunner:
        if self._recording_runner is None:
            meshcat = recording_meshcat()
            self._recording_runner = ClosedLoopRunner(
                build_pipeline(self.task, meshcat=meshcat, **self._options), record_meshcat=meshcat)
        return self._recording_runner

    def run(self, *, trial: int, seed: int, record_html: str | Path | None = None) -> TrialOutcome:
        """Plans, simulates and judges trial ``trial`` (1-based) drawn with ``seed``."""
        concrete = draw_trial(self.task, seed)
        runner = self._runner if record_html is None else self._recorder()
        try:
            scheduled = runner.plan(concrete)
        except InputError as error:  # con_1 unreachable for the UR5e
            plan = runner.pipeline.plan_output_port.Eval(runner.simulator.get_context()).result
            return TrialOutcome(trial, seed, plan, None, False, [Failure("unreachable", str(error))])
        plan = scheduled.result
        if not plan.planned:  # the pipeline's verdict: no executable plan, or a request
            judgement = runner.pipeline.trial_judgement(runner.simulator.get_context())
            return TrialOutcome(trial, seed, plan, None, False, list(judgement.failures))
        scheduled, run = runner.run(concrete, scheduled=scheduled, record_html=record_html)
        # The trial's path constraints travel with the run (``run.path_constraints``).
        judgement = judge_run(run, joint_limits=self._joint_limits, velocity_limits=self._velocity_limits,
                              kinematics=runner.kinematics)
        return TrialOutcome(trial, seed, scheduled.result, run, judgement.success, list(judgement.failures))


def run_trial(
    task: Task,
    features: Mapping[str, Feature],
    *,
    trial: int,
    seed: int,
    options: PlanningOptions = PlanningOptions(),
    policy: QPolicy | None = None,
    record_html: str | Path | None = None,
    with_table: bool = True,
) -> TrialOutcome:
    """Plans (as ``options`` say), simulates and judges one concrete trial of ``task`` (a
    one-off :class:`TrialRunner`; use one runner for many trials)."""
    runner = TrialRunner(task, features, options=options, policy=policy, with_table=with_table)
    return runner.run(trial=trial, seed=seed, record_html=record_html)


def run_trials(
    task: Task,
    features: Mapping[str, Feature],
    *,
    trials: int,
    seed: int = 0,
    options: PlanningOptions = PlanningOptions(),
    policy: QPolicy | None = None,
    record_html: str | Path | None = None,
    progress: Callable[[int, int, TrialOutcome], None] | None = None,
    meshcat: Meshcat | None = None,
    controller: str | None = None,
) -> tuple[list[TrialOutcome], float]:
    """Runs ``trials`` trials (seeds ``seed``, ``seed + 1``, ...) on one pipeline Diagram,
    each planned as ``options`` say (default: as ``drake-lfd plan`` plans;
    :meth:`PlanningOptions.paper_baseline
    <drake_lfd.planning.options.PlanningOptions.paper_baseline>` for the paper's Eq. 31
    without the joint-space check); the first one that plans is recorded to
    ``record_html``; with ``meshcat``, every trial is shown there as it runs;
    ``controller`` overrides the task's controller method (``"compiled"``, ``"drake"``,
    ``"pseudo_inverse"``). Returns the outcomes and the wall time (planning included)."""
    start = time.perf_counter()
    runner = TrialRunner(task, features, options=options, policy=policy, meshcat=meshcat, controller=controller)
    outcomes = []
    recorded = record_html is None
    for i in range(trials):
        outcome = runner.run(trial=i + 1, seed=seed + i, record_html=None if recorded else record_html)
        recorded = recorded or outcome.run is not None
        outcomes.append(outcome)
        if progress:
            progress(i + 1, trials, outcome)
    return outcomes, time.perf_counter() - start


def trial_json(outcome: TrialOutcome) -> dict:
    """One entry of ``trials`` in the ``simulate --json`` document (docs/cli.rst); also
    each line of the JSON-lines file of finished trials (with ``task`` added)."""
    entry = {
        "trial": outcome.trial,
        "seed": outcome.seed,
        "success": outcome.success,
        "failures": outcome.failures,
        "failure_kinds": failure_labels(outcome.failures),
        "status": outcome.plan.status if outcome.plan else None,
        "critical_configurations": critical_configurations_json(outcome.plan) if outcome.plan else [],
        "composition": composition_json(outcome.plan) if outcome.plan else [],
    }
    if outcome.plan is not None and outcome.plan.refinement is not None:
        entry["refinement"] = outcome.plan.refinement.to_json()
    if outcome.run is not None:
        entry.update(outcome.run.trial_fields())
        entry["min_distance_pair"] = outcome.run.min_distance_pair
        entry["critical_times_s"] = [float(e.time_s) for e in outcome.run.critical_errors]
    else:
        entry.update({"critical_errors": [], "min_shell_distance_m": None,
                      "max_joint_speed_fraction": None, "t": [], "q": []})
    return entry


def trial_record(task: Task, outcome: TrialOutcome) -> dict:
    """The JSON-lines record of one finished trial: ``{"task": NAME, **trial_json}``."""
    return {"task": task.name, **trial_json(outcome)}


def simulate_json(task: Task, outcomes: list[TrialOutcome], wall_time_s: float) -> dict:
    """The ``simulate --json`` document (docs/cli.rst). Extra per-trial fields:
    ``status`` (the plan's), ``min_distance_pair`` and ``critical_times_s`` (when each
    critical configuration was due, so the verdict can be re-derived from ``t``/``q``)."""
    trials = [trial_json(outcome) for outcome in outcomes]
    sim_time = float(sum(o.run.sim_time_s for o in outcomes if o.run is not None))
    return {
        "task": task.name,
        "X_WB": pose_json_from_rigid_transform(task.X_WB),
        "X_tool0_E": pose_json_from_rigid_transform(task.X_tool0_E),
        "trials_requested": len(outcomes),
        "success_count": sum(o.success for o in outcomes),
        "wall_time_s": float(wall_time_s),
        "sim_time_s": sim_time,
        "trials": trials,
    }


def composition_counts(outcomes: list[TrialOutcome]) -> dict[str, int]:
    """How often each composition was used, e.g. ``{"filling+stacking+screw_ccw": 20}``."""
    counts: dict[str, int] = {}
    for outcome in outcomes:
        label = outcome.composition_label
        if label:
            counts[label] = counts.get(label, 0) + 1
    return dict(sorted(counts.items(), key=lambda item: -item[1]))


def clearance_over_time(task: Task, run: ClosedLoopResult, stride: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Least signed distance of the robot and its tool to the task's obstacles and shells along a run,
    re-queried from the logged joints every ``stride`` samples: times (k,), metres (k,)."""
    from drake_lfd.robot.scene import KinematicScene
    from drake_lfd.robot.workcell import Workcell

    scene = KinematicScene(Workcell.of(task))
    t = run.t[::stride]
    return t, np.array([scene.signed_distances(q).min() for q in run.q[::stride]])


def write_trial_figures(task: Task, outcome: TrialOutcome, out: Path, prefix: str) -> dict[str, str]:
    """The SE(3) plan with triads, the joint trajectories with limits, with people in the
    cell the separation, ``S_p`` and the speed override over time and, when the task has
    obstacles or shells, the distance to them over time; returns {kind: file name}."""
    from drake_lfd.experiments.figures import (
        joint_trajectories_figure, plan_figure, separation_figure, shell_distance_figure,
    )

    figures = {}
    concrete = outcome.plan.task
    figures["plan"] = plan_figure(
        out / f"{prefix}_plan.png", outcome.plan.timed.poses, outcome.plan.timed.critical_indices,
        obstacles=concrete.obstacles, safety_shells=concrete.safety_shells,
        title=f"{prefix}: SE(3) plan, trial {outcome.trial}").name
    kinematics = UR5eKinematics(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E)
    lower, upper = kinematics.position_limits()
    figures["joints"] = joint_trajectories_figure(
        out / f"{prefix}_joints.png", outcome.run.t, outcome.run.q, lower=lower, upper=upper,
        velocity_limit=kinematics.velocity_limits(), title=f"{prefix}: joints, trial {outcome.trial}").name
    record = getattr(outcome.run, "collaboration", None)
    if record is not None:
        figures["separation"] = separation_figure(
            out / f"{prefix}_separation.png", record.separation_t, record.distance_m, record.protective_distance_m,
            record.t, record.override, people=record.people,
            title=f"{prefix}: separation from people and speed override, trial {outcome.trial}").name
    if task.obstacles or task.safety_shells:
        t, distance = clearance_over_time(task, outcome.run)
        figures["distance"] = shell_distance_figure(
            out / f"{prefix}_distance.png", t, distance,
            title=f"{prefix}: distance to obstacles and shells, trial {outcome.trial}").name
    return figures


#: Longest failure reason :func:`trial_summary_line` prints in full (the JSON keeps every
#: reason whole): the judge's reasons (a penetration with its depth and time, about 110
#: characters) fit; longer ones (an unreachable con_1, a demonstration request) are cut.
SUMMARY_REASON_CHARACTERS = 120


def shorten_reason(reason: str, limit: int = SUMMARY_REASON_CHARACTERS) -> str:
    """``reason`` cut to at most ``limit`` characters, ending in ``...`` when cut."""
    reason = " ".join(str(reason).split())
    return reason if len(reason) <= limit else reason[:limit - 3].rstrip() + "..."


def _count(number: int, noun: str) -> str:
    return f"{number} {noun}" + ("" if number == 1 else "s")


def describe_boxes(task: Task | None) -> str:
    """``"1 obstacle, 1 shell"``, or ``"no obstacles"`` for a task without boxes."""
    if task is None or not (task.obstacles or task.safety_shells):
        return "no obstacles"
    parts = []
    if task.obstacles:
        parts.append(_count(len(task.obstacles), "obstacle"))
    if task.safety_shells:
        parts.append(_count(len(task.safety_shells), "shell"))
    return ", ".join(parts)


def trial_summary_line(outcome: TrialOutcome, task: Task | None = None) -> str:
    """One console line per trial: composition (with ``--refine``, ``refined`` or why it
    was not), closest approach to the boxes, with people in the cell what they cost
    (:func:`people_cost`), and the verdict with every failure reason (each cut to
    :data:`SUMMARY_REASON_CHARACTERS`).

    ``task`` (or, without it, the trial's planned task) says which obstacles and shells
    the scene has, so a trial that did not run reads ``no run (1 obstacle, 1 shell)``.
    """
    if outcome.success:
        verdict = "success"
    else:
        verdict = "FAILED: " + ("; ".join(shorten_reason(f) for f in outcome.failures) or "no reason given")
    composition = outcome.composition_label or "no plan"
    scene_task = task if task is not None else (outcome.plan.task if outcome.plan is not None else None)
    if outcome.run is None:
        clearance = f"no run ({describe_boxes(scene_task)})"
    else:
        distance = outcome.run.min_shell_distance_m
        clearance = f"min distance {distance * 100:.1f} cm" if np.isfinite(distance) else describe_boxes(scene_task)
    refinement = getattr(outcome.plan, "refinement", None) if outcome.plan is not None else None
    if refinement is not None:  # planned with --refine: whether it took, or why not
        composition += "; refined" if refinement.refined else f"; not refined: {shorten_reason(refinement.reason)}"
    record = getattr(outcome.run, "collaboration", None)
    if record is not None:
        clearance += "; " + people_cost(record)
    return f"trial {outcome.trial} (seed {outcome.seed}): {composition}; {clearance}; {verdict}"


def people_cost(record) -> str:
    """``people cost 4.9 s (slowed 5.6 s, 1 protective stop, closest 0.54 m)``: what
    the people in the cell cost a run (a
    :class:`~drake_lfd.diagrams.collaboration_result.CollaborationRecord`)."""
    return (f"people cost {record.time_lost_s:.1f} s (slowed {record.time_scaled_s:.1f} s, "
            f"{_count(record.protective_stops, 'protective stop')}, closest {record.min_separation_m:.2f} m)")
