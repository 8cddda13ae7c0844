"""A library's feature cache, ``cache/features.sqlite``: what was checked about each log, and its feature.

One SQLite database per library (Python's ``sqlite3``), derived data that may be
deleted. It has one row per demonstration (:class:`CacheRow`): the identity of the
demonstration's joint log when it was last read (:class:`LogStamp`: size, modification
and change times in nanoseconds, inode), the sha256 of its bytes, the sample count and
duration read from it, the feature key (:func:`cache_key`), the feature's arrays, and
the few numbers of it that a listing shows (:data:`SUMMARY_FRACTIONS`), so that listing
10,000 demonstrations reads no feature.

What the rows are trusted for (the library, ``io/library.py``, decides when):

- A log whose :func:`log_stamp` equals its row's is the file that was read when the
  row was written (any write through the file system changes the change time, which no
  program can set back), so its sha256, samples and duration are the row's without
  reading it.
- A row's feature is used only when its key equals the one wanted: the key hashes
  everything that decides the feature's numbers (the log's sha256, the end-effector
  frame ``X_tool0_E``, the feature parameters, and the source of the code that computes
  features, :func:`code_fingerprint`).

Reading (:func:`read_rows`, :func:`read_features`) opens the database read-only and
never writes; a missing, damaged or locked database reads as empty (everything is then
recomputed from the logs). Writing (:func:`write_rows`, :func:`delete_rows`) is one
SQLite transaction (rollback journal, ``synchronous=FULL``): a reader, or a crash, sees
all of it or none of it; a database that cannot be read is replaced. Writers hold the
library's lock; SQLite's own locking orders them against readers.

Not for: deciding when to write (``Library.add``, ``Library.write_feature_caches``,
:mod:`drake_lfd.io.library`), computing features (:mod:`drake_lfd.core.features`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import sqlite3
import struct
from pathlib import Path
from typing import NamedTuple

import numpy as np

from drake_lfd.core import dual_quaternion as _dual_quaternion_module
from drake_lfd.core import features as _features_module
from drake_lfd.core import pose_conversions as _pose_conversions_module
from drake_lfd.core import quaternion as _quaternion_module
from drake_lfd.core import screw_motion as _screw_motion_module
from drake_lfd.core.features import Feature
from drake_lfd.core.resources import models_directory
from drake_lfd.robot import kinematics as _kinematics_module

__all__ = [
    "CACHE_FORMAT",
    "CACHE_NAME",
    "JOURNAL_SUFFIX",
    "LogStamp",
    "CacheRow",
    "log_stamp",
    "code_fingerprint",
    "cache_context",
    "cache_key",
    "read_rows",
    "read_features",
    "SUMMARY_FRACTIONS",
    "summary_indices",
    "feature_summary_rows",
    "read_summaries",
    "write_rows",
    "delete_rows",
]

# Bump when the rows' layout or the key's recipe changes (an older database is then ignored).
CACHE_FORMAT = "drake-lfd-feature-cache-4"
#: The database's file name in the library's ``cache/`` directory.
CACHE_NAME = "features.sqlite"
#: SQLite's rollback journal beside the database (present only during a write, or after a
#: writer was killed: the next writer rolls it back and deletes it).
JOURNAL_SUFFIX = "-journal"
#: Where along a feature (fractions of its deltas) a listing shows it (``library show``):
#: each row stores the deltas' rotation and translation there, so a listing reads no feature.
SUMMARY_FRACTIONS = (0.0, 0.5, 0.75)
# Up to this many rows are read by name; more, by reading the whole table once.
_FEW = 100
# Seconds a reader or writer waits for SQLite's own lock before giving up on the cache.
_BUSY_TIMEOUT_S = 30.0
# The feature's arrays, in the order of the row's columns.
_PARTS = ("rotations", "translations", "deltas", "poses")
_WIDTHS = {"rotations": 4, "translations": 3, "deltas": 8, "poses": 8}

_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    "CREATE TABLE IF NOT EXISTS demos ("
    " name TEXT PRIMARY KEY, size INTEGER NOT NULL, mtime_ns INTEGER NOT NULL, ctime_ns INTEGER NOT NULL,"
    " inode INTEGER NOT NULL, sha256 TEXT NOT NULL, samples INTEGER NOT NULL, duration_s REAL NOT NULL,"
    " feature_key TEXT NOT NULL, num_deltas INTEGER NOT NULL,"
    " summary BLOB NOT NULL, rotations BLOB NOT NULL, translations BLOB NOT NULL, deltas BLOB NOT NULL, poses BLOB)",
)


class LogStamp(NamedTuple):
    """A file's identity as ``os.stat`` gives it; equal stamps, unchanged file."""

    size: int
    mtime_ns: int
    ctime_ns: int
    inode: int


class CacheRow(NamedTuple):
    """One demonstration's row, without the feature arrays.

    Attributes
    ----------
    name : str
    stamp : LogStamp
        The joint log's stamp when it was read.
    sha256 : str
        Hex digest of the log's bytes then.
    samples : int
    duration_s : float
        What the log held then (``demonstration_logs.log_sample_summary``).
    feature_key : str
        :func:`cache_key` of the stored feature.
    """

    name: str
    stamp: LogStamp
    sha256: str
    samples: int
    duration_s: float
    feature_key: str


