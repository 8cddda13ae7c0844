"""The demonstration library ``LB = {HD_1, ..., HD_k}`` (Eq. 14), kept as a directory.

A library is a folder a user can read and back up with ordinary tools::

    LIB/
      library.json          the manifest (io/library_manifest.py): what the library holds
      demos/<name>.csv      one joint log per demonstration, the project's RTDE-style CSV
      cache/features.sqlite the feature cache (derived data, io/feature_cache.py)
      library.lock          empty; writers hold an exclusive flock on it (file_lock.py)

:class:`Library` opens, creates, reads and edits one; docs/libraries.rst documents the
directory for users.

The joint logs are the source of truth. Features depend on the end-effector frame, so
the library stores the one its demonstrations were recorded with (``X_tool0_E``) and
planning a task with another frame is refused (:func:`check_end_effector_frame`).
Features are computed by forward kinematics (with ``X_WB`` = identity: features do not
depend on where the robot stands). Reading a feature (:meth:`Library.feature`,
:meth:`Library.features`, :func:`library_features`) never writes: it uses the cache's
row when the log's stamp is the row's and its key is fresh (``io/feature_cache.py``;
all of a library's rows in one query) and recomputes from the log otherwise. Rows are
written only by :meth:`Library.add_prepared` (``add``) and
:meth:`Library.write_feature_caches` (which the command line calls before it uses a
library).

Durability: every file is written atomically (``atomic_files.atomic_write_bytes``: a
temporary file in the same directory, flushed and fsynced, ``os.replace``, then the
directory fsynced). ``add`` writes the logs before the manifest that references them (many at once:
:meth:`Library.add_prepared`, one turn of the lock and one manifest write),
``remove`` rewrites the manifest before deleting the log. A crash therefore leaves at
worst an unreferenced log (ignored, overwritten by a later ``add`` of that name) or a
temporary file, never a manifest pointing at a missing or partial log.

Concurrency: every write (``create``, ``add``, ``remove``, ``write_feature_caches``)
holds the exclusive lock on ``library.lock`` across its whole read-modify-write: it
re-reads the manifest from disk under the lock (so two ``add`` of different
demonstrations both land, and a name taken meanwhile is refused), writes the log, the
manifest and the cache, and first deletes the temporary files a killed writer left
(``.*.tmp``; under the lock no other writer can be mid-write). Opening a library holds
the shared lock while it reads the manifest and checks it against the logs, so a reader
never sees a manifest without its logs. The kernel frees a dead holder's lock.

Consistency: opening a library checks each entry against its log (the log exists, and
its sample count and duration are the manifest's ``samples`` and ``duration_s``), one
error naming the manifest and the field. A log whose stamp (size, modification and
change times, inode) is its cache row's is not read: the row holds what it had; any
other log is read and summarised. ``open(..., check_logs=False)`` skips this so
``remove`` can drop an entry whose log was deleted or damaged. Every check of a new
demonstration runs before anything is written, so a refused ``add`` (or
:meth:`Library.create_with`, a new library with its first demonstration) changes
nothing and creates nothing.

Names: ``Library.open`` takes a path to an existing directory, else the name of a
library bundled with drake-lfd (``drake_lfd/sims/libraries/<name>/`` when installed,
``sims/libraries/<name>/`` in a checkout; :func:`bundled_library_paths` says where).
Bundled libraries opened by name are read-only; :func:`copy_library` makes an editable
copy of one (or of any library) in a new directory, atomically. Demonstration names match ``[A-Za-z0-9_-]+`` and are unique ignoring case (so
their log files do not collide on case-insensitive file systems).

Not for: the manifest's format (``library_manifest.py``), the cache files
(``feature_cache.py``), reading foreign log formats (``demonstration_logs.py``, ``rtde_logs.py``, ``rosbag_logs.py``, ``log_import.py``),
comparing features (``similarity.py``), the command line (``cli/library.py``).
"""

from __future__ import annotations

import contextlib
import datetime
import gc
import hashlib
import math
import os
import shutil
import uuid
from pathlib import Path
from typing import NamedTuple

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.demonstrations import Demonstration, check_demonstration
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import (
    DEFAULT_NUM_SAMPLES,
    DEFAULT_ROTATION_LENGTH_M,
    Feature,
    arc_lengths_from_poses,
)
from drake_lfd.core.resources import bundled_library_directories, bundled_library_names, bundled_library_paths
from drake_lfd.io.atomic_files import atomic_write_bytes, atomic_write_many, fsync_directory
from drake_lfd.io.demonstration_logs import (
    check_plausible_motion,
    log_sample_summary,
    read_rtde_csv,
    rtde_csv_text,
)
from drake_lfd.io.feature_cache import (
    CACHE_NAME,
    JOURNAL_SUFFIX,
    CacheRow,
    cache_context,
    cache_key,
    delete_rows,
    log_stamp,
    feature_summary_rows,
    read_features,
    read_rows,
    read_summaries,
    write_rows,
)
from drake_lfd.io.file_lock import LockUnavailable, exclusive_lock, shared_lock
from drake_lfd.io.library_manifest import (
    CACHE_DIRECTORY,
    DEMOS_DIRECTORY,
    LOCK_NAME,
    MANIFEST_NAME,
    NAME_PATTERN,
    DemoEntry,
    Manifest,
    check_demo_name,
    read_manifest,
    read_manifest_bytes,
    write_manifest,
)
from drake_lfd.io.pose_records import angle_text, euler_zyx_from_rigid_transform, number_text, pose_yaml_text
from drake_lfd.robot.kinematics import UR5eKinematics, dual_quaternions_from_demonstration

