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
"""
