"""Atomic file writes: a reader (or a crash) sees the old file or the new one, never a mix.

Used for everything drake-lfd writes that a user keeps: library manifests and joint logs,
policies, recorded demonstrations, JSON results.
"""

from __future__ import annotations

import json
import os
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
    existing one keeps its mode.

    Parameters
    ----------
    path : str or Path
    data : bytes
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode & 0o777
    except FileNotFoundError:
        mode = 0o644
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
    """Writes ``document`` as indented JSON, atomically."""
    atomic_write_bytes(path, (json.dumps(document, indent=1) + "\n").encode("utf-8"))
