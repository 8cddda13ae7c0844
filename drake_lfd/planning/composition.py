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

:class:`CompositionProblem` computes the legal actions of a task as dense cost matrices
``cost[(j, k, d)]`` of shape ``(g_j, g_k)`` (``inf`` = illegal), each once, so an
episode or a planner never recomputes a similarity test; a row (every action from
con_j) is built when it is first asked for (:meth:`CompositionProblem.actions_from`,
:meth:`CompositionProblem.row`), the whole table when :attr:`CompositionProblem.cost`
is read. It runs the similarity kernel of ``core/similarity.py`` batched, never a copy
of it (docs/method.rst, "Cost of planning"):

* every task delta ``D_l* (x) D_k`` (Eq. 18) depends only on ``(l, a_l, k, a_k)``; for
  each end k the rows l = k-1, k-2, ... are swept backwards, each row's deltas going
  through ``fidelity.action_pair_costs`` (``similarity``'s test plus the cost mode's
  fidelity terms) against every demo delta of the demonstrations still in the sweep,
  vectorized over chunks of the library's padded stacks (``span_index.PreparedLibrary``,
  :data:`_PAIRS_PER_CHUNK` pair costs at a time, so the temporaries stay in the cache
  and bounded whatever the library's size);
* in a span, an intermediate con l's candidate affects only row l of the allocation,
  so the best choice is a per-demo-delta minimum over a_l; the order-preserving
  allocation (Definition 1) runs backwards as suffix minima, so one sweep per end
  serves the spans from every start;
* before a row runs, ``span_index.SpanIndex`` discards the demonstrations that provably
  cannot pass it, and a demonstration with no allocation of a row's deltas leaves the
  sweep: neither changes a verdict or a cost.

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
from drake_lfd.core.fidelity import FidelityWeights, action_pair_costs, check_cost_mode
from drake_lfd.core.similarity import (
    Allocation,
    Tolerances,
    allocation_backtrack,
    allocation_step,
    allocation_table,
    rotation_distance,
)
from drake_lfd.planning.span_index import prepared_library

__all__ = ["SUFFIX_SEPARATION", "Step", "SpanAllocation", "TableStats", "CompositionProblem"]

# Alternative suffixes of one span (:meth:`CompositionProblem.suffix_candidates`) start at
# least this many resampled samples apart (a tenth of a 100-sample demonstration).
SUFFIX_SEPARATION = 10
# Pair costs of one row computed at once (a chunk of the library's demonstrations): bounds
# the kernel's temporaries and keeps them in the processor's cache (chunks of 2^14-2^16
# pair costs are about twice as fast as 2^17 and more: bench_library_scale.py).
_PAIRS_PER_CHUNK = 1 << 15


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


@dataclasses.dataclass
class TableStats:
    """What building the table cost, in (demonstration, span) pairs.

    Attributes
    ----------
    pairs : int
        Pairs of the spans built so far (demonstrations times spans).
    dropped_earlier : int
        Pairs never considered: a shorter span of the same end already had no allocation
        for the demonstration, or the index discarded it there.
    discarded_by_index : int
        Pairs the index (or the length bound ``p <= n_d``) discarded.
    tested : int
        Pairs that went through the exact similarity test.
    """

    pairs: int = 0
    dropped_earlier: int = 0
    discarded_by_index: int = 0
    tested: int = 0


class _EndSweep:
    """The state of span end k's backward sweep: built down to start ``low``; ``demos``
    (s,) those still in the sweep, ``suffix`` (g_k, s, n_max) the least cost of
    allocating deltas ``low..k-1`` after each demo index (None before the first row)."""

    def __init__(self, k: int, demos: np.ndarray):
        self.k, self.low, self.demos = k, k, demos
        self.suffix: np.ndarray | None = None

    def finish(self, first_start: int) -> None:
        """Nothing more to build: no demonstration is left, or the span limit is reached."""
        self.low, self.demos, self.suffix = first_start, self.demos[:0], None


