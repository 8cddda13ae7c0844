"""The size of a planning problem, checked before anything is allocated.

A task's bounded angles give each critical configuration ``g_j`` angle candidates
(:func:`~drake_lfd.core.tasks.angle_candidates`: the product over its bounded angles of
the grid counts). :class:`~drake_lfd.planning.composition.CompositionProblem` then
compares, for each span end k, every candidate pair ``(l, a_l; k, a_k)`` of the span
window with every demonstration delta of the library (``N``, about 99 per
demonstration), one row ``(l, k)`` at a time: ``g_l * g_k * N`` pair costs in a batch,
with the kernel's temporaries about :data:`BYTES_PER_PAIR_COST` bytes each. Memory
therefore grows with the square of the candidates: a 0.5 deg grid on the paper's
filling-and-pouring task would need gigabytes. The counts are upper bounds: the index
of ``span_index.py`` and the sweep's pruning skip most pairs of a large library.

:func:`check_problem_size` counts all of this from the task's bounds alone (Python
integers, nothing allocated) and refuses, with one
:class:`~drake_lfd.core.errors.InputError` naming the task file, the field and the limit,
a problem over any of the limits below. The planners call it first
(``planner.build_problem``, ``planner.plan_task``; ``experiments/simulation.py`` before
it builds the pipeline), so a problem that is accepted stays under about 0.6 GB for
planning and plans within seconds. docs/task_files.rst documents the limits for users.

Not for: building the problem (``composition.py``) or the candidates themselves
(``core/tasks.py``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping, Sequence, Sized

from drake_lfd.core.errors import InputError
from drake_lfd.core.tasks import DEFAULT_ANGLE_GRID_DEG, angle_grid_count

__all__ = [
    "MAX_CANDIDATES_PER_CONFIGURATION",
    "MAX_PLANNING_BYTES",
    "MAX_PLANNING_WORK",
    "ALLOCATION_STEPS_PER_PAIR_COST",
    "BYTES_PER_PAIR_COST",
    "BYTES_PER_PAIR_COST_FIDELITY",
    "SUGGESTED_GRIDS_DEG",
    "ProblemSize",
    "candidate_counts",
    "estimate_problem_size",
    "check_problem_size",
]

#: Most angle candidates one critical configuration may have (the product of its bounded
#: angles' grid counts; ``[-pi, pi]`` at 15 deg is 25, two such angles 625).
MAX_CANDIDATES_PER_CONFIGURATION = 2000
#: Most memory the legal-action table may need while it is built (the largest span
#: end's batch of pair costs plus the cost matrices kept).
MAX_PLANNING_BYTES = 512 * 2**20
#: Most work over the whole problem, in pair costs: the kernel's pair costs plus the
#: allocation's steps (each intermediate con of a span runs one step over every pair
#: cost of the span's ends) divided by :data:`ALLOCATION_STEPS_PER_PAIR_COST`. Planning
#: time is proportional to it, so this bounds the time a plan may take to seconds on one
#: core (``benchmarks/bench_library_scale.py``; figures in benchmarks/RESULTS.md).
MAX_PLANNING_WORK = 400_000_000
#: Allocation steps that take as long as one pair cost (timed against each other).
ALLOCATION_STEPS_PER_PAIR_COST = 4
#: Bytes per pair cost while one span end is computed: alpha and beta (float64) and two
#: boolean masks and the allocation's work arrays (measured: 10.7 GiB peak for 5.2e8 pair costs).
BYTES_PER_PAIR_COST = 22
#: The same in the ``"fidelity"`` cost mode, which keeps each pair's first-pair terms and
#: the fidelity terms' temporaries beside alpha and beta (measured: 1.66 GB against
#: 0.70 GB peak for the same problem, baseline included).
BYTES_PER_PAIR_COST_FIDELITY = 66
#: Bytes per (end candidate, demo delta) an open sweep of the table keeps: its suffix
#: minima and the reduced row beside them (float64 each).
_BYTES_PER_SWEEP_ENTRY = 16
#: Bytes per candidate pair for its relative pose and the intermediate broadcast.
_BYTES_PER_CANDIDATE_PAIR = 200
#: Grids :func:`check_problem_size` tries when it suggests a coarser ``angle_grid_deg``.
SUGGESTED_GRIDS_DEG = (1, 1.5, 2, 2.5, 3, 4, 5, 6, 7.5, 9, 10, 12, 15, 18, 20, 22.5, 30, 45, 60, 90, 180)


@dataclasses.dataclass(frozen=True)
class ProblemSize:
    """What a composition problem will hold.

    Attributes
    ----------
    candidates : tuple of int
        Angle candidates of each critical configuration.
    candidate_pairs : int
        ``(l, a_l; k, a_k)`` pairs over every span end k and every l in its window.
    pair_costs : int
        Pair costs over the whole problem (``candidate_pairs`` times the demo deltas).
    work : int
        ``pair_costs`` plus the allocation's steps in pair-cost equivalents
        (:data:`MAX_PLANNING_WORK`).
    peak_bytes : int
        Estimated memory while the largest row (one start l, one end k) is computed,
        with every span end's sweep open.
    worst_end : int
        The span end with the most candidate pairs (0-based con index).
    """

    candidates: tuple[int, ...]
    candidate_pairs: int
    pair_costs: int
    work: int
    peak_bytes: int
    worst_end: int


def _grid_of(task, con) -> float:
    grid: float | None = getattr(con, "angle_grid_deg", None)
    if grid is None:
        grid = getattr(task, "angle_grid_deg", DEFAULT_ANGLE_GRID_DEG)
    return float(grid)


def _axis_counts(con, grid_deg: float) -> list[int]:
    step = math.radians(grid_deg)
    return [angle_grid_count(lo, hi, step) for lo, hi in zip(con.euler_zyx_lower, con.euler_zyx_upper)]


def candidate_counts(task, grid_deg: float | None = None) -> tuple[int, ...]:
    """Angle candidates of each critical configuration of ``task`` (a
    :class:`~drake_lfd.core.tasks.Task` or a :class:`~drake_lfd.core.tasks.ConcreteTask`),
    on ``grid_deg`` (default: the task's grid), counted without making them."""
    counts = []
    for con in task.critical_configurations:
        counts.append(math.prod(_axis_counts(con, _grid_of(task, con) if grid_deg is None else grid_deg)))
    return tuple(counts)


def estimate_problem_size(candidates: Sequence[int], demo_deltas: int, num_demos: int,
                          max_span: int | None = None, cost: str = "paper") -> ProblemSize:
    """The :class:`ProblemSize` of a composition problem with these candidate counts,
    ``demo_deltas`` deltas over ``num_demos`` demonstrations, spans of at most
    ``max_span`` (None: the whole task) and the cost mode ``cost``."""
    candidates = tuple(int(c) for c in candidates)
    n = len(candidates)
    span = max(n - 1, 1) if max_span is None else max(int(max_span), 1)
    pairs = 0
    steps = 0  # allocation steps, in candidate pairs: one reduction and suffix minimum per row
    peak_pairs, worst_window, worst_end, open_ends = 0, 0, 1, 0
    for k in range(1, n):
        first = max(0, k - span)
        window_pairs = sum(candidates[first:k]) * candidates[k]
        pairs += window_pairs
        steps += (k - first) * candidates[k]
        open_ends += candidates[k]
        row_pairs = max(candidates[first:k]) * candidates[k]  # the batch of one row (l, k)
        peak_pairs = max(peak_pairs, row_pairs)
        if window_pairs > worst_window:
            worst_window, worst_end = window_pairs, k
    demo_deltas = max(int(demo_deltas), 1)
    per_pair = BYTES_PER_PAIR_COST_FIDELITY if cost == "fidelity" else BYTES_PER_PAIR_COST
    # The largest row's batch, every open sweep's suffix minima (rows built on demand may
    # leave every span end open) and the cost matrices kept.
    peak_bytes = (peak_pairs * (demo_deltas * per_pair + _BYTES_PER_CANDIDATE_PAIR)
                  + open_ends * demo_deltas * _BYTES_PER_SWEEP_ENTRY
                  + pairs * max(int(num_demos), 1) * 8)
    work = (pairs + steps // ALLOCATION_STEPS_PER_PAIR_COST) * demo_deltas
    return ProblemSize(candidates, pairs, pairs * demo_deltas, work, peak_bytes, worst_end)


def _huge_text(number: int) -> str:
    """``1.2e+345`` for an int too large for a float (or for ``str``)."""
    exponent = int(math.log10(number))
    return f"{number / 10**exponent:.2g}e+{exponent}"


def _size_text(size_bytes: int) -> str:
    if size_bytes >= 2**30 * 10**12:
        return f"{_huge_text(size_bytes // 2**30)} GiB"
    if size_bytes >= 2**30:
        return f"{size_bytes / 2**30:.1f} GiB"
    return f"{size_bytes / 2**20:.0f} MiB"


def _count_text(count: int) -> str:
    return f"{count:,}" if count < 10**12 else _huge_text(count)


def _fits(size: ProblemSize) -> bool:
    return size.peak_bytes <= MAX_PLANNING_BYTES and size.work <= MAX_PLANNING_WORK


def _suggested_grid(task, grid_deg, demo_deltas, num_demos, max_span, cost) -> float | None:
    for grid in SUGGESTED_GRIDS_DEG:
        if grid <= grid_deg:
            continue
        counts = candidate_counts(task, grid)
        if max(counts) <= MAX_CANDIDATES_PER_CONFIGURATION and _fits(
                estimate_problem_size(counts, demo_deltas, num_demos, max_span, cost)):
            return grid
    return None


def _grid_advice(task, grid_deg, demo_deltas, num_demos, max_span, cost) -> str:
    suggestion = _suggested_grid(task, grid_deg, demo_deltas, num_demos, max_span, cost)
    if suggestion is None:
        return "bound fewer angles, narrow their bounds or split the task"
    return f"use angle_grid_deg: {suggestion:g} or coarser, or bound fewer angles"


def check_problem_size(task, features: Mapping[str, Sized] | Sequence[Sized],
                       max_span: int | None = None, cost: str = "paper") -> ProblemSize:
    """Refuses a planning problem too large to build, before anything is allocated.

    Parameters
    ----------
    task : Task or ConcreteTask
        Only its critical configurations' angle bounds and grid are read.
    features : mapping name -> Feature, or sequence of Feature
        The library's features (their delta counts; ``len(feature)``).
    max_span : int or None
        Longest span an action may cover (None: the whole task).
    cost : {"paper", "fidelity"}
        The cost mode (fidelity needs about three times the memory per pair cost).

    Returns
    -------
    ProblemSize

    Raises
    ------
    InputError
        Naming the task file and the field: ``critical_configurations[i].euler_zyx`` when
        one configuration has more than :data:`MAX_CANDIDATES_PER_CONFIGURATION`
        candidates, ``angle_grid_deg`` when the whole problem needs more than
        :data:`MAX_PLANNING_BYTES` or :data:`MAX_PLANNING_WORK`; the message gives the
        count, the limit and what to change.
    """
    values = list(features.values()) if isinstance(features, Mapping) else list(features)
    demo_deltas = sum(len(feature) for feature in values)
    num_demos = len(values)
    file = getattr(task, "file", None)
    cons = task.critical_configurations
    for index, con in enumerate(cons):
        grid = _grid_of(task, con)
        axes = _axis_counts(con, grid)
        count = math.prod(axes)
        if count <= MAX_CANDIDATES_PER_CONFIGURATION:
            continue
        field = f"critical_configurations[{index}].euler_zyx"
        widest = max(range(3), key=lambda axis: axes[axis])
        if axes[widest] > MAX_CANDIDATES_PER_CONFIGURATION:
            field += f"[{widest}]"
        turns = [float(hi) - float(lo) for lo, hi in zip(con.euler_zyx_lower, con.euler_zyx_upper)]
        if max(turns) > 2 * math.pi + 1e-9:
            advice = "narrow the bounds: a full turn, [-pi, pi], covers every orientation"
        else:
            advice = _grid_advice(task, grid, demo_deltas, num_demos, max_span, cost)
        raise InputError(
            f"con_{index + 1}: its bounded angles give {_count_text(count)} angle candidates on the "
            f"{grid:g} deg grid, more than the limit of {MAX_CANDIDATES_PER_CONFIGURATION:,} per "
            f"configuration; {advice}",
            file=file, field=field,
        )
    counts = candidate_counts(task)
    size = estimate_problem_size(counts, demo_deltas, num_demos, max_span, cost)
    if _fits(size):
        return size
    grid = _grid_of(task, cons[0])
    many = [f"con_{i + 1}" for i, c in enumerate(counts) if c > 1]
    which = (f"{', '.join(many)} {'has' if len(many) == 1 else 'have'}" if len(many) <= 4
             else f"{len(many)} configurations have")
    largest = max(counts)
    if size.peak_bytes > MAX_PLANNING_BYTES:
        need = (f"would need about {_size_text(size.peak_bytes)} of memory to plan (limit "
                f"{_size_text(MAX_PLANNING_BYTES)})")
    else:
        need = (f"would take about {_count_text(size.work)} similarity pair evaluations to plan "
                f"(limit {_count_text(MAX_PLANNING_WORK)}, about 16 s)")
    raise InputError(
        f"the task {need}: {which} up to {largest:,} angle candidates each on the "
        f"{grid:g} deg grid, and every candidate pair is compared with the library's {demo_deltas:,} "
        f"demonstration deltas; {_grid_advice(task, grid, demo_deltas, num_demos, max_span, cost)}",
        file=file, field="angle_grid_deg",
    )
