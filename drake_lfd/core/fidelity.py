"""Shape fidelity of a mapped demonstration: the allocation cost beyond the paper's Eq. 31.

The paper prices an action (demo d covering task span con_j .. con_k) by the total
rotation distance alpha of its allocation (Eq. 31), and the similarity test accepts
almost any translation direction (``d_beta = -0.9``). So a demonstration can be
stretched, shrunk or bent by the mapping (Eq. 22-25) at no cost: a 64 cm straight carry
is covered by the 15 cm lift-over-lower of ``stacking`` stretched 3.8x, which takes the
tool 53 cm off the straight line; and many suffixes of one demonstration that share its
rotations cost the same, so the allocation does not find the suffix a task was made
from.

The ``fidelity`` cost adds, per allocated pair (task delta l, demo delta i), terms that
measure how far the mapping deforms the demonstration (docs/method.rst, "Shape
fidelity"), each in units of alpha through :class:`FidelityWeights`:

* **direction**: the angle (rad) between the task translation ``t_l`` and the demo
  translation ``t_i`` (both in the body frame they start from, as beta, Eq. 20). For the
  first pair the mapping turns the demo's path by that angle relative to the tool (a
  lift becomes a sideways move); for later pairs it is how much the anchor correction
  bends the path.
* **stretch**: ``|ln(|t_l| / |t_i|)|``, the log of the pair's scale: symmetric in
  stretching and shrinking, 0 for a faithful copy, additive over nested scalings.
  Two translations shorter than ``min_translation_m`` have no direction and no size:
  both terms are 0 (one short and one long are not similar anyway).
* **anchor** (metres): ``|R_i^T t_l - R_l^T t_l|``, how far the pair's rotation
  mismatch (alpha, an angle) moves the pair's configuration relative to the span's end,
  over the task's lever arm ``t_l``; for the first pair exactly the position the
  mapping's correction must make up (docs/method.rst, Mapping). alpha alone prices a
  45 deg mismatch on a 40 cm carry like one on a 1 cm nudge.
* **excursion** (first pair only, metres): the mapping scales the whole suffix by
  ``s = |t_task| / |t_demo|`` (Eq. 23); points off the suffix's chord then move off the
  demonstrated shape by ``|s - 1| h``, with ``h`` the suffix's largest distance from
  its chord (:func:`suffix_excursions`). That is how far a lift-over-lower grows when it
  is stretched, and 0 for a straight demonstration or a faithful copy.

Every term depends only on one pair (the excursion only on the first pair's demo
index), so the least-cost allocation is still the O(p n) dynamic programme of
``similarity.py``; its rows just carry alpha plus the terms, which
:func:`action_pair_costs` computes for the similar pairs only (the similarity test
itself is unchanged: the cost only ranks what Definition 1 accepts).

Cost modes (:data:`COST_MODES`): ``"fidelity"`` adds the terms at full weight, to the
action's cost and to the choice of its allocation; ``"paper"`` keeps Eq. 31 as the
action's cost and adds the terms times :data:`PAPER_TIE_WEIGHT` only to choose the
allocation that is mapped, so ties in alpha (equal rotations along a demo) are broken by
fidelity, then by the earliest demo index.

Not for: the similarity test itself (``similarity.py``), choosing among actions (the
planners) or mapping (``mapping.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drake_lfd.core.dual_quaternion import (
    IDENTITY_DUAL_QUATERNION,
    dual_quaternion_conjugate,
    dual_quaternion_multiply,
    translation_from_dual_quaternion,
)
from drake_lfd.core.features import Feature
from drake_lfd.core.option_values import COST_MODES
from drake_lfd.core.similarity import (
    Tolerances,
    alpha_beta_matrices,
    pair_costs,
    similar_pair_costs,
    translation_directions,
)

__all__ = [
    "COST_MODES",
    "PAPER_TIE_WEIGHT",
    "FidelityWeights",
    "check_cost_mode",
    "suffix_excursions",
    "feature_excursions",
    "deltas_excursions",
    "fidelity_terms",
    "DemoDeltaTerms",
    "demo_delta_terms",
    "action_pair_costs",
]


# In the "paper" mode the fidelity terms only break ties in alpha. Far above the
# rounding of alpha's matrix form (~2e-8 for equal rotations) times the fidelity
# difference of neighbouring samples (~1e-2), far below any alpha difference that
# matters (1e-4 is 0.01 deg).
PAPER_TIE_WEIGHT = 1e-5


@dataclasses.dataclass(frozen=True)
class FidelityWeights:
    """Weights of the fidelity terms, each converting its term into units of alpha.

    alpha is ``2 sin(angle / 4)``, about half the rotation angle for small angles.

    Attributes
    ----------
    direction_per_rad : float
        Cost per radian between a pair's task and demo translations. 0.025: a
        translation turned by 150 deg (about the most ``d_beta = -0.9`` lets through)
        costs 0.065, like a rotation off by 7.5 deg. Kept low because a straight motion
        at a constant orientation may well run either way; the stretch, excursion and
        bend then decide.
    log_scale : float
        Cost per unit of ``|ln(scale)|`` of a pair. 0.125: a 2x stretch costs 0.087, like
        a rotation off by 10 deg.
    excursion_per_m : float
        Cost per metre that scaling moves the path off the demonstrated shape. 2.5: a
        lift grown by 5 cm costs 0.125, like a rotation off by 14 deg, so stretching a
        curved demonstration costs more than turning a straight one around.
    anchor_per_m : float
        Cost per metre the pair's rotation mismatch moves its configuration (the anchor
        correction's lever arm). 1.25: a 10 cm correction costs 0.125.

    bend_per_m : float
        Cost per metre a later pair's translation mismatch moves its configuration off
        where the aligned demonstration puts it (the chord between the two directions at
        the task translation's length): both it and the anchor are the correction the
        mapping must spread over the span (docs/method.rst, Mapping). Without it a span
        may swallow a configuration 40 cm off the demonstration's path (transferring,
        seed 2: a 375 mm correction) at the price of the small direction term. 1.25, as
        the anchor.

    The weights are a quarter of the first ones tried (0.1, 0.5, 10, 5, 5): at those, the
    terms outweighed alpha so far that on the paper's filling-and-pouring task the
    allocation traded rotation for shape and the mapping had to correct 61-113 mm and
    16-30 deg; at a quarter it corrects at most 7 mm and 1.8 deg there, and the
    benchmark's pass rate rises from 58 to 60 of 60 (``benchmarks/bench_fidelity.py``).
    """

    direction_per_rad: float = 0.025
    log_scale: float = 0.125
    excursion_per_m: float = 2.5
    anchor_per_m: float = 1.25
    bend_per_m: float = 1.25

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"FidelityWeights.{field.name} must be finite and >= 0, got {value}")


def check_cost_mode(cost: str) -> str:
    """``cost`` if it is one of :data:`COST_MODES`, else ValueError."""
    if cost not in COST_MODES:
        raise ValueError(f"cost must be one of {COST_MODES}, got {cost!r}")
    return cost


def suffix_excursions(positions: ArrayLike, min_length_m: float = Tolerances().min_translation_m
                      ) -> NDArray[np.float64]:
    """For each suffix ``i .. m-1`` of a demo path, its largest distance from its chord.

    Parameters
    ----------
    positions : array-like, shape (..., m, 3)
        The demo's (resampled) positions, in any one frame; leading dimensions are
        separate paths of the same length (computed at once).
    min_length_m : float
        A chord shorter than this has no direction: the mapping does not scale such a
        suffix (scale 1), so its excursion is 0.

    Returns
    -------
    h : array, shape (..., m - 1)
        ``h[i]`` is the largest distance (m) of ``positions[i:]`` from the line through
        ``positions[i]`` and ``positions[-1]``: one per demo delta index.
    """
    p = np.asarray(positions, dtype=float)
    m = p.shape[-2]
    chord = p[..., -1:, :] - p[..., :-1, :]  # (..., m - 1, 3)
    length = np.linalg.norm(chord, axis=-1)
    unit = chord / np.maximum(length, min_length_m)[..., None]
    # By components (contiguous along the path): for each i, the offsets of the later
    # positions j > i, their cross product with the chord's unit vector and its squared
    # length, rounded as np.cross and norm round them (position i itself is at 0).
    position = np.ascontiguousarray(np.moveaxis(p, -1, 0))  # (3, ..., m)
    direction = np.moveaxis(unit, -1, 0)  # (3, ..., m - 1)
    squared = np.empty(p.shape[:-2] + (m - 1,))
    for i in range(m - 1):
        offsets = [position[c, ..., i + 1:] - position[c, ..., i, None] for c in range(3)]
        squared[..., i] = _cross_squared(offsets, [direction[c, ..., i, None] for c in range(3)]).max(axis=-1)
    h = np.sqrt(squared)  # sqrt is monotone: the largest distance
    h[length < min_length_m] = 0.0
    return h


def _cross_squared(a: list, b: list) -> NDArray[np.float64]:
    """``|a x b|^2`` of vectors given by components (lists of 3 arrays that broadcast),
    rounded exactly as ``np.linalg.norm(np.cross(a, b), axis=-1) ** 2`` before its sqrt."""
    c0, c1, c2 = _cross(a, b)
    c0 *= c0
    c1 *= c1
    c2 *= c2
    c0 += c1
    c0 += c2
    return c0


def feature_excursions(feature: Feature, min_length_m: float = Tolerances().min_translation_m
                       ) -> NDArray[np.float64]:
    """:func:`suffix_excursions` of a demonstration's feature, one per delta index (its
    positions rebuilt from the deltas in the last pose's frame: the excursions do not
    depend on where the demonstration was)."""
    return deltas_excursions(feature.deltas, min_length_m)


def deltas_excursions(deltas: ArrayLike, min_length_m: float = Tolerances().min_translation_m
                      ) -> NDArray[np.float64]:
    """:func:`feature_excursions` of demonstrations given by their deltas.

    Parameters
    ----------
    deltas : array-like, shape (..., n, 8)
        Unit dual quaternions, a feature's ``deltas``; leading dimensions are separate
        demonstrations. A shorter demonstration may be padded after its deltas with the
        identity: its positions then end with copies of the last one, which change
        neither a chord nor a largest distance, so its first excursions are its own.
    min_length_m : float

    Returns
    -------
    h : array, shape (..., n)
    """
    deltas = np.asarray(deltas, dtype=float)
    poses = dual_quaternion_multiply(IDENTITY_DUAL_QUATERNION, dual_quaternion_conjugate(deltas))
    final = np.broadcast_to(IDENTITY_DUAL_QUATERNION, deltas.shape[:-2] + (1, 8))
    positions = translation_from_dual_quaternion(np.concatenate([poses, final], axis=-2))
    return suffix_excursions(positions, min_length_m)


def _rotated_by_conjugate(q: list, v: list) -> list:
    """``vector_rotated_by_quaternion(quaternion_conjugate(q), v)`` by components (lists
    of 4 and 3 arrays that broadcast), rounded exactly as that function: the conjugate's
    negated vector part ``u = -q_v`` is folded into the signs (``u x v = -(q_v x v)`` and
    ``u x (u x v) = q_v x (q_v x v)``, exact in IEEE arithmetic)."""
    w2 = 2.0 * q[0]
    qv = q[1:]
    uv = _cross(qv, v)  # -(u x v)
    uuv = _cross(qv, uv)  # u x (u x v)
    out = []
    for c in range(3):
        term = w2 * uv[c]
        start = v[c] - term  # v + 2 w (u x v)
        uuv[c] *= 2.0
        start += uuv[c]
        out.append(start)
    return out


def _cross(a: list, b: list) -> list:
    """``np.cross`` of vectors given by components, rounded as it rounds."""
    out = []
    for i, j in ((1, 2), (2, 0), (0, 1)):
        c = a[i] * b[j]
        c -= a[j] * b[i]
        out.append(c)
    return out


def fidelity_terms(
    beta: ArrayLike,
    task_rotations: ArrayLike,
    task_translations: ArrayLike,
    demo_rotations: ArrayLike,
    demo_translations: ArrayLike,
    demo_excursions: ArrayLike,
    weights: FidelityWeights = FidelityWeights(),
    min_length_m: float = Tolerances().min_translation_m,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fidelity terms of pairs (module docstring), elementwise with broadcasting:
    pair ``e`` is task delta ``e`` with demo delta ``e``, or, with task arrays of shape
    (p, 1, ...) and demo arrays of shape (1, n, ...), every pair of the two at once (the
    task side's own terms are then computed once per task delta).

    Parameters
    ----------
    beta : array-like, shape (...)
        The pairs' translation cosines (:func:`similarity.alpha_beta_matrices`).
    task_rotations : array-like, shape (..., 4)
        Unit quaternions.
    task_translations : array-like, shape (..., 3)
    demo_rotations : array-like, shape (..., 4)
        Unit quaternions.
    demo_translations : array-like, shape (..., 3)
    demo_excursions : array-like, shape (...)
        :func:`suffix_excursions` of the demo delta indices.
    weights : FidelityWeights
    min_length_m : float
        Translations shorter than this have no direction or size.

    Returns
    -------
    pair, first : arrays, shape (...) (the broadcast shape)
        ``pair``: the weighted direction, stretch and anchor terms; ``first``: the
        weighted excursion, which counts only where the pair is the allocation's first.
    """
    demo_q = np.asarray(demo_rotations, dtype=float)
    log_length, short_length = _log_lengths(demo_translations, min_length_m)
    return _pair_terms(beta, task_rotations, task_translations, [demo_q[..., c] for c in range(4)], log_length,
                       short_length, demo_excursions, weights, min_length_m)