def log_stamp(path) -> LogStamp:
    """The :class:`LogStamp` of ``path`` (follows a symbolic link); raises ``OSError``."""
    status = os.stat(path)
    return LogStamp(status.st_size, status.st_mtime_ns, status.st_ctime_ns, status.st_ino)


# Memoised for the life of the process: the hash is of the source that was imported, which
# is the code that computes this process's features.
@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of everything besides the log that decides a feature's numbers."""
    digest = hashlib.sha256()
    for path in (
        Path(_features_module.__file__),
        Path(_dual_quaternion_module.__file__),
        Path(_quaternion_module.__file__),
        Path(_pose_conversions_module.__file__),
        Path(_screw_motion_module.__file__),
        Path(_kinematics_module.__file__),
        models_directory() / "ur5e" / "ur5e.urdf",
    ):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_context(X_tool0_E, num_samples, rotation_length_m) -> bytes:
    """Hash of everything but the log that a feature key covers: the cache's format, the
    end-effector frame, the feature parameters and :func:`code_fingerprint` (computed once
    per library, so a key costs one small hash per log)."""
    digest = hashlib.sha256()
    digest.update(CACHE_FORMAT.encode())
    digest.update(np.ascontiguousarray(X_tool0_E.GetAsMatrix4(), dtype=float).tobytes())
    digest.update(repr((int(num_samples), float(rotation_length_m))).encode())
    digest.update(code_fingerprint().encode())
    return digest.digest()


def cache_key(log_sha256, context) -> str:
    """The key a row's feature must carry to be used for this log and context.

    Parameters
    ----------
    log_sha256 : str
        Hex sha256 of the joint log's bytes.
    context : bytes
        :func:`cache_context` of the library's frame and feature parameters.
    """
    return hashlib.sha256(context + bytes.fromhex(log_sha256)).hexdigest()


@contextlib.contextmanager
def _reading(path):
    """A read-only connection, or None when the database is missing or unreadable. Read-only
    opening creates nothing (no database, no journal)."""
    path = Path(path)
    connection = None
    if path.is_file():
        try:
            connection = sqlite3.connect(f"{path.absolute().as_uri()}?mode=ro", uri=True, timeout=_BUSY_TIMEOUT_S)
            row = connection.execute("SELECT value FROM meta WHERE key = 'format'").fetchone()
            if row is None or row[0] != CACHE_FORMAT:
                connection.close()
                connection = None
        except sqlite3.Error:
            if connection is not None:
                connection.close()
            connection = None
    try:
        yield connection
    finally:
        if connection is not None:
            connection.close()


def read_rows(path) -> dict[str, CacheRow]:
    """Name -> :class:`CacheRow` of every row (no arrays); empty when the database is
    missing, damaged or of another format."""
    with _reading(path) as connection:
        if connection is None:
            return {}
        try:
            fetched = connection.execute(
                "SELECT name, size, mtime_ns, ctime_ns, inode, sha256, samples, duration_s, feature_key FROM demos"
            ).fetchall()
        except sqlite3.Error:
            return {}
    return {
        row[0]: CacheRow(row[0], LogStamp(*row[1:5]), row[5], int(row[6]), float(row[7]), row[8]) for row in fetched
    }


def _array(blob, rows, width):
    # An owned, read-only copy: Feature keeps it as it is.
    array = np.frombuffer(blob, dtype="<f8").reshape(rows, width).astype(np.float64, copy=True)
    array.flags.writeable = False
    return array


def read_features(path, wanted, parts=None) -> dict:
    """The stored features whose key is the one wanted.

    Parameters
    ----------
    path : Path
        The database.
    wanted : dict
        Name -> the feature key wanted for it.
    parts : sequence of str, optional
        Only these arrays (of ``rotations``, ``translations``, ``deltas``, ``poses``),
        as a dict per name; default: the whole :class:`Feature`.

    Returns
    -------
    dict
        Name -> Feature (or dict of read-only arrays, shapes (n - 1, 4), (n - 1, 3),
        (n - 1, 8), (n, 8)) for the names whose row has the wanted key; a damaged row
        is left out (the caller recomputes it).
    """
    chosen = _PARTS if parts is None else tuple(parts)
    found = {}
    with _reading(path) as connection:
        if connection is None or not wanted:
            return found
        try:
            query = f"SELECT name, feature_key, num_deltas, {', '.join(chosen)} FROM demos"
            if len(wanted) <= _FEW:  # a few: read their rows only, not every feature of the library
                cursor = connection.execute(f"{query} WHERE name IN ({', '.join('?' * len(wanted))})", list(wanted))
            else:
                cursor = connection.execute(query)
            for row in cursor:
                name, key, num_deltas = row[0], row[1], row[2]
                if wanted.get(name) != key:
                    continue
                try:
                    arrays = {
                        part: None if blob is None else _array(blob, num_deltas + (part == "poses"), _WIDTHS[part])
                        for part, blob in zip(chosen, row[3:])
                    }
                    found[name] = Feature(**arrays) if parts is None else arrays
                except (TypeError, ValueError):
                    continue
        except sqlite3.Error:
            return {}
    return found


