"""Opening a library for planning: features in a fixed order, frame checks, policies.

Shared by the ``plan``, ``train`` and ``simulate`` commands. Not for editing libraries
(``library.py``).
"""

from __future__ import annotations

from drake_lfd.core.features import Feature
from drake_lfd.io.library import Library


def library_features(library: Library) -> dict[str, Feature]:
    """Name -> feature (with its resampled poses), in the library's order."""
    return {name: library.feature(name) for name in library.names}