__all__ = [
    "END_EFFECTOR_FRAME_TOLERANCE",
    "MIN_MOTION_LENGTH",
    "DURATION_TOLERANCE_S",
    "bundled_library_names",
    "bundled_library_paths",
    "tool_frame_options",
    "is_unused_library_directory",
    "remove_stale_temporaries",
    "collection_paused",
    "DemonstrationPreparer",
    "Library",
    "copy_library",
    "library_features",
    "check_end_effector_frame",
]

# Two end-effector frames closer than this (max abs difference of the 4x4 matrices)
# are the same frame written twice; anything more changes the features.
END_EFFECTOR_FRAME_TOLERANCE = 1e-9
# A demonstration whose tool path is shorter than this (arc length in metres, rotation
# counted as in features.py) does not move and has no feature worth matching.
MIN_MOTION_LENGTH = 1e-6


# A duration in the manifest within this of the log's (s) is the same duration.
DURATION_TOLERANCE_S = 1e-6


def _make_directory(path):
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        fsync_directory(path.parent)


def _temporaries(directory):
    """The temporary files an interrupted atomic write of a library file leaves."""
    directory = Path(directory)
    found = list(directory.glob(f".{MANIFEST_NAME}.*.tmp"))
    for sub in (DEMOS_DIRECTORY, CACHE_DIRECTORY):
        if (directory / sub).is_dir():
            found += [p for p in (directory / sub).glob(".*.tmp") if p.is_file()]
    journal = directory / CACHE_DIRECTORY / (CACHE_NAME + JOURNAL_SUFFIX)
    if journal.is_file():
        found.append(journal)
    return found


def remove_stale_temporaries(directory):
    """Deletes the temporary files (``.*.tmp``) that writers killed mid-write left in a
    library directory; call with the library's lock held (then no write is under way).
    A feature cache's rollback journal is left to SQLite: the next write of the cache
    rolls it back and deletes it (:mod:`~drake_lfd.io.feature_cache`). Returns the paths
    deleted."""
    removed = []
    for path in _temporaries(directory):
        if path.name.endswith(JOURNAL_SUFFIX):
            continue
        try:
            path.unlink()
            removed.append(path)
        except FileNotFoundError:
            pass
    return removed


def is_unused_library_directory(path):
    """True if ``path`` does not exist, or is a directory without a manifest that holds
    nothing but what a library write killed before its manifest leaves (the lock file,
    temporary files, ``demos/`` (with the logs of a killed create when the lock file is
    there) and an empty ``cache/``): a place a new library may go."""
    path = Path(path)
    if not path.exists():
        return True
    if not path.is_dir() or (path / MANIFEST_NAME).exists():
        return False
    debris = {str(p) for p in _temporaries(path)}
    if (path / LOCK_NAME).is_file() and (path / DEMOS_DIRECTORY).is_dir():
        # A create killed between its logs and its manifest (``Library.create(first=...)``).
        debris |= {str(p) for p in (path / DEMOS_DIRECTORY).iterdir() if p.is_file()}
    for child in path.iterdir():
        if child.name == LOCK_NAME and child.is_file():
            continue
        if str(child) in debris:
            continue
        if child.name in (DEMOS_DIRECTORY, CACHE_DIRECTORY) and child.is_dir():
            if all(str(grandchild) in debris for grandchild in child.iterdir()):
                continue
        return False
    return True


@contextlib.contextmanager
def collection_paused():
    """Pauses Python's cyclic garbage collector while a block builds many small objects
    that form no cycles (a manifest's entries, a listing's rows): with 10,000
    demonstrations its repeated scans of them took a quarter of the time."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


@contextlib.contextmanager
def _writing(directory, label):
    """Holds the library's exclusive lock and clears stale temporaries first."""
    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(exclusive_lock(Path(directory) / LOCK_NAME))
        except LockUnavailable as error:
            raise InputError(
                f"cannot lock the library for writing ({error.strerror}: {error.filename})", file=label
            ) from None
        remove_stale_temporaries(directory)
        yield


