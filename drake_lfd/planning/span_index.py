"""A library prepared for the legal-action table: padded stacks and an exact pre-filter.

:class:`PreparedLibrary` holds what :class:`~drake_lfd.planning.composition.CompositionProblem`
needs of a library and computes once per library (every trial of a task and every
replan reuse it, :func:`prepared_library`): the demonstrations' deltas stacked into
padded arrays ``(h, n_max, ...)``, so that numpy calls run the similarity kernel on many
demonstrations at once, the demo side of every pair cost (``fidelity.DemoDeltaTerms``:
unit translations, short flags, log lengths, computed once instead of once per row),
their suffix excursions (``core/fidelity.py``) and :class:`SpanIndex`.

:class:`SpanIndex` discards (demonstration, span) pairs that provably cannot pass the
similarity test before the test runs. The bound (docs/method.rst, "Cost of planning"):

* A span con_j .. con_k (``p = k - j`` task deltas) is legal for demonstration d only if
  some order-preserving allocation ``i_1 < ... < i_p`` pairs every task delta with a
  similar demo delta (Definition 1, Eq. 21). Two necessary conditions follow, each
  ignoring the order: ``p <= n_d``; and every task delta ``l`` of the span (for some
  candidate of con_l) has *some* similar delta in d.
* Similar means ``alpha <= d_alpha`` and ``beta >= d_beta`` (Eq. 19-21). The index tests
  the rotation part and the short-translation rule only, which is weaker, so still
  necessary.
* ``alpha(a, b) = min(|a - b|, |a + b|)`` is the chord distance of unit quaternions
  taken modulo sign, a metric (the quotient of a metric by the isometry ``q -> -q``),
  so it obeys the triangle inequality. Each demonstration's deltas are cut into blocks of
  :data:`BLOCK_DELTAS` consecutive ones with a centre ``c`` (the middle member's rotation)
  and a radius ``r = max alpha(q_i, c)`` over the members. If a member has
  ``alpha(q, q_i) <= d_alpha`` then ``alpha(q, c) <= d_alpha + r``: a block whose centre
  is farther holds no similar delta. A KD-tree (``scipy.spatial.cKDTree``) over the
  centres with both signs finds, in one query, every block within ``d_alpha + r_max``
  of a task rotation (Euclidean distance to ``+c`` or ``-c`` bounds ``alpha`` from
  above); each hit is then checked against its own block's radius.
* With ``d_beta > -1`` a short and a long translation are never similar (beta = -1,
  Eq. 20's rule), so a block serves a long task translation only if it holds a long
  delta, a short one only if it holds a short delta.
* Every comparison gets :data:`ALPHA_MARGIN` of slack: the kernel evaluates alpha as
  ``sqrt(2 - 2 |a . b|)``, within about 1e-8 of the exact distance.

So a discarded pair is one the exact test would reject: verdicts, costs and plans are
the same with and without the index (``tests/test_span_index.py`` compares them on
random problems).

Not for: the similarity test itself (``core/similarity.py``) or the table built from it
(``composition.py``).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from drake_lfd.core.dual_quaternion import IDENTITY_DUAL_QUATERNION
from drake_lfd.core.exact_memo import ExactMemo
from drake_lfd.core.features import Feature
from drake_lfd.core.fidelity import demo_delta_terms, deltas_excursions
from drake_lfd.core.similarity import Tolerances, rotation_distance

__all__ = ["BLOCK_DELTAS", "ALPHA_MARGIN", "SpanIndex", "PreparedLibrary", "prepared_library"]

#: Consecutive demo deltas summarised by one ball of rotations (a 90 deg turn over 99
#: deltas: about 7 deg, alpha 0.06, per block).
BLOCK_DELTAS = 8
#: Slack on every alpha comparison of the index, far above the kernel's rounding (1e-8).
ALPHA_MARGIN = 1e-6
# Sample pairs of the suffix excursions computed at once (about 10 bytes each: one
# sample's offsets at a time).
_EXCURSION_PAIRS = 1 << 22
# Libraries kept prepared (each holds its stacks; the key holds the features alive).
_PREPARED_KEPT = 4


class SpanIndex:
    """Which demonstrations may hold a delta similar to a task delta (module docstring).

    Parameters
    ----------
    rotations : array, shape (h, n_max, 4)
        Demo delta rotations, padded.
    short : array of bool, shape (h, n_max)
        Demo delta translations shorter than ``tolerances.min_translation_m``.
    lengths : array of int, shape (h,)
        Real deltas of each demonstration (the rest is padding).
    tolerances : similarity.Tolerances
    """

    def __init__(self, rotations: NDArray, short: NDArray, lengths: NDArray, tolerances: Tolerances):
        self.tolerances = tolerances
        self.num_demos = len(lengths)
        h, n_max = short.shape
        count = -(-n_max // BLOCK_DELTAS)  # blocks of the longest demonstration
        width = count * BLOCK_DELTAS
        q = np.zeros((h, width, 4))
        q[:, :n_max] = rotations
        is_short = np.zeros((h, width), dtype=bool)
        is_short[:, :n_max] = short
        starts = np.arange(count) * BLOCK_DELTAS  # (count,)
        sizes = np.clip(lengths[:, None] - starts[None, :], 0, BLOCK_DELTAS)  # (h, count)
        centre_at = starts[None, :] + sizes // 2
        centre = np.take_along_axis(q, np.minimum(centre_at, width - 1)[..., None], axis=1)  # (h, count, 4)
        members = q.reshape(h, count, BLOCK_DELTAS, 4)
        real = np.arange(BLOCK_DELTAS)[None, None, :] < sizes[..., None]  # (h, count, B)
        radius = np.where(real, rotation_distance(members, centre[:, :, None, :]), 0.0).max(axis=-1)
        blocks_short = is_short.reshape(h, count, BLOCK_DELTAS)
        exists = sizes > 0
        self._radii = radius[exists]
        self._demos = np.broadcast_to(np.arange(h)[:, None], (h, count))[exists].astype(np.intp)
        self._has_short = (blocks_short & real).any(axis=-1)[exists]
        self._has_long = (~blocks_short & real).any(axis=-1)[exists]
        centres = centre[exists]
        # Imported when first needed: imported at start-up, before pydrake started Meshcat,
        # scipy.spatial made a notebook kernel abort (tutorials/04_record_your_own).
        from scipy.spatial import cKDTree

        self._split_short = tolerances.d_beta > -1.0
        self._tree = cKDTree(np.concatenate([centres, -centres])) if len(centres) else None
        self._max_radius = float(self._radii.max()) if len(self._radii) else 0.0

    def candidates(self, task_rotations: NDArray, task_short: NDArray) -> NDArray[np.bool_]:
        """``mask[m, d]``: False when demonstration d holds no delta similar to task delta m.

        Parameters
        ----------
        task_rotations : array, shape (m, 4)
            Unit quaternions of the task deltas.
        task_short : array of bool, shape (m,)
            Task translations shorter than ``min_translation_m``.

        Returns
        -------
        mask : array of bool, shape (m, h)
            Conservative: True wherever a similar delta may exist.
        """
        m = len(task_rotations)
        mask = np.zeros((m, self.num_demos), dtype=bool)
        if self._tree is None or m == 0:
            return mask
        reach = self.tolerances.d_alpha + self._max_radius + ALPHA_MARGIN
        hits = type(self._tree)(task_rotations).sparse_distance_matrix(self._tree, reach, output_type="ndarray")
        rows, points, distance = hits["i"], hits["j"], hits["v"]
        blocks = points % len(self._radii)
        keep = distance <= self.tolerances.d_alpha + self._radii[blocks] + ALPHA_MARGIN
        if self._split_short:
            keep &= np.where(task_short[rows], self._has_short[blocks], self._has_long[blocks])
        mask[rows[keep], self._demos[blocks[keep]]] = True
        return mask


class PreparedLibrary:
    """A library's deltas as padded stacks, for the kernel to run over demonstrations at once.

    Parameters
    ----------
    features : sequence of features.Feature
        In order (index d).
    tolerances : similarity.Tolerances

    Attributes
    ----------
    features : tuple of features.Feature
    rotations : array, shape (h, n_max, 4)
        Demo delta rotations; padding is the zero quaternion.
    translations : array, shape (h, n_max, 3)
        Demo delta translations; padding is zero.
    lengths : array of int, shape (h,)
        Deltas of each demonstration.
    padded : bool
        Whether any demonstration is shorter than ``n_max`` (the kernel's results at the
        padding must then be made inf).
    index : SpanIndex
    terms : fidelity.DemoDeltaTerms
        The demo side of every pair cost (translation directions and log lengths),
        shape (h, n_max): computed once, gathered per chunk of a row.
    """

    def __init__(self, features: Sequence[Feature], tolerances: Tolerances):
        self.features = tuple(features)
        self.tolerances = tolerances
        self.lengths = np.array([len(f) for f in self.features], dtype=np.intp)
        h, n_max = len(self.features), int(self.lengths.max()) if self.features else 0
        self.rotations, self.translations = np.zeros((h, n_max, 4)), np.zeros((h, n_max, 3))
        for d, feature in enumerate(self.features):
            self.rotations[d, :self.lengths[d]] = feature.rotations
            self.translations[d, :self.lengths[d]] = feature.translations
        self.padded = bool(h and (self.lengths < n_max).any())
        self.valid = np.arange(n_max)[None, :] < self.lengths[:, None]
        short = np.linalg.norm(self.translations, axis=-1) < tolerances.min_translation_m
        self.index = SpanIndex(self.rotations, short, self.lengths, tolerances)
        self.terms = demo_delta_terms(self.translations, tolerances.min_translation_m)
        self._excursions = np.zeros((h, n_max))
        self._has_excursions = np.zeros(h, dtype=bool)

    def excursions(self, demos: NDArray) -> NDArray[np.float64]:
        """``fidelity.feature_excursions`` of the demonstrations ``demos`` (s,), padded:
        shape (s, n_max). Computed on first use and kept (O(n^2) per demonstration, so
        only the demonstrations that reach the exact test pay for it), for the missing
        ones of each length at once."""
        missing = np.unique(demos[~self._has_excursions[demos]])
        n_max = self._excursions.shape[1]
        step = max(1, _EXCURSION_PAIRS // max(1, n_max * n_max))  # bounds the temporaries
        for start in range(0, len(missing), step):
            block = missing[start:start + step]
            deltas = np.tile(IDENTITY_DUAL_QUATERNION, (len(block), n_max, 1))  # identity padding
            for row, d in enumerate(block.tolist()):
                deltas[row, :self.lengths[d]] = self.features[d].deltas
            self._excursions[block] = deltas_excursions(deltas, self.tolerances.min_translation_m)
            self._excursions[block] *= self.valid[block]  # the padding's are 0
        self._has_excursions[missing] = True
        return self._excursions[demos]


_PREPARED = ExactMemo(maxsize=_PREPARED_KEPT)  # (features, PreparedLibrary) by the features' ids


def prepared_library(features: Sequence[Feature], tolerances: Tolerances) -> PreparedLibrary:
    """The :class:`PreparedLibrary` of ``features``, built once and kept for the last
    few libraries (keyed by the feature objects themselves, which are immutable), so the
    trials of a task and its replans do not stack and index the library again."""
    features = tuple(features)
    key = (tuple(id(f) for f in features), tolerances)
    # (An id is reused once its object is gone: a kept entry counts only for the same objects.)
    _, prepared = _PREPARED.get(key, lambda: (features, PreparedLibrary(features, tolerances)),
                                fresh=lambda entry: all(a is b for a, b in zip(entry[0], features)))
    return prepared
