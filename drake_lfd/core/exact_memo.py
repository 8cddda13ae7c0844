"""A bounded, process-local memo keyed by exact inputs, for reusing planning work.

Trials of one task share work: an assembling trial has no variables, so every trial
times the same joint path; a filling-and-pouring trial changes only its later spans.
:class:`ExactMemo` keeps the last results of a pure function by its inputs, arrays
compared by their bytes (:func:`exact_key`), so a hit returns exactly what computing
afresh would: a trial's plan cannot depend on which trials ran before it in the process
(plans stay the same whatever the number of workers).

It is also the one least-recently-used cache of the package for anything kept by a
hashable key (a process's runners and feature sets, a prepared library): ``fresh``
rejects a remembered result the key no longer vouches for.

Not for: results that depend on anything but the key (state, time, randomness).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any

import numpy as np

__all__ = ["ExactMemo", "exact_key"]


def exact_key(*values: Any) -> tuple:
    """A hashable key equal for equal inputs to the bit: arrays by dtype, shape and bytes
    (so ``-0.0`` and ``0.0`` differ, as they may in a result), other values as they are
    (they must be hashable)."""
    key = []
    for value in values:
        if isinstance(value, np.ndarray):
            array = np.ascontiguousarray(value)
            key.append((array.dtype.str, array.shape, array.tobytes()))
        else:
            key.append(value)
    return tuple(key)


class ExactMemo:
    """The last ``maxsize`` results of a computation, by key (least recently used out).

    Parameters
    ----------
    maxsize : int
        Results kept (at least 1).
    """

    def __init__(self, maxsize: int):
        if maxsize < 1:
            raise ValueError(f"maxsize must be at least 1, got {maxsize}")
        self.maxsize = maxsize
        self._results: OrderedDict[Hashable, Any] = OrderedDict()
        self._lock = threading.Lock()  # trials may run in threads; compute runs outside it
        self.hits = 0
        self.misses = 0

    def get(self, key: Hashable, compute: Callable[[], Any],
            keep: Callable[[Any], bool] | None = None,
            fresh: Callable[[Any], bool] | None = None) -> Any:
        """The result remembered for ``key``, else ``compute()`` (remembered unless
        ``keep(result)`` is false; an exception it raises is not). A remembered result
        for which ``fresh(result)`` is false counts as missing, and is replaced."""
        with self._lock:
            if key in self._results and (fresh is None or fresh(self._results[key])):
                self._results.move_to_end(key)
                self.hits += 1
                return self._results[key]
            self.misses += 1
        result = compute()
        if keep is not None and not keep(result):
            return result
        with self._lock:
            self._results[key] = result
            while len(self._results) > self.maxsize:
                self._results.popitem(last=False)
        return result

    def clear(self) -> None:
        """Forgets every result (the counts stay)."""
        with self._lock:
            self._results.clear()

    def __len__(self) -> int:
        return len(self._results)
