"""A library directory on disk: its layout, its lock, the temporaries of killed writers,
the check of the manifest against the logs, and an atomic copy.

A library is a folder a user can read and back up with ordinary tools (a bundled one,
read-only, is found by its name: :func:`library_location`)::

    LIB/
      library.json          the manifest (io/library_manifest.py): what the library holds
      demos/<name>.csv      one joint log per demonstration, the project's RTDE-style CSV
      cache/features.sqlite the feature cache (derived data, io/feature_cache.py)
      library.lock          empty; writers hold an exclusive flock on it (file_lock.py)

Durability: every file is written atomically (``atomic_files.atomic_write_bytes``: a
temporary file in the same directory, flushed and fsynced, ``os.replace``, then the
directory fsynced). Writers put the logs down before the manifest that references them
and rewrite the manifest before deleting a log, so a crash leaves at worst an
unreferenced log (ignored, overwritten by a later add of that name) or a temporary file
(:func:`library_temporaries`), never a manifest pointing at a missing or partial log.

Concurrency: every write holds the exclusive lock on ``library.lock`` across its whole
read-modify-write (:func:`locked_for_writing`), which first deletes the temporary files
a killed writer left (``.*.tmp``; under the lock no other writer can be mid-write).
Readers hold the shared lock while they compare the manifest with the logs
(:func:`check_entries_against_logs`), so a reader never sees a manifest without its logs. The kernel
frees a dead holder's lock.

Not for: what a library holds and how it is edited (:mod:`drake_lfd.io.library`), the
manifest's format (``library_manifest.py``), the cache's files (``feature_cache.py``).
"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import shutil
import uuid
from pathlib import Path

from drake_lfd.core.errors import HINT, Hint, InputError
from drake_lfd.core.resources import bundled_library_directories, bundled_library_names
from drake_lfd.io.atomic_files import atomic_write_bytes, atomic_write_many, fsync_directory
from drake_lfd.io.demonstration_logs import log_sample_summary
from drake_lfd.io.feature_cache import CACHE_NAME, JOURNAL_SUFFIX, log_stamp
from drake_lfd.io.file_lock import LockUnavailable, exclusive_lock
from drake_lfd.io.library_manifest import (
    CACHE_DIRECTORY,
    DEMOS_DIRECTORY,
    LOCK_NAME,
    MANIFEST_NAME,
    NAME_PATTERN,
    write_manifest,
)

__all__ = [
    "DURATION_TOLERANCE_S",
    "make_directory",
    "library_temporaries",
    "remove_stale_temporaries",
    "library_location",
    "bundled_logs_root",
    "is_unused_library_directory",
    "remove_unused_directory",
    "collection_paused",
    "locked_for_writing",
    "check_entries_against_logs",
    "create_directory",
    "write_new_entries",
    "delete_entry_files",
    "copy_files",
]

# A duration in the manifest within this of the log's (s) is the same duration.
DURATION_TOLERANCE_S = 1e-6


def library_location(path_or_name):
    """Where a library named on the command line is: ``(directory, label, read_only)``.

    A path to an existing directory is a user's library (labelled by its absolute path);
    anything else is looked up as the name of a bundled library in
    ``core.resources.bundled_library_directories`` (installed first, then a checkout),
    read-only and labelled by its name.

    Raises
    ------
    InputError
        A file, or neither (the message lists what was tried and the bundled names).
    """
    candidate = Path(path_or_name)
    if candidate.is_dir():
        return candidate, str(candidate.resolve()), False
    if candidate.exists():
        raise InputError("is a file, not a library directory", file=path_or_name)
    name = str(path_or_name)
    looked_in = []
    if NAME_PATTERN.match(name):
        for directory in bundled_library_directories():
            if (directory / name / MANIFEST_NAME).is_file():
                return directory / name, name, True
            looked_in.append(str(directory))
    bundled = ", ".join(bundled_library_names()) or "none"
    tried = f"no directory {candidate.resolve()}"
    if looked_in:
        tried += f", and no bundled library of that name in {' or '.join(looked_in)}"
    raise InputError(f"no such library: {tried} (bundled libraries: {bundled})", file=name)


def bundled_logs_root(directory):
    """Where a bundled library's logs may link to, or None for any other library: a
    bundled library's ``demos/<name>.csv`` are links to the one stored copy in the
    scenarios' ``demos/`` beside ``libraries/`` (``sims/make_paper_libraries.py``; an
    installed wheel holds copies), whether it is opened by name or by path."""
    parent = Path(directory).resolve().parent
    if any(parent == Path(folder).resolve() for folder in bundled_library_directories()):
        return parent.parent
    return None


def make_directory(path):
    """Makes ``path`` (and its parents) if it is missing, its parent fsynced."""
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        fsync_directory(path.parent)


def library_temporaries(directory):
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
    for path in library_temporaries(directory):
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
    debris = {str(p) for p in library_temporaries(path)}
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


def remove_unused_directory(directory):
    """Takes away a directory a create made and could not finish (only while it holds
    nothing but a killed write's debris, :func:`is_unused_library_directory`)."""
    try:
        if is_unused_library_directory(directory):
            shutil.rmtree(directory)
    except OSError:
        pass


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
def locked_for_writing(directory, label):
    """Holds the library's exclusive lock and clears stale temporaries first; an
    InputError naming ``label`` if the lock cannot be taken."""
    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(exclusive_lock(Path(directory) / LOCK_NAME))
        except LockUnavailable as error:
            raise InputError(
                f"cannot lock the library for writing ({error.strerror}: {error.filename})", file=label
            ) from None
        remove_stale_temporaries(directory)
        yield


def check_entries_against_logs(directory, manifest, rows):
    """Each entry against its log: present, same sample count and duration (call with
    the library's lock held).

    A log whose stamp (size, modification and change time, inode) is its cache row's
    (``rows``: name -> :class:`~drake_lfd.io.feature_cache.CacheRow`) is the file the
    row was read from, so the row's sample count and duration are the log's and the log
    is not read again; any other log is read and summarised.

    Raises
    ------
    InputError
        Naming the manifest and the field, with the repair (a :class:`Hint`: remove the
        entry) when a log is missing or disagrees.
    """
    manifest_path = Path(directory) / MANIFEST_NAME
    for index, entry in enumerate(manifest.entries):
        log = os.path.join(directory, entry.file)  # a string: thousands of Path joins cost more than the stats
        field = f"demos[{index}]"
        remedy = f"restore the log, or drop the entry with '{HINT}' and add the demonstration again"
        hints = (Hint("library remove", (str(directory), entry.name)),)
        row = rows.get(entry.name)
        try:
            if row is not None and row.stamp == log_stamp(log):
                samples, duration_s = row.samples, row.duration_s
            else:
                log = Path(log)
                samples, duration_s = log_sample_summary(log.read_bytes(), log)
        except FileNotFoundError:
            raise InputError(
                f"the joint log {entry.file} is missing; {remedy}", file=manifest_path, field=f"{field}.file",
                hints=hints,
            ) from None
        except OSError as error:
            raise InputError(f"cannot read the joint log: {error.strerror}", file=log) from None
        if samples != entry.samples:
            raise InputError(
                f"is {entry.samples} but the joint log {entry.file} has {samples} samples "
                f"(one of them was edited by hand); {remedy}",
                file=manifest_path,
                field=f"{field}.samples",
                hints=hints,
            )
        if not math.isclose(duration_s, entry.duration_s, rel_tol=0.0, abs_tol=DURATION_TOLERANCE_S):
            raise InputError(
                f"is {entry.duration_s!r} s but the joint log {entry.file} spans {duration_s!r} s "
                f"(one of them was edited by hand); {remedy}",
                file=manifest_path,
                field=f"{field}.duration_s",
                hints=hints,
            )


def create_directory(directory, manifest, first=(), *, label):
    """Makes ``directory`` a library holding ``manifest`` and the logs of ``first``
    (prepared demonstrations, ``demo_preparation.PreparedDemo``), all in one turn of its
    lock: the manifest is the library, so a create killed before it leaves no library
    (the logs are debris a later create clears) and one killed after leaves them all.
    Returns the manifest written.

    Raises
    ------
    InputError
        Naming ``label``: a file, a library already (also when another process made it
        one meanwhile), or a directory holding anything but what a killed create leaves
        (:func:`is_unused_library_directory`). Where a library writer has been (its lock
        file is there), that is decided under the lock: a writer may be half-way through
        making it a library. Nothing is left behind then.
    """
    directory = Path(directory)
    not_empty = "exists and is not empty; choose a new directory for a library"
    if directory.exists():
        if not directory.is_dir():
            raise InputError("exists and is not a directory", file=label)
        if not is_unused_library_directory(directory):
            # (Checked after: another process may be making it a library right now.)
            if (directory / MANIFEST_NAME).exists():
                raise InputError("is a library already", file=label)
            if not (directory / LOCK_NAME).exists():
                raise InputError(not_empty, file=label)
            # A library writer has been here and may be writing now (its manifest's
            # temporary file is not yet a manifest): decide under the lock, below.
    created = not directory.exists()
    try:
        make_directory(directory)
        with locked_for_writing(directory, directory):
            if (directory / MANIFEST_NAME).exists():  # another process was quicker
                created = False
                raise InputError("is a library already", file=label)
            if not is_unused_library_directory(directory):  # no writer is at work now
                raise InputError(not_empty, file=label)
            make_directory(directory / DEMOS_DIRECTORY)
            make_directory(directory / CACHE_DIRECTORY)
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
                remove_unused_directory(directory)
        raise
    return manifest


def write_new_entries(directory, manifest, accepted):
    """Adds prepared demonstrations (``demo_preparation.PreparedDemo``) to the library at
    ``directory`` whose manifest on disk is ``manifest`` (call with its lock held): their
    logs, then one manifest listing them. A crash leaves at worst logs the manifest does
    not list; on an error the new logs are taken away again. Returns the new manifest
    and its bytes as written."""
    directory = Path(directory)
    make_directory(directory / DEMOS_DIRECTORY)
    written = [directory / item.entry.file for item in accepted]
    try:
        atomic_write_many([(log, item.log_bytes) for log, item in zip(written, accepted)])
        manifest = manifest.with_entries(manifest.entries + tuple(item.entry for item in accepted))
        written_bytes = write_manifest(directory, manifest)
    except BaseException:
        # Nothing references the new logs yet: take them away again.
        for log in written:
            with contextlib.suppress(OSError):
                log.unlink()
        raise
    return manifest, written_bytes


def delete_entry_files(directory, entry):
    """Deletes a removed entry's log and its feature file of older drake-lfd versions
    (``cache/NAME.npz``) where they are: call once the manifest no longer lists it (a
    damaged library may have neither, or a file where the cache folder should be)."""
    directory = Path(directory)
    for path in (directory / entry.file, directory / CACHE_DIRECTORY / f"{entry.name}.npz"):
        try:
            path.unlink()
        except (FileNotFoundError, NotADirectoryError):
            pass
    if (directory / DEMOS_DIRECTORY).is_dir():
        fsync_directory(directory / DEMOS_DIRECTORY)


def copy_files(source_directory, manifest, destination, *, check_log, finish):
    """Copies a library's manifest and logs into ``destination``, all or nothing.

    The copy is built in a temporary directory beside ``destination`` and renamed into
    place, so ``destination`` never holds half a copy.

    Parameters
    ----------
    source_directory : Path
        The library directory to copy (hold its shared lock).
    manifest : Manifest
        Its manifest, as read under that lock.
    destination : str or Path
        A directory that does not exist (its parents are created) or is empty.
    check_log : callable
        Called with each entry before its log is copied; raises to refuse a damaged log.
    finish : callable
        Called with the staging directory once it holds the manifest and the logs (to
        write its feature cache), before the rename.

    Raises
    ------
    InputError
        ``destination`` is a file or a non-empty directory. Nothing is left behind on
        any error.
    """
    destination = Path(destination)
    if destination.exists():
        if not destination.is_dir():
            raise InputError("exists and is not a directory", file=destination)
        if any(destination.iterdir()):
            raise InputError("exists and is not empty; choose a new directory for the copy", file=destination)
    parent = destination.absolute().parent
    make_directory(parent)
    staging = parent / f".{destination.name}.copy-{uuid.uuid4().hex[:12]}"
    staging.mkdir()
    try:
        make_directory(staging / DEMOS_DIRECTORY)
        make_directory(staging / CACHE_DIRECTORY)
        for entry in manifest.entries:
            check_log(entry)
            target = staging / entry.file
            make_directory(target.parent)
            atomic_write_bytes(target, (Path(source_directory) / entry.file).read_bytes())
        write_manifest(staging, manifest)
        finish(staging)
        fsync_directory(staging)
        if destination.exists():
            destination.rmdir()  # empty, checked above
        os.rename(staging, destination)
        fsync_directory(parent)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