def _check_logs(directory, manifest, rows):
    """Each entry against its log: present, same sample count and duration.

    A log whose stamp (size, modification and change time, inode) is its cache row's is
    the file the row was read from, so the row's sample count and duration are the
    log's and the log is not read again; any other log is read and summarised."""
    manifest_path = Path(directory) / MANIFEST_NAME
    for index, entry in enumerate(manifest.entries):
        log = os.path.join(directory, entry.file)  # a string: thousands of Path joins cost more than the stats
        field = f"demos[{index}]"
        remedy = (
            f"restore the log, or drop the entry with 'drake-lfd library remove {directory} {entry.name}' "
            "and add the demonstration again"
        )
        row = rows.get(entry.name)
        try:
            if row is not None and row.stamp == log_stamp(log):
                samples, duration_s = row.samples, row.duration_s
            else:
                log = Path(log)
                samples, duration_s = log_sample_summary(log.read_bytes(), log)
        except FileNotFoundError:
            raise InputError(
                f"the joint log {entry.file} is missing; {remedy}", file=manifest_path, field=f"{field}.file"
            ) from None
        except OSError as error:
            raise InputError(f"cannot read the joint log: {error.strerror}", file=log) from None
        if samples != entry.samples:
            raise InputError(
                f"is {entry.samples} but the joint log {entry.file} has {samples} samples "
                f"(one of them was edited by hand); {remedy}",
                file=manifest_path,
                field=f"{field}.samples",
            )
        if not math.isclose(duration_s, entry.duration_s, rel_tol=0.0, abs_tol=DURATION_TOLERANCE_S):
            raise InputError(
                f"is {entry.duration_s!r} s but the joint log {entry.file} spans {duration_s!r} s "
                f"(one of them was edited by hand); {remedy}",
                file=manifest_path,
                field=f"{field}.duration_s",
            )


class _PendingDemo(NamedTuple):
    """A checked demonstration ready to be written: entry, log bytes, feature."""

    entry: DemoEntry
    log_bytes: bytes
    feature: Feature


def _prepare(demonstration, name, description, *, kinematics, num_samples, rotation_length_m, source, label):
    """Every check of a new demonstration that does not depend on what the library
    holds (name syntax, the demonstration itself, that it moves the tool)."""
    check_demo_name(name)
    if not isinstance(description, str):
        raise InputError(f"expected a string, got {description!r}", field="description")
    file = label if source is None else source
    check_demonstration(demonstration, file=file)
    check_plausible_motion(
        demonstration.timestamps, demonstration.joint_positions, file=file, field_of=lambda i: f"sample {i}"
    )
    stored = Demonstration(
        name=name,
        timestamps=demonstration.timestamps,
        joint_positions=demonstration.joint_positions,
        description=description,
    )
    D = dual_quaternions_from_demonstration(stored, kinematics)
    length = float(arc_lengths_from_poses(D, rotation_length_m)[-1])
    if not length > MIN_MOTION_LENGTH:
        raise InputError(
            f"the demonstration does not move the tool (its path is {length:.3g} m long, counting "
            f"{rotation_length_m:g} m per radian of rotation); it has no feature to learn",
            file=file,
            field="samples",
        )
    feature = Feature.from_poses(D, num_samples=num_samples, rotation_length_m=rotation_length_m)
    entry = DemoEntry(
        name=name,
        file=f"{DEMOS_DIRECTORY}/{name}.csv",
        samples=stored.num_samples,
        duration_s=stored.duration_s,
        description=description,
        added=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    )
    return _PendingDemo(entry, rtde_csv_text(stored).encode("utf-8"), feature)


class DemonstrationPreparer:
    """Checks new demonstrations and computes their features for one end-effector frame,
    before any library is touched: what ``library add`` of many logs runs on each log
    (:meth:`Library.prepare` uses one too).

    Parameters
    ----------
    X_tool0_E : RigidTransform
    label : str
        How to name the library in errors.
    num_samples, rotation_length_m
        Feature parameters (``features.Feature.from_poses``).
    """

    def __init__(self, X_tool0_E, label, num_samples=DEFAULT_NUM_SAMPLES,
                 rotation_length_m=DEFAULT_ROTATION_LENGTH_M):
        self.kinematics = UR5eKinematics(X_tool0_E=X_tool0_E)
        self.label = str(label)
        self.num_samples = int(num_samples)
        self.rotation_length_m = float(rotation_length_m)

    def prepare(self, demonstration, name, description="", *, source=None):
        """The checked demonstration, ready for :meth:`Library.add_prepared`; writes
        nothing. Raises InputError as :meth:`Library.add` (bad name, invalid
        demonstration, one that does not move)."""
        return _prepare(
            demonstration, name, description, kinematics=self.kinematics, num_samples=self.num_samples,
            rotation_length_m=self.rotation_length_m, source=source, label=self.label,
        )


