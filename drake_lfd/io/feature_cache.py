"""Feature cache files: a demonstration's feature saved beside its log, and when to trust it.

A library keeps ``cache/<name>.npz`` per demonstration: the arrays of its
:class:`~drake_lfd.core.features.Feature` and the key they were computed for. The key
(:func:`cache_key`) hashes everything that decides the feature's numbers: the log's
bytes, the end-effector frame ``X_tool0_E``, the feature parameters, and the source of
the code that computes features (:func:`code_fingerprint`: ``features.py``,
``dual_quaternion.py``, ``kinematics.py`` and the UR5e model). A cache whose key differs,
or that is missing or unreadable, is not used (:func:`read_feature_cache` returns None)
and the feature is recomputed from the log. Writing (:func:`write_feature_cache`) is
atomic, so a reader sees the old cache or the new one, never half of one.

Not for: deciding when to write (the library's ``add`` and
``Library.write_feature_caches``, :mod:`drake_lfd.io.library`), computing features
(:mod:`drake_lfd.core.features`).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
from pathlib import Path

import numpy as np

from drake_lfd.core import dual_quaternion as _dual_quaternion_module
from drake_lfd.core import features as _features_module
from drake_lfd.core.features import Feature
from drake_lfd.core.resources import models_directory
from drake_lfd.io.atomic_files import atomic_write_bytes, fsync_directory
from drake_lfd.robot import kinematics as _kinematics_module

__all__ = [
    "CACHE_FORMAT",
    "code_fingerprint",
    "cache_key",
    "feature_npz_bytes",
    "read_feature_cache",
    "write_feature_cache",
]

# Bump when the cache file's layout changes.
CACHE_FORMAT = "drake-lfd-feature-cache-1"

_FEATURE_FIELDS = tuple(field.name for field in dataclasses.fields(Feature))


# Memoised for the life of the process: the hash is of the source that was imported, which
# is the code that computes this process's features.
@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of everything besides the log that decides a feature's numbers."""
    digest = hashlib.sha256()
    for path in (
        Path(_features_module.__file__),
        Path(_dual_quaternion_module.__file__),
        Path(_kinematics_module.__file__),
        models_directory() / "ur5e" / "ur5e.urdf",
    ):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_key(log_bytes, X_tool0_E, num_samples, rotation_length_m) -> str:
    """The key a cache file must carry to be used for this log, frame and parameters."""
    digest = hashlib.sha256()
    digest.update(CACHE_FORMAT.encode())
    digest.update(hashlib.sha256(log_bytes).digest())
    digest.update(np.ascontiguousarray(X_tool0_E.GetAsMatrix4(), dtype=float).tobytes())
    digest.update(repr((int(num_samples), float(rotation_length_m))).encode())
    digest.update(code_fingerprint().encode())
    return digest.hexdigest()


def feature_npz_bytes(key, feature) -> bytes:
    """The bytes of a cache file holding ``feature`` under ``key``."""
    arrays = {"key": np.array(key)}
    for name in _FEATURE_FIELDS:
        value = getattr(feature, name)
        if value is not None:
            arrays[name] = np.asarray(value)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def read_feature_cache(path, key) -> Feature | None:
    """The cached feature if ``path`` holds one for ``key``, else None (missing, damaged
    or stale files alike); its arrays are read-only."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            values = {}
            for name in _FEATURE_FIELDS:
                values[name] = np.array(data[name]) if name in data.files else None
    except (OSError, ValueError, KeyError, EOFError):
        return None
    for value in values.values():
        if value is not None:
            value.flags.writeable = False
    try:
        return Feature(**values)
    except (TypeError, ValueError):
        return None


def write_feature_cache(path, key, feature) -> bool:
    """Writes the cache file atomically, making its folder if needed; True if written.

    An unwritable cache is not an error (it is an optimisation: the feature is recomputed
    next time), so ``OSError`` gives False.
    """
    path = Path(path)
    try:
        if not path.parent.is_dir():
            path.parent.mkdir(parents=True, exist_ok=True)
            fsync_directory(path.parent.parent)
        atomic_write_bytes(path, feature_npz_bytes(key, feature))
    except OSError:
        return False
    return True
