"""The demonstration library ``LB = {HD_1, ..., HD_k}`` (Eq. 14): a directory opened,
created, read and edited through :class:`Library`.

The directory (``library.json``, ``demos/<name>.csv``, ``cache/features.sqlite``,
``library.lock``), its lock, its atomic writes and where a bundled library is found are
the store's (:mod:`~drake_lfd.io.library_store`); docs/libraries.rst documents it.

The joint logs are the source of truth. Features depend on the end-effector frame, so
the library stores the one its demonstrations were recorded with (``X_tool0_E``) and
planning a task with another frame is refused (:func:`check_end_effector_frame`).
Reading a feature never writes (:mod:`~drake_lfd.io.library_feature_reads`, which
:class:`Library` inherits). A new demonstration is checked and its feature computed
before anything is written (:mod:`~drake_lfd.io.demo_preparation`), so a refused
``add`` or :meth:`Library.create_with` changes and creates nothing; many logs at once:
:meth:`Library.add_many` (:mod:`~drake_lfd.io.bulk_add`).

Edits (``add``, many at once with :meth:`Library.add_prepared`; ``remove``) hold the
library's exclusive lock across their read-modify-write and re-read the manifest under
it, so two adds of different names both land and a name taken meanwhile is refused;
opening checks each entry against its log (``open(..., check_logs=False)`` skips that
so ``remove`` can repair a library). The order of the writes that makes a crash
harmless is the store's.

Bundled libraries (``Library.open("paper5")``) are read-only; :func:`copy_library`
makes an editable copy of one (or of any library), atomically. Demonstration names
match ``[A-Za-z0-9_-]+`` and are unique ignoring case (their log files must not collide
on case-insensitive file systems).

Not for: the directory's layout, lock and temporaries (``library_store.py``), the
manifest's format (``library_manifest.py``), the cache files (``feature_cache.py``),
foreign log formats (``log_import.py`` and the readers it uses), comparing features
(``similarity.py``), the command line (``cli/library.py``).
"""

from __future__ import annotations

import contextlib
import hashlib
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.errors import HINT, Hint, InputError
from drake_lfd.core.features import DEFAULT_NUM_SAMPLES, DEFAULT_ROTATION_LENGTH_M, Feature
from drake_lfd.core.resources import bundled_library_directories  # noqa: F401 (re-exported)
from drake_lfd.core.resources import bundled_library_names, bundled_library_paths
from drake_lfd.io.demo_preparation import MIN_MOTION_LENGTH, DemonstrationPreparer
from drake_lfd.io.demonstration_logs import read_rtde_csv
from drake_lfd.io.feature_cache import CACHE_NAME, CacheRow, delete_rows, log_stamp, read_rows, write_rows
from drake_lfd.io.file_lock import shared_lock
from drake_lfd.io.library_feature_reads import FeatureRecord, LibraryFeatureReads
from drake_lfd.io.library_manifest import (CACHE_DIRECTORY, LOCK_NAME, MANIFEST_NAME, Manifest, read_manifest,
                                           read_manifest_bytes, write_manifest)
from drake_lfd.io.library_store import (DURATION_TOLERANCE_S, bundled_logs_root, check_entries_against_logs,
                                        collection_paused, copy_files, create_directory, delete_entry_files,
                                        is_unused_library_directory, library_location, locked_for_writing,
                                        remove_stale_temporaries, write_new_entries)
from drake_lfd.io.pose_records import pose_yaml_text, tool_frame_arguments, tool_frame_options

# The names other modules import from here, whichever module defines them.
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


def same_frame(X_a, X_b):
    """Whether two end-effector frames are one (within :data:`END_EFFECTOR_FRAME_TOLERANCE`)."""
    return bool(np.max(np.abs(X_a.GetAsMatrix4() - X_b.GetAsMatrix4())) <= END_EFFECTOR_FRAME_TOLERANCE)