def _log_lengths(translations: ArrayLike, min_length_m: float) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """``ln(max(|t|, min_length_m))`` (the stretch term's demo side) and ``|t| < min_length_m``."""
    length = np.linalg.norm(np.asarray(translations, dtype=float), axis=-1)
    return np.log(np.maximum(length, min_length_m)), length < min_length_m


def _pair_terms(beta, task_rotations, task_translations, demo_components: list, demo_log_length, demo_short,
                demo_excursions, weights: FidelityWeights, min_length_m: float
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`fidelity_terms` from the demo side's own parts: its rotations by component
    (4 arrays), :func:`_log_lengths` and the excursions."""
    t = np.asarray(task_translations, dtype=float)
    task_q = np.asarray(task_rotations, dtype=float)
    task_length = np.linalg.norm(t, axis=-1)
    both_short = (task_length < min_length_m) & demo_short
    log_ratio = np.log(np.maximum(task_length, min_length_m)) - demo_log_length
    direction = np.clip(np.asarray(beta, dtype=float), -1.0, 1.0)
    np.arccos(direction, out=direction)
    pair = weights.direction_per_rad * direction
    stretch = np.abs(log_ratio)
    stretch *= weights.log_scale
    pair = pair + stretch
    any_both_short = bool(np.any(both_short))
    if any_both_short:
        both_short = np.broadcast_to(both_short, pair.shape)
        pair[both_short] = 0.0
    # Anchor: where the demo's rotation puts the pair's start, against the task's.
    v = [t[..., c] for c in range(3)]
    start_demo = _rotated_by_conjugate(demo_components, v)
    start_task = _rotated_by_conjugate([task_q[..., c] for c in range(4)], v)
    offset = [start_demo[c] - start_task[c] for c in range(3)]
    squared = offset[0] * offset[0]
    for c in (1, 2):
        offset[c] *= offset[c]
        squared += offset[c]
    np.sqrt(squared, out=squared)
    squared *= weights.anchor_per_m
    pair += squared
    # Bend: a later pair's anchor is where the first pair's alignment puts the demo; a
    # task translation turned from the demo's by ``direction`` moves it by the chord
    # ``2 |t_l| sin(direction / 2)``, which the anchor correction must make up. The first
    # pair is aligned exactly (no bend), so its share is taken back in ``first``.
    half = 0.5 * direction
    np.sin(half, out=half)
    bend = weights.bend_per_m * 2.0 * task_length * half
    if any_both_short:
        bend[both_short] = 0.0
    pair += bend
    # The mapping's scale if the pair is the first (Eq. 23: 1 for a short demo translation).
    scale = np.exp(log_ratio)
    if np.any(demo_short):
        scale = np.where(demo_short, 1.0, scale)
    scale -= 1.0
    first = np.abs(scale, out=scale)
    first *= weights.excursion_per_m
    first = first * np.asarray(demo_excursions, dtype=float)
    first -= bend
    return pair, first


@dataclasses.dataclass(frozen=True, eq=False)
class DemoDeltaTerms:
    """What the pair costs need of demo deltas alone, computed once for every task delta
    they meet (``span_index.PreparedLibrary`` keeps a library's and gathers them per
    chunk of demonstrations, so no row normalises a demo translation again). Each
    attribute has the deltas' shape (...) leading.

    Attributes
    ----------
    directions : (units (..., 3), short (...))
        ``similarity.translation_directions`` of the translations (beta's inputs).
    log_length : array, shape (...)
        ``ln(max(|t|, min_length_m))``, the stretch term's demo side.
    short_length : array of bool, shape (...)
        ``|t| < min_length_m`` by the norm the fidelity terms use.
    """

    directions: tuple[NDArray[np.float64], NDArray[np.bool_]]
    log_length: NDArray[np.float64]
    short_length: NDArray[np.bool_]

    def take(self, rows: NDArray) -> "DemoDeltaTerms":
        """The terms of the rows ``rows`` (indices or a slice) of the first axis
        (demonstrations of a padded stack (h, n_max, ...)), flattened to one axis of deltas."""
        units, short = self.directions
        return DemoDeltaTerms((units[rows].reshape(-1, 3), short[rows].reshape(-1)),
                              self.log_length[rows].reshape(-1), self.short_length[rows].reshape(-1))


def demo_delta_terms(demo_translations: ArrayLike, min_length_m: float = Tolerances().min_translation_m
                     ) -> DemoDeltaTerms:
    """The :class:`DemoDeltaTerms` of demo deltas' translations (..., 3)."""
    return DemoDeltaTerms(translation_directions(demo_translations, min_length_m),
                          *_log_lengths(demo_translations, min_length_m))


# Similar pairs whose fidelity terms are computed at once (bounds the temporaries,
# about 300 bytes a pair, and keeps them in cache).
_PAIRS_PER_BATCH = 1 << 15


def action_pair_costs(
    task_rotations: ArrayLike,
    task_translations: ArrayLike,
    demo_rotations: ArrayLike,
    demo_translations: ArrayLike,
    demo_excursions: ArrayLike,
    tolerances: Tolerances = Tolerances(),
    cost: str = "paper",
    weights: FidelityWeights = FidelityWeights(),
    tie_break: bool = True,
    demo_terms: DemoDeltaTerms | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Allocation row costs of every (task delta, demo delta) pair in a cost mode.

    Parameters
    ----------
    task_rotations : array-like, shape (p, 4)
    task_translations : array-like, shape (p, 3)
    demo_rotations : array-like, shape (n, 4)
    demo_translations : array-like, shape (n, 3)
    demo_excursions : array-like, shape (n,)
    tolerances : similarity.Tolerances
    cost : {"paper", "fidelity"}
    weights : FidelityWeights
    tie_break : bool
        In the ``"paper"`` mode: add the fidelity terms times :data:`PAPER_TIE_WEIGHT`
        (to choose an allocation), or leave them out (for the action's cost: the pair
        costs are then Eq. 31's alpha exactly, ``similarity.pair_costs``).
    demo_terms : DemoDeltaTerms, optional
        :func:`demo_delta_terms` of the demo deltas (shape (n,)), when computed once for
        many calls; the same numbers as without.

    Returns
    -------
    pair, first : arrays, shape (p, n)
        ``pair``: alpha plus the weighted direction, stretch and anchor terms where the
        pair is similar (Eq. 19-21), inf where it is not; ``first``: what the pair adds
        when it is the allocation's first (the excursion), 0 where it is not similar.
        The terms are computed for the similar pairs only, in blocks of flat arrays; a
        single task delta (a configuration with fixed orientations) broadcasts, so its
        own terms are computed once.
    """
    if check_cost_mode(cost) == "paper" and not tie_break:
        alpha = pair_costs(task_rotations, task_translations, demo_rotations, demo_translations, tolerances,
                           None if demo_terms is None else demo_terms.directions)
        return alpha, np.zeros(alpha.shape)  # calloc: no memory until written
    factor = 1.0 if cost == "fidelity" else PAPER_TIE_WEIGHT
    task_q, task_t = np.asarray(task_rotations, dtype=float), np.asarray(task_translations, dtype=float)
    demo_q, demo_t = np.asarray(demo_rotations, dtype=float), np.asarray(demo_translations, dtype=float)
    demo_h = np.asarray(demo_excursions, dtype=float)
    if demo_terms is None:
        demo_terms = demo_delta_terms(demo_t, tolerances.min_translation_m)
    alpha, beta = alpha_beta_matrices(task_q, task_t, demo_q, demo_t, tolerances.min_translation_m,
                                      demo_terms.directions)
    pair = similar_pair_costs(alpha, beta, tolerances)
    first = np.zeros(pair.shape)
    similar = np.flatnonzero(np.isfinite(pair))  # into pair.ravel()
    if len(similar) == 0:
        return pair, first
    pair_flat, first_flat, beta_flat = pair.reshape(-1), first.reshape(-1), beta.reshape(-1)
    components = np.ascontiguousarray(demo_q.T)  # (4, n): each batch gathers contiguous rows
    n = pair.shape[1]
    for start in range(0, len(similar), _PAIRS_PER_BATCH):
        e = similar[start:start + _PAIRS_PER_BATCH]
        if len(task_q) == 1:
            c, q, t = e, task_q[0], task_t[0]
        else:
            r, c = np.divmod(e, n)
            q, t = task_q[r], task_t[r]
        terms, first_terms = _pair_terms(beta_flat[e], q, t, list(components[:, c]),
                                         demo_terms.log_length[c], demo_terms.short_length[c], demo_h[c], weights,
                                         tolerances.min_translation_m)
        if factor != 1.0:
            terms *= factor
            first_terms *= factor
        pair_flat[e] += terms
        first_flat[e] = first_terms
    return pair, first