def _keys_by_start(table: dict, num_cons: int) -> list[list[tuple[int, int]] | None]:
    """``keys[j]``: the (k, d) of the table's entries starting at j, sorted (every row
    built: no None, the type of ``CompositionProblem._row_keys``)."""
    keys: list[list[tuple[int, int]]] = [[] for _ in range(num_cons)]
    for j, k, d in table:
        keys[j].append((k, d))
    return [sorted(row) for row in keys]


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
        use_index: bool = True,
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
        self.use_index = bool(use_index)
        self.library = prepared_library(self.demo_features, tolerances)
        self.stats = TableStats()
        self._cost: dict[tuple[int, int, int], np.ndarray] = {}
        self._complete = False
        self._row_keys: list[list[tuple[int, int]] | None] = [None] * self.num_cons
        self._row_keys[-1] = []
        self._built: list[list[tuple[int, int]]] = [[] for _ in range(self.num_cons)]  # (k, d) found per start
        self._sweeps = {k: _EndSweep(k, np.arange(self.num_demos)) for k in range(1, self.num_cons)}

    # -- building the legal-action table -------------------------------------------------
    @property
    def cost(self) -> dict[tuple[int, int, int], np.ndarray]:
        """Every legal action: ``cost[(j, k, d)]`` (g_j, g_k), inf where illegal, in the
        order of span end k, then start j, then demo d. Reading it builds the rows not
        built yet (:meth:`actions_from` builds only the row it needs)."""
        if not self._complete:
            for k in range(1, self.num_cons):
                self._extend(k, self._first_start(k))
            self._cost = dict(sorted(self._cost.items(), key=lambda item: (item[0][1], item[0][0], item[0][2])))
            self._row_keys = _keys_by_start(self._cost, self.num_cons)
            self._complete = True
        return self._cost

    @cost.setter
    def cost(self, table: dict[tuple[int, int, int], np.ndarray]) -> None:
        """Replaces the whole table (for example a copy to forbid actions in)."""
        self._cost = table
        self._complete = True
        self._row_keys = _keys_by_start(table, self.num_cons)

    def _first_start(self, k: int) -> int:
        return max(0, k - self.max_span)

    def _row(self, j: int) -> list[tuple[int, int]]:
        """The (span end, demo) keys of row j, in order, building the row if needed: each
        span end k within ``max_span`` is swept down to j."""
        keys = self._row_keys[j]
        if keys is None:
            for k in range(j + 1, min(self.num_cons - 1, j + self.max_span) + 1):
                self._extend(k, j)
            keys = self._row_keys[j] = sorted(self._built[j])
        return keys

    def _pair_costs(self, rotations, translations, demo_rotations, demo_translations, demo_excursions,
                    tie_break, demo_terms=None):
        """``fidelity.action_pair_costs`` in this problem's cost mode: (pair, first).
        ``tie_break``: for choosing an allocation (in the paper mode, the action costs
        are Eq. 31's alpha alone); ``demo_terms``: the demo deltas' prepared terms."""
        return action_pair_costs(rotations, translations, demo_rotations, demo_translations, demo_excursions,
                                 self.tolerances, self.cost_mode, self.fidelity_weights, tie_break, demo_terms)

    def _extend(self, k: int, j: int) -> None:
        """Sweeps span end k down to start j (see :meth:`_sweep_step`)."""
        sweep = self._sweeps[k]
        while sweep.low > max(j, self._first_start(k)):
            self._sweep_step(sweep)

    def _index_keeps(self, sweep: _EndSweep, rotations: np.ndarray, translations: np.ndarray, p: int) -> np.ndarray:
        """Which of the sweep's demonstrations may pass a span of ``p`` deltas whose first
        task deltas are ``rotations`` / ``translations`` (one per candidate pair): long
        enough (``p <= n_d``) and, with ``use_index``, admitted by the index."""
        keep = self.library.lengths[sweep.demos] >= p
        if self.use_index and len(sweep.demos):
            short = np.linalg.norm(translations, axis=-1) < self.tolerances.min_translation_m
            keep &= np.asarray(self.library.index.candidates(rotations, short).any(axis=0))[sweep.demos]
        self.stats.pairs += self.num_demos
        self.stats.dropped_earlier += self.num_demos - len(sweep.demos)
        self.stats.discarded_by_index += len(sweep.demos) - int(keep.sum())
        return keep

    def _sweep_step(self, sweep: _EndSweep) -> None:
        """Row l = ``sweep.low - 1`` of span end k: the spans (l, k) of every demonstration
        that may pass, and the suffix minima the longer spans (j < l, k) start from.

        The allocation of deltas l..k-1 runs backwards: ``B_l[i] = row_l[i] + min_(i' > i)
        B_(l+1)[i']`` with each intermediate row reduced over its con's candidates (they
        affect only their own row), and the span (l, k) costs ``min_i (row_l + first_l)[i]
        + min_(i' > i) B_(l+1)[i']`` for each (a_l, a_k): Definition 1's order-preserving
        allocation, the same minimum as ``similarity.allocation_step`` run forwards, one
        row per span end instead of one per span. A demonstration stays in the sweep while
        some allocation of deltas l..k-1 exists and the index admits it for task delta l."""
        k, l = sweep.k, sweep.low - 1
        sweep.low = l
        g_l, g_k = self.num_candidates[l], self.num_candidates[k]
        delta = dual_quaternion_relative(self.candidate_poses[l][:, None, :],
                                         self.candidate_poses[k][None, :, :]).reshape(-1, 8)
        rotations, translations = delta[:, :4], translation_from_dual_quaternion(delta)
        kept = np.flatnonzero(self._index_keeps(sweep, rotations, translations, k - l))
        demos = sweep.demos[kept]
        if len(demos) == 0:
            sweep.finish(self._first_start(k))
            return
        self.stats.tested += len(demos)
        last = l == self._first_start(k)
        n_max = self.library.rotations.shape[1]
        step = max(1, _PAIRS_PER_CHUNK // (g_l * g_k * max(n_max, 1)))
        totals, afters, alive = [], [], []
        every = len(kept) == len(sweep.demos)  # the index kept the whole sweep: slices, no copies
        for start in range(0, len(demos), step):
            part = slice(start, start + step)
            suffix = None if sweep.suffix is None else sweep.suffix[:, part if every else kept[part]]
            chunk_total, chunk_after = self._row_chunk(rotations, translations, demos[part], suffix, g_l, g_k, last)
            totals.append(chunk_total)
            if chunk_after is not None:
                keep = np.isfinite(chunk_after).any(axis=(0, 2))  # some allocation of deltas l..k-1 exists
                afters.append(chunk_after if keep.all() else chunk_after[:, keep])
                alive.append(demos[part][keep])
        total = totals[0] if len(totals) == 1 else np.concatenate(totals, axis=-1)  # (g_l, g_k, s)
        legal = np.flatnonzero(np.isfinite(total).any(axis=(0, 1)))
        if len(legal):
            matrices = np.moveaxis(total[:, :, legal], -1, 0).copy()  # each (g_l, g_k) contiguous
            matrices.flags.writeable = False  # shared by the row's entries: forbidding replaces one
            found = demos[legal].tolist()
            self._cost.update(zip([(l, k, d) for d in found], matrices))
            self._built[l].extend([(k, d) for d in found])
        if last:
            sweep.finish(l)
            return
        sweep.demos = alive[0] if len(alive) == 1 else np.concatenate(alive)
        sweep.suffix = afters[0] if len(afters) == 1 else np.concatenate(afters, axis=1)
        if len(sweep.demos) == 0:
            sweep.finish(self._first_start(k))

    def _row_chunk(self, rotations, translations, demos, suffix, g_l, g_k, last):
        """Row l of one span end for the demonstrations ``demos`` (c,): the spans' costs
        (g_l, g_k, c) and, unless ``last``, the suffix minima ``after`` (g_k, c, n_max)
        for the longer spans; ``suffix`` (g_k, c, n_max) those of row l + 1 (None on the
        first row). Every operation is per demonstration, so chunks of the library give
        the same numbers as the whole."""
        lib = self.library
        n_max = lib.rotations.shape[1]
        # The sweep's demonstrations are in order: a run of consecutive ones is a slice (views, no copies).
        rows = slice(int(demos[0]), int(demos[-1]) + 1) if demos[-1] - demos[0] == len(demos) - 1 else demos
        demo_q = lib.rotations[rows].reshape(-1, 4)
        demo_t = lib.translations[rows].reshape(-1, 3)
        demo_h = lib.excursions(demos).reshape(-1) if self.cost_mode == "fidelity" else np.zeros(len(demo_q))
        pair, first = self._pair_costs(rotations, translations, demo_q, demo_t, demo_h, False, lib.terms.take(rows))
        pair = pair.reshape(g_l, g_k, len(demos), n_max)
        if lib.padded:
            pair[..., ~lib.valid[rows]] = np.inf
        head = pair + first.reshape(pair.shape)
        if suffix is not None:
            head += suffix[None]
        total = head.min(axis=-1)  # (g_l, g_k, c)
        if last:
            return total, None
        reduced = pair.min(axis=0)  # (g_k, c, n): intermediate con l, its best candidate per delta
        if suffix is not None:
            reduced += suffix
        after = np.full(reduced.shape, np.inf)  # after[..., i] = min over i' > i
        if n_max > 1:
            after[..., :-1] = np.minimum.accumulate(reduced[..., :0:-1], axis=-1)[..., ::-1]
        return total, after

    # -- queries -------------------------------------------------------------------------
    def row(self, j: int) -> list[tuple[int, int, np.ndarray]]:
        """Row j of the table: ``(k, d, cost[(j, k, d)])`` in the order of span end k, then
        demo d (only the legal ones). Builds only that row."""
        return [(k, d, self._cost[(j, k, d)]) for k, d in self._row(j) if (j, k, d) in self._cost]

    def actions_from(self, j: int, a_j: int) -> list[Step]:
        """Legal actions from state (j, a_j), in a deterministic order (span end k, then
        demo d, then con_k's candidate). Builds only row j of the table."""
        steps = []
        for k, d in self._row(j):
            matrix = self._cost.get((j, k, d))
            if matrix is None:  # forbidden
                continue
            for a_k in np.flatnonzero(np.isfinite(matrix[a_j])):
                steps.append(Step(d, j, k, a_j, int(a_k), float(matrix[a_j, a_k])))
        return steps

    def forbid(self, step: Step) -> None:
        """Makes ``step`` (its demo, span and candidates) illegal, for example because its
        joint path is not executable; both planners then choose among the others."""
        key = (step.j, step.k, step.demo)
        self._row(step.j)
        if key not in self._cost:
            return
        matrix = self._cost[key].copy()
        matrix[step.a_j, step.a_k] = np.inf
        if np.isfinite(matrix).any():
            self._cost[key] = matrix
        else:
            del self._cost[key]

    def forbid_state(self, j: int, a_j: int) -> None:
        """Makes every action from state (j, a_j) illegal (for example: no joint
        configuration reaches that candidate of con_(j+1))."""
        for key in [(j, k, d) for k, d in self._row(j) if (j, k, d) in self._cost]:
            matrix = self._cost[key].copy()
            matrix[a_j, :] = np.inf
            if np.isfinite(matrix).any():
                self._cost[key] = matrix
            else:
                del self._cost[key]

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
        excursions = self.library.excursions(np.array([step.demo]))[0, :len(feature)]
        rows, winners = [], []
        for l in range(step.j, step.k):
            options = np.array([step.a_j]) if l == step.j else np.arange(self.num_candidates[l])
            delta = dual_quaternion_relative(self.candidate_poses[l][options], D_k)
            cost, first_cost = self._pair_costs(delta[:, :4], translation_from_dual_quaternion(delta),
                                                feature.rotations, feature.translations,
                                                excursions, tie_break=True)  # (options, n_d)
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