def tool_frame_options(X_tool0_E):
    """The ``library add`` options that choose the end-effector frame ``X_tool0_E``, as
    one would type them: ``--tool0-E-p 0 0 0.2 --tool0-E-euler-zyx 0 pi/2 0``.

    Angles are exact multiples of pi where they are (a negative one plus 2 pi, since
    argparse takes ``-pi/2`` for an option), else radians; both read back within
    :data:`END_EFFECTOR_FRAME_TOLERANCE`."""
    p = " ".join(number_text(v) for v in X_tool0_E.translation())
    euler = " ".join(angle_text(v, non_negative=True) for v in euler_zyx_from_rigid_transform(X_tool0_E))
    return f"--tool0-E-p {p} --tool0-E-euler-zyx {euler}"


class _FeatureRecord(NamedTuple):
    """A demonstration's feature, the cache key it belongs to, whether the cache holds it
    for the log as it is (``on_disk``), and the row that stores it."""

    key: str
    feature: Feature
    on_disk: bool
    row: CacheRow | None  # None: the log changed while it was read (nothing to store)


class _LogIdentity(NamedTuple):
    """What a joint log is now: its stamp, sha256, sample count and duration, and its
    bytes when they had to be read (None when its cache row vouches for it)."""

    stamp: object
    sha256: str
    samples: int
    duration_s: float
    log_bytes: bytes | None
    steady: bool  # False: the log changed while it was read


