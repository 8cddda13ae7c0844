"""Layer 7, experiments: trials, their verdicts and the paper's Section 6.

Trials run on the default pipeline (``drake_lfd.diagrams.pipeline``) unless their
``PlanningOptions`` and controller ask for the paper's baseline; their verdicts come
from ``drake_lfd.diagrams.judging``.

The modules:

* ``planning_api``: ``drake_lfd.plan_task``, one trial planned as ``drake-lfd plan``
  plans it.
* ``simulation``: closed-loop trials of a task on one pipeline: plan, run, judge.
* ``parallel_trials``: trials on worker processes or a cluster (dask.distributed).
* ``sweep``: trials at every robot base placement of a grid (``drake-lfd sweep``).
* ``rederive``: a run's verdict re-derived from its logged joint trajectory alone.
* ``paper``: the paper's Section 6 end to end, with a report.
* ``table5``: the paper's Table 5 beside the bundled demonstrations' features.
* ``figures``: figures on request (training curves, plans, joint trajectories,
  distances).
* ``fidelity_tasks``: tasks cut from library demonstrations, and whether a plan
  recovers them.
* ``pick_and_place``: random pick-and-place workcell tasks, as task files.
* ``notebooks``: what the tutorials need to run both as scripts and as notebooks.

It exports the trials and experiments users run from Python (``from
drake_lfd.experiments import plan_task``): ``plan_task``, closed-loop trials and their
summaries, the paper's Section 6, figures, the re-derivation of a verdict and
pick-and-place task files. ``__all__`` lists them and docs/api.rst documents them; each
is loaded from its module on first use, so importing the package loads none of the
modules that define them. Its other modules, and the names the exports leave out, are
internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "plan_task": "drake_lfd.experiments.planning_api",
    "run_trials": "drake_lfd.experiments.simulation",
    "TrialRunner": "drake_lfd.experiments.simulation",
    "TrialOutcome": "drake_lfd.experiments.simulation",
    "simulate_json": "drake_lfd.experiments.simulation",
    "trial_summary_line": "drake_lfd.experiments.simulation",
    "composition_counts": "drake_lfd.experiments.simulation",
    "run_paper": "drake_lfd.experiments.paper",
    "plan_figure": "drake_lfd.experiments.figures",
    "joint_trajectories_figure": "drake_lfd.experiments.figures",
    "training_curve_figure": "drake_lfd.experiments.figures",
    "rederive_run": "drake_lfd.experiments.rederive",
    "write_pick_and_place_tasks": "drake_lfd.experiments.pick_and_place",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