def summary_indices(num_deltas):
    """The deltas :data:`SUMMARY_FRACTIONS` pick of a feature of ``num_deltas`` deltas."""
    return tuple(int(round(fraction * (num_deltas - 1))) for fraction in SUMMARY_FRACTIONS)


def feature_summary_rows(feature):
    """``(rotations, translations)`` of ``feature`` at :func:`summary_indices`: lists of 3
    tuples (w, x, y, z) and (x, y, z)."""
    indices = list(summary_indices(len(feature.deltas)))
    return ([tuple(row) for row in feature.rotations[indices].tolist()],
            [tuple(row) for row in feature.translations[indices].tolist()])


def _summary_blob(feature):
    rotations, translations = feature_summary_rows(feature)
    return struct.pack(f"<{7 * len(SUMMARY_FRACTIONS)}d", *(v for row in rotations + translations for v in row))


def read_summaries(path, wanted) -> dict:
    """The listing's numbers of the stored features whose key is the one wanted, without
    reading the features (168 bytes a row: a listing of 10,000 reads 2 MB).

    Parameters
    ----------
    path : Path
    wanted : dict
        Name -> the feature key wanted for it.

    Returns
    -------
    dict
        Name -> ``(num_deltas, rotations, translations)`` as :func:`feature_summary_rows`.
    """
    found = {}
    count = len(SUMMARY_FRACTIONS)
    with _reading(path) as connection:
        if connection is None or not wanted:
            return found
        try:
            for name, key, num_deltas, blob in connection.execute(
                "SELECT name, feature_key, num_deltas, summary FROM demos"
            ):
                if wanted.get(name) != key:
                    continue
                try:
                    values = struct.unpack(f"<{7 * count}d", blob)
                except (struct.error, TypeError):
                    continue
                found[name] = (num_deltas, [values[4 * i:4 * i + 4] for i in range(count)],
                               [values[4 * count + 3 * i:4 * count + 3 * i + 3] for i in range(count)])
        except sqlite3.Error:
            return {}
    return found


@contextlib.contextmanager
def _writing(path):
    """A connection inside one transaction (committed at the end, rolled back on error);
    a database that cannot be used is replaced by a new one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    for attempt in (0, 1):
        connection = sqlite3.connect(path, timeout=_BUSY_TIMEOUT_S, isolation_level=None)
        try:
            connection.execute("PRAGMA journal_mode = DELETE")
            connection.execute("PRAGMA synchronous = FULL")
            connection.execute("BEGIN IMMEDIATE")
            connection.execute(_SCHEMA[0])
            row = connection.execute("SELECT value FROM meta WHERE key = 'format'").fetchone()
            if row is None or row[0] != CACHE_FORMAT:  # new, or of another format: start afresh
                connection.execute("DROP TABLE IF EXISTS demos")
                connection.execute("INSERT OR REPLACE INTO meta VALUES ('format', ?)", (CACHE_FORMAT,))
            connection.execute(_SCHEMA[1])
            break
        except sqlite3.DatabaseError:
            connection.close()
            if attempt:
                raise
            # Not a database (damaged, or another file): it is derived data, start afresh.
            for stale in (path, path.with_name(path.name + JOURNAL_SUFFIX)):
                with contextlib.suppress(FileNotFoundError):
                    stale.unlink()
    try:
        yield connection
        connection.execute("COMMIT")
    except BaseException:
        with contextlib.suppress(sqlite3.Error):
            connection.execute("ROLLBACK")
        raise
    finally:
        connection.close()


def _blob(array):
    return None if array is None else np.ascontiguousarray(array, dtype="<f8").tobytes()


def write_rows(path, rows) -> bool:
    """Stores rows, replacing any of the same names, in one transaction; True if written.

    Parameters
    ----------
    path : Path
        The database (created with its folder if missing).
    rows : iterable of (CacheRow, Feature)

    An unwritable cache is not an error (it is an optimisation: features are recomputed
    next time), so ``OSError`` and SQLite errors give False.
    """
    values = [
        (row.name, *row.stamp, row.sha256, row.samples, row.duration_s, row.feature_key, len(feature.deltas),
         _summary_blob(feature), *(_blob(getattr(feature, part)) for part in _PARTS))
        for row, feature in rows
    ]
    try:
        with _writing(path) as connection:
            connection.executemany(f"INSERT OR REPLACE INTO demos VALUES ({', '.join('?' * 15)})", values)
    except (OSError, sqlite3.Error):
        return False
    return True


def delete_rows(path, names) -> bool:
    """Deletes the rows of ``names`` (those present) in one transaction; True if done (or
    there is no database)."""
    if not Path(path).exists():
        return True
    try:
        with _writing(path) as connection:
            connection.executemany("DELETE FROM demos WHERE name = ?", [(name,) for name in names])
    except (OSError, sqlite3.Error):
        return False
    return True