class Library:
    """A demonstration library directory (Eq. 14). Use :meth:`open` or :meth:`create`.

    Attributes
    ----------
    path : Path
        The library directory (absolute).
    label : str
        How to name it to a user: the bundled name, or the absolute path.
    read_only : bool
        True for a bundled library opened by name.
    X_tool0_E : RigidTransform
        The end-effector frame the demonstrations' features are computed for.
    num_samples, rotation_length_m
        Feature parameters (``features.Feature.from_poses``).
    """

    def __init__(
        self,
        *,
        path,
        manifest: Manifest,
        label,
        read_only,
        num_samples=DEFAULT_NUM_SAMPLES,
        rotation_length_m=DEFAULT_ROTATION_LENGTH_M,
    ):
        self.path = Path(path).resolve()
        self._manifest = manifest
        self.X_tool0_E = manifest.X_tool0_E
        self.label = label
        self.read_only = read_only
        self.num_samples = int(num_samples)
        self.rotation_length_m = float(rotation_length_m)
        self._features = {}  # name -> _FeatureRecord
        self._kinematics = None  # built on first use, for X_tool0_E
        self._preparer = None  # likewise
        self._keys = {}  # log sha256 -> feature cache key, memoised
        self._context = None  # feature_cache.cache_context of the frame and parameters, on first use
        self._manifest_bytes = None  # library.json as it was when self._manifest was read from it
        self._rows = {}  # name -> CacheRow, the feature cache's rows as read (or written) by this object
        self._positions = {}  # name -> index into the manifest's entries
        self._set_manifest(manifest)

    def _set_manifest(self, manifest):
        self._manifest = manifest
        self._positions = {entry.name: index for index, entry in enumerate(manifest.entries)}

    # -- opening ---------------------------------------------------------------------
    @classmethod
    def open(cls, path_or_name, *, check_logs=True, **feature_parameters):
        """Opens a library directory, or a bundled library by name (read-only).

        Parameters
        ----------
        path_or_name : str or Path
            A path to an existing library directory; otherwise a bundled library name.
        check_logs : bool
            Check every entry against its joint log (it exists, its sample count and
            duration are the manifest's). False only to repair a library
            (``library remove`` of an entry whose log is gone).
        **feature_parameters
            ``num_samples``, ``rotation_length_m`` (defaults from ``features.py``).

        Raises
        ------
        InputError
            Neither exists (the message lists what was tried), the manifest is
            corrupt, or it disagrees with a log (naming the manifest and the field).
        """
        candidate = Path(path_or_name)
        if candidate.is_dir():
            return cls._load(
                candidate, label=str(candidate.resolve()), read_only=False, check_logs=check_logs,
                **feature_parameters,
            )
        if candidate.exists():
            raise InputError("is a file, not a library directory", file=path_or_name)
        name = str(path_or_name)
        looked_in = []
        if NAME_PATTERN.match(name):
            for directory in bundled_library_directories():
                if (directory / name / MANIFEST_NAME).is_file():
                    return cls._load(
                        directory / name, label=name, read_only=True, check_logs=check_logs,
                        **feature_parameters,
                    )
                looked_in.append(str(directory))
        bundled = ", ".join(bundled_library_names()) or "none"
        tried = f"no directory {candidate.resolve()}"
        if looked_in:
            tried += f", and no bundled library of that name in {' or '.join(looked_in)}"
        raise InputError(f"no such library: {tried} (bundled libraries: {bundled})", file=name)

    @classmethod
    def _load(cls, directory, *, label, read_only, check_logs=True, **feature_parameters):
        # The shared lock keeps writers out while the manifest and the logs are compared.
        with shared_lock(Path(directory) / LOCK_NAME), collection_paused():
            manifest_bytes = read_manifest_bytes(directory)
            manifest = read_manifest(directory, check_logs=check_logs, data=manifest_bytes)
            rows = read_rows(Path(directory) / CACHE_DIRECTORY / CACHE_NAME)
            if check_logs:
                _check_logs(directory, manifest, rows)
        library = cls(
            path=directory,
            manifest=manifest,
            label=label,
            read_only=read_only,
            **feature_parameters,
        )
        library._rows = rows
        library._manifest_bytes = manifest_bytes
        return library

    @classmethod
    def create(cls, path, X_tool0_E=None, *, first=(), **feature_parameters):
        """Creates a library directory (the directory may exist if empty), empty or holding
        ``first``.

        Parameters
        ----------
        path : str or Path
        X_tool0_E : RigidTransform, optional
            The end-effector frame of the demonstrations to come; identity by default.
        first : sequence of prepared demonstrations (:meth:`prepare`), optional
            Written in the same turn of the lock as the manifest, which lists them: the
            manifest is the library, so a create killed before it leaves no library (its
            logs are debris a later create clears), and one killed after leaves them all.
            Their names must differ (ignoring case).

        Raises
        ------
        InputError
            ``path`` is a file, a library already (also when another process made it
            one meanwhile), or a directory holding anything but what a killed
            ``create`` leaves (:func:`is_unused_library_directory`). Where a library
            writer has been (its lock file is there), that is decided under the lock: a
            writer may be half-way through making it a library.
        """
        directory = Path(path)
        not_empty = "exists and is not empty; choose a new directory for a library"
        if directory.exists():
            if not directory.is_dir():
                raise InputError("exists and is not a directory", file=path)
            if not is_unused_library_directory(directory):
                # (Checked after: another process may be making it a library right now.)
                if (directory / MANIFEST_NAME).exists():
                    raise InputError("is a library already", file=path)
                if not (directory / LOCK_NAME).exists():
                    raise InputError(not_empty, file=path)
                # A library writer has been here and may be writing now (its manifest's
                # temporary file is not yet a manifest): decide under the lock, below.
        created = not directory.exists()
        manifest = Manifest.new(RigidTransform() if X_tool0_E is None else X_tool0_E)
        try:
            _make_directory(directory)
            with _writing(directory, directory):
                if (directory / MANIFEST_NAME).exists():  # another process was quicker
                    created = False
                    raise InputError("is a library already", file=path)
                if not is_unused_library_directory(directory):  # no writer is at work now
                    raise InputError(not_empty, file=path)
                _make_directory(directory / DEMOS_DIRECTORY)
                _make_directory(directory / CACHE_DIRECTORY)
                if first:
                    atomic_write_many([(directory / item.entry.file, item.log_bytes) for item in first])
                    manifest = manifest.with_entries(tuple(item.entry for item in first))
                write_manifest(directory, manifest)
        except BaseException:
            if not (directory / MANIFEST_NAME).exists():
                for item in first:
                    with contextlib.suppress(OSError):
                        (directory / item.entry.file).unlink()
                if created:
                    _remove_unused_directory(directory)
            raise
        return cls(
            path=directory,
            manifest=manifest,
            label=str(directory.resolve()),
            read_only=False,
            **feature_parameters,
        )

    @classmethod
    def create_with(cls, path, demonstration, name, description="", *, X_tool0_E, source=None,
                    **feature_parameters):
        """A new library at ``path`` holding ``demonstration``: ``library add`` to a new
        directory. Every check of the demonstration runs before anything is written, so
        a refusal creates nothing. If another process made ``path`` a library meanwhile
        with the same frame, the demonstration is added to it.

        Parameters
        ----------
        path, X_tool0_E
            As for :meth:`create`.
        demonstration, name, description, source
            As for :meth:`add`.

        Returns
        -------
        (library, entry) : (Library, DemoEntry)

        Raises
        ------
        InputError
            As :meth:`create` and :meth:`add`; or the library made meanwhile has another
            end-effector frame.
        """
        DemonstrationPreparer(X_tool0_E, Path(path).absolute(), **feature_parameters).prepare(
            demonstration, name, description, source=source
        )
        library = cls.open_or_create(path, X_tool0_E, **feature_parameters)
        return library, library.add(demonstration, name, description, source=source)

    @classmethod
    def open_or_create(cls, path, X_tool0_E, **feature_parameters):
        """:meth:`create`, or, if another process made ``path`` a library meanwhile with the
        same end-effector frame, :meth:`open` it.

        Raises
        ------
        InputError
            As :meth:`create`; or the library made meanwhile has another frame.
        """
        try:
            library = cls.create(path, X_tool0_E, **feature_parameters)
        except InputError:
            if not (Path(path) / MANIFEST_NAME).is_file():
                raise
            library = cls.open(path, **feature_parameters)
            difference = np.max(np.abs(library.X_tool0_E.GetAsMatrix4() - X_tool0_E.GetAsMatrix4()))
            if difference > END_EFFECTOR_FRAME_TOLERANCE:
                raise InputError(
                    "became a library with another end-effector frame while this add ran "
                    f"({tool_frame_options(library.X_tool0_E)})",
                    file=library.label,
                    field="X_tool0_E",
                ) from None
        return library

    # -- reading ---------------------------------------------------------------------
    @property
    def manifest_path(self) -> Path:
        return self.path / MANIFEST_NAME

    @property
    def names(self):
        """Demonstration names in the order they were added, tuple of str."""
        return tuple(entry.name for entry in self._manifest.entries)

    @property
    def entries(self):
        """The manifest's entries, tuple of :class:`DemoEntry`."""
        return self._manifest.entries

    def __len__(self):
        return len(self._manifest.entries)

    def __contains__(self, name):
        return name in self._positions

    def entry(self, name):
        """The :class:`DemoEntry` of ``name``; InputError listing the names if absent."""
        position = self._positions.get(name)
        if position is not None:
            return self._manifest.entries[position]
        names = self.names
        known = ", ".join(names[:20]) + (f" and {len(names) - 20} more" if len(names) > 20 else "") or "none"
        raise InputError(f"no demonstration {name!r} (it has: {known})", file=self.label, field="name")

    def log_path(self, name):
        """Absolute path of the joint log of ``name``."""
        return self.path / self.entry(name).file

    def demonstration(self, name):
        """The demonstration ``name`` read from its joint log.

        Raises
        ------
        InputError
            The log is damaged or disagrees with the manifest's sample count.
        """
        entry = self.entry(name)
        log = self.path / entry.file
        demonstration, warnings = read_rtde_csv(
            log, name=name, description=entry.description, filter_runtime_state=False
        )
        if warnings:
            raise InputError(f"damaged joint log: {warnings[0].removeprefix(f'{log}: ')}", file=log)
        if demonstration.num_samples != entry.samples:
            raise InputError(
                f"has {demonstration.num_samples} samples but {MANIFEST_NAME} says {entry.samples}",
                file=log,
            )
        return demonstration

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
        if not (missing or unlisted or legacy or _temporaries(self.path)):
            return ()  # nothing to write, and no debris of a killed writer to clear
        written = []
        try:
            with _writing(self.path, self.label):
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
        """The :class:`_LogIdentity` of ``name``'s log: from its cache row when the log's
        stamp is the row's, else by reading the log."""
        log = os.path.join(self.path, self.entry(name).file)
        try:
            stamp = log_stamp(log)
            row = self._rows.get(name)
            if row is not None and row.stamp == stamp:
                return _LogIdentity(stamp, row.sha256, row.samples, row.duration_s, None, True)
            log = Path(log)
            log_bytes = log.read_bytes()
            steady = log_stamp(log) == stamp
        except OSError as error:
            raise InputError(f"cannot read the joint log: {error.strerror}", file=log) from None
        samples, duration_s = log_sample_summary(log_bytes, log)
        return _LogIdentity(stamp, hashlib.sha256(log_bytes).hexdigest(), samples, duration_s, log_bytes, steady)

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
            record = _FeatureRecord(key, feature, on_disk, row)
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

    def _refresh_manifest(self):
        """Re-reads the manifest if another process changed it since this object read it
        (call with a lock held); a read-only (bundled) library does not change."""
        if not self.read_only:
            self._manifest_on_disk()

    # -- writing ---------------------------------------------------------------------
    def _manifest_on_disk(self):
        """The manifest as it is on disk now (call with the lock held): the one this object
        read if the file holds the same bytes, else the file read again."""
        data = read_manifest_bytes(self.path)
        if data != self._manifest_bytes:
            with collection_paused():
                self._set_manifest(read_manifest(self.path, check_logs=False, data=data))
            self._manifest_bytes = data
        return self._manifest

    def check_writable(self):
        """Raises InputError (naming where it is installed and how to copy it) for a read-only
        (bundled) library."""
        if self.read_only:
            raise InputError(
                f"is a bundled library and read-only (installed in {self.path}); make an editable copy "
                f"with 'drake-lfd library copy {self.label} DIR' and use DIR, or start your own library "
                "with 'drake-lfd library add DIR DEMO.csv --name NAME --tool0-E-p X Y Z "
                "--tool0-E-euler-zyx YAW PITCH ROLL'",
                file=self.label,
            )

    def add(self, demonstration, name, description="", *, source=None):
        """Adds a demonstration: its joint log, then the manifest entry, then the cache,
        all under the library's lock (re-reading the manifest there, so concurrent adds
        of different names all land).

        Parameters
        ----------
        demonstration : Demonstration
        name : str
            ``[A-Za-z0-9_-]+``, unique in the library (ignoring case).
        description : str
        source : str or Path, optional
            The log the demonstration was read from, named in errors about it.

        Returns
        -------
        entry : DemoEntry

        Raises
        ------
        InputError
            Read-only library, bad or taken name, an invalid or implausible
            demonstration (:func:`~drake_lfd.io.demonstration_logs.check_plausible_motion`),
            or one that does not move. The library is unchanged then.
        """
        pending = self.prepare(demonstration, name, description, source=source)
        added, refused = self.add_prepared([pending])
        if refused:
            raise refused[0][1]
        return added[0]

    def prepare(self, demonstration, name, description="", *, source=None):
        """Every check of a new demonstration that does not depend on what the library
        holds, and its feature: what :meth:`add_prepared` writes. Writes nothing.

        Raises
        ------
        InputError
            As :meth:`add` (read-only library, bad name, invalid demonstration).
        """
        self.check_writable()
        if self._preparer is None:
            self._preparer = DemonstrationPreparer(self.X_tool0_E, self.label, self.num_samples, self.rotation_length_m)
        return self._preparer.prepare(demonstration, name, description, source=source)

    def add_prepared(self, pending):
        """Adds prepared demonstrations (:meth:`prepare`) in one turn of the library's lock:
        the manifest re-read there, the logs of those whose names are free, one manifest
        write listing them all, then their cache rows.

        Each demonstration is added whole or not at all: a crash leaves at worst logs the
        manifest does not list (ignored, overwritten by a later add of that name).

        Parameters
        ----------
        pending : sequence of prepared demonstrations

        Returns
        -------
        added : list of DemoEntry
            In the given order.
        refused : list of (int, InputError)
            The position in ``pending`` and why (the name is taken in the library, or
            earlier in ``pending``, ignoring case).

        Raises
        ------
        InputError
            The library's lock cannot be taken, or its end-effector frame changed on
            disk; nothing is added then.
        """
        self.check_writable()
        added, refused, accepted = [], [], []
        with _writing(self.path, self.label):
            frame = self._manifest.X_tool0_E_json
            manifest = self._manifest_on_disk()
            if manifest.X_tool0_E_json != frame:
                raise InputError(
                    "the library's end-effector frame changed on disk since it was opened", file=self.label
                )
            taken = {existing.name.lower(): existing.name for existing in manifest.entries}
            for position, item in enumerate(pending):
                name = item.entry.name
                if name.lower() in taken:
                    refused.append((position, InputError(
                        f"the library has a demonstration named {taken[name.lower()]!r} already; "
                        "remove it first or choose another name",
                        file=self.label,
                        field="name",
                    )))
                    continue
                taken[name.lower()] = name
                accepted.append(item)
            if not accepted:
                self._set_manifest(manifest)
                return added, refused
            _make_directory(self.path / DEMOS_DIRECTORY)
            written = [self.path / item.entry.file for item in accepted]
            try:
                atomic_write_many([(log, item.log_bytes) for log, item in zip(written, accepted)])
                entries = manifest.entries + tuple(item.entry for item in accepted)
                written_bytes = write_manifest(self.path, manifest.with_entries(entries))
            except BaseException:
                # Nothing references the new logs yet: take them away again.
                for log in written:
                    with contextlib.suppress(OSError):
                        log.unlink()
                raise
            self._set_manifest(manifest.with_entries(entries))
            self._manifest_bytes = written_bytes
            rows = []
            for item in accepted:
                name = item.entry.name
                with contextlib.suppress(OSError):
                    stamp = log_stamp(self.path / item.entry.file)
                    sha256 = hashlib.sha256(item.log_bytes).hexdigest()
                    rows.append((CacheRow(name, stamp, sha256, item.entry.samples, item.entry.duration_s,
                                          self._key(sha256)), item.feature))
            on_disk = write_rows(self._cache_path(), rows)
        for row, feature in rows:
            self._features[row.name] = _FeatureRecord(row.feature_key, feature, on_disk, row)
            if on_disk:
                self._rows[row.name] = row
        return [item.entry for item in accepted], refused

    def remove(self, name):
        """Removes a demonstration: the manifest entry first, then its log and cache row,
        under the library's lock. An entry whose log is missing (or damaged) can be
        removed: that is how a library is repaired.

        Raises
        ------
        InputError
            Read-only library or no such demonstration.
        """
        self.check_writable()
        with _writing(self.path, self.label):
            manifest = self._manifest_on_disk()
            entry = self.entry(name)
            entries = [e for e in manifest.entries if e.name != name]
            self._manifest_bytes = None  # (until the new manifest is written)
            self._manifest_bytes = write_manifest(self.path, manifest.with_entries(entries))
            self._set_manifest(manifest.with_entries(entries))
            self._features.pop(name, None)
            # The manifest no longer lists it: the removal is done. Its log and cache file
            # go too where they are (a damaged library may have neither, or a file where
            # the cache folder should be).
            for path in (self.path / entry.file, self.path / CACHE_DIRECTORY / f"{name}.npz"):
                try:
                    path.unlink()
                except (FileNotFoundError, NotADirectoryError):
                    pass
            if (self.path / DEMOS_DIRECTORY).is_dir():
                fsync_directory(self.path / DEMOS_DIRECTORY)
            if delete_rows(self._cache_path(), [name]):
                self._rows.pop(name, None)


