"""Planning one concrete task end to end, as ``drake-lfd plan`` does: :func:`plan_task`.

The public ``drake_lfd.plan_task``. It takes the library in any form (features by name,
an opened :class:`~drake_lfd.io.library.Library`, a library folder or a bundled name
such as ``"paper5"``), builds the task's work cell and, when the options ask for it, the
plan-time joint-space check the pipeline's controller will be held to, plans with
:func:`drake_lfd.planning.planner.plan_composition` and refines the plan when asked. The
command line calls this very function, so a script and ``drake-lfd plan TASK --library
LIB --seed S`` give the same plan.

It lives in ``experiments`` because it reads libraries (``io``) and builds the
pipeline's checker (``diagrams``); the planning itself is in ``planning``.

Not for: closed-loop trials (:mod:`drake_lfd.experiments.simulation`) or printing a plan
(``cli/plan.py``).
"""

from __future__ import annotations

from collections.abc import Mapping
from os import PathLike

import numpy as np

from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import ConcreteTask
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.io.library import Library
from drake_lfd.io.library_source import resolve_features
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import PlanResult, plan_composition
from drake_lfd.planning.q_learning import QPolicy
from drake_lfd.robot.workcell import Workcell

__all__ = ["plan_task"]


def plan_task(
    task: ConcreteTask,
    library: Mapping[str, Feature] | Library | str | PathLike,
    options: PlanningOptions | None = None,
    *,
    policy: QPolicy | None = None,
    seed: int | None = None,
    floor_z: float | None = None,
    checker=None,
    clearance_points_E: np.ndarray | None = None,
) -> PlanResult:
    """Plans one concrete trial of a task with a library, as ``drake-lfd plan`` does.

    Parameters
    ----------
    task : ConcreteTask
        The trial (:func:`~drake_lfd.core.tasks.draw_trial`).
    library : Mapping[str, Feature] or Library or str or PathLike
        The demonstrations: features by name, an opened library, a library folder or a
        bundled library name (``"paper5"``, ``"paper6"``).
    options : PlanningOptions, optional
        How to plan (default: :class:`~drake_lfd.planning.options.PlanningOptions`'s,
        those of ``drake-lfd plan``: exact planner, fidelity cost, joint-space check, no
        refinement; :meth:`PlanningOptions.paper_baseline
        <drake_lfd.planning.options.PlanningOptions.paper_baseline>` for the paper's).
    policy : QPolicy, optional
        The Q-policy of ``options.planner == "q"``.
    seed : int, optional
        Seeds the Q-planner's refinement (default: the trial's own ``seed``, else 0; the
        command line passes its ``--seed``, which drew the trial).
    floor_z : float, optional
        The table top the tool path keeps above (default: the work cell's
        ``planner_floor``, the table under the robot).
    checker : JointPathChecker, optional
        The plan-time joint-space check (default, with ``options.joint_check``: the one
        the pipeline's controller is held to,
        :func:`~drake_lfd.diagrams.pipeline.joint_path_checker` of the task's work cell
        and simulation settings; ignored without ``options.joint_check``).
    clearance_points_E : ndarray, optional
        (k, 3) points fixed in E that must stay clear (default: the tool's).

    Returns
    -------
    PlanResult
        The plan (refined when ``options.refine``; a refinement that fails leaves the
        plan with the reason), a demonstration request, or ``no_executable_plan``.
    """
    options = PlanningOptions() if options is None else options
    if not isinstance(options, PlanningOptions):
        raise TypeError(f"options must be PlanningOptions, got {type(options).__name__}")
    features = resolve_features(library, task)
    workcell = Workcell.of(task)
    if not options.joint_check:
        checker = None
    elif checker is None:
        checker = joint_path_checker(workcell, task.simulation)
    if seed is None:
        seed = 0 if task.seed is None else int(task.seed)
    result = plan_composition(
        task, features, options, policy=policy, seed=seed,
        floor_z=workcell.planner_floor if floor_z is None else floor_z, checker=checker,
        clearance_points_E=clearance_points_E,
    )
    if options.refine and result.planned:
        from drake_lfd.planning.refinement import refine_plan

        result = refine_plan(result, checker)
    return result
