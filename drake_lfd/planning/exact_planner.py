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
    """``value[j][a_j]``: least total cost from state (j, a_j) to the last con (inf if none).

    The demonstrations of one span are reduced first (an elementwise minimum of their
    cost matrices): rounding is monotone, so ``min_d (c_d + t + v)`` equals
    ``(min_d c_d) + t + v`` exactly and the values are those of a scan over every action."""
    n = problem.num_cons
    value = [np.full(g, np.inf) for g in problem.num_candidates]
    value[n - 1][:] = 0.0
    by_span: dict[tuple[int, int], list[np.ndarray]] = {}
    for (j, k, _d), matrix in problem.cost.items():
        by_span.setdefault((j, k), []).append(matrix)
    by_start: dict[int, list] = {}
    for (j, k), matrices in by_span.items():
        by_start.setdefault(j, []).append((k, np.minimum.reduce(matrices) if len(matrices) > 1 else matrices[0]))
    for j in range(n - 2, -1, -1):
        for k, matrix in by_start.get(j, []):
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
        k, d, a_k = _best_action(problem.row(j), a, value)
        steps.append(Step(d, j, k, a, a_k, float(problem.cost[(j, k, d)][a, a_k])))
        j, a = k, a_k
    return steps


def _best_action(row: list[tuple[int, int, np.ndarray]], a: int, value: list[np.ndarray]) -> tuple[int, int, int]:
    """``(k, d, a_k)`` of the action from (j, a) that a scan in the order of
    ``actions_from`` keeps: the first, replaced by a later one only when that one is
    lower by more than 1e-12. Only an action below every earlier one can replace the
    kept one (the kept one is within 1e-12 of the earlier minimum), so the scan runs
    over those records alone."""
    costs = [matrix[a] for _, _, matrix in row]
    counts = np.array([len(c) for c in costs])
    starts = np.cumsum(counts) - counts
    which = np.repeat(np.arange(len(row)), counts)
    ends = np.arange(int(counts.sum())) - starts[which]
    to_go = np.concatenate([value[k] for k, _, _ in row])
    totals = np.concatenate(costs) + TIE_BREAK_PER_STEP + to_go
    order = np.flatnonzero(np.isfinite(totals))
    earlier = np.minimum.accumulate(np.concatenate([[np.inf], totals[order][:-1]]))
    best = None
    for index in order[totals[order] < earlier].tolist():
        if best is None or totals[index] < totals[best] - 1e-12:
            best = index
    k, d, _ = row[int(which[best])]
    return k, d, int(ends[best])
