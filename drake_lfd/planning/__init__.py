"""Layer 3, planning: from a concrete task and a library's features to a composition.

``planner.plan_composition`` is what the planner system (``systems.planner``) runs;
paths below are relative to ``drake_lfd``. By default (``PlanningOptions()``) only
compositions whose joint path passes the check are kept and the plan's joint path is
timed by TOPP-RA; the paper's baseline (``PlanningOptions.paper_baseline()``) prices
actions by Eq. 31 alone, skips the check and times the SE(3) plan with the timing law::

    task + features --Eq. 19-21-->          legal actions  composition, span_index, stretching
    legal actions   --search-->             composition    exact_planner or q_learning
    composition     --joint-path check-->   executable     executable, refusals, robot.joint_path
    composition     --Eq. 22-25, timing-->  PlanResult     planner, robot.path_timing
                                                           (baseline: core.timing)
    PlanResult      --simulation clock-->   ScheduledPlan  replanning

The modules:

* ``options``: ``PlanningOptions``, the planning options with the command line's
  defaults, and ``paper_baseline()``.
* ``planner``: plan a task: compose, map, time (``plan_composition``, ``PlanResult``),
  or a demonstration request.
* ``composition``: which demonstration may cover which span of a task, the legal
  actions of Section 4.
* ``span_index``: a library prepared for the legal-action table, with an exact
  pre-filter.
* ``stretching``: bounded stretching, a mapping whose correction is large against its
  span is illegal.
* ``problem_size``: the size of a planning problem, checked before anything is
  allocated.
* ``exact_planner``: the optimal composition as a shortest path.
* ``executable``: the search that keeps only compositions whose joint path passes.
* ``refusals``: refusals no choice of composition can change, decided first.
* ``mdp``: the composition MDP: states, actions, transitions, rewards, penalties.
* ``q_learning``: Q-learning of a general policy (Algorithm 1) and its greedy walk
  (Algorithm 2).
* ``state_abstraction``: the policy's task-independent key of a planning state.
* ``training``: training a general policy on random tasks, and warm-start retraining.
* ``random_tasks``: the paper's random training tasks and chained test tasks.
* ``gym_env``: the MDP as a Gymnasium environment (optional extra).
* ``refinement``: demonstration-guided trajectory optimization of a composed plan
  (``--refine``): the run, from several starts, and its report.
* ``refinement_options``: the refinement's settings (``RefinementOptions``).
* ``refinement_bounds``: how far the task file lets the refinement move E from the
  composed path, span by span.
* ``refinement_tube``: the composed path at path fractions, deviations from it, and the
  tube around the demonstrations in the program.
* ``refinement_starts``: where the program starts, and the fixed choice among the
  motions that pass.
* ``refinement_check``: the check of a solved motion (sampled, followed, within the
  bounds).
* ``plain_optimizer``: the plain optimizer, the same program without the demonstrations'
  tube (the baseline the refinement is compared with).
* ``replanning``: a plan on the simulation clock (``ScheduledPlan``), and replanning
  when the task changes.

It exports what research code calls to plan (``from drake_lfd.planning import
PlanningOptions``): the options, ``plan_composition`` and its ``PlanResult``, the
composition problem and its exact and Q-learning planners, training a policy, the
paper's random tasks, the refinement and the plain optimizer, and the scheduled plan
(the Gymnasium environment needs the ``gym`` extra, so it stays in ``gym_env``).
``__all__`` lists them and docs/api.rst documents them; each is loaded from its module
on first use, so importing the package loads none of the modules that define them. Its
other modules, and the names the exports leave out, are internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "PlanningOptions": "drake_lfd.planning.options",
    "PlanResult": "drake_lfd.planning.planner",
    "ComposedStep": "drake_lfd.planning.planner",
    "UncoveredSegment": "drake_lfd.planning.planner",
    "plan_composition": "drake_lfd.planning.planner",
    "build_problem": "drake_lfd.planning.planner",
    "CompositionProblem": "drake_lfd.planning.composition",
    "plan_exact": "drake_lfd.planning.exact_planner",
    "QPolicy": "drake_lfd.planning.q_learning",
    "plan_q": "drake_lfd.planning.q_learning",
    "episodes_to_steady": "drake_lfd.planning.q_learning",
    "train_on_random_tasks": "drake_lfd.planning.training",
    "random_training_task": "drake_lfd.planning.random_tasks",
    "chained_task": "drake_lfd.planning.random_tasks",
    "ScheduledPlan": "drake_lfd.planning.replanning",
    "RefinementOptions": "drake_lfd.planning.refinement_options",
    "refine_plan": "drake_lfd.planning.refinement",
    "plain_plan": "drake_lfd.planning.plain_optimizer",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
