"""A library's features read: from its feature cache when a row vouches for a log as it
is, else computed from the log by forward kinematics; and the cache's missing rows
written.

:class:`LibraryFeatureReads` is the part of :class:`~drake_lfd.io.library.Library` that
reads features (``feature``, ``features``, ``feature_summaries``,
``write_feature_caches``). Reading never writes: a row is used when the log's stamp
(size, modification and change times, inode) is the row's and its key is fresh
(``io/feature_cache.py``; all of a library's rows in one query), and the feature is
recomputed from the log otherwise. Rows are written only by ``Library.add_prepared`` and
:meth:`LibraryFeatureReads.write_feature_caches` (which the command line calls before it
uses a library).

Not for: the cache's file format (:mod:`drake_lfd.io.feature_cache`), opening and
editing a library (:mod:`drake_lfd.io.library`), the feature math
(:mod:`drake_lfd.core.features`).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from pathlib import Path
from typing import NamedTuple

from drake_lfd.core.errors import InputError
from drake_lfd.core.features import Feature
from drake_lfd.io.demonstration_logs import log_sample_summary
from drake_lfd.io.feature_cache import (
    CACHE_NAME,
    JOURNAL_SUFFIX,
    CacheRow,
    cache_context,
    cache_key,
    delete_rows,
    feature_summary_rows,
    log_stamp,
    read_features,
    read_summaries,
    write_rows,
)
from drake_lfd.io.file_lock import shared_lock
from drake_lfd.io.library_manifest import CACHE_DIRECTORY, LOCK_NAME
from drake_lfd.io.library_store import collection_paused, library_temporaries, locked_for_writing
from drake_lfd.robot.kinematics import UR5eKinematics, dual_quaternions_from_demonstration

__all__ = ["FeatureRecord", "LogIdentity", "LibraryFeatureReads"]


class FeatureRecord(NamedTuple):
    """A demonstration's feature, the cache key it belongs to, whether the cache holds it
    for the log as it is (``on_disk``), and the row that stores it."""

    key: str
    feature: Feature
    on_disk: bool
    row: CacheRow | None  # None: the log changed while it was read (nothing to store)


class LogIdentity(NamedTuple):
    """What a joint log is now: its stamp, sha256, sample count and duration, and its
    bytes when they had to be read (None when its cache row vouches for it)."""

    stamp: object
    sha256: str
    samples: int
    duration_s: float
    log_bytes: bytes | None
    steady: bool  # False: the log changed while it was read


class LibraryFeatureReads:
    """The feature reading of :class:`~drake_lfd.io.library.Library`, which inherits it.

    It uses the library's ``path``, ``label``, ``read_only``, ``X_tool0_E``,
    ``num_samples``, ``rotation_length_m``, ``names``, ``entry``, ``demonstration`` and
    ``_refresh_manifest``, and keeps its memos in the library: ``_features`` (name ->
    :class:`FeatureRecord`), ``_rows`` (name -> the cache's row as read or written),
    ``_keys`` (log sha256 -> cache key), ``_context`` and ``_kinematics`` (built on
    first use).
    """

    def _start_feature_reads(self):
        """Empty memos (``Library.__init__`` calls this)."""
        self._features = {}  # name -> FeatureRecord
        self._kinematics = None  # built on first use, for X_tool0_E
        self._keys = {}  # log sha256 -> feature cache key, memoised
        self._context = None  # feature_cache.cache_context of the frame and parameters, on first use
        self._rows = {}  # name -> CacheRow, the feature cache's rows as read (or written) by this object

    def feature(self, name):
        """The feature ``HD`` of ``name`` (arc-length resampled, Eq. 12): from the feature
        cache when it holds it for the log as it is, else recomputed from the joint log.
        Writes nothing (see :meth:`write_feature_caches`)."""
        return self._feature_records([name])[name].feature

    def features(self, names=None):
        """Name -> feature of ``names`` (default: every demonstration, in the library's
        order), as :meth:`feature` gives them, read from the cache in one query; writes
        nothing."""
        # Under the shared lock, writers wait while the logs are read, and the library is
        # read as it is now: a demonstration another process removed since this object
        # read the manifest is no longer asked for (its log is gone).
        with shared_lock(self.path / LOCK_NAME):
            if names is None:
                self._refresh_manifest()
            names = self.names if names is None else tuple(names)
            with collection_paused():  # thousands of features and their arrays, no cycles
                records = self._feature_records(names)
        return {name: records[name].feature for name in names}

    def feature_summaries(self, names=None):
        """What a listing shows of each feature, without building the features: name ->
        ``(num_deltas, rotations, translations)``, the deltas' rotations (w, x, y, z) and
        translations at :data:`~drake_lfd.io.feature_cache.SUMMARY_FRACTIONS`
        (:func:`~drake_lfd.io.feature_cache.feature_summary_rows`), in ``names``' order
        (default: every demonstration). From the cache in one query, and from
        :meth:`feature` for a demonstration the cache does not hold for its log as it is.
        """
        names = self.names if names is None else tuple(names)
        wanted = {name: self._key(self._log_identity(name).sha256) for name in names}
        found = read_summaries(self._cache_path(), wanted)
        result = {}
        for name in names:
            if name not in found:
                feature = self.feature(name)
                found[name] = (len(feature), *feature_summary_rows(feature))
            result[name] = found[name]
        return result

    def resampled_poses(self, name):
        """The arc-length resampled end-effector poses of ``name`` as dual quaternions,
        shape (num_samples, 8), in the robot base frame: what the feature and the
        mapping (Eq. 22-25) index into."""
        return self.feature(name).poses

    def _cache_path(self):
        return self.path / CACHE_DIRECTORY / CACHE_NAME

    def write_feature_caches(self):
        """Stores in the feature cache every feature it lacks for the logs as they are.

        Reading never writes; ``add`` stores the new demonstration's feature, and the
        command line calls this before using a library, so a user's library keeps a
        fresh cache (rows of demonstrations no longer listed, and the per-demonstration
        ``cache/NAME.npz`` files of older drake-lfd versions, are deleted too). A
        read-only (bundled) library keeps no cache: nothing is written. A cache that
        cannot be written is skipped (it is an optimisation).

        Returns
        -------
        names : tuple of str
            The demonstrations whose cache row was written.
        """
        if self.read_only:
            return ()
        # A row is fresh when the log's stamp is the row's and its key the one wanted: then
        # nothing is read. The others are computed under the shared lock (writers wait;
        # the library as it is now), then written under the exclusive one.
        with shared_lock(self.path / LOCK_NAME):
            self._refresh_manifest()
            stale = [name for name in self.names if not self._row_is_fresh(name)]
            records = self._feature_records(stale)
        missing = [(name, records[name]) for name in stale if not records[name].on_disk and records[name].row]
        listed = set(self.names)
        unlisted = [name for name in self._rows if name not in listed]
        legacy = [p for p in (self.path / CACHE_DIRECTORY).glob("*.npz") if p.stem in listed]
        if not (missing or unlisted or legacy or library_temporaries(self.path)):
            return ()  # nothing to write, and no debris of a killed writer to clear
        written = []
        try:
            with locked_for_writing(self.path, self.label):
                if missing and write_rows(self._cache_path(), [(record.row, record.feature) for _, record in missing]):
                    for name, record in missing:
                        self._features[name] = record._replace(on_disk=True)
                        self._rows[name] = record.row
                        written.append(name)
                journal = self._cache_path().with_name(CACHE_NAME + JOURNAL_SUFFIX)
                # (Any write rolls back the journal a killed writer left, and deletes it.)
                if (unlisted or journal.exists()) and delete_rows(self._cache_path(), unlisted):
                    for name in unlisted:
                        self._rows.pop(name, None)
                for path in legacy:
                    with contextlib.suppress(OSError):
                        path.unlink()
        except InputError:  # the lock cannot be taken (read-only directory): no caches
            return ()
        return tuple(written)

    def _row_is_fresh(self, name):
        """Whether the cache row read for ``name`` holds its feature for the log as it is."""
        row = self._rows.get(name)
        memo = self._features.get(name)
        if row is None or (memo is not None and not memo.on_disk):  # (its row could not be used)
            return False
        try:
            stamp = log_stamp(os.path.join(self.path, self.entry(name).file))
        except OSError:
            return False
        return row.stamp == stamp and row.feature_key == self._key(row.sha256)

    def _key(self, sha256):
        key = self._keys.get(sha256)
        if key is None:
            if self._context is None:
                self._context = cache_context(self.X_tool0_E, self.num_samples, self.rotation_length_m)
            key = self._keys[sha256] = cache_key(sha256, self._context)
        return key

    def _log_identity(self, name):
        """The :class:`LogIdentity` of ``name``'s log: from its cache row when the log's
        stamp is the row's, else by reading the log."""
        log = os.path.join(self.path, self.entry(name).file)
        try:
            stamp = log_stamp(log)
            row = self._rows.get(name)
            if row is not None and row.stamp == stamp:
                return LogIdentity(stamp, row.sha256, row.samples, row.duration_s, None, True)
            log = Path(log)
            log_bytes = log.read_bytes()
            steady = log_stamp(log) == stamp
        except OSError as error:
            raise InputError(f"cannot read the joint log: {error.strerror}", file=log) from None
        samples, duration_s = log_sample_summary(log_bytes, log)
        return LogIdentity(stamp, hashlib.sha256(log_bytes).hexdigest(), samples, duration_s, log_bytes, steady)

    def _feature_records(self, names):
        """Name -> :class:`_FeatureRecord` of ``names``: memoised, else from the cache (one
        query for all), else computed from the log."""
        records, wanted, identities = {}, {}, {}
        for name in names:
            identity = self._log_identity(name)
            key = self._key(identity.sha256)
            memo = self._features.get(name)
            if memo is not None and memo.key == key:
                records[name] = memo
            else:
                wanted[name], identities[name] = key, identity
        stored = read_features(self._cache_path(), wanted) if wanted else {}
        for name, key in wanted.items():
            identity = identities[name]
            row = None
            if identity.steady:
                row = CacheRow(name, identity.stamp, identity.sha256, identity.samples, identity.duration_s, key)
            feature = stored.get(name)
            if feature is None:
                feature = self._compute_feature(self.demonstration(name))
            on_disk = name in stored and self._rows.get(name) == row
            record = FeatureRecord(key, feature, on_disk, row)
            self._features[name] = record
            records[name] = record
        return records

    def _dual_quaternions(self, demonstration):
        """Raw poses of E in the base frame (``X_WB`` = identity), shape (m, 8)."""
        if self._kinematics is None:
            self._kinematics = UR5eKinematics(X_tool0_E=self.X_tool0_E)
        return dual_quaternions_from_demonstration(demonstration, self._kinematics)

    def _compute_feature(self, demonstration):
        return Feature.from_poses(
            self._dual_quaternions(demonstration),
            num_samples=self.num_samples,
            rotation_length_m=self.rotation_length_m,
        )
