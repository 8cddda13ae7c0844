"""The demonstration library ``LB = {HD_1, ..., HD_k}`` (Eq. 14), kept as a directory.

A library is a folder a user can read and back up with ordinary tools::

    LIB/
      library.json          the manifest (io/library_manifest.py): what the library holds
      demos/<name>.csv      one joint log per demonstration, the project's RTDE-style CSV
      cache/<name>.npz      resampled poses and feature per demonstration (derived data)

:class:`Library` opens, creates, reads and edits one; docs/libraries.rst documents the
directory for users.

The joint logs are the source of truth. Features depend on the end-effector frame, so
the library stores the one its demonstrations were recorded with (``X_tool0_E``) and
planning a task with another frame is refused (:func:`check_end_effector_frame`).
Features are computed by forward kinematics (with ``X_WB`` = identity: features do not
depend on where the robot stands). Reading a feature (:meth:`Library.feature`,
:func:`library_features`) never writes: it uses the cache file when its key is fresh
(``io/feature_cache.py``) and recomputes from the log otherwise. Cache files are written
only by :meth:`Library.add` and :meth:`Library.write_feature_caches` (which the command
line calls before it uses a library).

Durability: every file is written atomically (``atomic_files.atomic_write_bytes``: a
temporary file in the same directory, flushed and fsynced, ``os.replace``, then the
directory fsynced). ``add`` writes the log before the manifest that references it,
``remove`` rewrites the manifest before deleting the log. A crash therefore leaves at
worst an unreferenced log (ignored, overwritten by a later ``add`` of that name), never a
manifest pointing at a missing or partial log. Concurrent writers are not coordinated:
do not run two ``add``/``remove`` at once on one library.

Names: ``Library.open`` takes a path to an existing directory, else the name of a
library bundled with drake-lfd (``drake_lfd/sims/libraries/<name>/`` when installed,
``sims/libraries/<name>/`` in a checkout; :func:`bundled_library_paths` says where).
Bundled libraries opened by name are read-only; :func:`copy_library` makes an editable
copy of one (or of any library) in a new directory, atomically. Demonstration names match ``[A-Za-z0-9_-]+`` and are unique ignoring case (so
their log files do not collide on case-insensitive file systems).

Not for: the manifest's format (``library_manifest.py``), the cache files
(``feature_cache.py``), reading foreign log formats (``demonstration_logs.py``),
comparing features (``similarity.py``), the command line (``cli/library.py``).
"""

from __future__ import annotations

import datetime
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
from drake_lfd.core.resources import bundled_library_directories
from drake_lfd.io.atomic_files import atomic_write_bytes, fsync_directory
from drake_lfd.io.demonstration_logs import read_rtde_csv, rtde_csv_text
from drake_lfd.io.feature_cache import cache_key, read_feature_cache, write_feature_cache
from drake_lfd.io.library_manifest import (
    CACHE_DIRECTORY,
    DEMOS_DIRECTORY,
    MANIFEST_NAME,
    NAME_PATTERN,
    DemoEntry,
    Manifest,
    check_demo_name,
    read_manifest,
    write_manifest,
)
from drake_lfd.io.pose_records import angle_text, euler_zyx_from_rigid_transform, number_text, pose_yaml_text
from drake_lfd.robot.kinematics import UR5eKinematics, dual_quaternions_from_demonstration

