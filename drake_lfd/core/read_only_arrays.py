"""Read-only numpy arrays for the frozen dataclasses that carry data between stages."""

from __future__ import annotations

import numpy as np


def read_only_array(values, shape=None) -> np.ndarray:
    """A float copy of ``values`` that cannot be written; ValueError if ``shape`` differs."""
    array = np.array(values, dtype=float)
    if shape is not None and array.shape != shape:
        raise ValueError(f"expected shape {shape}, got {array.shape}")
    array.flags.writeable = False
    return array