def _remove_unused_directory(directory):
    """Takes away a directory :meth:`Library.create` made and could not finish."""
    try:
        if is_unused_library_directory(directory):
            shutil.rmtree(directory)
    except OSError:
        pass


def copy_library(source, destination, **feature_parameters):
    """Copies a library (a bundled one, typically) into a new directory, editable.

    The copy has the source's manifest (frame, entries, order, ``added`` times), its
    joint logs and fresh feature caches. It is built in a temporary directory beside
    ``destination`` and renamed into place, so ``destination`` never holds half a copy.
    The source's shared lock is held while it is read (its manifest re-read under the
    lock), so a concurrent ``add`` or ``remove`` on the source waits and the copy is the
    library before or after it, never a mix.

    Parameters
    ----------
    source : Library, str or Path
        A library, or what :meth:`Library.open` takes (a directory or a bundled name).
    destination : str or Path
        A directory that does not exist (its parents are created) or is empty.
    **feature_parameters
        As for :meth:`Library.open`.

    Returns
    -------
    copy : Library
        The copy, opened from ``destination`` (not read-only).

    Raises
    ------
    InputError
        ``destination`` is a file or a non-empty directory; the source cannot be opened
        or one of its joint logs is damaged. Nothing is left behind then.
    """
    library = source if isinstance(source, Library) else Library.open(source, **feature_parameters)
    with shared_lock(Path(library.path) / LOCK_NAME):  # writers of the source wait until it is read
        # Re-read under the lock: a writer may have changed the source since it was opened.
        library = Library._load(library.path, label=library.label, read_only=library.read_only,
                                **feature_parameters)
        return _copy_into(library, destination, **feature_parameters)