class Library(LibraryFeatureReads):
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
        self._start_feature_reads()
        self._preparer = None  # built on first use, for X_tool0_E
        self._manifest_bytes = None  # library.json as it was when self._manifest was read from it
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
        directory, label, read_only = library_location(path_or_name)
        return cls._load(directory, label=label, read_only=read_only, check_logs=check_logs, **feature_parameters)

    @classmethod
    def _load(cls, directory, *, label, read_only, check_logs=True, **feature_parameters):
        # The shared lock keeps writers out while the manifest and the logs are compared.
        with shared_lock(Path(directory) / LOCK_NAME), collection_paused():
            manifest_bytes = read_manifest_bytes(directory)
            manifest = read_manifest(directory, check_logs=check_logs, data=manifest_bytes,
                                     links_within=bundled_logs_root(directory))
            rows = read_rows(Path(directory) / CACHE_DIRECTORY / CACHE_NAME)
            if check_logs:
                check_entries_against_logs(directory, manifest, rows)
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
        manifest = create_directory(directory, Manifest.new(RigidTransform() if X_tool0_E is None else X_tool0_E),
                                    first, label=path)
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
            if not same_frame(library.X_tool0_E, X_tool0_E):
                raise InputError(
                    f"became a library with another end-effector frame while this add ran ({HINT})",
                    file=library.label,
                    field="X_tool0_E",
                    hints=(Hint("", tool_frame_arguments(library.X_tool0_E)),),
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
                f"with '{HINT}' and use DIR, or start your own library with '{HINT}'",
                file=self.label,
                hints=(Hint("library copy", (self.label, "DIR")),
                       Hint("library add", ("DIR", "DEMO.csv", "--name", "NAME", "--tool0-E-p", "X", "Y", "Z",
                                            "--tool0-E-euler-zyx", "YAW", "PITCH", "ROLL"))),
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
        with locked_for_writing(self.path, self.label):
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
            manifest, written_bytes = write_new_entries(self.path, manifest, accepted)
            self._set_manifest(manifest)
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
            self._features[row.name] = FeatureRecord(row.feature_key, feature, on_disk, row)
            if on_disk:
                self._rows[row.name] = row
        return [item.entry for item in accepted], refused

    def add_many(self, paths, description="", *, options=None, progress=None):
        """Adds every log ``paths`` name (files, folders, glob patterns), each named after
        its file's stem, in batches of one turn of the lock each; each log that cannot be
        added is refused with a kind and a reason (:func:`~drake_lfd.io.bulk_add.add_logs`,
        which documents ``options`` and ``progress``). Returns a
        :class:`~drake_lfd.io.bulk_add.AddManyReport`; raises InputError (nothing added)
        for a read-only library, a bad time window or ``paths`` naming no log."""
        from drake_lfd.io.bulk_add import LogReadOptions, add_logs

        return add_logs(self, paths, description, options=options or LogReadOptions(), progress=progress)

    @classmethod
    def create_many(cls, path, paths, description="", *, X_tool0_E, options=None, progress=None):
        """A new library at ``path`` holding every valid log ``paths`` name, as
        :meth:`add_many`: created with the first batch in one turn of its lock (a killed
        create leaves no library); nothing is created when no log is accepted
        (``report.library`` is None). Raises InputError as :meth:`create` and
        :meth:`add_many`."""
        from drake_lfd.io.bulk_add import LogReadOptions, add_logs

        return add_logs(path, paths, description, X_tool0_E=X_tool0_E, options=options or LogReadOptions(),
                        progress=progress)

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
        with locked_for_writing(self.path, self.label):
            manifest = self._manifest_on_disk()
            entry = self.entry(name)
            entries = [e for e in manifest.entries if e.name != name]
            self._manifest_bytes = None  # (until the new manifest is written)
            self._manifest_bytes = write_manifest(self.path, manifest.with_entries(entries))
            self._set_manifest(manifest.with_entries(entries))
            self._features.pop(name, None)
            delete_entry_files(self.path, entry)  # (the manifest no longer lists it: the removal is done)
            if delete_rows(self._cache_path(), [name]):
                self._rows.pop(name, None)


def copy_library(source, destination, **feature_parameters):
    """Copies a library (a bundled one, typically) into a new directory, editable: the
    source's manifest (frame, entries, order, ``added`` times), its joint logs and fresh
    feature caches, built beside ``destination`` and renamed into place
    (:func:`~drake_lfd.io.library_store.copy_files`). The source's shared lock is held
    while it is read (its manifest re-read under the lock), so the copy is the library
    before or after a concurrent ``add`` or ``remove``, never a mix.

    ``source`` is a :class:`Library` or what :meth:`Library.open` takes; ``destination``
    a directory that does not exist (its parents are created) or is empty;
    ``feature_parameters`` as for :meth:`Library.open`. Returns the copy, opened (not
    read-only). Raises InputError (nothing left behind) when ``destination`` is a file or
    a non-empty directory, or the source cannot be opened or has a damaged log.
    """
    library = source if isinstance(source, Library) else Library.open(source, **feature_parameters)
    with shared_lock(Path(library.path) / LOCK_NAME):  # writers of the source wait until it is read
        # Re-read under the lock: a writer may have changed the source since it was opened.
        library = Library._load(library.path, label=library.label, read_only=library.read_only,
                                **feature_parameters)
        copy_files(
            library.path, library._manifest, destination,
            check_log=lambda entry: library.demonstration(entry.name),  # refuses a damaged log before copying it
            finish=lambda staging: Library._load(
                staging, label=str(staging), read_only=False, **feature_parameters).write_feature_caches(),
        )
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
        values to type: the ``library add`` command that records demonstrations for the
        task's frame (a :class:`~drake_lfd.core.errors.Hint`), and the task's
        ``X_tool0_E`` that matches the library.
    """
    if not same_frame(library.X_tool0_E, X_tool0_E_task):
        raise InputError(
            f"the task's end-effector frame {pose_yaml_text(X_tool0_E_task)} differs from the one "
            f"library {library.label} was recorded with, {pose_yaml_text(library.X_tool0_E)}; "
            f"record the demonstrations for the task's frame into a new library with '{HINT}', "
            f"or set the task's X_tool0_E to {pose_yaml_text(library.X_tool0_E)}",
            file=file,
            field="X_tool0_E",
            hints=(Hint("library add", ("NEWLIB", "DEMO.csv", "--name", "NAME",
                                        *tool_frame_arguments(X_tool0_E_task))),),
        )


def library_features(library: Library) -> dict[str, Feature]:
    """Name -> feature (with its resampled poses), in the library's order; writes nothing.

    What the ``plan``, ``train`` and ``simulate`` commands hand to the planners.
    """
    return library.features()