__all__ = [
    "END_EFFECTOR_FRAME_TOLERANCE",
    "MIN_MOTION_LENGTH",
    "bundled_library_names",
    "bundled_library_paths",
    "tool_frame_options",
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


def _make_directory(path):
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        fsync_directory(path.parent)


def bundled_library_names():
    """Names of the libraries bundled with drake-lfd (sorted; may be empty)."""
    names = set()
    for directory in bundled_library_directories():
        if directory.is_dir():
            names.update(p.name for p in directory.iterdir() if (p / MANIFEST_NAME).is_file())
    return sorted(names)


def bundled_library_paths():
    """Name -> directory of each bundled library, where ``Library.open(name)`` finds it
    (the first of :func:`~drake_lfd.core.resources.bundled_library_directories` that
    has it), sorted by name."""
    paths = {}
    for directory in bundled_library_directories():
        if directory.is_dir():
            for candidate in sorted(directory.iterdir()):
                if (candidate / MANIFEST_NAME).is_file() and candidate.name not in paths:
                    paths[candidate.name] = candidate.resolve()
    return dict(sorted(paths.items()))


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
    """A demonstration's feature, the cache key it belongs to, and whether a cache file
    with that key is on disk."""

    key: str
    feature: Feature
    on_disk: bool


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

    # -- opening ---------------------------------------------------------------------
    @classmethod
    def open(cls, path_or_name, **feature_parameters):
        """Opens a library directory, or a bundled library by name (read-only).

        Parameters
        ----------
        path_or_name : str or Path
            A path to an existing library directory; otherwise a bundled library name.
        **feature_parameters
            ``num_samples``, ``rotation_length_m`` (defaults from ``features.py``).

        Raises
        ------
        InputError
            Neither exists (the message lists what was tried), or the manifest is
            corrupt (naming the field).
        """
        candidate = Path(path_or_name)
        if candidate.is_dir():
            return cls._load(candidate, label=str(candidate.resolve()), read_only=False, **feature_parameters)
        if candidate.exists():
            raise InputError("is a file, not a library directory", file=path_or_name)
        name = str(path_or_name)
        looked_in = []
        if NAME_PATTERN.match(name):
            for directory in bundled_library_directories():
                if (directory / name / MANIFEST_NAME).is_file():
                    return cls._load(directory / name, label=name, read_only=True, **feature_parameters)
                looked_in.append(str(directory))
        bundled = ", ".join(bundled_library_names()) or "none"
        tried = f"no directory {candidate.resolve()}"
        if looked_in:
            tried += f", and no bundled library of that name in {' or '.join(looked_in)}"
        raise InputError(f"no such library: {tried} (bundled libraries: {bundled})", file=name)

    @classmethod
    def _load(cls, directory, *, label, read_only, **feature_parameters):
        return cls(
            path=directory,
            manifest=read_manifest(directory),
            label=label,
            read_only=read_only,
            **feature_parameters,
        )

    @classmethod
    def create(cls, path, X_tool0_E=None, **feature_parameters):
        """Creates an empty library directory (the directory may exist if empty).

        Parameters
        ----------
        path : str or Path
        X_tool0_E : RigidTransform, optional
            The end-effector frame of the demonstrations to come; identity by default.

        Raises
        ------
        InputError
            ``path`` is a file, a library already, or a non-empty directory.
        """
        directory = Path(path)
        if directory.exists():
            if not directory.is_dir():
                raise InputError("exists and is not a directory", file=path)
            if (directory / MANIFEST_NAME).exists():
                raise InputError("is a library already", file=path)
            if any(directory.iterdir()):
                raise InputError("exists and is not empty; choose a new directory for a library", file=path)
        _make_directory(directory)
        _make_directory(directory / DEMOS_DIRECTORY)
        _make_directory(directory / CACHE_DIRECTORY)
        manifest = Manifest.new(RigidTransform() if X_tool0_E is None else X_tool0_E)
        write_manifest(directory, manifest)
        return cls(
            path=directory,
            manifest=manifest,
            label=str(directory.resolve()),
            read_only=False,
            **feature_parameters,
        )

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
        return any(entry.name == name for entry in self._manifest.entries)

    def entry(self, name):
        """The :class:`DemoEntry` of ``name``; InputError listing the names if absent."""
        for entry in self._manifest.entries:
            if entry.name == name:
                return entry
        known = ", ".join(self.names) or "none"
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
        """The feature ``HD`` of ``name`` (arc-length resampled, Eq. 12): from its cache file
        when that is fresh, else recomputed from the joint log. Writes nothing (see
        :meth:`write_feature_caches`)."""
        return self._feature_record(name).feature

    def resampled_poses(self, name):
        """The arc-length resampled end-effector poses of ``name`` as dual quaternions,
        shape (num_samples, 8), in the robot base frame: what the feature and the
        mapping (Eq. 22-25) index into."""
        return self.feature(name).poses

    def cache_path(self, name):
        """Where the feature cache of ``name`` lives (it may not exist)."""
        return self.path / CACHE_DIRECTORY / f"{name}.npz"

    def write_feature_caches(self):
        """Writes the cache file of every demonstration whose cache is missing or stale.

        Reading never writes; ``add`` writes the new demonstration's cache, and the
        command line calls this before using a library, so a user's library keeps
        fresh caches. A read-only (bundled) library keeps no caches: nothing is written.
        A cache that cannot be written is skipped (it is an optimisation).

        Returns
        -------
        names : tuple of str
            The demonstrations whose cache file was written.
        """
        if self.read_only:
            return ()
        written = []
        for name in self.names:
            record = self._feature_record(name)
            if record.on_disk and self.cache_path(name).is_file():
                continue
            if write_feature_cache(self.cache_path(name), record.key, record.feature):
                self._features[name] = record._replace(on_disk=True)
                written.append(name)
        return tuple(written)

    def _feature_record(self, name):
        entry = self.entry(name)
        log = self.path / entry.file
        try:
            log_bytes = log.read_bytes()
        except OSError as error:
            raise InputError(f"cannot read the joint log: {error.strerror}", file=log) from None
        key = cache_key(log_bytes, self.X_tool0_E, self.num_samples, self.rotation_length_m)
        memo = self._features.get(name)
        if memo is not None and memo.key == key:
            return memo
        feature = read_feature_cache(self.cache_path(name), key)
        if feature is not None:
            record = _FeatureRecord(key, feature, on_disk=True)
        else:
            record = _FeatureRecord(key, self._compute_feature(self.demonstration(name)), on_disk=False)
        self._features[name] = record
        return record

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

    # -- writing ---------------------------------------------------------------------
    def _check_writable(self):
        if self.read_only:
            raise InputError(
                f"is a bundled library and read-only (installed in {self.path}); make an editable copy "
                f"with 'drake-lfd library copy {self.label} DIR' and use DIR, or start your own library "
                "with 'drake-lfd library add DIR DEMO.csv --name NAME --tool0-E-p X Y Z "
                "--tool0-E-euler-zyx YAW PITCH ROLL'",
                file=self.label,
            )

    def add(self, demonstration, name, description=""):
        """Adds a demonstration: its joint log, then the manifest entry, then the cache.

        Parameters
        ----------
        demonstration : Demonstration
        name : str
            ``[A-Za-z0-9_-]+``, unique in the library (ignoring case).
        description : str

        Returns
        -------
        entry : DemoEntry

        Raises
        ------
        InputError
            Read-only library, bad or taken name, an invalid demonstration, or one that
            does not move. The library is unchanged then.
        """
        self._check_writable()
        check_demo_name(name)
        for entry in self._manifest.entries:
            if entry.name.lower() == name.lower():
                raise InputError(
                    f"the library has a demonstration named {entry.name!r} already; "
                    "remove it first or choose another name",
                    file=self.label,
                    field="name",
                )
        if not isinstance(description, str):
            raise InputError(f"expected a string, got {description!r}", field="description")
        check_demonstration(demonstration)
        stored = Demonstration(
            name=name,
            timestamps=demonstration.timestamps,
            joint_positions=demonstration.joint_positions,
            description=description,
        )
        D = self._dual_quaternions(stored)
        if not arc_lengths_from_poses(D, self.rotation_length_m)[-1] > MIN_MOTION_LENGTH:
            raise InputError(
                "the demonstration does not move the tool; it has no feature to learn", field="samples"
            )
        feature = Feature.from_poses(D, num_samples=self.num_samples, rotation_length_m=self.rotation_length_m)
        log_bytes = rtde_csv_text(stored).encode("utf-8")
        relative = f"{DEMOS_DIRECTORY}/{name}.csv"
        log = self.path / relative
        entry = DemoEntry(
            name=name,
            file=relative,
            samples=stored.num_samples,
            duration_s=stored.duration_s,
            description=description,
            added=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        )
        _make_directory(self.path / DEMOS_DIRECTORY)
        atomic_write_bytes(log, log_bytes)
        entries = self._manifest.entries + (entry,)
        try:
            write_manifest(self.path, self._manifest.with_entries(entries))
        except BaseException:
            # Nothing references the new log yet: take it away again.
            try:
                log.unlink()
            except OSError:
                pass
            raise
        self._manifest = self._manifest.with_entries(entries)
        key = cache_key(log_bytes, self.X_tool0_E, self.num_samples, self.rotation_length_m)
        on_disk = write_feature_cache(self.cache_path(name), key, feature)
        self._features[name] = _FeatureRecord(key, feature, on_disk)
        return entry

    def remove(self, name):
        """Removes a demonstration: the manifest entry first, then its log and cache.

        Raises
        ------
        InputError
            Read-only library or no such demonstration.
        """
        self._check_writable()
        entry = self.entry(name)
        entries = [e for e in self._manifest.entries if e.name != name]
        write_manifest(self.path, self._manifest.with_entries(entries))
        self._manifest = self._manifest.with_entries(entries)
        self._features.pop(name, None)
        for path in (self.path / entry.file, self.cache_path(name)):
            try:
                path.unlink()
            except FileNotFoundError:
                pass
        fsync_directory(self.path / DEMOS_DIRECTORY)


def copy_library(source, destination, **feature_parameters):
    """Copies a library (a bundled one, typically) into a new directory, editable.

    The copy has the source's manifest (frame, entries, order, ``added`` times), its
    joint logs and fresh feature caches. It is built in a temporary directory beside
    ``destination`` and renamed into place, so ``destination`` never holds half a copy.

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
    return {name: library.feature(name) for name in library.names}