def _copy_into(library, destination, **feature_parameters):
    """:func:`copy_library` of an opened ``library``, with its shared lock held."""
    destination = Path(destination)
    if destination.exists():
        if not destination.is_dir():
            raise InputError("exists and is not a directory", file=destination)
        if any(destination.iterdir()):
            raise InputError("exists and is not empty; choose a new directory for the copy", file=destination)
    parent = destination.absolute().parent
    _make_directory(parent)
    staging = parent / f".{destination.name}.copy-{uuid.uuid4().hex[:12]}"
    staging.mkdir()
    try:
        _make_directory(staging / DEMOS_DIRECTORY)
        _make_directory(staging / CACHE_DIRECTORY)
        for entry in library.entries:
            library.demonstration(entry.name)  # refuses a damaged log before copying it
            target = staging / entry.file
            _make_directory(target.parent)
            atomic_write_bytes(target, (library.path / entry.file).read_bytes())
        write_manifest(staging, library._manifest)
        Library._load(staging, label=str(staging), read_only=False, **feature_parameters).write_feature_caches()
        fsync_directory(staging)
        if destination.exists():
            destination.rmdir()  # empty, checked above
        os.rename(staging, destination)
        fsync_directory(parent)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return Library.open(destination, **feature_parameters)


def check_end_effector_frame(library, X_tool0_E_task, file=None):
    """Refuses to plan a task whose end-effector frame differs from the library's.

    Features describe the motion of frame E; demonstrations recorded with one
    ``X_tool0_E`` say nothing exact about another, so a mismatch is an error rather
    than a silently wrong plan.

    Parameters
    ----------
    library : Library
    X_tool0_E_task : RigidTransform
        The task's end-effector frame.
    file : str or Path, optional
        The task file, named in the error.

    Raises
    ------
    InputError
        If any entry of the 4x4 matrices differs by more than
        :data:`END_EFFECTOR_FRAME_TOLERANCE`. The message names both fixes with the
        values to type: the ``library add`` options that record demonstrations for the
        task's frame (:func:`tool_frame_options`), and the task's ``X_tool0_E`` that
        matches the library.
    """
    difference = np.max(np.abs(library.X_tool0_E.GetAsMatrix4() - X_tool0_E_task.GetAsMatrix4()))
    if difference > END_EFFECTOR_FRAME_TOLERANCE:
        raise InputError(
            f"the task's end-effector frame {pose_yaml_text(X_tool0_E_task)} differs from the one "
            f"library {library.label} was recorded with, {pose_yaml_text(library.X_tool0_E)}; "
            "record the demonstrations for the task's frame into a new library with "
            f"'drake-lfd library add NEWLIB DEMO.csv --name NAME {tool_frame_options(X_tool0_E_task)}', "
            f"or set the task's X_tool0_E to {pose_yaml_text(library.X_tool0_E)}",
            file=file,
            field="X_tool0_E",
        )


def library_features(library: Library) -> dict[str, Feature]:
    """Name -> feature (with its resampled poses), in the library's order; writes nothing.

    What the ``plan``, ``train`` and ``simulate`` commands hand to the planners.
    """
    return library.features()
