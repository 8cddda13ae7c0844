"""Semantic similarity of a task segment and a demonstration (Eq. 19-21).

The one implementation of the similarity test and of Definition 1's allocation; every
planner calls it (see docs/method.rst, "Similarity"):

* :func:`alpha_beta_matrices`: ``alpha`` (rotation distance, Eq. 19) and ``beta``
  (translation cosine, Eq. 20, with the 1 mm short-translation rule) of every pair of a
  task delta and a demo delta;
* :func:`pair_costs`: the pair's cost, ``alpha`` where the pair is similar
  (``alpha <= d_alpha`` and ``beta >= d_beta``) and ``inf`` where it is not;
  :func:`similar_pair_costs` is that test on given ``alpha`` and ``beta`` (the
  shape-fidelity cost of ``fidelity.py`` adds its terms to it);
* :func:`allocation_step`, :func:`allocation_table`, :func:`allocation_backtrack`: the
  dynamic programme for the least-total-alpha order-preserving allocation
  ``i_1 < i_2 < ... < i_p`` (that total is the action's cost, Eq. 31).

All of them broadcast over leading dimensions, so the composition problem runs them on
every candidate of a span and every demonstration at once; :func:`allocate` is the
single-segment, single-demonstration use.

Not for: building features (``features.py``), choosing among demonstrations or segments
(the planners), or mapping the demo (``mapping.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MIN_TRANSLATION_M",
    "Tolerances",
    "Allocation",
    "rotation_distance",
    "translation_cosine",
    "translation_directions",
    "alpha_beta_matrices",
    "pair_costs",
    "similar_pair_costs",
    "allocation_step",
    "allocation_table",
    "allocation_backtrack",
    "allocate",
    "allocate_features",
]

# A translation shorter than this has no direction (docs/method.rst, "Similarity").
MIN_TRANSLATION_M = 1e-3


@dataclasses.dataclass(frozen=True)
class Tolerances:
    """Similarity tolerances, defaults from the paper's Table 6.

    Attributes
    ----------
    d_alpha : float
        Largest rotation distance alpha (0.5 is about 58 deg); a pair with alpha equal
        to it is similar.
    d_beta : float
        Smallest translation cosine beta; a pair with beta equal to it is similar.
    min_translation_m : float
        Translations shorter than this have no direction.
    """

    d_alpha: float = 0.5
    d_beta: float = -0.9
    min_translation_m: float = MIN_TRANSLATION_M


@dataclasses.dataclass(frozen=True, eq=False)
class Allocation:
    """An order-preserving allocation of task deltas to demo deltas (Definition 1).

    Attributes
    ----------
    indices : array of int, shape (p,)
        Strictly increasing demo delta indices (0-based rows of the demo feature, which
        are also indices of the demo poses the feature came from).
    cost : float
        Total alpha over the p pairs, the least among valid allocations.
    alphas : array, shape (p,)
        alpha of each pair.
    """

    indices: np.ndarray
    cost: float
    alphas: np.ndarray


# -- pairwise formulas ----------------------------------------------------------------------

def rotation_distance(q1: ArrayLike, q2: ArrayLike) -> NDArray[np.float64]:
    """Rotation distance ``alpha = min(|q1 - q2|, |q1 + q2|)`` (Eq. 5, 19), elementwise.

    For unit quaternions this is ``2 sin(angle / 4)``, ``angle`` in [0, pi] being the
    relative rotation angle, so it does not depend on the quaternions' signs. Accurate
    near 0, unlike the matrix form of :func:`alpha_beta_matrices`; used to report the
    alphas of a chosen allocation.

    Parameters
    ----------
    q1, q2 : array-like, shape (..., 4)
        Leading dimensions broadcast.

    Returns
    -------
    alpha : array, shape (...)
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    return np.minimum(np.linalg.norm(q1 - q2, axis=-1), np.linalg.norm(q1 + q2, axis=-1))


def translation_cosine(t1: ArrayLike, t2: ArrayLike,
                       min_length_m: float = MIN_TRANSLATION_M) -> NDArray[np.float64]:
    """Cosine ``beta`` between translations (Eq. 20) with the short-translation rule,
    elementwise.

    Two translations shorter than ``min_length_m`` are similar (beta = 1); one short and
    one long are not (beta = -1).

    Parameters
    ----------
    t1, t2 : array-like, shape (..., 3)
        Leading dimensions broadcast.
    min_length_m : float

    Returns
    -------
    beta : array, shape (...), in [-1, 1]
    """
    units1, short1 = translation_directions(t1, min_length_m)
    units2, short2 = translation_directions(t2, min_length_m)
    cosine = np.asarray(np.clip(np.sum(units1 * units2, axis=-1), -1.0, 1.0))
    return _apply_short_rule(cosine, short1, short2)


