"""Layer 7, experiments: trials, their verdicts and the paper's Section 6.

``planning_api`` (``drake_lfd.plan_task``: one trial planned as ``drake-lfd plan`` plans
it), ``simulation`` (trials of a task on one pipeline), ``judging`` (the success criteria),
``rederive`` (independent re-derivation of a run), ``paper`` (Section 6 end to end),
``table5`` (Table 5 comparison), ``figures``.
"""
