"""The exact planner: the optimal composition as a shortest path (beyond the paper).

Rewards are deterministic and additive, so the least-cost composition is a shortest path
over states ``(j, a_j)`` of a :class:`~drake_lfd.planning.composition.CompositionProblem`, solved
exactly by backward dynamic programming (the graph is a DAG: spans only move forward).
Ties are broken towards fewer demonstrations (a cost of ``TIE_BREAK_PER_STEP`` per step,
far below any alpha that matters), then towards the earlier (demo, span, candidate).

It is both a user option (``--planner exact``, docs/cli.rst) and the oracle for the
Q-policy (docs/method.rst, "Planning").

Not for: learning (``q_learning.py``) or the MDP's episodes (``mdp.py``); it reads the
legal-action table of ``composition.py`` directly.
"""

from __future__ import annotations

import numpy as np

from drake_lfd.planning.composition import CompositionProblem, Step

__all__ = ["TIE_BREAK_PER_STEP", "cost_to_go", "plan_exact"]

TIE_BREAK_PER_STEP = 1e-6


def cost_to_go(problem: CompositionProblem) -> list[np.ndarray]:
    """``value[j][a_j]``: least total cost from state (j, a_j) to the last con (inf if none)."""
    n = problem.num_cons
    value = [np.full(g, np.inf) for g in problem.num_candidates]
    value[n - 1][:] = 0.0
    by_start: dict[int, list] = {}
    for (j, k, d), matrix in problem.cost.items():
        by_start.setdefault(j, []).append((k, d, matrix))
    for j in range(n - 2, -1, -1):
        for k, _d, matrix in by_start.get(j, []):
            through = (matrix + TIE_BREAK_PER_STEP + value[k][None, :]).min(axis=1)
            value[j] = np.minimum(value[j], through)
    return value


def plan_exact(problem: CompositionProblem) -> list[Step] | None:
    """The optimal composition as a list of steps, or None when the task is not covered."""
    value = cost_to_go(problem)
    a = int(np.argmin(value[0]))
    if not np.isfinite(value[0][a]):
        return None
    steps = []
    j = 0
    while j < problem.num_cons - 1:
        best = None
        for step in problem.actions_from(j, a):
            total = step.cost + TIE_BREAK_PER_STEP + value[step.k][step.a_k]
            if best is None or total < best[0] - 1e-12:
                best = (total, step)
        steps.append(best[1])
        j, a = best[1].k, best[1].a_k
    return steps