def translation_directions(translations: ArrayLike, min_length_m: float = MIN_TRANSLATION_M
                           ) -> tuple[NDArray, NDArray]:
    """Unit directions (..., 3) and the short mask (...) of translations (..., 3), as
    :func:`alpha_beta_matrices` uses them. A short vector is divided by ``min_length_m``
    instead: its direction is never used (the short rule decides). A library computes
    its demonstrations' once (``demo_directions``) instead of once per task delta."""
    translations = np.asarray(translations, dtype=float)
    length = np.sqrt(np.einsum("...i,...i->...", translations, translations))
    short = length < min_length_m
    return translations / np.maximum(length, min_length_m)[..., None], short


def _apply_short_rule(beta: NDArray, short1: NDArray, short2: NDArray) -> NDArray:
    """In place: beta = 1 where both translations are short, -1 where exactly one is."""
    if np.any(short1) or np.any(short2):
        np.copyto(beta, -1.0, where=short1 | short2)
        np.copyto(beta, 1.0, where=short1 & short2)
    return beta


# -- the kernel -----------------------------------------------------------------------------

def alpha_beta_matrices(
    task_rotations: ArrayLike,
    task_translations: ArrayLike,
    demo_rotations: ArrayLike,
    demo_translations: ArrayLike,
    min_length_m: float = MIN_TRANSLATION_M,
    demo_directions: tuple[NDArray, NDArray] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """alpha (Eq. 19) and beta (Eq. 20) of every (task delta, demo delta) pair.

    alpha comes from one matrix product: for unit quaternions
    ``min(|a - b|, |a + b|)^2 = 2 - 2 |a . b|``. That form rounds to ~1e-8 rather than 0
    for equal rotations, which is harmless for the test; :func:`allocate` reports the
    chosen pairs' alphas with :func:`rotation_distance`.

    Parameters
    ----------
    task_rotations : array-like, shape (..., p, 4)
        Unit quaternions (either sign).
    task_translations : array-like, shape (..., p, 3)
    demo_rotations : array-like, shape (..., n, 4)
        Unit quaternions (either sign).
    demo_translations : array-like, shape (..., n, 3)
    min_length_m : float
        Translations shorter than this have no direction.
    demo_directions : (units, short), optional
        :func:`translation_directions` of ``demo_translations`` with ``min_length_m``,
        when already computed (the same numbers).

    Leading dimensions broadcast between task and demo.

    Returns
    -------
    alpha, beta : arrays, shape (..., p, n)
    """
    task_rotations = np.asarray(task_rotations, dtype=float)
    demo_rotations = np.asarray(demo_rotations, dtype=float)
    alpha = np.abs(task_rotations @ np.swapaxes(demo_rotations, -1, -2))
    alpha *= -2.0
    alpha += 2.0
    np.maximum(alpha, 0.0, out=alpha)
    np.sqrt(alpha, out=alpha)
    task_units, task_short = translation_directions(task_translations, min_length_m)
    if demo_directions is None:
        demo_directions = translation_directions(demo_translations, min_length_m)
    demo_units, demo_short = demo_directions
    beta = task_units @ np.swapaxes(demo_units, -1, -2)
    np.clip(beta, -1.0, 1.0, out=beta)
    _apply_short_rule(beta, task_short[..., :, None], demo_short[..., None, :])
    return alpha, beta


def pair_costs(
    task_rotations: ArrayLike,
    task_translations: ArrayLike,
    demo_rotations: ArrayLike,
    demo_translations: ArrayLike,
    tolerances: Tolerances = Tolerances(),
    demo_directions: tuple[NDArray, NDArray] | None = None,
) -> NDArray[np.float64]:
    """Cost of pairing each task delta with each demo delta: alpha where the pair is
    similar (``alpha <= d_alpha`` and ``beta >= d_beta``, Eq. 19-21), inf where not.

    Shapes and ``demo_directions`` as in :func:`alpha_beta_matrices`; returns an array
    of shape (..., p, n).
    """
    alpha, beta = alpha_beta_matrices(task_rotations, task_translations, demo_rotations,
                                      demo_translations, tolerances.min_translation_m, demo_directions)
    return similar_pair_costs(alpha, beta, tolerances)


def similar_pair_costs(alpha: NDArray, beta: NDArray, tolerances: Tolerances = Tolerances()) -> NDArray[np.float64]:
    """The similarity test (Eq. 21) on :func:`alpha_beta_matrices`' output: ``alpha``
    where ``alpha <= d_alpha`` and ``beta >= d_beta``, inf elsewhere (written into
    ``alpha``, which is returned). :func:`pair_costs` and the fidelity cost
    (``fidelity.py``, which also needs ``beta``) share it."""
    similar = alpha <= tolerances.d_alpha
    similar &= beta >= tolerances.d_beta
    alpha[~similar] = np.inf
    return alpha


def allocation_step(previous: ArrayLike, row: ArrayLike, out: NDArray | None = None) -> NDArray[np.float64]:
    """One row of the allocation dynamic programme (Definition 1, Eq. 21).

    ``previous[..., i]`` is the least total alpha of allocating task deltas 1..l-1 with
    delta l-1 at demo index i (inf: impossible); ``row[..., i]`` the pair cost of delta
    l with demo index i (:func:`pair_costs`). Returns the least total for deltas 1..l
    with delta l at index i: ``row[i] + min over i' < i of previous[i']``. The order is
    strict (``i' < i``): two task deltas never share a demo delta. The best predecessor
    is a prefix minimum, so a step costs O(n).

    Parameters
    ----------
    previous, row : array-like, shape (..., n)
        Leading dimensions broadcast.
    out : array, shape (..., n), optional
        Where to write the result; may be ``row`` itself.

    Returns
    -------
    cost : array, shape (..., n)
    """
    previous = np.asarray(previous, dtype=float)
    row = np.asarray(row, dtype=float)
    cost = np.empty(np.broadcast_shapes(previous.shape, row.shape)) if out is None else out
    if cost.shape[-1] == 0:
        return cost
    best_before = np.minimum.accumulate(previous, axis=-1)
    np.add(best_before[..., :-1], row[..., 1:], out=cost[..., 1:])
    cost[..., 0] = np.inf
    return cost


def allocation_table(pair_cost: ArrayLike) -> NDArray[np.float64]:
    """All rows of the allocation dynamic programme for pair costs (..., p, n).

    ``table[..., l, i]`` is the least total alpha of allocating task deltas 1..l+1 with
    delta l+1 at demo index i (see :func:`allocation_step`); ``table[..., -1, :].min()``
    is the least total of the whole segment (inf: no valid allocation).
    """
    table = np.array(pair_cost, dtype=float)
    for l in range(1, table.shape[-2]):
        allocation_step(table[..., l - 1, :], table[..., l, :], out=table[..., l, :])
    return table


def allocation_backtrack(table: ArrayLike) -> NDArray[np.int_] | None:
    """The demo indices ``i_1 < ... < i_p`` of the least allocation of one segment, from
    its :func:`allocation_table` (p, n); None when there is none. Ties go to the
    earliest demo indices."""
    table = np.asarray(table, dtype=float)
    p, n = table.shape
    if p == 0 or n == 0:
        return None
    indices = np.empty(p, dtype=int)
    indices[p - 1] = int(np.argmin(table[p - 1]))
    if not np.isfinite(table[p - 1, indices[p - 1]]):
        return None
    for l in range(p - 2, -1, -1):
        indices[l] = int(np.argmin(table[l, : indices[l + 1]]))
    return indices


def allocate(task_rotations: ArrayLike, task_translations: ArrayLike, demo_rotations: ArrayLike,
             demo_translations: ArrayLike, tolerances: Tolerances = Tolerances()) -> Allocation | None:
    """Least-alpha order-preserving allocation of task deltas to demo deltas (Eq. 21).

    :func:`pair_costs`, then the dynamic programme (:func:`allocation_table`, O(p n))
    and :func:`allocation_backtrack`. Ties go to the earliest demo indices.

    Parameters
    ----------
    task_rotations : array-like, shape (p, 4)
    task_translations : array-like, shape (p, 3)
    demo_rotations : array-like, shape (n, 4)
    demo_translations : array-like, shape (n, 3)
    tolerances : Tolerances

    Returns
    -------
    allocation : Allocation or None
        None when no valid allocation exists (including p > n).
    """
    task_rotations = np.asarray(task_rotations, dtype=float)
    demo_rotations = np.asarray(demo_rotations, dtype=float)
    p, n = len(task_rotations), len(demo_rotations)
    if p == 0 or p > n:
        return None
    table = allocation_table(pair_costs(task_rotations, task_translations, demo_rotations,
                                        demo_translations, tolerances))
    indices = allocation_backtrack(table)
    if indices is None:
        return None
    alphas = rotation_distance(task_rotations, demo_rotations[indices])
    indices.flags.writeable = False
    alphas.flags.writeable = False
    return Allocation(indices=indices, cost=float(alphas.sum()), alphas=alphas)


def allocate_features(task_feature, demo_feature, tolerances: Tolerances = Tolerances()) -> Allocation | None:
    """:func:`allocate` for two ``features.Feature`` objects (task segment, demo)."""
    return allocate(task_feature.rotations, task_feature.translations,
                    demo_feature.rotations, demo_feature.translations, tolerances)
