"""Atomic file writes: a reader (or a crash) sees the old file or the new one, never a mix.

Used for everything drake-lfd writes that a user keeps: library manifests and joint logs,
policies, recorded demonstrations, JSON results. JSON written here is strict
(:func:`atomic_write_json`: non-finite numbers as ``null``, as :mod:`drake_lfd.io.strict_json`).
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

__all__ = ['fsync_directory', 'atomic_write_bytes', 'atomic_write_many', 'atomic_write_json']

# From this many files on, atomic_write_many flushes them with one sync() of the file systems
# instead of an fsync each (an fsync costs milliseconds: 10,000 logs would take a minute).
SYNC_ALL_FROM_FILES = 8

def fsync_directory(directory):
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # platforms without directory descriptors
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_bytes(path, data):
    """Replaces ``path`` with ``data`` so readers see the old or the new file, never a mix.

    Writes a temporary file in the same directory, flushes and fsyncs it, renames it
    over ``path`` with ``os.replace`` and fsyncs the directory. On any failure the
    temporary file is removed and ``path`` is untouched. A new file gets mode 0644, an
    existing one keeps its mode. A ``path`` that is not a regular file (a device such as
    ``/dev/stdout``, a named pipe) is written into directly.

    Parameters
    ----------
    path : str or Path
    data : bytes
    """
    path = Path(path)
    try:
        status = path.stat()
        mode = status.st_mode & 0o777
    except FileNotFoundError:
        status = None
        mode = 0o644
    if status is not None and not stat.S_ISREG(status.st_mode):
        # A device or a pipe (``--json /dev/stdout``, a named pipe): nothing to replace
        # atomically, and renaming over /dev/stdout would replace the device itself.
        with open(path, "wb") as file:
            file.write(data)
            file.flush()
        return
    fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with _naming(path):
            with os.fdopen(fd, "wb") as file:
                file.write(data)
                file.flush()
                os.fsync(file.fileno())
            os.chmod(temporary, mode)
            os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise
    fsync_directory(path.parent)


@contextlib.contextmanager
def _naming(path):
    """Gives an OSError raised without a file name (a write's "No space left on device")
    the name of the file being written, so the one line the user reads names it."""
    try:
        yield
    except OSError as error:
        if error.filename is not None or error.errno is None:
            raise
        raise OSError(error.errno, error.strerror or str(error), str(path)) from error


def atomic_write_many(items):
    """Writes several files, each atomically as :func:`atomic_write_bytes` does, with the
    flushing batched: every temporary file is written, then flushed to disk (an fsync
    each, or for :data:`SYNC_ALL_FROM_FILES` files or more one ``os.sync``, which on
    Linux returns when the data is on disk), then renamed into place, then each
    directory fsynced once. A reader sees each file old or new, never a mix; a crash
    before the renames leaves only temporary files.

    Parameters
    ----------
    items : sequence of (path, bytes)
        Regular files (or new paths); every ``path`` distinct.

    Raises
    ------
    OSError
        Writing or renaming failed; the temporary files not yet renamed are removed
        (files already renamed into place stay).
    """
    staged = []  # (temporary, path, mode)
    renamed = 0
    try:
        for path, data in items:
            path = Path(path)
            try:
                mode = path.stat().st_mode & 0o777
            except FileNotFoundError:
                mode = 0o644
            fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
            staged.append((temporary, path, mode))
            with _naming(path), os.fdopen(fd, "wb") as file:
                file.write(data)
                if len(items) < SYNC_ALL_FROM_FILES:
                    file.flush()
                    os.fsync(file.fileno())
            os.chmod(temporary, mode)
        if len(items) >= SYNC_ALL_FROM_FILES:
            os.sync()
        for temporary, path, _ in staged:
            os.replace(temporary, path)
            renamed += 1
    except BaseException:
        for temporary, _, _ in staged[renamed:]:
            try:
                os.unlink(temporary)
            except FileNotFoundError:
                pass
        raise
    for directory in sorted({str(Path(path).parent) for path, _ in items}):
        fsync_directory(directory)


def atomic_write_json(path, document) -> None:
    """Writes ``document`` as indented, strict JSON, atomically: a number that is not
    finite is written as ``null`` (the value does not exist or could not be computed,
    :mod:`drake_lfd.io.strict_json`), never as ``NaN`` or ``Infinity``."""
    from drake_lfd.io.strict_json import strict_json_text  # that module writes through this one

    atomic_write_bytes(path, (strict_json_text(document) + "\n").encode("utf-8"))
