"""Which demonstration may cover which span of a task: the legal actions of Section 4.

A task is a chain of critical configurations con_0 .. con_(n-1) (0-based here; 1-based
in files and JSON). Each has candidate orientations: one when its Euler angles are
fixed, a grid when some are bounded (the planner's freedoms). A *state* is
``(j, a_j)``: con_j reached with candidate ``a_j``. An *action* from it is
``(demo d, span end k > j, candidate a_k)``; it is legal when the segment
con_j .. con_k is semantically similar to demo d (Definition 1) for some choice of the
intermediate cons' candidates, and its reward is minus the least total alpha (Eq. 31),
or, in the ``"fidelity"`` cost mode, minus the least total of alpha plus the shape-fidelity
terms of ``core/fidelity.py`` (docs/method.rst, "Shape fidelity"). See docs/method.rst,
"Planning".

:class:`CompositionProblem` computes every legal action of a task at once, as dense
cost matrices ``cost[(j, k, d)]`` of shape ``(g_j, g_k)`` (``inf`` = illegal), so an
episode or a planner never recomputes a similarity test. It runs the similarity kernel
of ``core/similarity.py`` batched, never a copy of it:

* every task delta ``D_l* (x) D_k`` (Eq. 18) depends only on ``(l, a_l, k, a_k)``, so
  for each end k all of them are formed in one broadcast and go through
  ``fidelity.action_pair_costs`` (``similarity``'s test plus the cost mode's fidelity
  terms) against every demo delta of the library in one call;
* in a span, an intermediate con l's candidate affects only row l of the allocation,
  so the best choice is a per-demo-delta minimum over a_l, and
  ``similarity.allocation_step`` runs the order-preserving allocation for all
  ``(a_j, a_k)`` pairs together.

:meth:`CompositionProblem.span_allocation` recovers, for one chosen action, the
intermediate candidates and the allocation that the mapping needs (same kernel, same
dynamic programme, ``similarity.allocation_backtrack``).

Not for: the MDP built on these actions (``mdp.py``), choosing among actions
(``exact_planner.py``, ``q_learning.py``) or mapping (``core/mapping.py``).
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from drake_lfd.core.dual_quaternion import dual_quaternion_relative, translation_from_dual_quaternion
from drake_lfd.core.features import Feature
from drake_lfd.core.fidelity import FidelityWeights, action_pair_costs, check_cost_mode, feature_excursions
from drake_lfd.core.similarity import (
    Allocation,
    Tolerances,
    allocation_backtrack,
    allocation_step,
    allocation_table,
    rotation_distance,
)

__all__ = ["SUFFIX_SEPARATION", "Step", "SpanAllocation", "CompositionProblem"]

# Alternative suffixes of one span (:meth:`CompositionProblem.suffix_candidates`) start at
# least this many resampled samples apart (a tenth of a 100-sample demonstration).
SUFFIX_SEPARATION = 10


@dataclasses.dataclass(frozen=True)
class Step:
    """One action taken: demo ``demo`` covers con_j .. con_k with candidates a_j, a_k."""

    demo: int
    j: int
    k: int
    a_j: int
    a_k: int
    cost: float


@dataclasses.dataclass(frozen=True)
class SpanAllocation:
    """What the mapping needs for one step.

    Attributes
    ----------
    candidates : tuple of int, length k - j + 1, the candidate of each con j..k.
    allocation : similarity.Allocation (indices into the demo's resampled poses).
    """

    candidates: tuple[int, ...]
    allocation: Allocation


class CompositionProblem:
    """All legal actions of one concrete task against one library.

    Parameters
    ----------
    candidate_poses : sequence of arrays, each shape (g_j, 8)
        Unit dual quaternions X_WE of each critical configuration's candidates.
    demo_features : sequence of features.Feature
        The library's features, in a fixed order (index d).
    tolerances : similarity.Tolerances
    max_span : int or None
        Longest span k - j an action may cover (None: the whole task).
    cost : {"paper", "fidelity"}
        The action cost: Eq. 31's total alpha (fidelity only breaks its ties), or alpha
        plus the shape-fidelity terms (``core/fidelity.py``).
    fidelity_weights : fidelity.FidelityWeights
    """

    def __init__(
        self,
        candidate_poses: Sequence[np.ndarray],
        demo_features: Sequence[Feature],
        tolerances: Tolerances = Tolerances(),
        max_span: int | None = None,
        cost: str = "paper",
        fidelity_weights: FidelityWeights = FidelityWeights(),
    ):
        self.cost_mode = check_cost_mode(cost)
        self.fidelity_weights = fidelity_weights
        self.candidate_poses = [np.atleast_2d(np.asarray(c, dtype=float)) for c in candidate_poses]
        if len(self.candidate_poses) < 2:
            raise ValueError("a task needs at least 2 critical configurations")
        self.num_cons = len(self.candidate_poses)
        self.num_candidates = [len(c) for c in self.candidate_poses]
        self.demo_features = list(demo_features)
        self.num_demos = len(self.demo_features)
        self.tolerances = tolerances
        self.max_span = self.num_cons - 1 if max_span is None else int(max_span)
        self._offsets = np.cumsum([0] + [len(f) for f in self.demo_features])
        self._stacked_demo = self._stack_demos()
        self._excursions = [feature_excursions(f, tolerances.min_translation_m) for f in self.demo_features]
        self._stacked_excursions = np.concatenate(self._excursions) if self.num_demos else np.zeros(0)
        self.cost = self._legal_action_costs()

    # -- building the legal-action table -------------------------------------------------
    def _stack_demos(self) -> tuple[np.ndarray, np.ndarray]:
        """All demo deltas stacked: rotations (N, 4), translations (N, 3)."""
        if self.num_demos == 0:
            return np.zeros((0, 4)), np.zeros((0, 3))
        return (np.concatenate([f.rotations for f in self.demo_features]),
                np.concatenate([f.translations for f in self.demo_features]))

    def _pair_costs(self, rotations, translations, demo_rotations, demo_translations, demo_excursions,
                    tie_break):
        """``fidelity.action_pair_costs`` in this problem's cost mode: (pair, first).
        ``tie_break``: for choosing an allocation (in the paper mode, the action costs
        are Eq. 31's alpha alone)."""
        return action_pair_costs(rotations, translations, demo_rotations, demo_translations, demo_excursions,
                                 self.tolerances, self.cost_mode, self.fidelity_weights, tie_break)

    def _delta_cost_rows(self, k: int) -> tuple[list[np.ndarray | None], list[np.ndarray | None]]:
        """For end k: ``rows[l]`` (g_l, g_k, N), the pair cost (``fidelity.action_pair_costs``)
        of delta(l, a_l; k, a_k) with every stacked demo delta, and ``firsts[l]`` what a
        pair adds as an allocation's first; None for l outside ``max_span``. Every delta
        ending at k goes through the kernel in one call."""
        D_k = self.candidate_poses[k]
        g_k = len(D_k)
        first = max(0, k - self.max_span)
        sources = [self.candidate_poses[l] for l in range(first, k)]
        delta = dual_quaternion_relative(np.concatenate(sources)[:, None, :], D_k[None, :, :]).reshape(-1, 8)
        cost, first_cost = self._pair_costs(delta[:, :4], translation_from_dual_quaternion(delta),
                                            *self._stacked_demo, self._stacked_excursions, tie_break=False)
        rows: list[np.ndarray | None] = [None] * first
        firsts: list[np.ndarray | None] = [None] * first
        offset = 0
        for source in sources:
            count = len(source) * g_k
            rows.append(cost[offset : offset + count].reshape(len(source), g_k, -1))
            firsts.append(first_cost[offset : offset + count].reshape(len(source), g_k, -1))
            offset += count
        return rows, firsts

    def _legal_action_costs(self) -> dict[tuple[int, int, int], np.ndarray]:
        cost = {}
        for k in range(1, self.num_cons):
            rows, firsts = self._delta_cost_rows(k)
            # An intermediate con's candidate affects only its own row of the allocation:
            # reduce each intermediate row over its candidates, (g_k, N).
            reduced = [None if r is None else r.min(axis=0) for r in rows]
            for j in range(max(0, k - self.max_span), k):
                for d in range(self.num_demos):
                    lo, hi = self._offsets[d], self._offsets[d + 1]
                    current = rows[j][:, :, lo:hi] + firsts[j][:, :, lo:hi]  # (g_j, g_k, n_d)
                    for l in range(j + 1, k):
                        current = allocation_step(current, reduced[l][None, :, lo:hi])
                    total = current.min(axis=-1) if current.shape[-1] else np.full(current.shape[:2], np.inf)
                    if np.isfinite(total).any():
                        cost[(j, k, d)] = total
        return cost

    # -- queries -------------------------------------------------------------------------
    def actions_from(self, j: int, a_j: int) -> list[Step]:
        """Legal actions from state (j, a_j), in a deterministic order."""
        steps = []
        for (jj, k, d), matrix in self.cost.items():
            if jj != j:
                continue
            for a_k in np.flatnonzero(np.isfinite(matrix[a_j])):
                steps.append(Step(d, j, k, a_j, int(a_k), float(matrix[a_j, a_k])))
        return steps

    def forbid(self, step: Step) -> None:
        """Makes ``step`` (its demo, span and candidates) illegal, for example because its
        joint path is not executable; both planners then choose among the others."""
        key = (step.j, step.k, step.demo)
        if key not in self.cost:
            return
        matrix = self.cost[key].copy()
        matrix[step.a_j, step.a_k] = np.inf
        if np.isfinite(matrix).any():
            self.cost[key] = matrix
        else:
            del self.cost[key]

    def forbid_state(self, j: int, a_j: int) -> None:
        """Makes every action from state (j, a_j) illegal (for example: no joint
        configuration reaches that candidate of con_(j+1))."""
        for key in [key for key in self.cost if key[0] == j]:
            matrix = self.cost[key].copy()
            matrix[a_j, :] = np.inf
            if np.isfinite(matrix).any():
                self.cost[key] = matrix
            else:
                del self.cost[key]

    def covered_gaps(self) -> np.ndarray:
        """``covered[g]`` is True when some legal action spans the gap con_g -> con_(g+1)."""
        covered = np.zeros(self.num_cons - 1, dtype=bool)
        for (j, k, _d) in self.cost:
            covered[j:k] = True
        return covered

    def span_rows(self, step: Step) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The allocation's pair-cost rows of ``step`` (the first with its first-pair
        terms, each intermediate con reduced over its candidates) and, per row, which
        candidate won each demo sample."""
        feature = self.demo_features[step.demo]
        D_k = self.candidate_poses[step.k][step.a_k]
        rows, winners = [], []
        for l in range(step.j, step.k):
            options = np.array([step.a_j]) if l == step.j else np.arange(self.num_candidates[l])
            delta = dual_quaternion_relative(self.candidate_poses[l][options], D_k)
            cost, first_cost = self._pair_costs(delta[:, :4], translation_from_dual_quaternion(delta),
                                                feature.rotations, feature.translations,
                                                self._excursions[step.demo], tie_break=True)  # (options, n_d)
            if l == step.j:
                cost += first_cost
            rows.append(cost.min(axis=0))
            winners.append(options[np.argmin(cost, axis=0)])  # ties: the first candidate
        return rows, winners

    def suffix_candidates(self, step: Step, limit: int) -> list[int]:
        """Up to ``limit`` demo samples the span may start from (which suffix of the
        demonstration covers it), best first: by the least total cost of an allocation
        starting there (rounded to 1e-9, so noise cannot order equal ones), then by
        sample, each at least ``SUFFIX_SEPARATION`` samples from those before it (a
        neighbouring sample maps to nearly the same path, so it is no alternative). The
        first is the allocation :meth:`span_allocation` picks."""
        rows, _ = self.span_rows(step)
        totals = []
        for first in np.flatnonzero(np.isfinite(rows[0])).tolist():
            masked = [np.where(np.arange(len(rows[0])) == first, rows[0], np.inf)] + rows[1:]
            total = float(allocation_table(np.array(masked))[-1].min())
            if np.isfinite(total):
                totals.append((round(total, 9), first))
        totals.sort()
        chosen: list[int] = []
        for _, first in totals:
            if len(chosen) == limit:
                break
            if all(abs(first - other) >= SUFFIX_SEPARATION for other in chosen):
                chosen.append(first)
        return chosen

    def span_allocation(self, step: Step, first_index: int | None = None) -> SpanAllocation:
        """Intermediate candidates and the exact allocation for one legal ``step``.

        The same kernel and dynamic programme as the legal-action table, for one
        ``(a_j, a_k)``: each intermediate row is reduced over its con's candidates
        (keeping which candidate won), then the allocation is backtracked. With
        ``first_index``, the allocation starts at that demo sample (another suffix of
        the demonstration, :meth:`suffix_candidates`).
        """
        feature = self.demo_features[step.demo]
        D_k = self.candidate_poses[step.k][step.a_k]
        rows, winners = self.span_rows(step)
        if first_index is not None:
            rows = [np.where(np.arange(len(rows[0])) == first_index, rows[0], np.inf)] + rows[1:]
        indices = allocation_backtrack(allocation_table(np.array(rows)))
        if indices is None:
            raise ValueError(f"step {step} is not a legal action")
        p = len(rows)
        candidates = tuple(int(winners[l][indices[l]]) for l in range(p)) + (step.a_k,)
        task_rotations = dual_quaternion_relative(
            np.array([self.candidate_poses[step.j + l][candidates[l]] for l in range(p)]), D_k)[:, :4]
        alphas = rotation_distance(task_rotations, feature.rotations[indices])
        indices.flags.writeable = False
        alphas.flags.writeable = False
        return SpanAllocation(candidates, Allocation(indices=indices, cost=float(alphas.sum()), alphas=alphas))
