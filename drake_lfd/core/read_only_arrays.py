"""Read-only numpy arrays for the frozen dataclasses that carry data between stages.

A frozen dataclass does not stop a caller from writing into the arrays it holds; these
copies do. Not for: checking what the values mean (the stage modules check that).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["read_only_array"]


def read_only_array(values: ArrayLike, shape: tuple[int, ...] | None = None) -> NDArray[np.float64]:
    """A float copy of ``values`` that cannot be written.

    Parameters
    ----------
    values : array-like
    shape : tuple of int, optional
        The shape ``values`` must have.

    Returns
    -------
    array : array, shape of ``values``
        A new float array with ``flags.writeable`` False.

    Raises
    ------
    ValueError
        If ``shape`` is given and differs.
    """
    array = np.array(values, dtype=float)
    if shape is not None and array.shape != shape:
        raise ValueError(f"expected shape {shape}, got {array.shape}")
    array.flags.writeable = False
    return array
