"""Atomic file writes: a reader (or a crash) sees the old file or the new one, never a mix.

Used for everything drake-lfd writes that a user keeps: library manifests and joint logs,
policies, recorded demonstrations, JSON results. JSON written here is strict
(:func:`atomic_write_json`: non-finite numbers as ``null``, as :mod:`drake_lfd.io.strict_json`).
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

__all__ = ['fsync_directory', 'atomic_write_bytes', 'atomic_write_json']

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



def atomic_write_json(path, document) -> None:
    """Writes ``document`` as indented, strict JSON, atomically: a number that is not
    finite is written as ``null`` (the value does not exist or could not be computed,
    :mod:`drake_lfd.io.strict_json`), never as ``NaN`` or ``Infinity``."""
    from drake_lfd.io.strict_json import strict_json_text  # that module writes through this one

    atomic_write_bytes(path, (strict_json_text(document) + "\n").encode("utf-8"))
