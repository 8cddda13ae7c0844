"""The composition MDP of Section 4 (SPEC 7): which demonstration may cover which span.

A task is a chain of critical configurations con_0 .. con_(n-1) (0-based here; 1-based
in files and JSON). Each has candidate orientations: one when its Euler angles are
fixed, a grid when some are bounded (the planner's freedoms). A *state* is
``(j, a_j)``: con_j reached with candidate ``a_j``. An *action* from it is
``(demo d, span end k > j, candidate a_k)``; it is legal when the segment
con_j .. con_k is semantically similar to demo d (Definition 1) for some choice of the
intermediate cons' candidates, and its reward is minus the least total alpha (Eq. 31).

:class:`CompositionProblem` computes every legal action of a task at once, as dense
cost matrices ``cost[(j, k, d)]`` of shape ``(g_j, g_k)`` (``inf`` = illegal), so an
episode or a planner never recomputes a similarity test. The work is vectorised:

* every task delta ``D_l* (x) D_k`` (Eq. 18) depends only on ``(l, a_l, k, a_k)``, so
  for each end k all of them are formed in one broadcast, and compared with all demo
  samples at once (alpha through one matrix product, SPEC 5's beta rule);
* in a span, an intermediate con l's candidate affects only row l of the allocation,
  so the best choice is a per-demo-sample minimum over a_l, and the order-preserving
  allocation (a prefix-minimum dynamic programme, as in ``similarity.allocate``) runs
  for all ``(a_j, a_k)`` pairs together.

:meth:`CompositionProblem.span_allocation` recovers, for one chosen action, the
intermediate candidates and the allocation that the mapping needs.

Not for: choosing among actions (``exact_planner.py``, ``q_learning.py``) or mapping.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from drake_lfd.core.dual_quaternion import (
    dual_quaternion_canonical,
    dual_quaternion_relative,
    translation_from_dual_quaternion,
)
from drake_lfd.core.features import Feature
from drake_lfd.core.similarity import Allocation, Tolerances, rotation_distance


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
    """

    def __init__(
        self,
        candidate_poses: Sequence[np.ndarray],
        demo_features: Sequence[Feature],
        tolerances: Tolerances = Tolerances(),
        max_span: int | None = None,
    ):
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
        self.cost = self._legal_action_costs()

    # -- building the legal-action table -------------------------------------------------
    def _stack_demos(self):
        """All demo samples stacked: rotations (N, 4), unit translations (N, 3), short mask."""
        if self.num_demos == 0:
            return np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0, dtype=bool)
        rotations = np.concatenate([f.rotations for f in self.demo_features])
        translations = np.concatenate([f.translations for f in self.demo_features])
        length = np.linalg.norm(translations, axis=1, keepdims=True)
        short = length[:, 0] < self.tolerances.min_translation_m
        return rotations, translations / np.where(short[:, None], 1.0, length), short

    def _delta_cost_rows(self, k: int) -> list[np.ndarray | None]:
        """For end k: ``rows[l]`` (g_l, g_k, N) cost of pairing delta(l, a_l; k, a_k)
        with every stacked demo sample (alpha, or inf when not similar); None for l
        outside ``max_span``. All deltas ending at k are tested in one pass: two matrix
        products (rotations, translation directions) and elementwise tests."""
        tol = self.tolerances
        demo_rotations, demo_units, demo_short = self._stacked_demo
        # alpha <= d_alpha  <=>  |r_task . r_demo| >= 1 - d_alpha^2 / 2 (unit quaternions).
        min_dot = 1.0 - 0.5 * tol.d_alpha**2
        D_k = self.candidate_poses[k]
        g_k = len(D_k)
        first = max(0, k - self.max_span)
        sources = [self.candidate_poses[l] for l in range(first, k)]
        delta = dual_quaternion_relative(np.concatenate(sources)[:, None, :], D_k[None, :, :]).reshape(-1, 8)
        translation = translation_from_dual_quaternion(delta)
        task_length = np.linalg.norm(translation, axis=-1)
        task_short = task_length < tol.min_translation_m
        task_units = translation / np.where(task_short, 1.0, task_length)[:, None]

        dots = np.abs(delta[:, :4] @ demo_rotations.T)
        similar = dots >= min_dot
        similar &= task_units @ demo_units.T >= tol.d_beta
        if task_short.any() or demo_short.any():
            # SPEC 5: both short -> beta 1; exactly one short -> beta -1.
            both = task_short[:, None] & demo_short
            either = task_short[:, None] | demo_short
            beta_ok = np.where(both, 1.0, -1.0) >= tol.d_beta
            similar = np.where(either, beta_ok & (dots >= min_dot), similar)
        # alpha = sqrt(2 - 2 |dot|), in place; inf where not similar.
        cost = np.sqrt(np.maximum(2.0 - 2.0 * dots, 0.0, out=dots), out=dots)
        cost[~similar] = np.inf

        rows: list[np.ndarray | None] = [None] * first
        offset = 0
        for source in sources:
            count = len(source) * g_k
            rows.append(cost[offset : offset + count].reshape(len(source), g_k, -1))
            offset += count
        return rows

    def _legal_action_costs(self) -> dict[tuple[int, int, int], np.ndarray]:
        cost = {}
        for k in range(1, self.num_cons):
            rows = self._delta_cost_rows(k)
            # Intermediate rows, reduced over their own candidates: (g_k, N).
            reduced = [None if r is None else r.min(axis=0) for r in rows]
            for j in range(max(0, k - self.max_span), k):
                for d in range(self.num_demos):
                    lo, hi = self._offsets[d], self._offsets[d + 1]
                    current = rows[j][:, :, lo:hi]  # (g_j, g_k, n_d)
                    for l in range(j + 1, k):
                        best_before = np.minimum.accumulate(current, axis=-1)
                        shifted = np.full_like(current, np.inf)
                        shifted[..., 1:] = best_before[..., :-1] + reduced[l][None, :, lo + 1 : hi]
                        current = shifted
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

    def covered_gaps(self) -> np.ndarray:
        """``covered[g]`` is True when some legal action spans the gap con_g -> con_(g+1)."""
        covered = np.zeros(self.num_cons - 1, dtype=bool)
        for (j, k, _d) in self.cost:
            covered[j:k] = True
        return covered

    def span_allocation(self, step: Step) -> SpanAllocation:
        """Intermediate candidates and the exact allocation for one legal ``step``."""
        feature = self.demo_features[step.demo]
        tol = self.tolerances
        D_k = self.candidate_poses[step.k][step.a_k]
        chosen_rows = []
        chosen_candidates = []
        for l in range(step.j, step.k):
            options = [step.a_j] if l == step.j else range(self.num_candidates[l])
            best_row, best_arg = None, None
            for a_l in options:
                delta = dual_quaternion_canonical(
                    dual_quaternion_relative(self.candidate_poses[l][a_l], D_k)
                )
                row = _similarity_cost_row(delta, feature, tol)
                if best_row is None:
                    best_row, best_arg = row, np.full(row.shape, a_l)
                else:
                    better = row < best_row
                    best_row = np.where(better, row, best_row)
                    best_arg = np.where(better, a_l, best_arg)
            chosen_rows.append(best_row)
            chosen_candidates.append(best_arg)
        table = np.array(chosen_rows)
        p, n = table.shape
        for l in range(1, p):
            best_before = np.minimum.accumulate(table[l - 1])
            table[l, 0] = np.inf
            table[l, 1:] += best_before[:-1]
        indices = np.empty(p, dtype=int)
        indices[-1] = int(np.argmin(table[-1]))
        if not np.isfinite(table[-1, indices[-1]]):
            raise ValueError(f"step {step} is not a legal action")
        for l in range(p - 2, -1, -1):
            indices[l] = int(np.argmin(table[l, : indices[l + 1]]))
        candidates = tuple(int(chosen_candidates[l][indices[l]]) for l in range(p)) + (step.a_k,)
        task_rotations = np.array(
            [
                dual_quaternion_canonical(
                    dual_quaternion_relative(self.candidate_poses[step.j + l][candidates[l]], D_k)
                )[:4]
                for l in range(p)
            ]
        )
        alphas = rotation_distance(task_rotations, feature.rotations[indices])
        return SpanAllocation(candidates, Allocation(indices=indices, cost=float(alphas.sum()), alphas=alphas))


def _similarity_cost_row(delta: np.ndarray, feature: Feature, tol: Tolerances) -> np.ndarray:
    """alpha of one task delta against every demo delta, inf where not similar."""
    alpha = rotation_distance(delta[None, :4], feature.rotations)
    t = translation_from_dual_quaternion(delta)
    length = np.linalg.norm(t)
    demo_length = np.linalg.norm(feature.translations, axis=1)
    short, demo_short = length < tol.min_translation_m, demo_length < tol.min_translation_m
    cosine = feature.translations @ t / np.where(short | demo_short, 1.0, length * demo_length)
    beta = np.where(short & demo_short, 1.0, np.where(short | demo_short, -1.0, cosine))
    return np.where((alpha <= tol.d_alpha) & (beta >= tol.d_beta), alpha, np.inf)
